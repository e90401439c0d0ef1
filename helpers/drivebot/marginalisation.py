"""Node pruning by marginalisation (coursework Q3b): remove a vertex and keep what its edges knew.

Deleting a vertex with its edges (``remove_vertex``) throws information away; *marginalising* it replaces its
edges by one dense linear prior on its neighbours. With the Gauss–Newton system of the vertex's edges split into
the vertex to remove (index m) and its neighbours (index a, see :func:`local_system`),

    H = [[H_aa, H_am],      b = [b_a,        (H = Σ JᵀΩJ, b = Σ JᵀΩe over the vertex's edges only)
         [H_ma, H_mm]],          b_m],

eliminating δx_m from H δx = b (the Schur complement) gives the system on the neighbours alone

    Λ = H_aa − H_am H_mm⁻¹ H_ma,        η = b_a − H_am H_mm⁻¹ b_m.                               (1)

Λ is the *marginal* information: Λ⁻¹ is exactly the (a, a) block of H⁻¹, so the covariances of the vertices that
stay are unchanged. The price is **fill-in**: Λ couples *every pair* of neighbours, so H gets dense blocks.

In the graph, Λ and η become one :func:`linear_prior_class` edge over the neighbours (a linearised factor, as
GTSAM's ``LinearContainerFactor``): with Λ = V diag(λ) Vᵀ (positive λ only; Λ is often rank-deficient, e.g.
a pose marginal fixes only relative geometry), J = diag(√λ) Vᵀ and r₀ = diag(1/√λ) Vᵀ η,

    e(x) = J (x ⊟ x₀) + r₀,  Ω = I   ⇒   JᵀΩJ = Λ  and  JᵀΩe(x₀) = η,                          (2)

where x₀ is the linearisation point (the neighbours' estimates when marginalised) and ⊟ wraps heading
differences: exactly (1) at x₀, linear away from it (the usual approximation of sliding-window filters). Its χ²
need not equal the removed edges' (a constant offset), so compare χ² only between graphs marginalised alike.
"""
from __future__ import annotations

import numpy as np

from ..graph import BaseEdge, BaseVertex, VertexPointXY, VertexSE2, wrap_angle
from ..validation import float_array, index_list

__all__ = ["schur_complement", "local_system", "linear_prior_factor", "linear_prior_class", "marginalise_vertex",
           "hessian_blocks"]


def _supported(vertex_type: type) -> bool:
    """VertexSE2 / VertexPointXY with the additive ⊞ (the prior (2) subtracts estimates)."""
    return issubclass(vertex_type, (VertexSE2, VertexPointXY)) and vertex_type.oplus_jacobian_batch is None


