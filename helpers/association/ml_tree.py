"""Maximum-likelihood association as a search over the interpretation tree (lecture L09).

Tree: one level per *observation* i = 0 … K−1 (the lecture's orientation); at level i the observation
takes one of the N landmarks or "new" (likelihood α, Probabilistic Robotics p. 322). A full hypothesis is
a leaf; the tree has (N + 1)^K leaves — for N = K the lecture's O((K + 1)^K). The cost of a hypothesis is
its negative log-likelihood under the independence assumption,

    J(c) = Σ_i ℓ(i, c^i),   ℓ(i, k) = ½ d²_ki + ½ log det(2π S_k),   ℓ(i, new) = −log α,

and a landmark may explain at most one observation (one-to-one). Without that constraint each c^i is
chosen on its own (the lecture's "evaluate c^i individually", :func:`independent_ml`); with it the choices
interact and a search is needed.

:func:`ml_tree_search` is a **best-first** (graph-search, A*) exploration: partial hypotheses wait in a
priority queue ordered by cost so far + an optimistic estimate of the rest (each remaining observation at
its cheapest option, ignoring the one-to-one constraint — never an over-estimate), and the cheapest is
expanded next. The first full hypothesis taken from the queue is therefore the optimum, usually after
expanding a tiny part of the tree. A pairing with ℓ(i, k) ≥ −log α is never opened: "new" costs no more
and keeps landmark k free. :func:`greedy_descent` is the purely greedy walk (best child at each level).
"""
from __future__ import annotations

import heapq
import itertools
import numbers
from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..validation import finite_number, float_array
from .common import Association, finish, prepare

__all__ = ["MLTreeResult", "ml_costs", "ml_tree_search", "greedy_descent", "independent_ml", "assignment_ml",
           "tree_size", "hypothesis_cost"]


@dataclass(frozen=True)
class MLTreeResult:
    """Result of a tree search: ``labels`` (K,) landmark of each observation or −1 ("new"), its
    ``cost`` (negative log-likelihood), ``expanded`` / ``generated`` node counts, ``budget_exhausted``,
    and ``association`` (the same hypothesis in the common interface, one entry per landmark)."""

    labels: np.ndarray
    cost: float
    expanded: int
    generated: int
    budget_exhausted: bool
    association: Association


def _check_alpha(alpha):
    if isinstance(alpha, bool) or not isinstance(alpha, numbers.Real) or not np.isfinite(alpha) or alpha <= 0:
        raise ValueError(f"alpha must be a positive finite likelihood (a density), got {alpha!r}")
    return float(alpha)


def ml_costs(density, Y, alpha):
    """(problem, ell, new): ell (K, N) = ℓ(i, k) for observation i and landmark k, new = −log α."""
    alpha = _check_alpha(alpha)
    problem = prepare(density, Y)
    ell = (0.5 * problem.ic_d2 + 0.5 * problem.logdet[:, None]).T
    return problem, ell, float(-np.log(alpha))


def tree_size(n_landmarks: int, n_observations: int) -> tuple[int, int]:
    """(leaves, nodes) of the full interpretation tree: (N + 1)^K leaves, Σ_{l=0..K} (N + 1)^l nodes
    (exact Python integers)."""
    for name, v in (("n_landmarks", n_landmarks), ("n_observations", n_observations)):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 0:
            raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
    b = int(n_landmarks) + 1
    return b ** int(n_observations), sum(b ** level for level in range(int(n_observations) + 1))


def hypothesis_cost(ell, new, labels) -> float:
    """J(c) of observation labels (landmark or −1) under the costs of :func:`ml_costs` (ell (K, N), new);
    labels has K entries, each −1 or a landmark in [0, N) (ValueError naming the argument otherwise)."""
    ell = float_array(ell, "ell")
    if ell.ndim != 2 or not np.all(np.isfinite(ell)):
        raise ValueError(f"ell must be a finite (K, N) cost array, got shape {ell.shape}")
    new = finite_number(new, "new")
    arr = np.asarray(labels)
    if arr.shape != (ell.shape[0],) or (arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer))):
        raise ValueError(f"labels must hold {ell.shape[0]} integers (one per observation), got {arr.dtype} {arr.shape}")
    if np.any(arr < -1) or np.any(arr >= ell.shape[1]):
        raise ValueError(f"labels entries must be -1 or a landmark in [0, {ell.shape[1]}): {arr.tolist()}")
    return _cost(ell, new, arr.astype(np.intp))


def _cost(ell, new, labels) -> float:
    """:func:`hypothesis_cost` without the checks."""
    labels = np.asarray(labels)
    paired = labels >= 0
    return float(ell[np.flatnonzero(paired), labels[paired]].sum() + new * np.count_nonzero(~paired))


