"""Marginal covariances: blocks of H⁻¹ by the sparse inverse on the pattern of the LDLᵀ factor.

Takahashi et al. (1973). qdldl's factors satisfy Pᵀ H P = (I + L) D (I + L)ᵀ with P[perm[j], j] = 1
(L strictly lower, CSC). The inverse Z = (Pᵀ H P)⁻¹ satisfies, for j = n−1, …, 0 and i in the pattern of column
j of L:
    Z_ij = − Σ_{k ∈ struct(L_:j)} L_kj Z_ik,        Z_jj = 1/d_j − Σ_{k ∈ struct(L_:j)} L_kj Z_kj
which only ever needs Z on the pattern of L (the rows of a column form a clique of the filled graph). Every
entry of H's pattern — in particular every vertex's diagonal block — lies inside that pattern, so all vertex
covariance blocks come out exactly, without a dense inverse. No maintained Python library offers this sparse
inverse subset, so the recursion on qdldl's L is a numba kernel.

``marginal_blocks`` asks for the d×d diagonal block of every requested free vertex (grouped by dimension, one
kernel call for all); fixed vertices get a zero block.
"""

import numpy as np
import scipy.sparse as sp
from numba import njit

__all__ = ["sparse_inverse_on_pattern", "marginal_blocks"]


@njit(cache=True)
def _takahashi(n, lp, li, lx, d):
    """Z = (Pᵀ H P)⁻¹ on the pattern of L (CSC lp, li, lx; rows sorted): zx[q] = Z at L's entry q, zd = diag Z."""
    zx = np.zeros(len(lx))
    zd = np.zeros(n)
    pos = -np.ones(n, dtype=np.int64)     # pos[i] = q when row i is in column j's pattern (entry q of L), else −1
    acc = np.zeros(n)                     # acc[q − s] accumulates Z_ij for the entry q of column j
    for j in range(n - 1, -1, -1):        # columns last to first: Z_ij needs only columns > j
        s, t = lp[j], lp[j + 1]
        for q in range(s, t):
            pos[li[q]] = q
            acc[q - s] = 0.0
        # Z_ij = − Σ_{k ∈ struct(L_:j)} L_kj Z_ik  for every i in struct(L_:j); Z is symmetric and i, k > j, so
        # Z_ik is either diagonal (i = k) or stored at the entry of L in column min(i, k), row max(i, k)
        for q in range(s, t):
            k, lkj = li[q], lx[q]
            acc[q - s] -= lkj * zd[k]                     # i = k:  Z_kj −= L_kj Z_kk
            for u in range(lp[k], lp[k + 1]):             # rows r > k of column k that are in column j too
                r = li[u]
                pr = pos[r]
                if pr >= 0:
                    zrk = zx[u]
                    acc[pr - s] -= lkj * zrk              # i = r:  Z_rj −= L_kj Z_rk
                    acc[q - s] -= lx[pr] * zrk            # i = k:  Z_kj −= L_rj Z_kr
        # Z_jj = 1/d_j − Σ_{k ∈ struct(L_:j)} L_kj Z_kj
        diag = 1.0 / d[j]
        for q in range(s, t):
            zx[q] = acc[q - s]
            diag -= lx[q] * acc[q - s]
            pos[li[q]] = -1
        zd[j] = diag
    return zx, zd


@njit(cache=True)
def _lookup(lp, li, zx, zd, pi, pj):
    """Z[pi[t], pj[t]] for every t (permuted indices): the diagonal from zd, any other entry found by bisection
    among the rows of column min(a, b) of L; NaN outside L's pattern."""
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


def sparse_inverse_on_pattern(factor, rows, cols):
    """Entries (H⁻¹)[rows, cols] from ``factor``, a qdldl solver holding a positive definite factorisation of H.

    Every requested entry must lie in the filled pattern of L (true for every entry of H's pattern: entries inside
    a vertex's diagonal block and pairs of vertices joined by an edge); NaN is returned for any other entry.
    """
    lower, d, perm = factor.factors()
    n = len(perm)
    rows, cols = np.asarray(rows), np.asarray(cols)
    if rows.shape != cols.shape or rows.ndim != 1 or (rows.size and (min(rows.min(), cols.min()) < 0
                                                                       or max(rows.max(), cols.max()) >= n)):
        raise ValueError(f"sparse_inverse_on_pattern: rows and cols must be equally long 1-D lists of indices in "
                         f"[0, {n}), got shapes {rows.shape} and {cols.shape}")
    lower = sp.csc_matrix(lower)
    lower.sort_indices()
    perm = np.asarray(perm, dtype=np.int64)
    pinv = np.empty_like(perm)
    pinv[perm] = np.arange(n)
    lp = lower.indptr.astype(np.int64)
    li = lower.indices.astype(np.int64)
    lx = np.ascontiguousarray(lower.data, dtype=float)
    zx, zd = _takahashi(n, lp, li, lx, np.ascontiguousarray(d, dtype=float))
    return _lookup(lp, li, zx, zd, pinv[rows.astype(np.int64)], pinv[cols.astype(np.int64)])


def marginal_blocks(vertices, hessian_index, factor):
    """{vertex: (d, d) block of H⁻¹} for ``vertices`` (in their order); zero blocks for fixed vertices.

    ``hessian_index[handle]``: the vertex's first row in X (−1 when fixed); ``factor``: a qdldl solver holding the
    positive definite factorisation of H (used only when a vertex is free).
    """
    out = {}
    free = [v for v in vertices if hessian_index[v._h] >= 0]
    for v in vertices:
        if hessian_index[v._h] < 0:
            out[v] = np.zeros((type(v).dimension, type(v).dimension))
    if not free:
        return out
    dims = np.array([type(v).dimension for v in free])
    starts = hessian_index[np.array([v._h for v in free])]
    groups, rows, cols = [], [], []
    for d in np.unique(dims):
        sel = np.nonzero(dims == d)[0]
        a, b = np.divmod(np.arange(d * d), d)
        rows.append((starts[sel][:, None] + a).ravel())
        cols.append((starts[sel][:, None] + b).ravel())
        groups.append((int(d), sel))
    vals = sparse_inverse_on_pattern(factor, np.concatenate(rows), np.concatenate(cols))
    pos = 0
    for d, sel in groups:
        block = vals[pos: pos + len(sel) * d * d].reshape(len(sel), d, d)
        pos += len(sel) * d * d
        for i, s in enumerate(sel):
            out[free[s]] = block[i]
    return {v: out[v] for v in vertices}                 # the caller's order
