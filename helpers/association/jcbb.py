"""Joint compatibility branch and bound (JCBB, Neira & Tardós 2001) with the incremental joint distance.

Interpretation tree over the *landmarks* (idx has one entry per landmark, as in the lab's SNN). Only
landmarks with at least one individually compatible (IC) observation open a level; the others are
starred without branching. Levels are visited in a fixed order: fewest IC candidates first (ties → lower
landmark index), the classic "most constrained first" rule; the order is reported in
``stats["level_order"]``.

At a node H (a partial hypothesis with a pairings and joint distance D²_H) on level t, landmark k:

1. **Incremental joint distance (lecture L09).** With C_H = L Lᵀ, w = L⁻¹ f_H (D²_H = ‖w‖²),
   B = Cov(f_H, ν_k) = P[rows(H), rows(k)] and D = P_kk, appending the pairing (k, i) gives

       L W = B,   D − WᵀW = L₂ L₂ᵀ,   w_n = L₂⁻¹ (ν_ki − Wᵀ w),   D²_{H+(k,i)} = D²_H + ‖w_n‖²,

   with new factor [[L, 0], [Wᵀ, L₂]]. Here μ_k + Wᵀw and L₂L₂ᵀ are the mean and covariance of landmark
   k's prediction *conditioned on the pairings of H*, so the code keeps, for every later level q, the
   block column W_q = L⁻¹ P[rows(H), rows(q)] (it grows by d rows per pairing: one block forward
   substitution, O(a d²) per level) together with the conditional mean and Cholesky factor of q. A child's
   D² is then D²_H + ‖L₂,q⁻¹(y_i − μ_{q|H})‖², O(d²) per candidate; no fresh factorisation ever happens.
   These conditional distances depend only on H, so they are computed once per pairing and reused by all
   the star nodes below it.
2. **Bound.** possible = an upper bound on the pairings any descendant can still add; the node is
   discarded when a + possible < pairings(Best), or a + possible = pairings(Best) and D²_H ≥ D²_Best (D²
   only grows along a branch). For the star branch this is the lecture's "pairings(H) + remaining possible
   ≥ best"; it is applied at every node. possible is the smallest of: the levels left; the unused
   observations that are still a candidate of a later level and pass D²_H + d²(o | q, H) ≤ χ²_{d(a+U)} (U the
   simple bound — D² of any superset is at least that of H + (q, o)); and the longest chain of later levels
   q₁ < q₂ < … whose best conditional candidate keeps the i-th prefix jointly compatible,
   D²_H + min_o d²(o | q_i, H) ≤ χ²_{d(a+i)}. When a + possible = pairings(Best) exactly, a descendant must
   add that many pairings on distinct levels, so its D² is at least the corresponding order statistic of
   the per-level minima; if that is ≥ D²_Best the node is discarded too. Every rule only removes nodes
   that cannot beat Best: the result is the exact optimum of the tree (tested against exhaustive search).
3. **Incumbent.** H completed with stars is a hypothesis: if it has more pairings than Best, or as many
   and a smaller D², it becomes Best (objective: most pairings, then smallest D²).
4. **Children.** The IC observations of landmark k not already used in H whose joint distance passes
   D² ≤ χ²_{d(a+1)}(c) are tried nearest-first (smallest joint D², ties → lower observation index); the
   others fail the joint gate and are cut with their whole subtree. The star branch (k unpaired) comes last.

Note that with the joint gate applied at every node the admissible hypotheses are those whose every
prefix (in level order) is jointly compatible, so the level order can matter in borderline cases.

The search is an iterative depth-first loop compiled with numba (deterministic: no parallelism, no
fastmath). ``max_nodes`` caps the number of expanded nodes; when it is hit the best hypothesis found so
far is returned with ``budget_exhausted=True``. ``trace=True`` records every node, JC rejection and bound
cut for drawing the interpretation tree (small problems).
"""
from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from helpers.association.common import Association, _check_int, empty_association, finish, prepare
from helpers.gaussian import chi2inv, confidence_level

__all__ = ["jcbb", "JCBBTrace", "TRACE_EXPANDED", "TRACE_JC_FAIL", "TRACE_BOUND", "TRACE_BEST",
           "level_order"]

TRACE_EXPANDED = 0   #: node expanded (passed the joint gate and the bound)
TRACE_JC_FAIL = 1    #: child rejected by the joint χ² gate (its subtree is never visited)
TRACE_BOUND = 2      #: node cut by the bound (cannot beat the incumbent)
TRACE_BEST = 3       #: node expanded and became the new incumbent Best
_TRACE_STATUS_NAMES = {0: "expanded", 1: "jc_fail", 2: "bound", 3: "best"}


