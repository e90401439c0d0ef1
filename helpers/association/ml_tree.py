"""Maximum-likelihood association as a search over the interpretation tree (lecture L09).

Tree: one level per *observation* i = 0 … K−1 (the lecture's orientation); at level i the observation takes one
of the N landmarks or "new" (likelihood α, Probabilistic Robotics p. 322). A full hypothesis is a leaf; the tree
has (N + 1)^K leaves. The cost of a hypothesis is its negative log-likelihood under the independence assumption,

    J(c) = Σ_i ℓ(i, c^i),   ℓ(i, k) = ½ d²_ki + ½ log det(2π S_k),   ℓ(i, new) = −log α,

and a landmark may explain at most one observation (one-to-one). Without that constraint each c^i is chosen on
its own (:func:`independent_ml`); with it the choices interact and a search is needed.

:func:`ml_tree_search` is a **best-first** (A*) search: partial hypotheses wait in a priority queue ordered by
cost so far + an optimistic estimate of the rest (each remaining observation at its cheapest option, ignoring
the one-to-one constraint: never an over-estimate), and the cheapest is expanded next, so the first full
hypothesis taken from the queue is the optimum. A pairing with ℓ(i, k) ≥ −log α is never opened: "new" costs no
more and keeps landmark k free. :func:`greedy_descent` takes the cheapest child at every level.
"""
from __future__ import annotations

import heapq
import itertools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import linear_sum_assignment

from ..gaussian import Gaussian
from ..validation import float_array, int_array, integer, positive_number
from .common import AssociationProblem, prepare
from .maximum_likelihood import ml_scores

__all__ = ["MLTreeResult", "ml_costs", "ml_tree_search", "greedy_descent", "independent_ml", "assignment_ml",
           "tree_size", "hypothesis_cost"]


@dataclass(frozen=True)
class MLTreeResult:
    """Result of a tree search: ``labels`` (K,) landmark of each observation or −1 ("new"), its ``cost``
    (negative log-likelihood), ``expanded`` / ``generated`` node counts and ``budget_exhausted``."""

    labels: np.ndarray
    cost: float
    expanded: int
    generated: int
    budget_exhausted: bool


def ml_costs(density: Gaussian, Y: ArrayLike, alpha: float) -> tuple[AssociationProblem, np.ndarray, float]:
    """(problem, ell, new): ell (K, N) = ℓ(i, k) for observation i and landmark k, new = −log α."""
    alpha = positive_number(alpha, "alpha")
    problem = prepare(density, Y)
    return problem, ml_scores(problem, None).T, float(-np.log(alpha))


def tree_size(n_landmarks: int, n_observations: int) -> tuple[int, int]:
    """(leaves, nodes) of the full interpretation tree: (N + 1)^K leaves, Σ_{l=0..K} (N + 1)^l nodes (exact)."""
    b = integer(n_landmarks, "n_landmarks", minimum=0) + 1
    K = integer(n_observations, "n_observations", minimum=0)
    return b ** K, sum(b ** level for level in range(K + 1))


def hypothesis_cost(ell: ArrayLike, new: float, labels: ArrayLike) -> float:
    """J(c) of the observation labels (K entries, each −1 or a landmark in [0, N)) under the costs of
    :func:`ml_costs` (ell (K, N), new); ValueError naming ``labels`` otherwise."""
    ell = float_array(ell, "ell")
    labels = int_array(labels, "labels")
    if labels.shape != (ell.shape[0],) or np.any(labels < -1) or np.any(labels >= ell.shape[1]):
        raise ValueError(f"labels must hold one entry per observation ({ell.shape[0]}), each -1 or a landmark in "
                         f"[0, {ell.shape[1]}), got {labels.tolist()}")
    return _cost(ell, new, labels)


def _cost(ell: np.ndarray, new: float, labels: np.ndarray) -> float:
    paired = labels >= 0
    return float(ell[np.flatnonzero(paired), labels[paired]].sum() + new * np.count_nonzero(~paired))


