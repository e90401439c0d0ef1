"""Joint marginal covariances of a few vertices from one LDLᵀ factorisation of the graph's Hessian.

Data association needs, for the current pose x and the candidate landmarks L, the joint covariance of (x, L)
**with the cross-blocks** — the blocks Σ_xL and Σ_LL that a per-vertex marginal does not give. The Takahashi
recursion of ``helpers.graph.marginals`` yields every entry of Σ = H⁻¹ on the filled pattern of the factor, but
Σ_LL between two landmarks never seen from a common pose lies outside it. Columns do not have that limit:

    H = P (I + L) D (I + L)ᵀ Pᵀ   ⇒   Σ e_r = P (I + L)⁻ᵀ D⁻¹ (I + L)⁻¹ Pᵀ e_r,

one forward and one backward sweep over L per column, O(nnz(L)) each. For k vertices of dimension d the k·d
columns give every block among them (Σ_uv = rows of u in the columns of v), at O(k·d·nnz(L)) — against O(n³)
or O(n²) for a dense inverse. Columns are cached per vertex until the next factorisation, so a landmark that is a
candidate in many scans costs its columns once.

``MarginalColumns.refresh(graph)`` factorises the undamped H = Σ JᵀΩJ at the graph's current estimates (the
structure must be built) with the optimiser's own qdldl solver (``hessian_factors``) and copies the factor out, so
later changes to the graph (new vertices and edges, another factorisation by the optimiser) do not disturb the
columns of this one. It records the Hessian index of every vertex it may be asked about, because those indices
go stale as soon as the graph changes.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["MarginalColumns", "ldl_solve_columns", "hessian_factors"]


@njit(cache=True)
def _solve_unit_columns(n, lp, li, lx, d, perm, pinv, rows):
    """X[:, t] = H⁻¹ e_{rows[t]} from the factors of Pᵀ H P = (I + L) D (I + L)ᵀ (L strictly lower, CSC)."""
    k = len(rows)
    out = np.zeros((n, k))
    y = np.zeros(n)
    for t in range(k):
        y[:] = 0.0
        start = pinv[rows[t]]
        y[start] = 1.0
        for j in range(start, n):          # (I + L) y = Pᵀ e_r; entries before ``start`` stay 0
            yj = y[j]
            if yj != 0.0:
                for q in range(lp[j], lp[j + 1]):
                    y[li[q]] -= lx[q] * yj
        for j in range(n):
            y[j] /= d[j]
        for j in range(n - 1, -1, -1):     # (I + L)ᵀ w = y
            acc = y[j]
            for q in range(lp[j], lp[j + 1]):
                acc -= lx[q] * y[li[q]]
            y[j] = acc
        for j in range(n):
            out[perm[j], t] = y[j]
    return out


def ldl_solve_columns(factors, rows):
    """Columns ``rows`` of H⁻¹ (n, len(rows)) from ``factors`` = (L CSC strictly lower, d, perm) of qdldl."""
    lower, d, perm = factors
    n = len(d)
    pinv = np.empty(n, dtype=np.int64)
    pinv[perm] = np.arange(n)
    return _solve_unit_columns(n, lower.indptr.astype(np.int64), lower.indices.astype(np.int64),
                               np.ascontiguousarray(lower.data, dtype=float), np.ascontiguousarray(d, dtype=float),
                               np.asarray(perm, dtype=np.int64), pinv, np.asarray(rows, dtype=np.int64))


def hessian_factors(graph):
    """(L, d, perm) of the undamped H = Σ JᵀΩJ at the graph's current estimates
    (``SparseOptimizer.hessian_factors``: the graph's own LDLᵀ solver refactorises H numerically, reusing the
    fill-reducing ordering and symbolic analysis of ``initialize_optimization`` — 0.6 ms for n = 3 911 against
    4.2 ms for a fresh qdldl solver on ``graph.hessian()``), or None when H is not positive definite;
    (None, empty, empty) for a graph without free vertices."""
    factors = graph.hessian_factors()         # raises GraphError when the structure is not current
    if factors is None and graph.dimension == 0:
        return None, np.zeros(0), np.zeros(0, dtype=np.int64)
    return factors


class MarginalColumns:
    """Σ = H⁻¹ blocks of chosen vertices from one factorisation (module docstring).

    ``refresh(graph, vertices)`` factorises; ``joint(vertices)`` returns the dense joint covariance of the
    given vertices (in order; a fixed vertex has zero rows and columns). Counters: ``factorisations``,
    ``columns_solved``.
    """

    def __init__(self):
        self._factors = None
        self._index = {}
        self._columns = {}
        self._joints = {}           # recent joint() results: a scan often has the same candidates as the last
        self.n = 0
        self.factorisations = 0
        self.columns_solved = 0

    @property
    def ready(self) -> bool:
        return self._factors is not None

    def refresh(self, graph, vertices) -> bool:
        """Factorise the graph's undamped Hessian at its current state and remember the Hessian index of
        ``vertices`` (every vertex a later ``joint`` may name). Returns False — and keeps the previous
        factorisation — when H is not positive definite."""
        factors = hessian_factors(graph)
        if factors is None:
            return False
        index = {}
        for v in vertices:
            h = v.hessian_index
            index[v] = -1 if h is None else int(h)
        self._factors, self._columns, self._index, self.n = factors, {}, index, graph.dimension
        self._joints = {}
        self.factorisations += 1
        return True

    def register_without_factorisation(self, vertices) -> None:
        """No factorisation yet (e.g. only the fixed first pose): ``vertices`` have zero covariance."""
        self._factors, self._columns, self.n, self._joints = None, {}, 0, {}
        self._index = {v: -1 for v in vertices}

    def has(self, vertex) -> bool:
        return vertex in self._index

    def prefetch(self, vertices) -> None:
        """Solve the columns of all ``vertices`` not yet cached in one kernel call."""
        todo = [v for v in vertices if v not in self._columns and self._index.get(v, -1) >= 0]
        if not todo:
            return
        rows = np.concatenate([np.arange(self._index[v], self._index[v] + type(v).dimension) for v in todo])
        cols = ldl_solve_columns(self._factors, rows)
        self.columns_solved += len(rows)
        pos = 0
        for v in todo:
            dim = type(v).dimension
            self._columns[v] = cols[:, pos:pos + dim]
            pos += dim

    def joint(self, vertices) -> np.ndarray:
        """Dense joint covariance of ``vertices`` (each must have been named at ``refresh``). The last few
        results are kept until the next refresh (the same candidates come back scan after scan)."""
        key = tuple(vertices)
        hit = self._joints.get(key)
        if hit is not None:
            return hit.copy()
        for v in key:
            if v not in self._index:
                raise ValueError(f"vertices: {v!r} was not registered at the last refresh")
        out = self._joint(list(key))
        if len(self._joints) >= 8:
            self._joints.pop(next(iter(self._joints)))          # the oldest entry
        self._joints[key] = out
        return out.copy()

    def _joint(self, vertices) -> np.ndarray:
        dims = np.array([type(v).dimension for v in vertices], dtype=np.int64)
        offs = np.concatenate([[0], np.cumsum(dims)])
        out = np.zeros((offs[-1], offs[-1]))
        free = [i for i, v in enumerate(vertices) if self._index[v] >= 0]
        if not free:
            return out
        self.prefetch([vertices[i] for i in free])
        pos = np.concatenate([np.arange(offs[i], offs[i + 1]) for i in free])
        rows = np.concatenate([np.arange(self._index[vertices[i]], self._index[vertices[i]] + dims[i]) for i in free])
        sub = np.empty((rows.size, rows.size))
        at = 0
        for i in free:
            sub[:, at:at + dims[i]] = self._columns[vertices[i]][rows]
            at += dims[i]
        out[np.ix_(pos, pos)] = 0.5 * (sub + sub.T)
        return out