def _result(problem, ell, new, labels, expanded, generated, exhausted, name):
    labels = np.asarray(labels, dtype=np.intp)
    idx = np.full(problem.n, -1, dtype=np.intp)
    idx[labels[labels >= 0]] = np.flatnonzero(labels >= 0)
    assoc = finish(problem, idx, name, {"nodes": int(expanded), "generated": int(generated)},
                   budget_exhausted=exhausted)
    return MLTreeResult(labels=labels, cost=_cost(ell, new, labels), expanded=int(expanded),
                        generated=int(generated), budget_exhausted=bool(exhausted), association=assoc)


def _options(ell, new):
    """Per observation: the landmarks worth opening (ℓ < −log α), cheapest first (ties → lower index)."""
    out = []
    for row in ell:
        k = np.flatnonzero(row < new)
        out.append(k[np.argsort(row[k], kind="stable")])
    return out


def greedy_descent(density, Y, alpha) -> MLTreeResult:
    """Walk the tree once, taking the cheapest child at every level (observation order 0 … K−1)."""
    problem, ell, new = ml_costs(density, Y, alpha)
    used, labels = set(), []
    for k_opts in _options(ell, new):
        k = next((int(k) for k in k_opts if int(k) not in used), -1)
        labels.append(k)
        if k >= 0:
            used.add(k)
    K = len(labels)
    return _result(problem, ell, new, labels, K + 1, K + 1, False, "ml_greedy_descent")


def ml_tree_search(density, Y, alpha, max_nodes: int | None = None) -> MLTreeResult:
    """Best-first (A*) search of the ML interpretation tree; returns the exact optimum unless the
    ``max_nodes`` expansion budget runs out (then the cheapest open node is completed greedily and
    ``budget_exhausted`` is True)."""
    if max_nodes is not None and (isinstance(max_nodes, bool) or not isinstance(max_nodes, numbers.Integral)
                                  or max_nodes < 1):
        raise ValueError(f"max_nodes must be a positive integer or None, got {max_nodes!r}")
    problem, ell, new = ml_costs(density, Y, alpha)
    K = ell.shape[0]
    opts = _options(ell, new)
    best_each = np.array([min(new, float(ell[i, o[0]])) if o.size else new for i, o in enumerate(opts)])
    rest = np.concatenate([np.cumsum(best_each[::-1])[::-1], [0.0]])   # optimistic cost of levels i..K−1
    tie = itertools.count()
    heap = [(rest[0], next(tie), 0.0, ())]                            # (g + h, tie, g, labels so far)
    expanded, generated = 0, 1
    while heap:
        f, _, g, labels = heapq.heappop(heap)
        i = len(labels)
        if i == K:
            return _result(problem, ell, new, labels, expanded, generated, False, "ml_tree_search")
        if max_nodes is not None and expanded >= max_nodes:
            used = {k for k in labels if k >= 0}
            tail = []
            for k_opts in opts[i:]:
                k = next((int(k) for k in k_opts if int(k) not in used), -1)
                tail.append(k)
                if k >= 0:
                    used.add(k)
            return _result(problem, ell, new, labels + tuple(tail), expanded, generated, True, "ml_tree_search")
        expanded += 1
        used = {k for k in labels if k >= 0}
        for k in opts[i]:
            if int(k) not in used:
                g_child = g + float(ell[i, k])
                heapq.heappush(heap, (g_child + rest[i + 1], next(tie), g_child, labels + (int(k),)))
                generated += 1
        heapq.heappush(heap, (g + new + rest[i + 1], next(tie), g + new, labels + (-1,)))
        generated += 1
    raise AssertionError("unreachable: the 'new' child always exists")   # pragma: no cover


def independent_ml(density, Y, alpha) -> np.ndarray:
    """Each observation's own best choice, argmin_k ℓ(i, k) or −1 if −log α is cheaper — the lecture's
    product of independent maxima. Two observations may choose the same landmark."""
    _, ell, new = ml_costs(density, Y, alpha)
    if ell.shape[1] == 0:
        return np.full(ell.shape[0], -1, dtype=np.intp)
    k = np.argmin(ell, axis=1)
    return np.where(ell[np.arange(ell.shape[0]), k] < new, k, -1).astype(np.intp)


def assignment_ml(density, Y, alpha) -> tuple[np.ndarray, float]:
    """(labels, cost) of the one-to-one optimum as an assignment problem (Hungarian algorithm, scipy's
    ``linear_sum_assignment``): K observations × (N landmarks + K private "new" slots). An independent
    reference for :func:`ml_tree_search` at any size."""
    _, ell, new = ml_costs(density, Y, alpha)
    K, N = ell.shape
    if K == 0:
        return np.zeros(0, dtype=np.intp), 0.0
    big = 1e6 + 10.0 * (np.abs(ell).sum() + K * abs(new))          # forbidden: dearer than any hypothesis
    C = np.full((K, N + K), big)
    C[:, :N] = np.where(ell < new, ell, big)
    C[np.arange(K), N + np.arange(K)] = new
    rows, cols = linear_sum_assignment(C)
    labels = np.where(cols < N, cols, -1).astype(np.intp)[np.argsort(rows)]
    return labels, _cost(ell, new, labels)
