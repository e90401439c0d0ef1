"""Marginal covariances: blocks of H⁻¹ by the sparse inverse on the pattern of the LDLᵀ factor (Takahashi et al.,
1973).

qdldl's factors satisfy Pᵀ H P = (I + L) D (I + L)ᵀ with P[perm[j], j] = 1 (L strictly lower, CSC). The inverse
Z = (Pᵀ H P)⁻¹ satisfies, for j = n−1, …, 0 and i in the pattern of column j of L:
    Z_ij = − Σ_{k ∈ struct(L_:j)} L_kj Z_ik,        Z_jj = 1/d_j − Σ_{k ∈ struct(L_:j)} L_kj Z_kj
which only ever needs Z on the pattern of L. Every entry of H's pattern (every vertex's diagonal block in
particular) lies in that pattern, so the vertex covariance blocks come out exactly, without a dense inverse.
No maintained Python library offers this sparse inverse subset, so the recursion is a numba kernel.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from numba import njit

__all__ = ["sparse_inverse_on_pattern", "marginal_blocks"]


@njit(cache=True)
def _takahashi(n: int, lp: np.ndarray, li: np.ndarray, lx: np.ndarray, d: np.ndarray) -> tuple:
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


def sparse_inverse_on_pattern(factor: object, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """Entries (H⁻¹)[rows, cols] from ``factor``, a qdldl solver holding a positive definite factorisation of H.
    Every requested entry must lie in the filled pattern of L (true for every entry of H's pattern)."""
    lower, d, perm = factor.factors()
    lower = sp.csc_matrix(lower)
    lower.sort_indices()
    zx, zd = _takahashi(len(perm), lower.indptr.astype(np.int64), lower.indices.astype(np.int64),
                        np.ascontiguousarray(lower.data, dtype=float), np.ascontiguousarray(d, dtype=float))
    z = (sp.csc_matrix((zx, lower.indices, lower.indptr), shape=lower.shape) + sp.diags(zd)).tocsr()
    pinv = np.empty(len(perm), dtype=np.int64)
    pinv[np.asarray(perm)] = np.arange(len(perm))
    a, b = pinv[np.asarray(rows)], pinv[np.asarray(cols)]
    return np.asarray(z[np.maximum(a, b), np.minimum(a, b)]).ravel()       # Z is symmetric: read its lower half


def marginal_blocks(vertices: list, hessian_index: np.ndarray, factor: object) -> dict:
    """{vertex: (d, d) block of H⁻¹} for ``vertices`` (in their order); zero blocks for fixed vertices.
    ``hessian_index[handle]``: a vertex's first row in X (−1 when fixed); ``factor``: a qdldl solver holding the
    positive definite factorisation of H (used only when a vertex is free)."""
    out = {v: np.zeros((v.dimension, v.dimension)) for v in vertices}
    for d in {v.dimension for v in out}:          # one lookup per vertex dimension, for all its free vertices
        free = [v for v in out if v.dimension == d and hessian_index[v._h] >= 0]
        if free:
            rows = hessian_index[[v._h for v in free]][:, None, None] + np.arange(d)[:, None] + 0 * np.arange(d)
            blocks = sparse_inverse_on_pattern(factor, rows.ravel(), rows.transpose(0, 2, 1).ravel())
            out.update(zip(free, blocks.reshape(len(free), d, d)))
    return out