def schur_complement(H: np.ndarray, b: np.ndarray, keep: np.ndarray,
                     marginalise: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(Λ, η) of equation (1): the system on ``keep`` after eliminating the indices ``marginalise``.

    ``H`` (n, n) symmetric with an invertible (m, m) block, ``b`` (n,); ``keep`` and ``marginalise`` are
    distinct indices into H.
    """
    H, b = float_array(H, "H"), float_array(b, "b")
    keep = index_list(keep, H.shape[0], "keep", distinct=True)
    marg = index_list(marginalise, H.shape[0], "marginalise", distinct=True)
    if np.intersect1d(keep, marg).size:
        raise ValueError("keep and marginalise must be disjoint indices into H")
    H_mm = H[np.ix_(marg, marg)]
    H_am = H[np.ix_(keep, marg)]
    try:
        X = np.linalg.solve(H_mm, np.column_stack([H_am.T, b[marg]]))   # H_mm⁻¹ [H_ma | b_m]
    except np.linalg.LinAlgError:
        raise ValueError("the block of H to marginalise is singular (the vertex is not determined by its "
                         "edges), so it cannot be marginalised") from None
    lam = H[np.ix_(keep, keep)] - H_am @ X[:, :-1]
    return 0.5 * (lam + lam.T), b[keep] - H_am @ X[:, -1]


def local_system(vertex: BaseVertex) -> tuple[list[BaseVertex], np.ndarray, np.ndarray]:
    """(neighbours, H, b) of the Gauss–Newton system of ``vertex``'s edges at the current estimates.

    ``neighbours``: the other vertices its edges touch, in first-seen order, fixed ones included (the prior edge
    then stays attached to the anchor); H and b are ordered [vertex, neighbours…].
    """
    order, start = [vertex], {vertex: 0}
    n = type(vertex).dimension
    for e in vertex.edges():
        for v in e.vertices():
            if v not in start:
                if not _supported(type(v)):
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


def linear_prior_class(vertex_types: list[type], rank: int) -> type[BaseEdge]:
    """The edge class of equation (2) for these neighbour types and this rank (one class per signature)."""
    key = (tuple(vertex_types), int(rank))
    if key not in _PRIOR_CLASSES:
        dims = [t.dimension for t in vertex_types]
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
            "vertex_types": key[0], "measurement_dimension": key[1],
            "parameters": {"x0": np.zeros(sum(dims)), "jac": np.zeros((key[1], sum(dims)))},
            "evaluate": staticmethod(evaluate)})
    return _PRIOR_CLASSES[key]


def linear_prior_factor(lam: np.ndarray, eta: np.ndarray, rtol: float = 1e-10) -> tuple[np.ndarray, np.ndarray]:
    """(J (r, n), r₀ (r,)) of equation (2) with JᵀJ = Λ and Jᵀr₀ = η (eigenvalues ≤ rtol·max dropped)."""
    w, V = np.linalg.eigh(0.5 * (lam + lam.T))
    if w.size == 0 or w[-1] <= 0:
        raise ValueError("lam has no positive eigenvalue: the marginal carries no information")
    if w[0] < -1e-8 * w[-1]:
        raise ValueError(f"lam must be positive semi-definite (an information matrix), but has the eigenvalue "
                         f"{w[0]:.3g} (largest {w[-1]:.3g})")
    pos = w > rtol * w[-1]
    root = np.sqrt(w[pos])
    return root[:, None] * V[:, pos].T, (V[:, pos].T @ eta) / root


def marginalise_vertex(graph: object, vertex: BaseVertex) -> BaseEdge | None:
    """Marginalise ``vertex`` out of ``graph``: remove it and its edges, add one dense prior (2) on its
    neighbours. Returns the new edge (None when every neighbour is fixed: then nothing is left to constrain).
    Build the structure again before optimising (``graph.initialize_optimization()``)."""
    if not isinstance(vertex, BaseVertex) or vertex.graph is not graph or vertex.fixed or \
            not _supported(type(vertex)):
        raise ValueError(f"vertex must be a free VertexSE2 or VertexPointXY of this graph, got {vertex!r}")
    neighbours, H, b = local_system(vertex)
    d = type(vertex).dimension
    lam, eta = schur_complement(H, b, np.arange(d, H.shape[0]), np.arange(d))
    graph.remove_vertex(vertex)
    if all(v.fixed for v in neighbours):
        return None
    J, r0 = linear_prior_factor(lam, eta)
    cls = linear_prior_class([type(v) for v in neighbours], J.shape[0])
    edge = cls(neighbours, measurement=-r0, information=np.eye(J.shape[0]),
               x0=np.concatenate([v.estimate for v in neighbours]), jac=J)
    graph.add_edge(edge)
    return edge


def hessian_blocks(graph: object, vertices: list[BaseVertex]) -> tuple[np.ndarray, np.ndarray]:
    """H of ``graph`` (built structure) re-ordered so that the free ``vertices`` come in the given order;
    returns (H dense, starts) with ``starts`` each vertex's first row (for spy plots with block grid lines)."""
    idx, starts = [], []
    for v in vertices:
        if v.graph is not graph or v.hessian_index is None or v.hessian_index < 0:
            raise ValueError(f"every vertex must be a free vertex of the graph with a built structure, got {v!r}")
        starts.append(len(idx))
        idx.extend(range(v.hessian_index, v.hessian_index + type(v).dimension))
    H = graph.hessian().toarray()
    return H[np.ix_(idx, idx)], np.array(starts, dtype=np.int64)
