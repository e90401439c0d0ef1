"""JCBB with the whole search compiled (``jcbb_kernel``): the online-SLAM front-end's association and the fast
side of ``benchmarks/jcbb.py``.

Same contract, tree, bound and result as the course's :func:`helpers.association.jcbb.jcbb` (the same
association after the same number of expanded nodes; ``tests/test_jcbb_fast.py`` checks it on random scenes),
without the trace. The course's search is a Python recursion over compiled numerics; this one is a single
compiled loop over an explicit stack, several times faster on large trees.
"""
from __future__ import annotations

import functools

import numba
import numpy as np

from ..association.common import Association, empty_association, finish, prepare
from ..gaussian import chi2inv, confidence_level
from ..validation import integer
from .jcbb_kernel import jcbb_search

__all__ = ["jcbb"]


@functools.lru_cache(maxsize=256)
def _joint_gates(c: float, d: int, K: int) -> np.ndarray:
    """χ²_{d·a}(c) for a = 1 … K + 1 (read-only; the front-end asks for the same few gates every scan)."""
    gates = chi2inv(c, d * np.arange(1, K + 2))
    gates.setflags(write=False)
    return gates


@numba.njit(cache=True)
def _tree_arrays(ic_d2, threshold):
    """The tree from the individual distances: ``level_order`` of the IC matrix d² ≤ ``threshold`` (levels
    (T,)), each level's IC observations ascending (``cand_obs[cand_ptr[t]:cand_ptr[t+1]]``) and, per
    observation, the last level that has it as a candidate (−1: none)."""
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


def jcbb(density, Y, n_sigma: float = 3.0, max_nodes: int | None = None) -> Association:
    """JCBB association, compiled: the arguments and result of :func:`helpers.association.jcbb.jcbb` (stats
    ``nodes``, ``levels``, ``level_order``; no trace)."""
    max_nodes = integer(max_nodes, "max_nodes", minimum=1, allow_none=True)
    problem = prepare(density, Y, n_sigma)
    levels, cand_ptr, cols, last_level = _tree_arrays(problem.ic_d2, problem.ic_threshold)
    stats = {"nodes": 1, "levels": int(levels.size), "level_order": levels}
    if levels.size == 0:
        return empty_association(problem, "jcbb", stats)
    K = min(levels.size, problem.m)
    thresh = np.zeros(K + 2)                                     # thresh[a] = χ²_{d·a}(c)
    thresh[1:] = _joint_gates(confidence_level(n_sigma), problem.d, K)
    best_idx, best_k, best_d2, nodes, exhausted = jcbb_search(
        np.ascontiguousarray(problem.mu.ravel()), np.ascontiguousarray(problem.P), np.ascontiguousarray(problem.Y),
        problem.d, levels, cand_ptr, cols, last_level, thresh, -1 if max_nodes is None else max_nodes)
    stats["nodes"] = int(nodes)
    return finish(problem, best_idx, "jcbb", stats, budget_exhausted=bool(exhausted),
                  d2=0.0 if best_k == 0 else best_d2)
