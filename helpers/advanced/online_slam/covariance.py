"""Joint marginal covariances of a few vertices from one LDLᵀ factorisation of the graph's Hessian.

Data association needs, for the current pose x and the candidate landmarks L, the joint covariance of (x, L)
**with the cross-blocks** — the blocks Σ_xL and Σ_LL that a per-vertex marginal does not give. The Takahashi
recursion of ``helpers.graph.marginals`` yields every entry of Σ = H⁻¹ on the filled pattern of the factor, but
Σ_LL between two landmarks never seen from a common pose lies outside it. Columns do not have that limit:

    H = P (I + L) D (I + L)ᵀ Pᵀ   ⇒   Σ e_r = P (I + L)⁻ᵀ D⁻¹ (I + L)⁻¹ Pᵀ e_r,

one forward and one backward sweep over L per column, O(nnz(L)) each. For k vertices of dimension d the k·d
columns give every block among them (Σ_uv = rows of u in the columns of v), at O(k·d·nnz(L)) — against O(n³)
or O(n²) for a dense inverse. Only the rows of the vertices registered at the factorisation are ever read, and
the backward sweep's w_j needs only the w of the rows of L's column j, which are ancestors of j in the
elimination tree: so each column is solved on the union of the tree paths from the registered rows to the root
(``_solve_unit_columns_on``; same operations, same numbers, on q2_e about a sixth of the time). Columns are
cached per vertex until the next factorisation, so a landmark that is a candidate in many scans costs its
columns once.

``MarginalColumns.refresh(graph)`` factorises the undamped H = Σ JᵀΩJ at the graph's current estimates (the
structure must be built) with the optimiser's own qdldl solver (``hessian_factors``) and copies the factor out, so
later changes to the graph (new vertices and edges, another factorisation by the optimiser) do not disturb the
columns of this one. It records the Hessian index of every vertex it may be asked about, because those indices
go stale as soon as the graph changes.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["MarginalColumns", "ldl_solve_columns", "hessian_factors", "FACTORISE"]

#: default of ``MarginalColumns.refresh``'s ``factors``: factorise H here
FACTORISE = object()


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


@njit(cache=True)
def _ancestor_closure(n, lp, li, starts):
    """Ascending positions (in the factor's order) of every node on the elimination-tree paths from ``starts``
    to the root. The parent of column j is the smallest row of column j of L; every row of column j is an
    ancestor of j, so the set is closed under "rows of L's column"."""
    parent = np.full(n, -1, dtype=np.int64)
    for j in range(n):
        for q in range(lp[j], lp[j + 1]):
            if parent[j] < 0 or li[q] < parent[j]:
                parent[j] = li[q]
    mark = np.zeros(n, dtype=np.bool_)
    for s in starts:
        j = s
        while j >= 0 and not mark[j]:
            mark[j] = True
            j = parent[j]
    return np.flatnonzero(mark)


@njit(cache=True)
def _solve_unit_columns_on(lp, li, lx, d, pinv, rows, keep, slot):
    """Rows ``keep`` of X[:, t] = (Pᵀ H P)⁻¹ e_{pinv[rows[t]]}, in the factor's order: the sweeps of
    ``_solve_unit_columns`` restricted to ``keep`` (ascending, closed under the elimination tree's ancestors,
    containing every pinv[rows[t]]; ``slot[j]`` = position of j in ``keep``). The forward sweep's non-zeros lie
    on the path from the start to the root, and w_j needs only the w of the rows of column j — ancestors of j —
    so the same operations in the same order give the same values on ``keep``."""
    k, s = len(rows), len(keep)
    out = np.zeros((s, k))
    y = np.zeros(s)
    for t in range(k):
        y[:] = 0.0
        first = slot[pinv[rows[t]]]
        y[first] = 1.0
        for a in range(first, s):          # (I + L) y = Pᵀ e_r
            j = keep[a]
            yj = y[a]
            if yj != 0.0:
                for q in range(lp[j], lp[j + 1]):
                    y[slot[li[q]]] -= lx[q] * yj
        for a in range(s):
            y[a] /= d[keep[a]]
        for a in range(s - 1, -1, -1):     # (I + L)ᵀ w = y
            j = keep[a]
            acc = y[a]
            for q in range(lp[j], lp[j + 1]):
                acc -= lx[q] * y[slot[li[q]]]
            y[a] = acc
        out[:, t] = y
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
    (``FastOptimizer.hessian_factors``: the graph's own LDLᵀ solver refactorises H numerically, reusing the
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
    given vertices (in order; a fixed vertex has zero rows and columns). Only the rows of the registered
    vertices are ever read, so each column is solved on the elimination-tree ancestors of those rows alone
    (``_solve_unit_columns_on``: the same numbers as the full sweep there, in a fraction of the work).
    Counters: ``factorisations``, ``columns_solved``.
    """

    def __init__(self):
        self._factors = None        # (indptr, indices, data of L, d, pinv, keep, slot) in the kernel's dtypes
        self._index = {}            # vertex -> Hessian index (−1: fixed)
        self._slots = {}            # free vertex -> its rows' positions in the solved part of a column
        self._columns = {}
        self._joints = {}           # recent joint() results: a scan often has the same candidates as the last
        self.n = 0
        self.factorisations = 0
        self.columns_solved = 0

    @property
    def ready(self) -> bool:
        return self._factors is not None

    def refresh(self, graph, vertices, factors=FACTORISE) -> bool:
        """Factorise the graph's undamped Hessian at its current state and remember the Hessian index of
        ``vertices`` (every vertex a later ``joint`` may name). Returns False — and keeps the previous
        factorisation — when H is not positive definite. ``factors``: ``hessian_factors(graph)`` when the caller
        has them already (the structure unchanged since), None when they were not positive definite."""
        if factors is FACTORISE:
            factors = hessian_factors(graph)
        if factors is None:
            return False
        lower, d, perm = factors
        n = len(d)
        index = {}
        for v in vertices:
            h = v.hessian_index
            index[v] = -1 if h is None else int(h)
        pinv = np.empty(n, dtype=np.int64)
        pinv[np.asarray(perm, dtype=np.int64)] = np.arange(n)
        if lower is None:                       # no free vertex: nothing to solve
            lp, li, lx = np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
        else:
            lp, li = lower.indptr.astype(np.int64), lower.indices.astype(np.int64)
            lx = np.ascontiguousarray(lower.data, dtype=float)
        own = {v: pinv[h:h + type(v).dimension] for v, h in index.items() if h >= 0}
        starts = np.concatenate(list(own.values())) if own else np.zeros(0, dtype=np.int64)
        keep = _ancestor_closure(n, lp, li, starts)
        slot = np.full(n, -1, dtype=np.int64)
        slot[keep] = np.arange(len(keep))
        self._factors = (lp, li, lx, np.ascontiguousarray(d, dtype=float), pinv, keep, slot)
        self._slots = {v: slot[p] for v, p in own.items()}
        self._columns, self._index, self.n, self._joints = {}, index, graph.dimension, {}
        self.factorisations += 1
        return True

    def register_without_factorisation(self, vertices) -> None:
        """No factorisation yet (e.g. only the fixed first pose): ``vertices`` have zero covariance."""
        self._factors, self._columns, self.n, self._joints, self._slots = None, {}, 0, {}, {}
        self._index = {v: -1 for v in vertices}

    def has(self, vertex) -> bool:
        return vertex in self._index

    def prefetch(self, vertices) -> None:
        """Solve the columns of all ``vertices`` not yet cached in one kernel call."""
        todo = [v for v in vertices if v not in self._columns and self._index.get(v, -1) >= 0]
        if not todo:
            return
        rows = np.concatenate([np.arange(self._index[v], self._index[v] + type(v).dimension) for v in todo])
        lp, li, lx, d, pinv, keep, slot = self._factors
        cols = _solve_unit_columns_on(lp, li, lx, d, pinv, rows, keep, slot)
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
        slots = np.concatenate([self._slots[vertices[i]] for i in free])
        sub = np.empty((slots.size, slots.size))
        at = 0
        for i in free:
            sub[:, at:at + dims[i]] = self._columns[vertices[i]][slots]
            at += dims[i]
        out[np.ix_(pos, pos)] = 0.5 * (sub + sub.T)
        return out
