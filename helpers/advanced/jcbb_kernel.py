"""Compiled JCBB search (numba), one loop over an explicit stack: the kernel of ``helpers.advanced.jcbb_fast``.

It walks the interpretation tree of :mod:`helpers.association.jcbb` with the same bound, so it returns the
same association after the same number of nodes; what makes it faster is that the whole search is compiled
and that no conditional covariance is formed: only the block columns of the Cholesky factor it needs.

**Incremental joint distance.** At a node H with a pairings, C_H = L Lᵀ and w = L⁻¹ f_H (D²_H = ‖w‖²).
Appending the pairing (k, i), with B = Cov(f_H, ν_k) = P[rows(H), rows(k)] and D = P_kk:

    L W = B,   D − WᵀW = L₂ L₂ᵀ,   w_n = L₂⁻¹ (ν_ki − Wᵀ w),   D²_{H+(k,i)} = D²_H + ‖w_n‖²,

with new factor [[L, 0], [Wᵀ, L₂]]. μ_k + Wᵀw and L₂L₂ᵀ are the mean and covariance of landmark k's
prediction *conditioned on the pairings of H*. For every level q the kernel keeps the block column
G_q = L⁻¹ P[rows(H), rows(q)] (stored transposed in ``GT``; it grows by d rows per pairing, one block
forward substitution), the conditional mean ``mean[j, q]`` and the Cholesky factor ``chol[j, q]`` given
the first j pairings of H (:func:`_condition_on_pairing`). A child's D² is then
D²_H + ‖L₂,q⁻¹(y_i − μ_{q|H})‖² (:func:`_whitened_sq`), O(d²) per candidate. These values depend only on
H, so they are cached once per pairing (:func:`_fill_d2_cache`) and reused by every star node below it.

**Bound** (:func:`_pairings_bound`): an upper bound ``possible`` on the pairings any descendant can still
add — the smallest of the levels left, the unused observations that can still be paired jointly
compatibly, and the longest chain of later levels whose best conditional candidate keeps each prefix
jointly compatible; plus an order-statistic test on D² when a + possible only ties pairings(Best). The
node is cut (:func:`_cannot_beat`) when a + possible < pairings(Best), or = and D²_H ≥ D²_Best.

Determinism: no parallelism, no fastmath. Speed: numba reference-counts every array
passed to a call, so helpers unpack tuple fields into locals before their loops, and the per-level and
per-candidate loops call only tiny ``inline="always"`` helpers.
"""
from __future__ import annotations

from collections import namedtuple

import numba
import numpy as np

__all__ = ["jcbb_search"]

#: The search tree: landmark of each level, IC candidates of level t in cand_obs[cand_ptr[t]:cand_ptr[t+1]]
#: (observation order), last_level[o] = last level listing observation o (−1: none), thresh[a] = χ²_{d·a}.
_Tree = namedtuple("_Tree", "levels cand_ptr cand_obs last_level thresh")
#: Conditional predictions given the first j pairings of H: GT = Gᵀ, mean[j, q], chol[j, q], ok[j, q].
_Conditionals = namedtuple("_Conditionals", "GT mean chol ok")
#: Per-level DFS state: the JC children (obs, d2, n_children) nearest first, the next child to try, whether
#: the star was taken, the active choice and D²_H before it.
_Stack = namedtuple("_Stack", "obs d2 n_children next_child star_done choice d2_before")
#: Search scratch: used observations, the d²-cache per depth (and whether it is valid), small buffers.
_Work = namedtuple("_Work", "used mark mins dcache dvalid tmp wn Gn Sq")


# -- small dense linear algebra ----------------------------------------------------------------------------
@numba.njit(cache=True, inline="always")
def _chol_small(A, Lout):
    """Lower Cholesky factor of the small SPD matrix A into Lout; False if A is not positive definite."""
    d = A.shape[0]
    for a in range(d):
        for b in range(a + 1):
            s = A[a, b]
            for u in range(b):
                s -= Lout[a, u] * Lout[b, u]
            if a == b:
                if not s > 0.0:
                    return False
                Lout[a, a] = np.sqrt(s)
            else:
                Lout[a, b] = s / Lout[b, b]
        for b in range(a + 1, d):
            Lout[a, b] = 0.0
    return True


@numba.njit(cache=True, inline="always")
def _whitened_sq(Lc, y, mean, o, tmp):
    """‖Lc⁻¹ (y[:, o] − mean)‖² for a lower-triangular d×d Lc (tmp receives the whitened vector)."""
    d = Lc.shape[0]
    dd = 0.0
    for a in range(d):
        s = y[a, o] - mean[a]
        for u in range(a):
            s -= Lc[a, u] * tmp[u]
        tmp[a] = s / Lc[a, a]
        dd += tmp[a] * tmp[a]
    return dd


