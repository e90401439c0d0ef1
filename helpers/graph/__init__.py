"""helpers.graph — the coursework's g2o-style graph optimiser, vectorised per edge class and sparse.

Students build a graph one element at a time::

    from helpers.graph import SparseOptimizer, VertexSE2, EdgeSE2
    g = SparseOptimizer()
    a, b = VertexSE2(0, [0, 0, 0], fixed=True), VertexSE2(1, [0.9, 0.1, 0.0])
    g.add_vertex(a); g.add_vertex(b)
    g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0], information=np.eye(3)))
    g.initialize_optimization()          # builds the structure (again after any add/remove/set_fixed)
    chi2 = g.optimize()                  # the default LM (≤ 100 iterations); algorithm="lm" (the coursework's
                                         # LM), "gn" (Gauss–Newton) or "lm-gtsam" (GTSAM's LM with its own
                                         # stopping rules); g.statistics per iteration
    cov = g.compute_marginals([b])[b]    # 3×3 block of H⁻¹ at the solution

Conventions: e = h(x) − z, χ² = Σ eᵀΩe, H = Σ JᵀΩJ, b = Σ JᵀΩe, dX = H⁻¹ b (LM: (H + μI)⁻¹ b), X ← X ⊞ (−dX).

ALGORITHMS — ``optimize(max_iterations=100, algorithm="default")``
-----------------------------------------------------------------
"default" (``DefaultParams``; ``algorithms_default``) is meant to reach the optimum from far away, e.g. straight
from a dataset's dead-reckoning start: Levenberg–Marquardt with GTSAM's λ schedule (λ₀ = 1e−5 absolute, λI damping,
accept when actual / predicted decrease > 1e−3, then λ/10, else 10λ); ``VertexSE2`` poses move along the arcs of the
SE(2) exponential map (as ``VertexSE2Exp`` / GTSAM's Pose2: same linear step, only the curve differs, and a rigid
turn of a chain of poses is then exact); it stops only when χ² fell by ≤ 1e−9·χ² over the last 5 accepted
iterations, the linear model predicts a decrease ≤ 1e−14·χ², or ‖b‖∞ / √χ² < 1e−12. On the shipped datasets
(``tests/test_graph_convergence.py``) it reaches GTSAM's optimum χ² (to 1e−6) within 100 iterations, except Victoria
Park (there after 143; after 100 it is at 210 200, below GTSAM's default result 210 660) and W20000, where after 200
iterations it is below GTSAM LM's χ² after 200. The named algorithms keep their own parameters:
"lm" — the coursework's LM (τ = 1e−3 relative damping; what DriveBot runs, ``tau=`` sets τ), "gn" — Gauss–Newton
with step halving, "lm-gtsam" — GTSAM's LM including its stopping rules (relative decrease < 1e−5).

PROTOCOL — defining a new VERTEX class
--------------------------------------
Subclass ``BaseVertex``; set ``dimension``; if ⊞ is not plain addition, override the *vectorised*
``oplus_batch(x, dx)`` (staticmethod, arrays (V, dimension) → (V, dimension)). Extra per-vertex data (a time
stamp, a landmark id) are ordinary attributes set in ``__init__`` after calling ``super().__init__(id, ...)``::

    class VehicleVertex(VertexSE2):          # inherits dimension 3 and the ψ-wrapping oplus_batch
        def __init__(self, time, id=None, estimate=None, fixed=False):
            super().__init__(id, estimate, fixed)
            self.time = float(time)

Ids are allocated per class from 0 when not given; a graph rejects a second vertex with the same (class, id).

If the class's ⊞ is not (to first order) plain addition of the update to the coordinates, also give the vectorised
``oplus_jacobian_batch(x)`` (staticmethod, (V, d) → (V, d, d) = ∂(x ⊞ δ)/∂δ at δ = 0): edges keep giving
Jacobians with respect to the coordinates, and the optimiser multiplies them by it. ``VertexSE2Exp`` (GTSAM's
Pose2 update x ∘ Exp(δ), body-frame δ) is the example; its marginals are then covariances of δ.

PROTOCOL — defining a new EDGE class
------------------------------------
Subclass ``BaseEdge`` and set, at class level,

    vertex_types           tuple with one vertex class per slot (any number of slots; subclasses accepted)
    measurement_dimension  m
    parameters             optional dict name -> default, one value per edge (shape = the default's shape);
                           becomes a constructor keyword, an attribute (``edge.dt``) and ``set_parameter``

and give the model, as staticmethods over all E edges of the class at once, in one of two tiers:

    error_batch(states, z, params)                 the error only; ``BaseEdge.evaluate`` then supplies the
                                                   Jacobians by central differences through each slot's ⊞
                                                   (``numeric_jacobians``) — the quickest way to a working edge;
    evaluate(states, z, params, jacobians=True)    the error and analytic Jacobians (what the shipped edges do):
        states  list, states[k] is the (E, d_k) array of the estimates in slot k
        z       (E, m) measurements;  params {name: (E, *shape)}
        returns (e, jac): e (E, m) = h(x) − z (wrap angular components!), and jac = [J_0, J_1, ...] with
                J_k = ∂e/∂(coordinates of vertex k) (= ∂e/∂δ for additive ⊞), shape (E, m, d_k) — or None.

Write the model with numpy array operations over the E edges (no Python loop), the equations in the docstring;
``batch_matrix`` stacks a Jacobian written row by row. Test J against central differences through ⊞.
Where profiling shows a model dominates, ``evaluate`` may call a compiled kernel (``kernels.py``); the numpy
model then stays in the class as ``evaluate_reference`` and a test checks that both agree (EdgeSE2 and the
DriveBot kinematics edge do this: on 64k edges their kernels take a third to a half of the numpy time).

Example — the DriveBot velocity-form kinematics edge with a per-edge time step (this is, line for line, the
numpy model ``helpers.drivebot.VehicleKinematicsEdge.evaluate_reference``; a test keeps the two identical)::

    class VehicleKinematicsEdge(BaseEdge):
        vertex_types = (VertexSE2, VertexSE2)
        measurement_dimension = 3
        parameters = {"dt": 0.1}

        @staticmethod
        def evaluate(states, z, params, jacobians=True):
            xk, xn = states
            inv_dt = 1.0 / params["dt"]
            c, s = np.cos(xk[:, 2]), np.sin(xk[:, 2])
            dx, dy = xn[:, 0] - xk[:, 0], xn[:, 1] - xk[:, 1]
            dpsi = wrap_angle(xn[:, 2] - xk[:, 2])
            e = np.stack([c * dx + s * dy, -s * dx + c * dy, dpsi], axis=1) * inv_dt[:, None] - z
            if not jacobians:
                return e, None
            jk = batch_matrix([[-c, -s, -dx * s + dy * c],
                               [s, -c, -dx * c - dy * s],
                               [0, 0, -1]])
            jn = batch_matrix([[c, s, 0],
                               [-s, c, 0],
                               [0, 0, 1]])
            return e, [jk * inv_dt[:, None, None], jn * inv_dt[:, None, None]]

    edge = VehicleKinematicsEdge([v_prev, v_new], measurement=u, information=np.linalg.inv(R_odo), dt=0.1)

The same edge in the first tier — error only, numeric Jacobians::

    class KinematicsErrorOnly(BaseEdge):
        vertex_types = (VertexSE2, VertexSE2)
        measurement_dimension = 3
        parameters = {"dt": 0.1}

        @staticmethod
        def error_batch(states, z, params):
            xk, xn = states
            c, s = np.cos(xk[:, 2]), np.sin(xk[:, 2])
            dx, dy = xn[:, 0] - xk[:, 0], xn[:, 1] - xk[:, 1]
            dpsi = wrap_angle(xn[:, 2] - xk[:, 2])
            return np.stack([c * dx + s * dy, -s * dx + c * dy, dpsi], axis=1) / params["dt"][:, None] - z

Many edges of one class at once (loaders): ``g.add_edges(EdgeClass, rows_of_vertices, measurements (E, m),
information (E, m, m) or (m, m), **params)`` — vectorised validation, same result as adding them one by one.

Performance model: adding an element is O(1) (amortised arrays); ``initialize_optimization`` is vectorised over
edges (gather indices, and the Hessian pattern laid out from the distinct vertex pairs, ``block_pattern``); the
first factorisation of a pattern builds a ``qdldl.Solver`` (AMD ordering, symbolic LDLᵀ) — or, for a large
pattern whose factor has dense columns, CHOLMOD's supernodal factorisation through cvxopt (``cholmod_backend``);
each iteration calls every edge class's ``evaluate`` once, forms W J M in one pass and adds JᵀΩJ into H's CSC data
(``batched``), and refactorises (qdldl's ``Solver.update``, or CHOLMOD's numeric step). Marginals: Takahashi
sparse inverse on qdldl's L (``marginals``), no dense inverse. Modules by responsibility: ``storage`` / ``elements`` (growable arrays,
add/remove), ``structure`` (indexing, sparsity pattern, gauge check), ``linearise`` (evaluate, whiten, assemble H
and b), ``algorithms`` (Gauss–Newton, the coursework's LM, GTSAM's LM schedule; parameter dataclasses),
``algorithms_default`` (the default algorithm), ``linear`` (the pattern and the LDLᵀ solver), ``batched`` (the
per-edge products), ``marginals``, ``kernels`` (compiled fast paths, each tested equal to its edge's ``evaluate_reference``).

Per-object API (from ``BaseEdge``): ``set_vertex(k, v)``, ``vertex(k)``, ``vertices()``, ``set_measurement``,
``set_information`` (must be symmetric positive definite), ``measurement``, ``information``, ``error()``,
``jacobians()``, ``chi2()``; an edge may be edited while in a graph, also after ``initialize_optimization`` (values
are written through to the store and re-gathered before the next linearisation). ``check_measurements(z, name)``
(classmethod hook, default: accept) lets an edge class reject physically impossible measurements in
``set_measurement`` and ``add_edges`` alike.

The standard 2D set (``edges2d``): EdgeSE2 (between, GTSAM's BetweenFactor error), EdgeSE2Prior, EdgePositionPrior
(GPS with ``lever_arm``), EdgeHeadingPrior (compass with ``offset``, wrapped), EdgeRangeBearing (z = (range,
bearing)), EdgePointPrior, EdgeSE2PointXY (g2o's EDGE_SE2_XY). Angles: ``wrap_angle`` (and the simulator's
``wrap_angle_mod``) in ``angles``. Errors: ``GraphError`` (a ValueError), ``GaugeFreedomError`` and
``NonFiniteError`` (NaN/inf χ², error or Jacobian, naming the edges). ``optimize`` is transactional: on any exception
or interrupt the vertices hold the last accepted state.
"""

