"""helpers.graph — the coursework's g2o-style graph optimiser: vertices, edges, sparse Gauss–Newton / LM.

Build a graph one element at a time, then optimise::

    from helpers.graph import SparseOptimizer, VertexSE2, EdgeSE2
    g = SparseOptimizer()
    a, b = VertexSE2(0, [0, 0, 0], fixed=True), VertexSE2(1, [0.9, 0.1, 0.0])
    g.add_vertex(a); g.add_vertex(b)
    g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0], information=np.eye(3)))
    g.initialize_optimization()          # builds the structure (again after any add/remove/set_fixed)
    chi2 = g.optimize(50, algorithm="lm")   # "lm" (the coursework's LM) or "gn"; g.statistics per iteration
    cov = g.compute_marginals([b])[b]    # 3×3 block of H⁻¹ at the solution

The model: every edge predicts h(x) from its vertices and has the error e = h(x) − z (angles wrapped) with
information Ω; χ² = Σ eᵀΩe. Linearising e(X ⊞ δ) ≈ e + Jδ gives the normal equations H dX = b with
H = Σ JᵀΩJ and b = Σ JᵀΩe, and the step X ← X ⊞ (−dX); Levenberg–Marquardt solves (H + μI) dX = b instead.

A new VERTEX class subclasses ``BaseVertex``, sets ``dimension`` and, if ⊞ is not plain addition, overrides the
vectorised ``oplus_batch(x, dx)`` (arrays (V, d) → (V, d)). Extra per-vertex data are ordinary attributes.

A new EDGE class subclasses ``BaseEdge`` and sets ``vertex_types`` (one vertex class per slot),
``measurement_dimension`` and, optionally, ``parameters`` ({name: default}, one value per edge, a constructor
keyword). Its model is a staticmethod over all E edges of the class at once: either ``error_batch(states, z,
params)`` (the error only; Jacobians by central differences through ⊞) or ``evaluate(states, z, params,
jacobians=True)`` returning e (E, m) and [J_0, J_1, ...], J_k = ∂e/∂(vertex k) of shape (E, m, d_k). For
example, a pose that sees a point at a known offset in the world frame (z = m − t)::

    class EdgeWorldOffset(BaseEdge):
        vertex_types = (VertexSE2, VertexPointXY)
        measurement_dimension = 2

        @staticmethod
        def evaluate(states, z, params, jacobians=True):
            x, m = states
            e = m - x[:, :2] - z                           # e = m − t − z
            if not jacobians:
                return e, None
            jx = batch_matrix([[-1, 0, 0], [0, -1, 0]])     # ∂e/∂[x, y, ψ]
            jm = batch_matrix([[1, 0], [0, 1]])             # ∂e/∂m
            return e, [np.broadcast_to(jx, (len(z), 2, 3)), np.broadcast_to(jm, (len(z), 2, 2))]

The standard 2D set is in ``edges2d`` (EdgeSE2, EdgeSE2Prior, EdgePositionPrior, EdgeHeadingPrior,
EdgeRangeBearing, EdgePointPrior, EdgeSE2PointXY); angles are wrapped by ``wrap_angle`` (``angles``). Errors:
``GraphError`` (a ValueError), ``GaugeFreedomError`` (nothing anchors a component) and ``NonFiniteError`` (NaN/inf,
naming the edges). ``optimize`` is transactional: on any exception or interrupt the vertices hold the last
accepted state. ``SparseOptimizer`` (``optimizer``) documents the rest of the API.
"""

from .angles import wrap_angle, wrap_angle_mod
from .edge import BaseEdge, batch_matrix, check_information, information_from_covariance, numeric_jacobians
from .edges2d import (EdgeHeadingPrior, EdgePointPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2, EdgeSE2PointXY,
                      EdgeSE2Prior)
from .errors import GaugeFreedomError, GraphError, NonFiniteError
from .optimizer import SparseOptimizer
from .vertex import BaseVertex, VertexPointXY, VertexSE2

__all__ = ["wrap_angle", "wrap_angle_mod", "BaseVertex", "VertexSE2", "VertexPointXY", "BaseEdge", "check_information",
           "information_from_covariance", "batch_matrix", "numeric_jacobians", "EdgeSE2", "EdgeSE2Prior",
           "EdgePositionPrior", "EdgeHeadingPrior", "EdgeRangeBearing", "EdgePointPrior", "EdgeSE2PointXY",
           "SparseOptimizer", "GraphError", "GaugeFreedomError", "NonFiniteError"]