# -- conditional predictions: the incremental Cholesky update of the joint distance ------------------------
@numba.njit(cache=True)
def _initial_conditionals(mu, P, d, levels, K):
    """Depth 0 (H empty): each level's prediction is its marginal N(μ_q, P_qq)."""
    T = levels.size
    Tm = max(T, 1)
    GT = np.zeros((d * Tm, max(d * K, 1)))      # Gᵀ, so the O(a) inner products run on contiguous rows
    mean = np.zeros((K + 1, Tm, d))
    chol = np.zeros((K + 1, Tm, d, d))
    ok = np.zeros((K + 1, Tm), dtype=np.bool_)
    Sq = np.zeros((d, d))
    for q in range(T):
        lq = levels[q]
        for a in range(d):
            mean[0, q, a] = mu[d * lq + a]
            for b in range(d):
                Sq[a, b] = P[d * lq + a, d * lq + b]
        ok[0, q] = _chol_small(Sq, chol[0, q])
    return _Conditionals(GT, mean, chol, ok)


@numba.njit(cache=True)
def _condition_on_pairing(cond, P, Y, d, levels, k, t, o, work):
    """H (k pairings) gains (levels[t], o): condition every later level q on the k + 1 pairings.

    New block row of G_q: Gn = L₂⁻¹ (P[rows(t), rows(q)] − W_tᵀ G_q) (forward substitution, L₂ = cL[k, t]);
    then μ_{q|H+} = μ_{q|H} + Gnᵀ w_n and Σ_{q|H+} = Σ_{q|H} − Gnᵀ Gn, factored into cL[k + 1, q]
    (cOK[k + 1, q] False if it is not positive definite). One loop body on purpose: a call per level
    would cost numba reference counting on every array argument.
    """
    GT, cM, cL, cOK = cond
    Gn, wn, Sq = work.Gn, work.wn, work.Sq
    p = d * k
    lt = levels[t]
    Lt = cL[k, t]
    _whitened_sq(Lt, Y, cM[k, t], o, wn)                       # w_n = L₂⁻¹ (y_o − μ_{t|H})
    for q in range(t + 1, levels.size):
        lq = levels[q]
        for b in range(d):                                      # Gn, by forward substitution
            for a in range(d):
                s = P[d * lt + a, d * lq + b]
                for r in range(p):
                    s -= GT[d * t + a, r] * GT[d * q + b, r]
                for u in range(a):
                    s -= Lt[a, u] * Gn[u, b]
                Gn[a, b] = s / Lt[a, a]
        for a in range(d):                                      # store Gnᵀ; conditional mean and covariance
            for b in range(d):
                GT[d * q + b, p + a] = Gn[a, b]
            sm = cM[k, q, a]
            for u in range(d):
                sm += Gn[u, a] * wn[u]
            cM[k + 1, q, a] = sm
            for b in range(d):
                s = 0.0
                for u in range(d):
                    s += Gn[u, a] * Gn[u, b]
                Sq[a, b] = cL[k, q, a, 0] * cL[k, q, b, 0]
                for u in range(1, d):
                    Sq[a, b] += cL[k, q, a, u] * cL[k, q, b, u]
                Sq[a, b] -= s
        cOK[k + 1, q] = cOK[k, q] and _chol_small(Sq, cL[k + 1, q])


@numba.njit(cache=True)
def _fill_d2_cache(cond, Y, tree, k, t, D2, work):
    """dcache[k, e] = D²_H + d²(o_e | q_e, H) for every candidate edge e of the levels t… (inf when o_e is
    used). H is fixed while the search stays at depth k (stars do not change it): computed once per
    pairing, not once per node."""
    cand_ptr, cand_obs, used, dcache, tmp = tree.cand_ptr, tree.cand_obs, work.used, work.dcache, work.tmp
    for q in range(t, tree.levels.size):
        for e in range(cand_ptr[q], cand_ptr[q + 1]):
            o = cand_obs[e]
            if used[o] or not cond.ok[k, q]:
                dcache[k, e] = np.inf
            else:
                dcache[k, e] = D2 + _whitened_sq(cond.chol[k, q], Y, cond.mean[k, q], o, tmp)
    work.dvalid[k] = True


