"""Batched per-edge products of the linearisation, compiled: Jᵀ J and Jᵀ e per edge (``batched_jtj``,
``batched_jte``; the reference path), the same products added straight into H's CSC data and b at precomputed
positions (``scatter_jtj``, ``scatter_jte``), and the whitened Jacobians W J M (``whitened_jacobians``; M = the
⊞ Jacobian of the slot's vertex, W the edge's whitening matrix or its diagonal).

Every product sums in one fixed order (``_column_dot`` and the loops below), so a fused kernel and the two-step
reference give bit-for-bit the same numbers (``tests/test_graph_engine.py``). The large work arrays of an
iteration come from ``plain_zeros`` / ``plain_copy`` / ``plain_empty_int32`` (numba's allocator: no huge-page
advice, see the comment above them).
"""

import numpy as np
from numba import njit

from ...validation import integer

__all__ = ["batched_jtj", "batched_jte", "batched_matmul", "scatter_jtj", "scatter_jtj_upper", "scatter_jte",
           "whitened_jacobians", "plain_zeros", "plain_copy", "plain_empty_int32"]


@njit(cache=True)
def batched_jtj(a, b, upper):
    """(E, m, p), (E, m, q) → Aᵀ B per edge, flattened to (E, p·q) — or, when ``upper`` (p = q), only the
    upper triangle (E, p(p+1)/2) in row-major order (matching numpy.triu_indices)."""
    E, _, p = a.shape
    q = b.shape[2]
    width = p * (p + 1) // 2 if upper else p * q
    out = np.empty((E, width))
    for e in range(E):
        t = 0
        for i in range(p):
            for j in range(i if upper else 0, q):
                out[e, t] = _column_dot(a, b, e, i, j)
                t += 1
    return out


@njit(cache=True, inline="always")
def _column_dot(a, b, e, i, j):
    """Σ_r a[e, r, i] b[e, r, j]: one entry of edge e's Aᵀ B (the one summation order both products use)."""
    acc = 0.0
    for r in range(a.shape[1]):
        acc += a[e, r, i] * b[e, r, j]
    return acc


@njit(cache=True)
def batched_jte(a, v):
    """(E, m, p), (E, m) → Aᵀ v per edge, (E, p)."""
    E, m, p = a.shape
    out = np.empty((E, p))
    for e in range(E):
        for i in range(p):
            acc = 0.0
            for r in range(m):
                acc += a[e, r, i] * v[e, r]
            out[e, i] = acc
    return out


@njit(cache=True)
def scatter_jtj(a, b, upper, positions, start, out):
    """out[positions[start + t]] += v_t for the values v_t of ``batched_jtj(a, b, upper)``, in its order; returns
    start + their count. The same additions in the same order as ``np.bincount(positions, weights=values)``, so the
    result is bit-for-bit that of ``batched_jtj`` followed by ``HessianPattern.assemble``, without the (E, p·q)
    intermediate."""
    E, _, p = a.shape
    q = b.shape[2]
    t = start
    for e in range(E):
        for i in range(p):
            for j in range(i if upper else 0, q):
                out[positions[t]] += _column_dot(a, b, e, i, j)
                t += 1
    return t


@njit(cache=True)
def _scatter_jtj_upper(a, positions, start, out):
    """The kernel of ``scatter_jtj_upper``: ``scatter_jtj(a, a, True, ...)``, the upper triangle of AᵀA (a diagonal
    block H_kk), the same additions in
    the same order. The entries (i, j) are enumerated from index lists: one loop of fixed length per edge, and A
    read once, run in about 0.6× the time of the triangle's nested loops."""
    E, _, p = a.shape
    width = p * (p + 1) // 2
    ii, jj = np.empty(width, dtype=np.int64), np.empty(width, dtype=np.int64)
    u = 0
    for i in range(p):
        for j in range(i, p):
            ii[u], jj[u] = i, j
            u += 1
    t = start
    for e in range(E):
        for u in range(width):
            out[positions[t + u]] += _column_dot(a, a, e, ii[u], jj[u])
        t += width
    return t



def scatter_jtj_upper(a, positions, start, out):
    """``scatter_jtj(a, a, True, positions, start, out)`` (the upper triangle of AᵀA, a diagonal block H_kk) by
    ``_scatter_jtj_upper``; returns the next start. ValueError when ``a`` is not (E, m, p) or ``positions`` holds
    fewer than start + E·p(p+1)/2 entries. The positions themselves are trusted (they come from the pattern)."""
    if np.ndim(a) != 3:
        raise ValueError(f"scatter_jtj_upper: a must have shape (E, m, p), got {np.shape(a)}")
    E, _, p = a.shape
    if start < 0 or len(positions) < start + E * p * (p + 1) // 2:
        raise ValueError(f"scatter_jtj_upper: positions must hold start + {E * p * (p + 1) // 2} entries from "
                         f"start {start}, got {len(positions)}")
    return _scatter_jtj_upper(a, positions, start, out)

@njit(cache=True)
def scatter_jte(a, v, positions, start, out):
    """out[positions[start + t]] += (Aᵀ v)_t in ``batched_jte``'s order (as ``scatter_jtj``); returns the next start."""
    E, m, p = a.shape
    t = start
    for e in range(E):
        for i in range(p):
            acc = 0.0
            for r in range(m):
                acc += a[e, r, i] * v[e, r]
            out[positions[t]] += acc
            t += 1
    return t