@dataclass(frozen=True)
class JCBBTrace:
    """Nodes of the searched interpretation tree, in visiting order (entry 0 is the root).

    parent (int, −1 for the root), level (tree depth − 1 of the choice; −1 root), landmark (−1 root),
    obs (observation paired at this node, −1 for a star), d2 (joint D² of the node's hypothesis),
    status (TRACE_* codes); truncated is True when more nodes were visited than recorded.
    """

    parent: np.ndarray
    level: np.ndarray
    landmark: np.ndarray
    obs: np.ndarray
    d2: np.ndarray
    status: np.ndarray
    truncated: bool

    def status_name(self, i: int) -> str:
        return _TRACE_STATUS_NAMES[int(self.status[i])]


@numba.njit(cache=True)
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


@numba.njit(cache=True)
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


@numba.njit(cache=True)
def _jcbb_kernel(mu, P, Y, d, levels, cand_ptr, cand_obs, last_level, thresh, max_nodes, trace_cap):
    n = mu.size // d
    m = Y.shape[1]
    T = levels.size
    K = min(T, m)
    Tm = max(T, 1)
    pmax = max(d * K, 1)
    # Conditional predictions of every level's landmark given the first j pairings of H (j = 0..K):
    # mean cM[j, q] = μ_q + G_qᵀ w and Cholesky factor cL[j, q] of P_qq − G_qᵀ G_q, where the rows of
    # G = L⁻¹ P[rows(H), rows(levels)] grow by d rows per pairing (forward substitution of one block).
    GT = np.zeros((d * Tm, pmax))                 # Gᵀ, so the O(a) inner products run on contiguous rows
    cM = np.zeros((K + 1, Tm, d))
    cL = np.zeros((K + 1, Tm, d, d))
    cOK = np.zeros((K + 1, Tm), dtype=np.bool_)
    Sq = np.zeros((d, d))
    for q in range(T):
        lq = levels[q]
        for a in range(d):
            cM[0, q, a] = mu[d * lq + a]
            for b in range(d):
                Sq[a, b] = P[d * lq + a, d * lq + b]
        cOK[0, q] = _chol_small(Sq, cL[0, q])
    tmp = np.zeros(d)
    wn = np.zeros(d)
    Gn = np.zeros((d, d))
    used = np.zeros(m, dtype=np.bool_)
    mark = np.zeros(m, dtype=np.bool_)
    mins = np.zeros(Tm)
    # d²-cache: for the current H at depth k, dcache[k, e] = D²_H + d²(o_e | q_e, H) for every candidate
    # edge e of a later level (inf when o_e is used). H is fixed while the search stays at depth k (star
    # branches do not change it), so the values are computed once per pairing, not once per node.
    E = cand_obs.size
    dcache = np.full((K + 1, max(E, 1)), np.inf)
    dvalid = np.zeros(K + 1, dtype=np.bool_)
    idx = np.full(n, -1, dtype=np.int64)
    best_idx = idx.copy()
    best_k = 0
    best_d2 = np.inf
    maxc = 1
    for t in range(T):
        maxc = max(maxc, cand_ptr[t + 1] - cand_ptr[t])
    lv_obs = np.zeros((Tm, maxc), dtype=np.int64)
    lv_d2 = np.zeros((Tm, maxc))
    lv_nc = np.zeros(Tm, dtype=np.int64)
    lv_ptr = np.zeros(Tm, dtype=np.int64)
    lv_star = np.zeros(Tm, dtype=np.bool_)
    lv_choice = np.full(Tm, -1, dtype=np.int64)
    lv_d2_before = np.zeros(Tm)
    lv_node = np.zeros(T + 1, dtype=np.int64)
    tcap = max(trace_cap, 1)
    tr_parent = np.full(tcap, -1, dtype=np.int64)
    tr_level = np.full(tcap, -1, dtype=np.int64)
    tr_obs = np.full(tcap, -1, dtype=np.int64)
    tr_status = np.zeros(tcap, dtype=np.int64)
    tr_d2 = np.zeros(tcap)
    ntr = 0
    truncated = False
    if trace_cap > 0:
        ntr = 1                      # root
    k = 0
    D2 = 0.0
    nodes = 0
    jc_evals = 0
    exhausted = False
    t = 0
    entering = True
    while True:
        if entering:
            entering = False
            # ---- bound: how many more pairings could any descendant still make? -------------------------
            possible = 0
            if t < T and not dvalid[k]:
                for q in range(t, T):
                    for e in range(cand_ptr[q], cand_ptr[q + 1]):
                        o = cand_obs[e]
                        if used[o] or not cOK[k, q]:
                            dcache[k, e] = np.inf
                        else:
                            dcache[k, e] = D2 + _whitened_sq(cL[k, q], Y, cM[k, q], o, tmp)
                            jc_evals += 1
                dvalid[k] = True
            if t < T:
                reach = 0
                for o in range(m):
                    if not used[o] and last_level[o] >= t:
                        reach += 1
                U = min(T - t, reach)
                if U > 0 and k + U >= best_k:
                    # JC-aware refinement. A pairing (q, o) can appear in a descendant H' only if
                    # D²_H + d²(o | q, H) ≤ D²_H' ≤ χ²_{d(k+U)} (the joint distance grows with the set),
                    # and the i-th pairing added below H must keep its prefix jointly compatible:
                    # D²_H + min_o d²(o | q_i, H) ≤ χ²_{d(k+i)} with q_1 < q_2 < … in level order
                    # (greedy scan = the longest such chain, as thresholds grow with i).
                    lim = thresh[k + U]
                    n_ob = 0
                    chain = 0
                    n_mins = 0
                    for o in range(m):
                        mark[o] = False
                    for q in range(t, T):
                        if not cOK[k, q]:
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
                        if best_q <= thresh[k + chain + 1]:
                            chain += 1
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
                else:
                    possible = U
            if k + possible < best_k or (k + possible == best_k and D2 >= best_d2):
                if trace_cap > 0 and lv_node[t] >= 0:
                    tr_status[lv_node[t]] = 2
                t -= 1
                if t < 0:
                    break
                continue
            if max_nodes >= 0 and nodes >= max_nodes:
                exhausted = True
                if trace_cap > 0 and lv_node[t] >= 0:
                    tr_status[lv_node[t]] = 2
                break
            nodes += 1
            if k > best_k or (k == best_k and D2 < best_d2):
                best_k = k
                best_d2 = D2
                best_idx[:] = idx
                if trace_cap > 0 and lv_node[t] >= 0:
                    tr_status[lv_node[t]] = 3
            if t == T:
                t -= 1
                if t < 0:
                    break
                continue
            # ---- expand level t: joint distance of every child, D²_H + ‖L₂⁻¹(y_o − μ_{t|H})‖² ------
            nc = 0
            if k < K and cOK[k, t]:
                for e in range(cand_ptr[t], cand_ptr[t + 1]):
                    o = cand_obs[e]
                    if used[o]:
                        continue
                    d2new = dcache[k, e]
                    if d2new <= thresh[k + 1]:
                        pos = nc                          # insertion: ascending D², ties keep obs order
                        while pos > 0 and lv_d2[t, pos - 1] > d2new:
                            lv_obs[t, pos] = lv_obs[t, pos - 1]
                            lv_d2[t, pos] = lv_d2[t, pos - 1]
                            pos -= 1
                        lv_obs[t, pos] = o
                        lv_d2[t, pos] = d2new
                        nc += 1
                    elif trace_cap > 0:
                        if ntr < trace_cap:
                            tr_parent[ntr] = lv_node[t]
                            tr_level[ntr] = t
                            tr_obs[ntr] = o
                            tr_status[ntr] = 1
                            tr_d2[ntr] = d2new
                            ntr += 1
                        else:
                            truncated = True
            lv_nc[t] = nc
            lv_ptr[t] = 0
            lv_star[t] = False
            lv_choice[t] = -1
        # ---- advance level t: undo the active choice, take the next child or the star, or go up --------
        if lv_choice[t] >= 0:
            o = lv_choice[t]
            k -= 1
            used[o] = False
            idx[levels[t]] = -1
            D2 = lv_d2_before[t]
            lv_choice[t] = -1
        if lv_ptr[t] < lv_nc[t]:
            c = lv_ptr[t]
            lv_ptr[t] += 1
            o = lv_obs[t, c]
            p = d * k
            lt = levels[t]
            # new block row of G for every later level q: Gn = L₂⁻¹ (P[rows(t), rows(q)] − W_tᵀ G_q),
            # then the conditional mean and covariance of q given H + (t, o).
            Lt = cL[k, t]
            _whitened_sq(Lt, Y, cM[k, t], o, wn)          # w_n = L₂⁻¹ (y_o − μ_{t|H})
            dvalid[k + 1] = False
            for q in range(t + 1, T):
                lq = levels[q]
                for b in range(d):
                    for a in range(d):
                        s = P[d * lt + a, d * lq + b]
                        for r in range(p):
                            s -= GT[d * t + a, r] * GT[d * q + b, r]
                        for u in range(a):
                            s -= Lt[a, u] * Gn[u, b]
                        Gn[a, b] = s / Lt[a, a]
                for a in range(d):
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
            lv_d2_before[t] = D2
            D2 = lv_d2[t, c]
            used[o] = True
            idx[lt] = o
            k += 1
            lv_choice[t] = o
            obs_here = o
        elif not lv_star[t]:
            lv_star[t] = True
            # a star keeps H: the conditional predictions at depth k stay valid for the later levels
            obs_here = -1
        else:
            t -= 1
            if t < 0:
                break
            continue
        if trace_cap > 0:
            if ntr < trace_cap:
                tr_parent[ntr] = lv_node[t]
                tr_level[ntr] = t
                tr_obs[ntr] = obs_here
                tr_status[ntr] = 0
                tr_d2[ntr] = D2
                lv_node[t + 1] = ntr
                ntr += 1
            else:
                truncated = True
                lv_node[t + 1] = -1
        t += 1
        entering = True
    return (best_idx, best_k, best_d2, nodes, jc_evals, exhausted,
            tr_parent[:ntr], tr_level[:ntr], tr_obs[:ntr], tr_status[:ntr], tr_d2[:ntr], truncated)


