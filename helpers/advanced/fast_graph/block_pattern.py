"""The Hessian pattern built from vertex blocks: the fast path of ``HessianPattern``'s constructor.

``HessianPattern(n, rows, cols, valid)`` (the reference) takes one (row, col) pair per scalar contribution — 21 per
SE(2)–SE(2) edge, 1.4 million on W10000 — and sorts them all. The pattern is made of blocks, though: an edge
between vertices u and v (first rows s_u < s_v, dimensions d_u, d_v) contributes the whole d_u × d_v block
(s_u…, s_v…) and the upper triangles of its two diagonal blocks. So it is enough to find the distinct vertex
pairs (u ≤ v) — three per such edge — and lay the scalar entries out from them:

- block column v holds its distinct block rows u < v in ascending order, then its diagonal block; scalar column
  c = s_v + j therefore lists the rows s_u … s_u + d_u − 1 of every such u, then s_v … s_v + j (only s_v + j when
  no edge contributes to v's diagonal block: the diagonal is always in the pattern);
- an entry (r, c) of block (u, v), u < v, sits at indptr[c] + off(u, v) + (r − s_u), where off(u, v) counts the
  rows of the block rows before u in column v; an entry of a diagonal block at diag_pos[c] − (c − r).

``pattern_from_blocks`` returns the ``HessianPattern`` the reference would build from the same contributions,
array for array (``tests/test_graph_engine.py`` checks it on several graphs); on W10000 it sorts 0.19 M vertex
pairs instead of 1.4 M scalar keys (``benchmarks/RESULTS.md``).
"""

import numpy as np
from numba import njit

from .batched import plain_empty_int32
from .linear import HessianPattern, csc_unique

__all__ = ["pattern_from_blocks"]


@njit(cache=True)
def _layout(vstart, vdim, bu, bv):
    """Scalar CSC layout from the distinct vertex pairs. ``bu``/``bv``: vertex ordinals (bu ≤ bv) of every valid
    block contribution. Returns (indices, indptr, diag_pos, keys, block offsets off(u, v), block id of each
    contribution)."""
    V = vstart.size
    n = 0 if V == 0 else vstart[V - 1] + vdim[V - 1]
    brow, bptr, binv = csc_unique(V, bu, bv)
    boff = np.zeros(brow.size, dtype=np.int64)
    offrows = np.zeros(V, dtype=np.int64)
    full_diag = np.zeros(V, dtype=np.bool_)
    for v in range(V):
        acc = 0
        for q in range(bptr[v], bptr[v + 1]):
            u = brow[q]
            boff[q] = acc
            if u == v:
                full_diag[v] = True
            else:
                acc += vdim[u]
        offrows[v] = acc
    indptr = np.zeros(n + 1, dtype=np.int64)
    for v in range(V):
        for j in range(vdim[v]):
            indptr[vstart[v] + j + 1] = offrows[v] + (j + 1 if full_diag[v] else 1)
    for c in range(n):
        indptr[c + 1] += indptr[c]
    nnz = indptr[n]
    indices = np.empty(nnz, dtype=np.int32)
    keys = np.empty(nnz, dtype=np.int64)
    diag_pos = np.empty(n, dtype=np.int64)
    for v in range(V):
        for j in range(vdim[v]):
            c = vstart[v] + j
            t = indptr[c]
            for q in range(bptr[v], bptr[v + 1]):
                u = brow[q]
                if u != v:
                    for i in range(vdim[u]):
                        indices[t] = vstart[u] + i
                        t += 1
            for r in range(vstart[v] if full_diag[v] else c, c + 1):
                indices[t] = r
                t += 1
            diag_pos[c] = t - 1
            for p in range(indptr[c], t):
                keys[p] = (np.int64(c) << 32) | np.int64(indices[p])
    return indices, indptr, diag_pos, keys, boff, binv


@njit(cache=True)
def _scatter_group(hk, hl, dk, dl, same, bid, boff, indptr, diag_pos, nnz, out, start):
    """CSC positions of one slot pair's contributions in ``linearise``'s order (per edge: the upper triangle of
    the d_k × d_k block row by row when ``same``, else the d_k × d_l block row by row); ``bid`` −1 marks an
    edge with a fixed vertex in the pair (its contributions go to the dropped bin ``nnz``). Returns the next
    start."""
    t = start
    for e in range(hk.size):
        for a in range(dk):
            for b in range(a if same else 0, dl):
                if bid[e] < 0:
                    out[t] = nnz
                else:
                    r, c = hk[e] + a, hl[e] + b
                    if r > c:
                        r, c = c, r
                    if same:
                        out[t] = diag_pos[c] - (c - r)
                    else:
                        out[t] = indptr[c] + boff[bid[e]] + (r - min(hk[e], hl[e]))
                t += 1
    return t


