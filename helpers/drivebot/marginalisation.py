"""Node pruning by marginalisation (coursework Q3b): remove a vertex and keep what its edges knew.

Deleting a vertex together with its edges (what the graph's ``remove_vertex`` does) throws information away.
*Marginalising* it keeps that information: the vertex's edges are replaced by one dense linear prior on its
neighbours. With the Gauss–Newton system of the vertex's edges split into the vertex to remove (index m) and
its neighbours (index a; fixed ones included, see :func:`local_system`),

    H = [[H_aa, H_am],      b = [b_a,        (H = Σ JᵀΩJ, b = Σ JᵀΩe over the vertex's edges only)
         [H_ma, H_mm]],          b_m],

eliminating δx_m from H δx = b (the Schur complement) gives the system on the neighbours alone

    Λ = H_aa − H_am H_mm⁻¹ H_ma,        η = b_a − H_am H_mm⁻¹ b_m.                               (1)

Λ is the information the removed edges carried about the neighbours, and it is the *marginal* information:
for any SPD H, (Λ⁻¹) is exactly the (a, a) block of H⁻¹ (block inversion), so covariances of the vertices that
stay are unchanged. The price is **fill-in**: Λ couples *every pair* of neighbours (the previous and next pose
and all landmarks the pose saw), so H gets dense blocks where it had none.

In the graph, Λ and η become one :func:`linear_prior_class` edge over the neighbours (a linearised factor, as
GTSAM's ``LinearContainerFactor``): with Λ = V diag(λ) Vᵀ (positive λ only; Λ is often rank-deficient, e.g.
a pose marginal fixes only relative geometry), J = diag(√λ) Vᵀ and r₀ = diag(1/√λ) Vᵀ η,

    e(x) = J (x ⊟ x₀) + r₀,  Ω = I   ⇒   JᵀΩJ = Λ  and  JᵀΩe(x₀) = η,                          (2)

where x₀ is the linearisation point (the neighbours' estimates at marginalisation time) and ⊟ wraps heading
differences. Its contribution to H and b at x₀ is exactly (1); away from x₀ it stays linear (the usual
approximation of marginalisation in sliding-window filters). χ² of the new edge is ‖e‖², which need not equal
the removed edges' χ² (a constant offset), so compare χ² only between graphs marginalised the same way.

Functions: :func:`schur_complement` (plain numpy reference of (1)), :func:`local_system` (H, b of one
vertex's edges), :func:`linear_prior_factor` ((2) from Λ, η), :func:`marginalise_vertex` (the graph
operation), :func:`hessian_blocks` (H re-ordered by vertex, for spy plots).
"""
from __future__ import annotations

import numbers

import numpy as np

from ..graph import BaseEdge, BaseVertex, VertexPointXY, VertexSE2, wrap_angle
from ..validation import float_array, int_array

__all__ = ["schur_complement", "local_system", "linear_prior_factor", "linear_prior_class", "marginalise_vertex",
           "hessian_blocks"]

_SUPPORTED = (VertexSE2, VertexPointXY)


def _symmetric(H, name):
    """A finite symmetric square float matrix (asymmetry up to 1e−9 of its largest entry is round-off)."""
    H = float_array(H, name)
    if H.ndim != 2 or H.shape[0] != H.shape[1] or not np.all(np.isfinite(H)):
        raise ValueError(f"{name} must be a finite square matrix, got shape {H.shape}")
    if H.size and np.max(np.abs(H - H.T)) > 1e-9 * max(np.max(np.abs(H)), np.finfo(float).tiny):
        raise ValueError(f"{name} must be symmetric")
    return H


def _indices(values, n, name):
    """Distinct indices in [0, n) as an int64 array (empty allowed)."""
    idx = int_array(np.ravel(values), name)
    if np.any(idx < 0) or np.any(idx >= n):
        raise ValueError(f"{name} has an index out of range [0, {n}): {idx.tolist()}")
    if np.unique(idx).size != idx.size:
        raise ValueError(f"{name} has duplicate indices: {idx.tolist()}")
    return idx


