"""Compiled elimination and back-substitution of ``chain_factor`` (the same equations, loop by loop).

``ChainFactor.eliminate_reference`` / ``solve_reference`` are the plain-numpy statements of the maths; these kernels
do the same arithmetic without numpy's per-call cost, which dominates for 3×3 pivots (measured in
``benchmarks/drivebot.py``: the elimination of the q2_b chain). ``tests/test_incremental.py`` checks both against
each other and against a dense solve.
"""

import numba
import numpy as np

__all__ = ["eliminate_chain", "solve_chain"]


@numba.njit(cache=True)
def _cholesky_lower(M, n, L):
    """L (n×n, lower) with L Lᵀ = M[:n, :n]; returns −1, or the first column whose pivot is not positive."""
    for j in range(n):
        s = M[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return j
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, n):
            t = M[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / d
        for i in range(j):
            L[i, j] = 0.0
    return -1


@numba.njit(cache=True)
def _forward(L, n, B, col0, ncol, out):
    """out[:n, :ncol] = L⁻¹ B[:n, col0:col0 + ncol] (L lower n×n)."""
    for c in range(ncol):
        for i in range(n):
            t = B[i, col0 + c]
            for k in range(i):
                t -= L[i, k] * out[k, c]
            out[i, c] = t / L[i, i]


@numba.njit(cache=True)
def eliminate_chain(A, a, F, f, Am, am, Rkk, Rk1, RkM, y, Rmm, ym, k0, N, p, D):
    """Rows of x_{k0} … x_{N−1} and of the map (``chain_factor`` docstring). Returns −1, or the chain index of a
    pose whose pivot is not positive definite, or N + j when the map's fails at map column j."""
    s = 2 * p + D
    M = np.empty((s, s))
    r = np.empty((s, 1))
    L = np.empty((p, p))
    W = np.empty((p, s - p))
    yk = np.empty((p, 1))
    for k in range(k0, N):
        for i in range(s):
            r[i, 0] = -a[k, i]
            for j in range(s):
                M[i, j] = A[k, i, j]
        for i in range(p + D):                      # F_k over (x_k, m) into (x_k, x_{k+1}, m)
            li = i if i < p else i + p
            r[li, 0] += f[k, i]
            for j in range(p + D):
                lj = j if j < p else j + p
                M[li, lj] += F[k, i, j]
        if _cholesky_lower(M, p, L) >= 0:
            return k
        _forward(L, p, M, p, s - p, W)
        _forward(L, p, r, 0, 1, yk)
        for i in range(p):
            for j in range(p):
                Rkk[k, i, j] = L[j, i]
                Rk1[k, i, j] = W[i, j]
            for j in range(D):
                RkM[k, i, j] = W[i, p + j]
            y[k, i] = yk[i, 0]
        for i in range(s - p):                      # F_{k+1} = M_rest − Wᵀ W, f_{k+1} = r_rest − Wᵀ y_k
            t = r[p + i, 0]
            for q in range(p):
                t -= W[q, i] * yk[q, 0]
            f[k + 1, i] = t
            for j in range(s - p):
                t = M[p + i, p + j]
                for q in range(p):
                    t -= W[q, i] * W[q, j]
                F[k + 1, i, j] = t
    if D == 0:
        return -1
    Fm = np.empty((D, D))
    rm = np.empty((D, 1))
    for i in range(D):
        rm[i, 0] = f[N, p + i] - am[i]
        for j in range(D):
            Fm[i, j] = F[N, p + i, p + j] + Am[i, j]
    Lm = np.empty((D, D))
    j = _cholesky_lower(Fm, D, Lm)
    if j >= 0:
        return N + j
    ymv = np.empty((D, 1))
    _forward(Lm, D, rm, 0, 1, ymv)
    for i in range(D):
        ym[i] = ymv[i, 0]
        for j in range(D):
            Rmm[i, j] = Lm[j, i]
    return -1


@numba.njit(cache=True)
def solve_chain(Rkk, Rk1, RkM, y, Rmm, ym, N, p, D):
    """Back-substitution R δ = y: δ_m, then δ_k = R_kk⁻¹ (y_k − R_k,k+1 δ_{k+1} − R_k,m δ_m), k = N−1 … 0."""
    dm = np.zeros(D)
    for i in range(D - 1, -1, -1):
        t = ym[i]
        for j in range(i + 1, D):
            t -= Rmm[i, j] * dm[j]
        dm[i] = t / Rmm[i, i]
    dc = np.zeros((N, p))
    for k in range(N - 1, -1, -1):
        for i in range(p - 1, -1, -1):
            t = y[k, i]
            for j in range(D):
                t -= RkM[k, i, j] * dm[j]
            if k + 1 < N:
                for j in range(p):
                    t -= Rk1[k, i, j] * dc[k + 1, j]
            for j in range(i + 1, p):
                t -= Rkk[k, i, j] * dc[k, j]
            dc[k, i] = t / Rkk[k, i, i]
    return dc, dm


@numba.njit(cache=True)
def add_slot_terms(A, a, Am, am, slots, ew, J, starts, dims, p):
    """Add every edge's J̃ᵀJ̃ and J̃ᵀẽ into its slot (A[slot], a[slot]; the map slot −1 into Am, am, whose rows are
    the map columns). J (E, m, Σd) holds the edge's whitened Jacobians side by side, ``starts`` (E, slots) each
    vertex's first local column in (x_k, x_{k+1}, m) (−1 for a fixed vertex), ``dims`` (slots,) their sizes."""
    E, m = ew.shape
    nv = len(dims)
    off = np.zeros(nv + 1, np.int64)
    for v in range(nv):
        off[v + 1] = off[v] + dims[v]
    for e in range(E):
        k = slots[e]
        Ht = A[k] if k >= 0 else Am          # the map slot: Am, am, which have no chain columns
        gt = a[k] if k >= 0 else am
        shift = 0 if k >= 0 else 2 * p
        for u in range(nv):
            su = starts[e, u]
            if su < 0:
                continue
            for i in range(dims[u]):
                ci = off[u] + i
                g = 0.0
                for q in range(m):
                    g += J[e, q, ci] * ew[e, q]
                gt[su + i - shift] += g
                for v in range(nv):
                    sv = starts[e, v]
                    if sv < 0:
                        continue
                    for j in range(dims[v]):
                        cj = off[v] + j
                        h = 0.0
                        for q in range(m):
                            h += J[e, q, ci] * J[e, q, cj]
                        Ht[su + i - shift, sv + j - shift] += h