# -- the bound ---------------------------------------------------------------------------------------------
@numba.njit(cache=True, inline="always")
def _simple_bound(tree, t, used):
    """U = min(levels left, unused observations that are still a candidate of a level ≥ t)."""
    last_level = tree.last_level
    reach = 0
    for o in range(used.size):
        if not used[o] and last_level[o] >= t:
            reach += 1
    return min(tree.levels.size - t, reach)


@numba.njit(cache=True)
def _jc_bound(cond, tree, k, t, U, D2, best_k, best_d2, work):
    """JC-aware refinement of U. A pairing (q, o) can appear in a descendant H' only if
    D²_H + d²(o | q, H) ≤ D²_H' ≤ χ²_{d(k+U)} (the joint distance grows with the set), and the i-th pairing
    added below H must keep its prefix jointly compatible: D²_H + min_o d²(o | q_i, H) ≤ χ²_{d(k+i)} with
    q_1 < q_2 < … in level order (greedy scan = the longest such chain, as thresholds grow with i).
    Returns −1 when even a tie in pairings cannot beat D²_Best (order statistic of the per-level minima)."""
    thresh, cand_ptr, cand_obs, ok = tree.thresh, tree.cand_ptr, tree.cand_obs, cond.ok
    used, mark, mins, dcache = work.used, work.mark, work.mins, work.dcache
    lim = thresh[k + U]
    n_ob = 0
    chain = 0
    n_mins = 0
    for o in range(mark.size):
        mark[o] = False
    for q in range(t, tree.levels.size):
        if not ok[k, q]:
            continue
        best_q = np.inf
        for e in range(cand_ptr[q], cand_ptr[q + 1]):
            o = cand_obs[e]
            if used[o]:
                continue
            dq = dcache[k, e]
            if dq <= lim:
                if not mark[o]:
                    mark[o] = True
                    n_ob += 1
                if dq < best_q:
                    best_q = dq
        if k + chain + 1 < thresh.size and best_q <= thresh[k + chain + 1]:
            chain += 1                  # (a chain past the last threshold already exceeds n_ob)
        if best_q <= lim:
            mins[n_mins] = best_q
            n_mins += 1
    possible = min(chain, n_ob)
    need = best_k - k
    if k + possible == best_k and need > 0 and D2 < best_d2:
        # every descendant with best_k pairings adds `need` pairings on distinct levels,
        # so its D² ≥ the need-th smallest per-level minimum
        srt = np.sort(mins[:n_mins])
        if srt[need - 1] >= best_d2:
            possible = -1
    return possible


@numba.njit(cache=True)
def _pairings_bound(cond, tree, k, t, D2, best_k, best_d2, work):
    """Upper bound on the pairings any descendant of the node (depth k, level t) can still add."""
    if t >= tree.levels.size:
        return 0
    U = _simple_bound(tree, t, work.used)
    if U > 0 and k + U >= best_k:
        return _jc_bound(cond, tree, k, t, U, D2, best_k, best_d2, work)
    return U


@numba.njit(cache=True, inline="always")
def _cannot_beat(k, possible, D2, best_k, best_d2):
    """Bound test: no descendant can have more pairings than Best, or as many and a smaller D²."""
    return k + possible < best_k or (k + possible == best_k and D2 >= best_d2)


# -- node expansion and the depth-first stack --------------------------------------------------------------
@numba.njit(cache=True)
def _new_stack(tree):
    T = tree.levels.size
    Tm = max(T, 1)
    maxc = 1
    for t in range(T):
        maxc = max(maxc, tree.cand_ptr[t + 1] - tree.cand_ptr[t])
    return _Stack(np.zeros((Tm, maxc), dtype=np.int64), np.zeros((Tm, maxc)), np.zeros(Tm, dtype=np.int64),
                  np.zeros(Tm, dtype=np.int64), np.zeros(Tm, dtype=np.bool_), np.full(Tm, -1, dtype=np.int64),
                  np.zeros(Tm))


@numba.njit(cache=True)
def _new_work(d, m, T, K, n_edges):
    return _Work(np.zeros(m, dtype=np.bool_), np.zeros(m, dtype=np.bool_), np.zeros(max(T, 1)),
                 np.full((K + 1, max(n_edges, 1)), np.inf), np.zeros(K + 1, dtype=np.bool_),
                 np.zeros(d), np.zeros(d), np.zeros((d, d)), np.zeros((d, d)))


@numba.njit(cache=True, inline="always")
def _insert_child(stack, t, nc, o, d2new):
    """Insert child (o, D²) among the nc children of level t: ascending D², ties keep observation order."""
    obs, d2 = stack.obs, stack.d2
    pos = nc
    while pos > 0 and d2[t, pos - 1] > d2new:
        obs[t, pos] = obs[t, pos - 1]
        d2[t, pos] = d2[t, pos - 1]
        pos -= 1
    obs[t, pos] = o
    d2[t, pos] = d2new


