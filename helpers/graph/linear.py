"""Sparse linear algebra of the optimiser: the Hessian pattern, the LDLᵀ factorisation and sparse-inverse marginals.

Pattern. Every edge contributes the blocks H_kl = J_kᵀ Ω J_l (k ≤ l) between its free vertices. The upper
triangle (row ≤ col) of all contributions is computed once per structure change from the edge → vertex index
arrays (``np.unique`` on linear keys gives the CSC pattern and, for every contribution, the position of its value
in the CSC data array); every iteration only scatters the new values with ``np.bincount``.

Factorisation. qdldl (LDLᵀ with an AMD fill-reducing ordering, chosen by measurement; see the peers spec §5):
``qdldl.Solver`` does the ordering and the symbolic analysis once per pattern, ``Solver.update`` refactorises new
values on the same pattern (LM changes only the diagonal, H + μI).

Marginals (Takahashi et al. 1973). With P H Pᵀ = (I + L) D (I + L)ᵀ, the inverse Z = (P H Pᵀ)⁻¹ satisfies,
for j = n−1, …, 0 and i in the pattern of column j of L:
    Z_ij = − Σ_{k ∈ struct(L_:j)} L_kj Z_ik,        Z_jj = 1/d_j − Σ_{k ∈ struct(L_:j)} L_kj Z_kj
which only ever needs Z on the pattern of L (the rows of a column form a clique of the filled graph). Every
diagonal block of H lies inside that pattern, so all vertex covariance blocks come out exactly, without a dense
inverse; the recursion is a numba kernel.
"""

import numpy as np
import scipy.sparse as sp
from numba import njit

import qdldl

__all__ = ["HessianPattern", "LDLSolver", "sparse_inverse_on_pattern"]


class HessianPattern:
    """CSC pattern of the upper triangle of H and the scatter map from contributions to CSC data.

    ``rows``/``cols``: global (free) indices of every contribution (row ≤ col). ``n``: size of H.
    """

    def __init__(self, n, rows, cols, valid):
        self.n = int(n)
        valid = np.asarray(valid, dtype=bool)
        rows = np.asarray(rows, dtype=np.int64)[valid]
        cols = np.asarray(cols, dtype=np.int64)[valid]
        diag = np.arange(self.n, dtype=np.int64)
        # make every diagonal entry part of the pattern (damping and isolated variables)
        rows = np.concatenate([rows, diag])
        cols = np.concatenate([cols, diag])
        key = cols * max(self.n, 1) + rows
        uniq, inverse = np.unique(key, return_inverse=True)
        nvalid = len(key) - self.n
        self.nnz = len(uniq)
        # contributions touching a fixed vertex go to a dummy bin (index nnz) that is dropped
        self.scatter = np.full(len(valid), self.nnz, dtype=np.int64)
        self.scatter[valid] = inverse[:nvalid]
        self.indices = (uniq % max(self.n, 1)).astype(np.int32)
        ucols = uniq // max(self.n, 1)
        self.indptr = np.zeros(self.n + 1, dtype=np.int32)
        np.cumsum(np.bincount(ucols, minlength=self.n), out=self.indptr[1:])
        self.diag_pos = inverse[nvalid:].astype(np.int64)

    def assemble(self, values):
        """CSC data of the upper triangle of H from the contribution values (same order as rows/cols)."""
        return np.bincount(self.scatter, weights=values, minlength=self.nnz + 1)[: self.nnz]

    def matrix(self, data):
        """scipy CSC (upper triangle) for the given data."""
        return sp.csc_matrix((data, self.indices, self.indptr), shape=(self.n, self.n))

    def full_matrix(self, data):
        """Symmetric scipy CSC (both triangles)."""
        upper = self.matrix(data)
        return (upper + sp.triu(upper, k=1).T).tocsc()


class LDLSolver:
    """qdldl wrapper: the symbolic factorisation is reused while the pattern object stays the same."""

    def __init__(self):
        self._pattern = None
        self._solver = None

    def factor(self, pattern, data):
        mat = pattern.matrix(data)
        if self._solver is None or self._pattern is not pattern:
            self._solver = qdldl.Solver(mat, upper=True)
            self._pattern = pattern
        else:
            self._solver.update(mat, upper=True)
        return self

    def solve(self, rhs):
        return self._solver.solve(np.ascontiguousarray(rhs, dtype=float))

    def factors(self):
        """(L strictly lower CSC with sorted indices, d, p) with H = P (I+L) D (I+L)ᵀ Pᵀ, P[p, arange] = 1."""
        lower, d, p = self._solver.factors()
        lower = sp.csc_matrix(lower)
        lower.sort_indices()
        return lower, np.asarray(d, dtype=float), np.asarray(p, dtype=np.int64)


@njit(cache=True)
def _takahashi(n, lp, li, lx, d):
    zx = np.zeros(len(lx))
    zd = np.zeros(n)
    pos = -np.ones(n, dtype=np.int64)
    acc = np.zeros(n)
    for j in range(n - 1, -1, -1):
        s = lp[j]
        t = lp[j + 1]
        for q in range(s, t):
            pos[li[q]] = q
            acc[q - s] = 0.0
        for q in range(s, t):
            k = li[q]
            lkj = lx[q]
            acc[q - s] -= lkj * zd[k]
            for u in range(lp[k], lp[k + 1]):
                r = li[u]
                pr = pos[r]
                if pr >= 0:
                    zrk = zx[u]
                    acc[pr - s] -= lkj * zrk
                    acc[q - s] -= lx[pr] * zrk
        diag = 1.0 / d[j]
        for q in range(s, t):
            zx[q] = acc[q - s]
            diag -= lx[q] * acc[q - s]
            pos[li[q]] = -1
        zd[j] = diag
    return zx, zd


@njit(cache=True)
def _lookup(lp, li, zx, zd, pi, pj):
    out = np.empty(len(pi))
    for t in range(len(pi)):
        a = pi[t]
        b = pj[t]
        if a == b:
            out[t] = zd[a]
            continue
        col = min(a, b)
        row = max(a, b)
        lo = lp[col]
        hi = lp[col + 1] - 1
        val = np.nan
        while lo <= hi:
            mid = (lo + hi) // 2
            r = li[mid]
            if r == row:
                val = zx[mid]
                break
            if r < row:
                lo = mid + 1
            else:
                hi = mid - 1
        out[t] = val
    return out


def sparse_inverse_on_pattern(solver, rows, cols):
    """Entries (H⁻¹)[rows, cols] (original ordering) from the current factorisation of ``solver``.

    Every requested entry must lie in the filled pattern (true for entries inside a vertex's diagonal block and
    for pairs of vertices joined by an edge); otherwise NaN is returned for it.
    """
    lower, d, p = solver.factors()
    n = len(d)
    pinv = np.empty(n, dtype=np.int64)
    pinv[p] = np.arange(n)
    lp = lower.indptr.astype(np.int64)
    li = lower.indices.astype(np.int64)
    zx, zd = _takahashi(n, lp, li, lower.data.astype(float), d)
    return _lookup(lp, li, zx, zd, pinv[np.asarray(rows, dtype=np.int64)], pinv[np.asarray(cols, dtype=np.int64)])
