"""Joint compatibility branch and bound (JCBB, Neira & Tardós 2001), in two tiers.

* :func:`jcbb_reference` — the teaching version: a recursive depth-first search in plain numpy that
  recomputes the joint Mahalanobis distance of every hypothesis from its definition. Read this one first.
* :func:`jcbb` — the fast version: the same search compiled with numba (``jcbb_kernel``), with the
  incremental joint distance of lecture L09 and a tighter bound. It returns the same association (tested
  on many random scenes) after visiting far fewer nodes, and can record the searched tree
  (:class:`JCBBTrace`, ``TRACE_*`` codes) for drawing.

Both search the same interpretation tree for the same objective:

* **Levels.** One level per landmark with at least one individually compatible (IC) observation,
  d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki ≤ χ²_d(c); landmarks without one are starred without branching. Levels are
  visited most constrained first: fewest IC candidates, ties → lower landmark index (:func:`level_order`,
  reported in ``stats["level_order"]``).
* **Children** of a node H (a pairings) on level t, landmark k: the IC observations i of k not used in H
  whose enlarged hypothesis is jointly compatible, D²_{H+(k,i)} ≤ χ²_{d(a+1)}(c), tried nearest first
  (smallest D², ties → lower observation index); then the star branch (k unpaired). A child failing the
  joint gate is cut with its whole subtree, so the admissible hypotheses are those whose every prefix (in
  level order) is jointly compatible.
* **Objective.** Most pairings, then smallest D²_H. Every node (H completed with stars) is compared with
  the incumbent Best and replaces it only when strictly better, so of several equally good hypotheses the
  one met first in the depth-first order is returned — by both tiers.
* **Bound.** A node is discarded when pairings(H) + (pairings its descendants can still add) <
  pairings(Best), or = pairings(Best) and D²_H ≥ D²_Best (D² never decreases along a branch). The bounds
  only remove nodes that cannot beat Best, so both tiers return the exact optimum of the tree.

Gates use c = 2Φ(n_σ) − 1 and ``≤``. ``max_nodes`` caps the expanded nodes; when hit, the best hypothesis
found so far is returned with ``budget_exhausted=True`` (the two tiers count different nodes, so their
capped results may differ).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numba
import numpy as np

from ..gaussian import chi2inv, confidence_level
from .common import Association, _check_int, _joint_d2, empty_association, finish, prepare
from .jcbb_kernel import TRACE_BEST, TRACE_BOUND, TRACE_EXPANDED, TRACE_JC_FAIL, jcbb_search

__all__ = ["jcbb", "jcbb_reference", "JCBBTrace", "TRACE_EXPANDED", "TRACE_JC_FAIL", "TRACE_BOUND",
           "TRACE_BEST", "level_order"]

_TRACE_STATUS_NAMES = {TRACE_EXPANDED: "expanded", TRACE_JC_FAIL: "jc_fail", TRACE_BOUND: "bound",
                       TRACE_BEST: "best"}


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


@functools.lru_cache(maxsize=256)
def _joint_gates(c: float, d: int, K: int) -> np.ndarray:
    """χ²_{d·a}(c) for a = 1 … K + 1 (read-only; the front-end asks for the same few gates every scan)."""
    gates = chi2inv(c, d * np.arange(1, K + 2))
    gates.setflags(write=False)
    return gates


def level_order(compatible) -> np.ndarray:
    """Landmarks that open a tree level, in visiting order: at least one IC candidate; fewest candidates
    first, ties → lower landmark index. ``compatible``: boolean (n, m) IC matrix."""
    compatible = np.asarray(compatible)
    if compatible.ndim != 2 or compatible.dtype != bool:
        raise ValueError(f"compatible must be a boolean (n, m) matrix, got {compatible.dtype} {compatible.shape}")
    counts = np.count_nonzero(compatible, axis=1)
    lm = np.flatnonzero(counts > 0)
    return lm[np.lexsort((lm, counts[lm]))]


@numba.njit(cache=True)
def _tree_arrays(ic_d2, threshold):
    """The compiled search's tree from the individual distances: ``level_order`` of the IC matrix
    d² ≤ ``threshold`` (levels (T,)), each level's IC observations ascending (``cand_obs[cand_ptr[t]:cand_ptr[t+1]]``)
    and, per observation, the last level that has it as a candidate (−1: none)."""
    n, m = ic_d2.shape
    counts = np.zeros(n, dtype=np.int64)
    for k in range(n):
        for i in range(m):
            if ic_d2[k, i] <= threshold:
                counts[k] += 1
    lm = np.flatnonzero(counts > 0)
    levels = lm[np.argsort(counts[lm] * (n + 1) + lm)]          # fewest candidates first, ties → lower index
    T = levels.size
    cand_ptr = np.zeros(T + 1, dtype=np.int64)
    for t in range(T):
        cand_ptr[t + 1] = cand_ptr[t] + counts[levels[t]]
    cand_obs = np.empty(cand_ptr[T], dtype=np.int64)
    last_level = np.full(m, -1, dtype=np.int64)
    q = 0
    for t in range(T):
        for i in range(m):
            if ic_d2[levels[t], i] <= threshold:
                cand_obs[q] = i
                last_level[i] = t
                q += 1
    return levels.astype(np.int64), cand_ptr, cand_obs, last_level


def _tree(density, Y, n_sigma):
    """The validated problem, its IC matrix, the level order and the stats shared by both tiers."""
    problem = prepare(density, Y, n_sigma)
    compatible = problem.ic_d2 <= problem.ic_threshold
    levels = level_order(compatible)
    stats = {"nodes": 0, "jc_evaluations": 0, "levels": int(levels.size), "level_order": levels,
             "ic_pairs": int(np.count_nonzero(compatible))}
    return problem, compatible, levels, stats


# --------------------------------------------------------------------------------------------------------
# tier 1: the readable recursive search
# --------------------------------------------------------------------------------------------------------
class _ReferenceSearch:
    """State of one :func:`jcbb_reference` search: the hypothesis H being built and the incumbent Best."""

    def __init__(self, problem, candidates, levels, max_nodes):
        self.problem, self.candidates, self.levels, self.max_nodes = problem, candidates, levels, max_nodes
        self.gate = problem.jc_threshold(np.arange(1, len(levels) + 1))    # gate[a − 1] = χ²_{d·a}(c)
        self.idx = np.full(problem.n, -1)              # H: idx[k] = observation paired with landmark k
        self.used = set()                              # observations already paired in H
        self.best_idx, self.best_pairings, self.best_d2 = self.idx.copy(), 0, np.inf
        self.nodes = self.jc_evaluations = 0
        self.exhausted = False

    def joint_d2(self, k, i):
        """D² of H + (k, i), from the definition f_Hᵀ C_H⁻¹ f_H (a Cholesky factorisation of C_H)."""
        self.idx[k] = i
        d2 = _joint_d2(self.problem, self.idx)
        self.idx[k] = -1
        self.jc_evaluations += 1
        return d2

    def remaining(self, t):
        """Pairings the levels t, t+1, … can still add: levels with an unused candidate, at most as many
        as the distinct unused observations among their candidates."""
        free = [set(c.tolist()) - self.used for c in self.candidates[t:]]
        return min(sum(1 for f in free if f), len(set().union(*free)))

    def visit(self, t, a, d2):
        """Node on level t whose hypothesis H has a pairings and joint distance d2."""
        if self.exhausted:
            return
        possible = self.remaining(t)
        if a + possible < self.best_pairings or (a + possible == self.best_pairings and d2 >= self.best_d2):
            return                                                  # bound: cannot beat Best
        if self.max_nodes is not None and self.nodes >= self.max_nodes:
            self.exhausted = True
            return
        self.nodes += 1
        if a > self.best_pairings or (a == self.best_pairings and d2 < self.best_d2):
            self.best_idx, self.best_pairings, self.best_d2 = self.idx.copy(), a, d2      # new incumbent
        if t == len(self.levels):
            return
        k = self.levels[t]
        children = []
        for i in self.candidates[t]:
            if i not in self.used:
                d2_child = self.joint_d2(k, i)
                if d2_child <= self.gate[a]:                        # joint gate χ²_{d(a+1)}(c)
                    children.append((d2_child, int(i)))
        for d2_child, i in sorted(children):                        # nearest first, ties → lower i
            self.idx[k] = i
            self.used.add(i)
            self.visit(t + 1, a + 1, d2_child)
            self.idx[k] = -1
            self.used.discard(i)
        self.visit(t + 1, a, d2)                                    # the star branch: k unpaired


def jcbb_reference(density, Y, n_sigma: float = 3.0, max_nodes: int | None = None) -> Association:
    """JCBB written as the textbook recursion (Neira & Tardós 2001); the oracle for :func:`jcbb`.

    A hypothesis H pairs a landmarks k_1 … k_a with distinct observations i_1 … i_a. Its innovation and
    covariance stack the pairs (the density already includes the measurement noise):

        f_H = [y_{i_1} − μ_{k_1}; …; y_{i_a} − μ_{k_a}],   C_H = P[rows(H), rows(H)],
        D²_H = f_Hᵀ C_H⁻¹ f_H = ‖L⁻¹ f_H‖²   with C_H = L Lᵀ (Cholesky).

    H is jointly compatible when D²_H ≤ χ²_{d·a}(c): if H is right, D²_H is χ² with d·a degrees of freedom.
    Unlike the individual test, C_H carries the cross-covariances: a shared pose error moves all
    predictions together, so a constellation of pairings can pass jointly where each pair looks wrong alone
    (or fail jointly although each passes alone). Adding a pairing never decreases D².

    Algorithm (depth-first over the interpretation tree; see the module docstring for the tree):

        visit(t, H):                                    # level t, landmark k = levels[t]
            if pairings(H) + remaining(t) < pairings(Best), or = and D²_H ≥ D²_Best:  return   # bound
            if H beats Best (more pairings, or as many and smaller D²):  Best ← H
            if t = T:  return
            for each IC observation i of k not used in H, nearest (smallest D²_{H+(k,i)}) first:
                if D²_{H+(k,i)} ≤ χ²_{d(a+1)}(c):  visit(t + 1, H + (k, i))
            visit(t + 1, H)                              # star node: k unpaired

    remaining(t) counts the levels t… that still have an unused candidate (capped by the number of those
    candidates). Every D² is computed from scratch: O((d·a)³) per candidate, which is what :func:`jcbb`
    avoids with the incremental Cholesky update.

    Same inputs as :func:`jcbb` except tracing; stats: ``nodes`` (expanded nodes, root included; more than
    ``jcbb`` needs, its bound is tighter), ``jc_evaluations`` (joint distances computed), ``levels``,
    ``level_order`` and ``ic_pairs``.
    """
    max_nodes = _check_int(max_nodes, "max_nodes", minimum=1, allow_none=True)
    problem, compatible, levels, stats = _tree(density, Y, n_sigma)
    if problem.m == 0 or levels.size == 0:
        stats["nodes"] = 1
        return empty_association(problem, "jcbb_reference", stats)
    candidates = [np.flatnonzero(compatible[k]) for k in levels]             # ascending observation index
    search = _ReferenceSearch(problem, candidates, levels, max_nodes)
    search.visit(0, 0, 0.0)
    stats["nodes"], stats["jc_evaluations"] = search.nodes, search.jc_evaluations
    return finish(problem, search.best_idx, "jcbb_reference", stats, budget_exhausted=search.exhausted,
                  d2=0.0 if search.best_pairings == 0 else search.best_d2)


# --------------------------------------------------------------------------------------------------------
# tier 2: the compiled search
# --------------------------------------------------------------------------------------------------------
def jcbb(density, Y, n_sigma: float = 3.0, max_nodes: int | None = None, trace: bool = False,
         trace_capacity: int = 20000) -> Association:
    """JCBB association, compiled (see the module docstring; the numerics are in ``jcbb_kernel``).

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
    levels, cand_ptr, cols, last_level = _tree_arrays(problem.ic_d2, problem.ic_threshold)
    stats = {"nodes": 0, "jc_evaluations": 0, "levels": int(levels.size), "level_order": levels,
             "ic_pairs": int(cand_ptr[-1])}
    if problem.m == 0 or levels.size == 0:
        stats["nodes"] = 1
        return empty_association(problem, "jcbb", stats)
    K = min(levels.size, problem.m)
    thresh = np.zeros(K + 2)                                     # thresh[a] = χ²_{d·a}(c)
    thresh[1:] = _joint_gates(confidence_level(n_sigma), problem.d, K)
    out = jcbb_search(np.ascontiguousarray(problem.mu.ravel()), np.ascontiguousarray(problem.P),
                      np.ascontiguousarray(problem.Y), problem.d, levels, cand_ptr, cols, last_level, thresh,
                      -1 if max_nodes is None else max_nodes, trace_capacity if trace else 0)
    best_idx, best_k, best_d2, nodes, jc_evals, exhausted = out[:6]
    stats["nodes"] = int(nodes)
    stats["jc_evaluations"] = int(jc_evals)
    if trace:
        parent, lev, obs, status, d2s, truncated = out[6:]
        landmark = np.where(lev >= 0, levels[np.maximum(lev, 0)], -1)
        stats["trace"] = JCBBTrace(parent=parent, level=lev, landmark=landmark, obs=obs, d2=d2s,
                                   status=status, truncated=bool(truncated))
    return finish(problem, best_idx, "jcbb", stats, budget_exhausted=bool(exhausted),
                  d2=0.0 if best_k == 0 else best_d2, jc_gates=thresh)