def level_order(compatible) -> np.ndarray:
    """Landmarks that open a tree level, in visiting order: at least one IC candidate; fewest candidates
    first, ties → lower landmark index. ``compatible``: boolean (n, m) IC matrix."""
    counts = np.count_nonzero(compatible, axis=1)
    lm = np.flatnonzero(counts > 0)
    return lm[np.lexsort((lm, counts[lm]))]


def jcbb(density, Y, n_sigma: float = 3.0, max_nodes: int | None = None, trace: bool = False,
         trace_capacity: int = 20000) -> Association:
    """JCBB association (see the module docstring).

    Parameters
    ----------
    density : Gaussian of size d·n (predicted measurements of the n landmarks, full cross-covariance)
    Y : (d, m) observations
    n_sigma : gate width; IC gate χ²_d(c) and joint gate χ²_{d·a}(c), c = 2Φ(n_σ) − 1 (``≤``)
    max_nodes : expanded-node budget (None = unlimited); when hit, the best hypothesis so far is returned
        with ``budget_exhausted=True``
    trace : record the searched tree in ``stats["trace"]`` (a :class:`JCBBTrace`, at most
        ``trace_capacity`` entries)

    stats: ``nodes`` (expanded nodes, root included), ``jc_evaluations`` (candidate joint distances
    computed), ``levels`` (landmarks with an IC candidate), ``level_order``, ``ic_pairs`` and ``trace``.
    """
    max_nodes = _check_int(max_nodes, "max_nodes", minimum=1, allow_none=True)
    if not isinstance(trace, bool):
        raise ValueError(f"trace must be True or False, got {trace!r}")
    trace_capacity = _check_int(trace_capacity, "trace_capacity", minimum=1)
    problem = prepare(density, Y, n_sigma)
    d, n, m = problem.d, problem.n, problem.m
    compatible = problem.ic_d2 <= problem.ic_threshold
    levels = level_order(compatible)
    stats = {"nodes": 0, "jc_evaluations": 0, "levels": int(levels.size), "level_order": levels,
             "ic_pairs": int(np.count_nonzero(compatible))}
    if m == 0:
        stats["nodes"] = 1
        return empty_association(problem, "jcbb", stats)
    sub = compatible[levels]                                     # (T, m)
    rows, cols = np.nonzero(sub)                                 # row-major: per level, obs ascending
    cand_ptr = np.concatenate([[0], np.cumsum(np.count_nonzero(sub, axis=1))]).astype(np.int64)
    if levels.size == 0:
        stats["nodes"] = 1
        return empty_association(problem, "jcbb", stats)
    last_level = np.where(sub.any(axis=0), sub.shape[0] - 1 - np.argmax(sub[::-1], axis=0), -1)
    K = min(levels.size, m)
    thresh = np.zeros(K + 2)
    thresh[1:] = chi2inv(confidence_level(n_sigma), d * np.arange(1, K + 2))
    out = _jcbb_kernel(np.ascontiguousarray(problem.mu.ravel()), np.ascontiguousarray(problem.P),
                       np.ascontiguousarray(problem.Y), d, levels.astype(np.int64), cand_ptr,
                       cols.astype(np.int64), last_level.astype(np.int64), thresh,
                       -1 if max_nodes is None else max_nodes, trace_capacity if trace else 0)
    best_idx, best_k, best_d2, nodes, jc_evals, exhausted = out[:6]
    stats["nodes"] = int(nodes)
    stats["jc_evaluations"] = int(jc_evals)
    if trace:
        parent, lev, obs, status, d2s, truncated = out[6:]
        landmark = np.where(lev >= 0, levels[np.maximum(lev, 0)] if levels.size else -1, -1)
        stats["trace"] = JCBBTrace(parent=parent, level=lev, landmark=landmark, obs=obs, d2=d2s,
                                   status=status, truncated=bool(truncated))
    return finish(problem, best_idx, "jcbb", stats, budget_exhausted=bool(exhausted),
                  d2=0.0 if best_k == 0 else best_d2)