def schur_complement(H, b, keep, marginalise):
    """(Λ, η) of equation (1): the system on ``keep`` after eliminating the indices ``marginalise``.

    ``H`` (n, n) symmetric with an invertible (m, m) block, ``b`` (n,), ``keep`` and ``marginalise`` disjoint
    index arrays. Plain numpy (dense solve), the reference for :func:`marginalise_vertex`.
    """
    H = _symmetric(H, "H")
    b = float_array(b, "b")
    if b.shape != (H.shape[0],):
        raise ValueError(f"b must have shape ({H.shape[0]},), got {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError("b must be finite (no NaN or inf)")
    keep, marg = _indices(keep, H.shape[0], "keep"), _indices(marginalise, H.shape[0], "marginalise")
    if np.intersect1d(keep, marg).size:
        raise ValueError("keep and marginalise must be disjoint indices into H")
    if marg.size == 0:
        return H[np.ix_(keep, keep)].copy(), b[keep].copy()
    H_mm = H[np.ix_(marg, marg)]
    H_am = H[np.ix_(keep, marg)]
    try:
        X = np.linalg.solve(H_mm, np.column_stack([H_am.T, b[marg]]))   # H_mm⁻¹ [H_ma | b_m]
    except np.linalg.LinAlgError:
        raise ValueError("the block of H to marginalise is singular (the vertex is not determined by its "
                         "edges), so it cannot be marginalised") from None
    lam = H[np.ix_(keep, keep)] - H_am @ X[:, :-1]
    return 0.5 * (lam + lam.T), b[keep] - H_am @ X[:, -1]


def local_system(vertex):
    """(neighbours, H, b) of the Gauss–Newton system of ``vertex``'s edges at the current estimates.

    ``neighbours`` are the other vertices its edges touch (in first-seen order), fixed ones included; H and b
    are ordered [vertex, neighbours…]. A fixed neighbour's rows never enter the optimiser's H, but keeping it
    in the prior edge keeps that edge attached to the anchor (so the graph's gauge check still sees it).
    """
    if not isinstance(vertex, _SUPPORTED) or type(vertex).oplus_jacobian_batch is not None:
        raise ValueError(f"vertex must be a VertexSE2 or VertexPointXY (additive ⊞), got {type(vertex).__name__}")
    if vertex.graph is None or vertex.fixed:
        raise ValueError("vertex must be a free vertex of a graph (not fixed, not removed)")
    order, start = [vertex], {vertex: 0}
    n = type(vertex).dimension
    for e in vertex.edges():
        for v in e.vertices():
            if v not in start:
                if not isinstance(v, _SUPPORTED) or type(v).oplus_jacobian_batch is not None:
                    raise ValueError(f"unsupported neighbour {type(v).__name__} (additive ⊞ vertices only)")
                start[v] = n
                order.append(v)
                n += type(v).dimension
    H, b = np.zeros((n, n)), np.zeros(n)
    for e in vertex.edges():
        err, jac, info = e.error(), e.jacobians(), e.information
        cols = [(start[v], type(v).dimension, J) for v, J in zip(e.vertices(), jac)]
        for i, di, Ji in cols:
            b[i:i + di] += Ji.T @ info @ err
            for j, dj, Jj in cols:
                H[i:i + di, j:j + dj] += Ji.T @ info @ Jj
    return order[1:], H, b


_PRIOR_CLASSES: dict = {}


def linear_prior_class(vertex_types, rank):
    """The edge class of equation (2) for these neighbour types and this rank (one class per signature)."""
    vertex_types = tuple(vertex_types)
    if not vertex_types or not all(isinstance(t, type) and issubclass(t, _SUPPORTED)
                                   and t.oplus_jacobian_batch is None for t in vertex_types):
        raise ValueError(f"vertex_types must be VertexSE2 / VertexPointXY classes, got {vertex_types!r}")
    if isinstance(rank, bool) or not isinstance(rank, (int, np.integer)) or rank < 1:
        raise ValueError(f"rank must be a positive integer, got {rank!r}")
    key = (vertex_types, int(rank))
    if key not in _PRIOR_CLASSES:
        dims = [t.dimension for t in vertex_types]
        n = sum(dims)
        angle = np.concatenate([[0.0, 0.0, 1.0] if issubclass(t, VertexSE2) else [0.0] * t.dimension
                                for t in vertex_types]).astype(bool)
        splits = np.cumsum(dims)[:-1]

        def evaluate(states, z, params, jacobians=True):
            d = np.concatenate(states, axis=1) - params["x0"]          # x ⊟ x₀ ...
            d[:, angle] = wrap_angle(d[:, angle])                       # ... with wrapped headings
            J = params["jac"]
            e = np.einsum("erk,ek->er", J, d) - z                       # z = −r₀
            return e, (np.split(J, splits, axis=2) if jacobians else None)

        _PRIOR_CLASSES[key] = type(f"LinearPrior{len(vertex_types)}x{rank}", (BaseEdge,), {
            "__doc__": "Dense linear prior from marginalisation: e = J (x ⊟ x₀) + r₀, Ω = I (equation (2)).",
            "vertex_types": vertex_types, "measurement_dimension": int(rank),
            "parameters": {"x0": np.zeros(n), "jac": np.zeros((int(rank), n))},
            "evaluate": staticmethod(evaluate)})
    return _PRIOR_CLASSES[key]


def linear_prior_factor(lam, eta, rtol=1e-10):
    """(J (r, n), r₀ (r,)) of equation (2) with JᵀJ = Λ and Jᵀr₀ = η (eigenvalues ≤ rtol·max dropped)."""
    lam = _symmetric(lam, "lam")
    eta = float_array(eta, "eta")
    if eta.shape != (lam.shape[0],):
        raise ValueError(f"eta must have shape ({lam.shape[0]},), got {eta.shape}")
    if not np.all(np.isfinite(eta)):
        raise ValueError("eta must be finite (no NaN or inf)")
    if isinstance(rtol, bool) or not isinstance(rtol, numbers.Real) or not 0 <= rtol < 1:
        raise ValueError(f"rtol must be a number in [0, 1), got {rtol!r}")
    w, V = np.linalg.eigh(0.5 * (lam + lam.T))
    if w.size == 0 or w[-1] <= 0:
        raise ValueError("lam has no positive eigenvalue: the marginal carries no information")
    if w[0] < -1e-8 * w[-1]:
        raise ValueError(f"lam must be positive semi-definite (an information matrix), but has the eigenvalue "
                         f"{w[0]:.3g} (largest {w[-1]:.3g})")
    pos = w > rtol * w[-1]
    root = np.sqrt(w[pos])
    return root[:, None] * V[:, pos].T, (V[:, pos].T @ eta) / root


def marginalise_vertex(graph, vertex):
    """Marginalise ``vertex`` out of ``graph``: remove it and its edges, add one dense prior (2) on its
    neighbours. Returns the new edge (None when every neighbour is fixed: then nothing is left to constrain).
    Build the structure again before optimising (``graph.initialize_optimization()``)."""
    if not isinstance(vertex, BaseVertex) or vertex.graph is not graph:
        raise ValueError(f"vertex must be a vertex of this graph, got {vertex!r}")
    neighbours, H, b = local_system(vertex)
    d = type(vertex).dimension
    keep, marg = np.arange(d, H.shape[0]), np.arange(d)
    lam, eta = schur_complement(H, b, keep, marg)
    graph.remove_vertex(vertex)
    if all(v.fixed for v in neighbours):
        return None
    J, r0 = linear_prior_factor(lam, eta)
    cls = linear_prior_class([type(v) for v in neighbours], J.shape[0])
    edge = cls(neighbours, measurement=-r0, information=np.eye(J.shape[0]),
               x0=np.concatenate([v.estimate for v in neighbours]), jac=J)
    graph.add_edge(edge)
    return edge


def hessian_blocks(graph, vertices):
    """H of ``graph`` (built structure) re-ordered so that the free ``vertices`` come in the given order;
    returns (H dense, starts) with ``starts`` each vertex's first row (for spy plots with block grid lines)."""
    idx, starts, n, seen = [], [], 0, set()
    for v in vertices:
        if v in seen:
            raise ValueError(f"vertices must be distinct, got {v!r} twice")
        seen.add(v)
        if not isinstance(v, BaseVertex) or v.graph is not graph or v.hessian_index is None or v.hessian_index < 0:
            raise ValueError(f"every vertex must be a free vertex of the graph with a built structure, got {v!r}")
        d = type(v).dimension
        idx.extend(range(v.hessian_index, v.hessian_index + d))
        starts.append(n)
        n += d
    H = graph.hessian().toarray()
    return H[np.ix_(idx, idx)], np.array(starts, dtype=np.int64)