@njit(cache=True)
def batched_matmul(a, b):
    """(E, p, q), (E, q, r) → A B per edge (the two-step reference of ``whitened_jacobians``)."""
    E, p, q = a.shape
    r = b.shape[2]
    out = np.empty((E, p, r))
    for e in range(E):
        for i in range(p):
            for c in range(r):
                acc = 0.0
                for k in range(q):
                    acc += a[e, i, k] * b[e, k, c]
                out[e, i, c] = acc
    return out


@njit(cache=True)
def _whitened_jacobians(jac, oplus, handles, whitening, diagonal):
    """The kernel of ``whitened_jacobians``: J̃ = W J M per edge, (E, m, d): ``jac`` J (E, m, d);
    M = ``oplus[handles[e]]`` (the ⊞ Jacobian of the
    slot's vertex; skipped when ``handles`` is empty, M = I); W = ``whitening`` (E, m, m), or its diagonal as
    (E, m, 1) when ``diagonal``. The same products in the same order as ``batched_matmul(J, M[handles])``
    followed by ``batched_matmul(W, ·)`` (or the elementwise w_i · (JM)_ic), without the intermediate arrays;
    one plain loop per case (a branch inside the loops costs half the time). Arguments as ``whitened_jacobians``
    checks them."""
    E, m, d = jac.shape
    out = np.empty((E, m, d))
    if handles.size > 0 and diagonal:
        for e in range(E):
            h = handles[e]
            for i in range(m):
                wi = whitening[e, i, 0]
                for c in range(d):
                    acc = 0.0
                    for k in range(d):
                        acc += jac[e, i, k] * oplus[h, k, c]
                    out[e, i, c] = wi * acc
    elif diagonal:
        for e in range(E):
            for i in range(m):
                wi = whitening[e, i, 0]
                for c in range(d):
                    out[e, i, c] = wi * jac[e, i, c]
    else:
        jm = np.empty((m, d))
        for e in range(E):
            if handles.size > 0:
                h = handles[e]
                for i in range(m):
                    for c in range(d):
                        acc = 0.0
                        for k in range(d):
                            acc += jac[e, i, k] * oplus[h, k, c]
                        jm[i, c] = acc
            else:
                jm[:, :] = jac[e]
            for i in range(m):
                for c in range(d):
                    acc = 0.0
                    for k in range(m):
                        acc += whitening[e, i, k] * jm[k, c]
                    out[e, i, c] = acc
    return out



def whitened_jacobians(jac, oplus, handles, whitening, diagonal):
    """J̃ = W J M per edge, (E, m, d), checked (``_whitened_jacobians`` computes it): ``jac`` J (E, m, d); M =
    ``oplus[handles[e]]`` (the ⊞ Jacobians (H, d, d) of the vertices; ``handles`` empty: M = I); W =
    ``whitening`` (E, m, m), or its diagonal as (E, m, 1) when ``diagonal``. ValueError naming the argument when
    a shape does not fit or a handle is outside [0, H)."""
    if np.ndim(jac) != 3:
        raise ValueError(f"whitened_jacobians: jac must have shape (E, m, d), got {np.shape(jac)}")
    E, m, d = jac.shape
    want = (E, m, 1) if diagonal else (E, m, m)
    if np.shape(whitening) != want:
        raise ValueError(f"whitened_jacobians: whitening must have shape {want}, got {np.shape(whitening)}")
    if np.size(handles):
        if np.shape(handles) != (E,) or np.ndim(oplus) != 3 or np.shape(oplus)[1:] != (d, d):
            raise ValueError(f"whitened_jacobians: handles must have shape ({E},) and oplus (H, {d}, {d}), got "
                             f"{np.shape(handles)} and {np.shape(oplus)}")
        if handles.min() < 0 or handles.max() >= oplus.shape[0]:
            raise ValueError(f"whitened_jacobians: handles must lie in [0, {oplus.shape[0]})")
    return _whitened_jacobians(jac, oplus, handles, whitening, bool(diagonal))

# Large work arrays allocated by numba's runtime. numpy advises transparent huge pages for every array of 4 MB or
# more; where the kernel must compact memory to provide them, the first writes into such an array stall (W10000's
# 5.4 MB of scatter positions: 5–33 ms from one process to the next, against 5 ms every time allocated here).


@njit(cache=True)
def _zeros(size):
    return np.zeros(size)


@njit(cache=True)
def _empty_int32(size):
    return np.empty(size, dtype=np.int32)


def plain_zeros(size):
    """np.zeros(size) (float64) without huge-page advice (see above); ``size`` an integer ≥ 0."""
    return _zeros(integer(size, "size", minimum=0))


@njit(cache=True)
def _copy(a):
    return a.copy()


def plain_copy(a):
    """a.copy() of a 1-D float64 array without huge-page advice (see above)."""
    if not isinstance(a, np.ndarray) or a.ndim != 1 or a.dtype != np.float64:
        raise ValueError(f"plain_copy: a must be a 1-D float64 array, got {type(a).__name__} "
                         f"{getattr(a, 'dtype', '')} {np.shape(a)}")
    return _copy(a)


def plain_empty_int32(size):
    """An uninitialised int32 array of ``size`` entries (an integer ≥ 0) without huge-page advice (see above)."""
    return _empty_int32(integer(size, "size", minimum=0))