@numba.njit(cache=True)
def _expand_level(cond, tree, k, t, work, stack):
    """Children of the node at level t: the unused IC observations whose joint D² (from the d²-cache)
    passes χ²_{d(k+1)}, nearest first."""
    cand_obs, used, dcache = tree.cand_obs, work.used, work.dcache
    nc = 0
    K = cond.mean.shape[0] - 1
    if k < K and cond.ok[k, t]:
        for e in range(tree.cand_ptr[t], tree.cand_ptr[t + 1]):
            o = cand_obs[e]
            if used[o]:
                continue
            d2new = dcache[k, e]
            if d2new <= tree.thresh[k + 1]:
                _insert_child(stack, t, nc, o, d2new)
                nc += 1
    stack.n_children[t] = nc
    stack.next_child[t] = 0
    stack.star_done[t] = False
    stack.choice[t] = -1


@numba.njit(cache=True)
def _take_next_child(cond, P, Y, d, tree, k, t, D2, idx, work, stack):
    """Pair level t's landmark with its next child observation o (H has k pairings and distance D2):
    condition the later levels on it and mark o used. Returns D² of the child."""
    c = stack.next_child[t]
    stack.next_child[t] += 1
    o = stack.obs[t, c]
    work.dvalid[k + 1] = False
    _condition_on_pairing(cond, P, Y, d, tree.levels, k, t, o, work)
    stack.d2_before[t] = D2
    work.used[o] = True
    idx[tree.levels[t]] = o
    stack.choice[t] = o
    return stack.d2[t, c]


@numba.njit(cache=True)
def _undo_choice(tree, t, idx, work, stack):
    """Remove level t's active pairing from H; returns D²_H without it."""
    o = stack.choice[t]
    work.used[o] = False
    idx[tree.levels[t]] = -1
    stack.choice[t] = -1
    return stack.d2_before[t]


# -- the search --------------------------------------------------------------------------------------------
@numba.njit(cache=True)
def jcbb_search(mu, P, Y, d, levels, cand_ptr, cand_obs, last_level, thresh, max_nodes):
    """Depth-first branch and bound over the interpretation tree (iterative: an explicit per-level stack).

    Entering a node (depth k = pairings of H, level t): bound → budget → count → incumbent → expand.
    Advancing level t: undo the active choice, then take the next child, else the star, else go up.
    Returns (best_idx, best_k, best_d2, nodes, budget_exhausted).
    """
    tree = _Tree(levels, cand_ptr, cand_obs, last_level, thresh)
    T = levels.size
    K = min(T, Y.shape[1])
    cond = _initial_conditionals(mu, P, d, levels, K)
    work = _new_work(d, Y.shape[1], T, K, cand_obs.size)
    stack = _new_stack(tree)
    idx = np.full(mu.size // d, -1, dtype=np.int64)
    best_idx = idx.copy()
    best_k, best_d2 = 0, np.inf
    k, D2, t = 0, 0.0, 0
    nodes = 0
    exhausted = False
    entering = True
    while True:
        if entering:
            entering = False
            if t < T and not work.dvalid[k]:
                _fill_d2_cache(cond, Y, tree, k, t, D2, work)
            possible = _pairings_bound(cond, tree, k, t, D2, best_k, best_d2, work)
            if _cannot_beat(k, possible, D2, best_k, best_d2):
                t -= 1
                if t < 0:
                    break
                continue
            if max_nodes >= 0 and nodes >= max_nodes:
                exhausted = True
                break
            nodes += 1
            if k > best_k or (k == best_k and D2 < best_d2):        # incumbent: H completed with stars
                best_k, best_d2 = k, D2
                best_idx[:] = idx
            if t == T:
                t -= 1
                if t < 0:
                    break
                continue
            _expand_level(cond, tree, k, t, work, stack)
        if stack.choice[t] >= 0:
            D2 = _undo_choice(tree, t, idx, work, stack)
            k -= 1
        if stack.next_child[t] < stack.n_children[t]:
            D2 = _take_next_child(cond, P, Y, d, tree, k, t, D2, idx, work, stack)
            k += 1
        elif not stack.star_done[t]:
            stack.star_done[t] = True          # a star keeps H: the predictions at depth k stay valid
        else:
            t -= 1
            if t < 0:
                break
            continue
        t += 1
        entering = True
    return best_idx, best_k, best_d2, nodes, exhausted