def _vertex_layout(n, vertex_starts, vertex_dims):
    """(starts, dimensions, ordinal of each start row) after checking that the vertices tile rows 0 … n−1."""
    vstart = np.ascontiguousarray(vertex_starts, dtype=np.int64)
    vdim = np.ascontiguousarray(vertex_dims, dtype=np.int64)
    ends = vstart + vdim
    if vstart.ndim != 1 or vdim.shape != vstart.shape or np.any(vdim < 1) \
            or (vstart.size and (vstart[0] != 0 or ends[-1] != n or np.any(vstart[1:] != ends[:-1]))) \
            or (vstart.size == 0 and n != 0):
        raise ValueError(f"pattern_from_blocks: vertex_starts and vertex_dims must tile the rows 0 … {n - 1} "
                         "(starts ascending, each the previous start plus its dimension, dimensions ≥ 1)")
    ordinal = np.full(n + 1, -1, dtype=np.int64)
    ordinal[vstart] = np.arange(vstart.size)
    return vstart, vdim, ordinal


def _check_group(g, hk, hl, dk, dl, valid, ordinal, vdim):
    """ValueError naming group ``g`` unless its slots' rows are −1 or a vertex's first row of dimension d_k, d_l."""
    if hk.ndim != 1 or hl.shape != hk.shape:
        raise ValueError(f"pattern_from_blocks: group {g}: hk and hl must be 1-D arrays of one length, got shapes "
                         f"{hk.shape} and {hl.shape}")
    for rows, d, name in ((hk, dk, "hk"), (hl, dl, "hl")):
        used = rows[valid]
        inside = (used >= 0) & (used < len(ordinal) - 1)
        if not inside.all() or np.any(ordinal[used] < 0) or np.any(vdim[ordinal[used]] != d):
            raise ValueError(f"pattern_from_blocks: group {g}: every {name} must be −1 or the first row of a vertex "
                             f"of dimension {d}")


def pattern_from_blocks(n, vertex_starts, vertex_dims, groups):
    """The ``HessianPattern`` of the contributions of ``groups``, built from vertex blocks (module docstring).

    ``vertex_starts``/``vertex_dims``: first row and dimension of every free vertex, starts ascending and
    contiguous (they tile 0 … n−1); ``groups``: in ``linearise``'s order, one (hk, hl, dk, dl, same) per slot pair
    of every edge class — the slots' first rows (−1 for a fixed vertex), dimensions, and whether k = l."""
    vstart, vdim, ordinal = _vertex_layout(n, vertex_starts, vertex_dims)
    bu, bv, ok = [], [], []
    for g, (hk, hl, dk, dl, _) in enumerate(groups):
        hk, hl = np.asarray(hk), np.asarray(hl)
        valid = (hk >= 0) & (hl >= 0)
        _check_group(g, hk, hl, dk, dl, valid, ordinal, vdim)
        u, v = ordinal[np.minimum(hk, hl)[valid]], ordinal[np.maximum(hk, hl)[valid]]
        bu.append(u)
        bv.append(v)
        ok.append(valid)
    cat = [np.concatenate(x) if x else np.zeros(0, dtype=np.int64) for x in (bu, bv)]
    indices, indptr, diag_pos, keys, boff, binv = _layout(vstart, vdim, cat[0], cat[1])
    pattern = HessianPattern.__new__(HessianPattern)
    pattern.n, pattern.nnz = int(n), int(indptr[-1])
    pattern.indices, pattern.indptr = indices, indptr.astype(np.int32)
    pattern.diag_pos, pattern.keys = diag_pos, keys
    total = sum(len(hk) * (dk * (dk + 1) // 2 if same else dk * dl) for hk, _, dk, dl, same in groups)
    scatter = plain_empty_int32(total)               # no huge-page advice (batched)
    t, used = 0, 0
    for (hk, hl, dk, dl, same), valid in zip(groups, ok):
        bid = np.full(len(hk), -1, dtype=np.int64)
        m = int(np.count_nonzero(valid))
        bid[valid] = binv[used:used + m]
        used += m
        t = _scatter_group(np.ascontiguousarray(hk, dtype=np.int64), np.ascontiguousarray(hl, dtype=np.int64),
                           int(dk), int(dl), bool(same), bid, boff, indptr, diag_pos, pattern.nnz, scatter, t)
    pattern.scatter = scatter
    return pattern