from . import kernels
from .angles import wrap_angle, wrap_angle_mod
from .edge import BaseEdge, batch_matrix, check_information, information_from_covariance, numeric_jacobians
from .edges2d import (EdgeHeadingPrior, EdgePointPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2,
                      EdgeSE2PointXY, EdgeSE2Prior)
from .errors import GaugeFreedomError, GraphError, NonFiniteError
from .algorithms import GaussNewtonParams, GTSAMLevenbergMarquardtParams, LevenbergMarquardtParams
from .algorithms_default import DefaultParams
from .optimizer import SparseOptimizer
from .vertex import BaseVertex, VertexPointXY, VertexSE2, VertexSE2Exp

__all__ = ["DefaultParams", "GaussNewtonParams", "LevenbergMarquardtParams", "GTSAMLevenbergMarquardtParams", "wrap_angle", "wrap_angle_mod", "BaseVertex", "VertexSE2", "VertexSE2Exp", "VertexPointXY", "BaseEdge",
           "check_information", "information_from_covariance", "batch_matrix", "numeric_jacobians", "EdgeSE2", "EdgeSE2Prior", "EdgePositionPrior",
           "EdgeHeadingPrior", "EdgeRangeBearing", "EdgePointPrior", "EdgeSE2PointXY", "SparseOptimizer", "GraphError",
           "GaugeFreedomError", "NonFiniteError"]