def _result(ell: np.ndarray, new: float, labels: tuple, expanded: int, generated: int,
            exhausted: bool) -> MLTreeResult:
    labels = np.asarray(labels, dtype=np.intp)
    return MLTreeResult(labels, _cost(ell, new, labels), expanded, generated, exhausted)


def _options(ell: np.ndarray, new: float) -> list[np.ndarray]:
    """Per observation: the landmarks worth opening (ℓ < −log α), cheapest first (ties → lower index)."""
    out = []
    for row in ell:
        k = np.flatnonzero(row < new)
        out.append(k[np.argsort(row[k], kind="stable")])
    return out


def _greedy(opts: list[np.ndarray], labels: tuple = ()) -> tuple:
    """``labels`` completed level by level with the cheapest landmark not yet used (or "new")."""
    used = {k for k in labels if k >= 0}
    for k_opts in opts[len(labels):]:
        k = next((int(k) for k in k_opts if int(k) not in used), -1)
        labels += (k,)
        used.add(k)
    return labels


def greedy_descent(density: Gaussian, Y: ArrayLike, alpha: float) -> MLTreeResult:
    """Walk the tree once, taking the cheapest child at every level (observation order 0 … K−1)."""
    _, ell, new = ml_costs(density, Y, alpha)
    K = ell.shape[0]
    return _result(ell, new, _greedy(_options(ell, new)), K + 1, K + 1, False)


def ml_tree_search(density: Gaussian, Y: ArrayLike, alpha: float, max_nodes: int | None = None) -> MLTreeResult:
    """Best-first (A*) search of the ML interpretation tree: the exact optimum, unless the ``max_nodes``
    expansion budget runs out (then the cheapest open node is completed greedily, ``budget_exhausted``)."""
    max_nodes = integer(max_nodes, "max_nodes", minimum=1, allow_none=True)
    _, ell, new = ml_costs(density, Y, alpha)
    K = ell.shape[0]
    opts = _options(ell, new)
    best_each = np.array([min(new, float(ell[i, o[0]])) if o.size else new for i, o in enumerate(opts)])
    rest = np.concatenate([np.cumsum(best_each[::-1])[::-1], [0.0]])   # optimistic cost of levels i..K−1
    tie = itertools.count()
    heap = [(rest[0], next(tie), 0.0, ())]                            # (g + h, tie, g, labels so far)
    expanded, generated = 0, 1
    while True:                                                       # the "new" child always exists
        f, _, g, labels = heapq.heappop(heap)
        i = len(labels)
        if i == K or (max_nodes is not None and expanded >= max_nodes):
            return _result(ell, new, _greedy(opts, labels), expanded, generated, i < K)
        expanded += 1
        used = {k for k in labels if k >= 0}
        for k in opts[i]:
            if int(k) not in used:
                g_child = g + float(ell[i, k])
                heapq.heappush(heap, (g_child + rest[i + 1], next(tie), g_child, labels + (int(k),)))
                generated += 1
        heapq.heappush(heap, (g + new + rest[i + 1], next(tie), g + new, labels + (-1,)))
        generated += 1


def independent_ml(density: Gaussian, Y: ArrayLike, alpha: float) -> np.ndarray:
    """Each observation's own best choice, argmin_k ℓ(i, k) or −1 if −log α is cheaper: the lecture's product of
    independent maxima. Two observations may choose the same landmark."""
    _, ell, new = ml_costs(density, Y, alpha)
    if ell.shape[1] == 0:
        return np.full(ell.shape[0], -1, dtype=np.intp)
    k = np.argmin(ell, axis=1)
    return np.where(ell[np.arange(ell.shape[0]), k] < new, k, -1).astype(np.intp)


def assignment_ml(density: Gaussian, Y: ArrayLike, alpha: float) -> tuple[np.ndarray, float]:
    """(labels, cost) of the one-to-one optimum as an assignment problem (Hungarian algorithm, scipy's
    ``linear_sum_assignment``): K observations × (N landmarks + K private "new" slots)."""
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
