"""Joint compatibility branch and bound (JCBB; Neira & Tardós 2001, lecture L09).

**The interpretation tree.** One level per landmark with at least one individually compatible (IC) observation,
d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki ≤ χ²_d(c), the most constrained first: fewest IC candidates, ties → lower landmark
index (:func:`level_order`). The children of a node H (a pairings) on level t are the unused IC observations i
of the level's landmark k whose enlarged hypothesis passes the joint gate D²_{H+(k,i)} ≤ χ²_{d(a+1)}(c), nearest
first (ties → lower i), then the star (k unpaired). The best hypothesis has the most pairings, then the smallest
D²_H; a node replaces the incumbent Best only when strictly better (of equal hypotheses the first met wins).

**The incremental joint distance** (the lecture: "this test is carried out incrementally"). Given the pairings
of H, the other landmarks' predictions are Gaussian, N(μ_{·|H}, Σ_{·|H}); pairing level t with the observation y
updates them like a Kalman filter:

    Σ_{t|H} = L Lᵀ,   w = L⁻¹ (y − μ_{t|H}),   G = L⁻¹ Σ_{t,·|H},
    D²_{H+} = D²_H + wᵀw,   μ_{·|H+} = μ_{·|H} + Gᵀ w,   Σ_{·|H+} = Σ_{·|H} − GᵀG

(the block row that extends the Cholesky factor of C_H). So every candidate's joint distance is an individual
distance against the conditional prediction, D²_{H+(q,o)} = D²_H + d²(o | q, H): JC is IC given H.

**The bound.** A node is cut when no descendant can beat Best: a + possible < pairings(Best), or = and
D²_H ≥ D²_Best, where ``possible`` bounds the pairings a descendant can still add (:func:`pairings_bound`):
at most the levels left and the unused observations that are still some level's candidate (U); a candidate
(q, o) can be in a descendant only if D²_H + d²(o | q, H) ≤ χ²_{d(a+U)}, the widest gate a descendant
meets; the i-th pairing added below H must pass χ²_{d(a+i)}, so at most as many levels as form a chain
D²_H + min_o d²(o | q_i, H) ≤ χ²_{d(a+i)}; and when a + possible only ties pairings(Best), a descendant adds
``need`` pairings on distinct levels, so its D² is at least the need-th smallest per-level minimum.

The search (:meth:`_Search.visit`) is plain Python; what it computes for every hypothesis (the conditional
predictions, the candidates' joint distances, the bound) is compiled with numba as plain loops: notebook 08 runs
the search on thousands of scenes. Gates use c = 2Φ(n_σ) − 1 and ``≤``.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from ..gaussian import Gaussian, chi2inv, confidence_level
from ..validation import boolean, integer
from .common import Association, AssociationProblem, empty_association, finish, prepare

__all__ = ["jcbb", "JCBBTrace", "level_order", "TRACE_EXPANDED", "TRACE_JC_FAIL", "TRACE_BOUND", "TRACE_BEST"]

TRACE_EXPANDED = 0   #: node expanded (passed the joint gate and the bound)
TRACE_JC_FAIL = 1    #: child rejected by the joint χ² gate (its subtree is never visited)
TRACE_BOUND = 2      #: node cut by the bound (cannot beat the incumbent)
TRACE_BEST = 3       #: node expanded and became the new incumbent Best


@dataclass(frozen=True)
class JCBBTrace:
    """Nodes of the searched tree in visiting order (entry 0 is the root, with parent, level and landmark −1):
    parent, level (depth − 1), landmark, obs (the observation paired at the node, −1 for a star), d2 (D² of the
    node's hypothesis), status (TRACE_* codes)."""

    parent: np.ndarray
    level: np.ndarray
    landmark: np.ndarray
    obs: np.ndarray
    d2: np.ndarray
    status: np.ndarray


def level_order(compatible: np.ndarray) -> np.ndarray:
    """Landmarks that open a tree level, in visiting order: at least one IC candidate; fewest candidates
    first, ties → lower landmark index. ``compatible``: boolean (n, m) IC matrix."""
    counts = np.count_nonzero(compatible, axis=1)
    lm = np.flatnonzero(counts > 0)
    return lm[np.lexsort((lm, counts[lm]))]


# --------------------------------------------------------------------------------------------------------
# the numerics of one hypothesis (compiled: plain loops)
# --------------------------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _cholesky(A: np.ndarray) -> tuple[np.ndarray, bool]:
    """Lower Cholesky factor L of a small symmetric matrix A (A = L Lᵀ) and whether A is positive definite."""
    d = A.shape[0]
    L = np.zeros((d, d))
    for a in range(d):
        for b in range(a + 1):
            s = A[a, b]                              # L_ab = (A_ab − Σ_u L_au L_bu) / L_bb
            for u in range(b):
                s -= L[a, u] * L[b, u]
            if a == b:
                if not s > 0.0:
                    return L, False
                L[a, a] = np.sqrt(s)
            else:
                L[a, b] = s / L[b, b]
    return L, True


@numba.njit(cache=True)
def condition_on_pairing(mean: np.ndarray, cov: np.ndarray, t: int, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The predictions (mean (T, d), cov (T·d, T·d)) conditioned on one more pairing: level t's landmark
    observed at y. Returns new arrays; only the levels after t are updated (the search never reads the others)."""
    T, d = mean.shape
    r = d * t
    L, _ = _cholesky(cov[r:r + d, r:r + d])              # Σ_t = L Lᵀ (positive definite: t has a candidate)
    w = np.empty(d)
    G = np.empty((d, T * d))
    for a in range(d):                                    # forward substitution, row a of L
        s = y[a] - mean[t, a]                             # w = L⁻¹ (y − μ_t)
        for u in range(a):
            s -= L[a, u] * w[u]
        w[a] = s / L[a, a]
        for c in range(r + d, T * d):                     # G = L⁻¹ Σ_{t,·}
            s = cov[r + a, c]
            for u in range(a):
                s -= L[a, u] * G[u, c]
            G[a, c] = s / L[a, a]
    new_mean = mean.copy()
    new_cov = cov.copy()
    for c in range(r + d, T * d):
        for a in range(d):                                # μ ← μ + Gᵀ w
            new_mean[c // d, c % d] += G[a, c] * w[a]
        for e in range(r + d, c + 1):                     # Σ ← Σ − Gᵀ G  (symmetric)
            s = 0.0
            for a in range(d):
                s += G[a, c] * G[a, e]
            new_cov[c, e] -= s
            new_cov[e, c] = new_cov[c, e]
    return new_mean, new_cov


@numba.njit(cache=True)
def candidate_distances(mean: np.ndarray, cov: np.ndarray, D2: float, t: int, Y: np.ndarray, ic: np.ndarray,
                        used: np.ndarray) -> np.ndarray:
    """cand (T, m): D²_H + d²(o | q, H) for every IC candidate o of every level q ≥ t that is not used in H;
    ∞ elsewhere, and for a level whose conditional covariance is not positive definite (round-off)."""
    T, d = mean.shape
    m = Y.shape[1]
    cand = np.full((T, m), np.inf)
    w = np.empty(d)
    for q in range(t, T):
        L, ok = _cholesky(cov[d * q:d * q + d, d * q:d * q + d])      # Σ_{q|H} = L Lᵀ
        if not ok:
            continue
        for o in range(m):
            if not ic[q, o] or used[o]:
                continue
            d2 = 0.0
            for a in range(d):                                          # w = L⁻¹ (y_o − μ_{q|H})
                s = Y[a, o] - mean[q, a]
                for u in range(a):
                    s -= L[a, u] * w[u]
                w[a] = s / L[a, a]
                d2 += w[a] * w[a]
            cand[q, o] = D2 + d2                                        # D²_{H+(q,o)} = D²_H + ‖w‖²
    return cand


@numba.njit(cache=True)
def pairings_bound(cand: np.ndarray, t: int, a: int, D2: float, used: np.ndarray, last_level: np.ndarray,
                   gates: np.ndarray, best_a: int, best_d2: float) -> int:
    """Upper bound on the pairings a descendant of the node (level t, H with a pairings and distance D2) can
    still add (module docstring), or −1 when even a tie in pairings cannot beat D²_Best.
    last_level[o]: the last level that has o as a candidate (−1: none); gates[j] = χ²_{d·j}(c)."""
    T, m = cand.shape
    if t == T:
        return 0
    reach = 0                                   # unused observations that are a candidate of a level ≥ t
    for o in range(m):
        if not used[o] and last_level[o] >= t:
            reach += 1
    U = min(T - t, reach)
    if U == 0 or a + U < best_a:
        return U
    widest = gates[a + U]
    n_obs = 0                                   # observations with a candidate under the widest gate
    for o in range(m):
        for q in range(t, T):
            if cand[q, o] <= widest:
                n_obs += 1
                break
    chain = 0                                   # levels q_1 < q_2 < … with D²_H + min d²(o | q_i, H) ≤ χ²_{d(a+i)}
    nearest = np.full(T - t, np.inf)
    for q in range(t, T):
        for o in range(m):
            nearest[q - t] = min(nearest[q - t], cand[q, o])
        if a + chain + 1 < gates.size and nearest[q - t] <= gates[a + chain + 1]:
            chain += 1
    possible = min(chain, n_obs)
    need = best_a - a
    if a + possible == best_a and need > 0 and D2 < best_d2:
        if np.sort(nearest)[need - 1] >= best_d2:          # every such descendant has D² ≥ D²_Best
            return -1
    return possible


@numba.njit(cache=True)
def nearest_first(d2: np.ndarray, gate: float) -> np.ndarray:
    """The indices i with d2[i] ≤ gate, in ascending d2 (ties → lower i)."""
    passing = np.flatnonzero(d2 <= gate)
    return passing[np.argsort(d2[passing], kind="mergesort")]


# --------------------------------------------------------------------------------------------------------
# the search
# --------------------------------------------------------------------------------------------------------
@functools.lru_cache(maxsize=256)
def _joint_gates(c: float, d: int, T: int) -> np.ndarray:
    """gates[a] = χ²_{d·a}(c) for a = 0 … T + 1 (gates[0] = 0; read-only: one array per setting)."""
    gates = np.concatenate([[0.0], chi2inv(c, d * np.arange(1, T + 2))])
    gates.setflags(write=False)
    return gates


class _Search:
    """One JCBB search: the tree (levels and their IC candidates), the hypothesis H being built (``idx``,
    ``used``) and the incumbent Best; ``nodes`` counts the expanded nodes, ``trace`` records the tree."""

    def __init__(self, problem, levels, max_nodes, tracing):
        d, T = problem.d, levels.size
        self.levels, self.T, self.max_nodes = levels, T, max_nodes
        self.Y = np.ascontiguousarray(problem.Y)
        self.ic = problem.ic_d2[levels] <= problem.ic_threshold                  # (T, m) candidates per level
        self.last_level = np.where(self.ic.any(axis=0), T - 1 - np.argmax(self.ic[::-1], axis=0), -1)  # −1: none
        self.gates = _joint_gates(confidence_level(problem.n_sigma), d, T)
        self.idx = np.full(problem.n, -1)               # H: idx[k] = observation paired with landmark k
        self.used = np.zeros(problem.m, dtype=bool)     # observations paired in H
        self.best_idx, self.best_a, self.best_d2 = self.idx.copy(), 0, np.inf
        self.nodes, self.exhausted = 0, False
        self.trace, self.tracing = [], tracing
        rows = (d * levels[:, None] + np.arange(d)).ravel()
        self.mean = np.ascontiguousarray(problem.mu[levels])                      # predictions given H = ∅
        self.cov = np.ascontiguousarray(problem.P[np.ix_(rows, rows)])

    def record(self, parent, level, obs, status, d2):
        """Append a trace entry; returns its index (−1: not recorded)."""
        if not self.tracing:
            return -1
        self.trace.append([parent, level, obs, status, d2])
        return len(self.trace) - 1

    def mark(self, node, status):
        """Set the status of a recorded node."""
        if node >= 0:
            self.trace[node][3] = status

    def children(self, t, a, cand, node):
        """The observations level t's landmark can take: the candidates under the joint gate χ²_{d(a+1)},
        nearest first (ties → lower observation); the candidates over it are recorded as JC failures."""
        gate = self.gates[a + 1]
        if self.tracing:
            for i in np.flatnonzero((cand[t] > gate) & (cand[t] < np.inf)):
                self.record(node, t, int(i), TRACE_JC_FAIL, float(cand[t, i]))
        return nearest_first(cand[t], gate).tolist()

    def visit(self, t, a, D2, mean, cov, cand, node):
        """Visit the node on level t of the interpretation tree and then, depth first, its subtree (t = T: a leaf).

        The node's hypothesis H is held in ``self.idx`` (each landmark's observation, or −1) and ``self.used`` (the
        observations paired in H); it has ``a`` pairings and the joint distance ``D2`` = D²_H. ``mean`` (T, d) and
        ``cov`` (T·d, T·d) are the levels' predictions given H, ``cand`` (T, m) the candidates' joint distances
        D²_{H+(q,o)} (:func:`candidate_distances`), ``node`` the node's trace entry (−1 when not tracing).

        The contract (the tree, Best and the bound: module docstring):

        - the bound (:func:`pairings_bound`) comes first: a node that cannot beat Best is cut: not counted, marked
          TRACE_BOUND, no subtree;
        - then the budget: ``self.nodes`` counts the expanded nodes, the root included, at most ``self.max_nodes``
          (None: no limit); the node met when the budget is spent is marked TRACE_BOUND, sets ``self.exhausted``,
          and the search ends (nothing is expanded after it);
        - an expanded node whose H beats Best becomes Best (``best_idx``: a copy of ``self.idx``, ``best_a``,
          ``best_d2``) and is marked TRACE_BEST;
        - below a node on level t < T: its children in the order of :meth:`children` (which records the joint-gate
          failures), each a pairing of level t's landmark, then last the star (the landmark left unpaired); each is
          recorded with ``record(node, t, its observation or −1, TRACE_EXPANDED, its D²)`` and visited on level
          t + 1 with the predictions given its hypothesis (:func:`condition_on_pairing`, :func:`candidate_distances`);
        - on return, ``self.idx`` and ``self.used`` are as they were on entry.
        """
        possible = pairings_bound(cand, t, a, D2, self.used, self.last_level, self.gates, self.best_a, self.best_d2)
        if a + possible < self.best_a or (a + possible == self.best_a and D2 >= self.best_d2):
            self.mark(node, TRACE_BOUND)
            return
        if self.nodes == self.max_nodes:
            self.exhausted = True
            self.mark(node, TRACE_BOUND)
            return
        self.nodes += 1
        if a > self.best_a or (a == self.best_a and D2 < self.best_d2):
            self.best_idx, self.best_a, self.best_d2 = self.idx.copy(), a, D2
            self.mark(node, TRACE_BEST)
        if t == self.T:
            return
        landmark = self.levels[t]
        for i in self.children(t, a, cand, node):
            d2 = float(cand[t, i])
            mean_i, cov_i = condition_on_pairing(mean, cov, t, self.Y[:, i])
            self.idx[landmark], self.used[i] = i, True
            cand_i = candidate_distances(mean_i, cov_i, d2, t + 1, self.Y, self.ic, self.used)
            self.visit(t + 1, a + 1, d2, mean_i, cov_i, cand_i, self.record(node, t, i, TRACE_EXPANDED, d2))
            self.idx[landmark], self.used[i] = -1, False
            if self.exhausted:
                return
        self.visit(t + 1, a, D2, mean, cov, cand, self.record(node, t, -1, TRACE_EXPANDED, D2))

    def run(self):
        """Search from the root (H = ∅)."""
        cand = candidate_distances(self.mean, self.cov, 0.0, 0, self.Y, self.ic, self.used)
        self.visit(0, 0, 0.0, self.mean, self.cov, cand, self.record(-1, -1, -1, TRACE_EXPANDED, 0.0))

    def trace_arrays(self) -> JCBBTrace:
        rows = np.array(self.trace, dtype=float).reshape(-1, 5)
        parent, level, obs, status = (rows[:, c].astype(np.int64) for c in range(4))
        landmark = np.where(level >= 0, self.levels[np.maximum(level, 0)], -1)
        return JCBBTrace(parent=parent, level=level, landmark=landmark, obs=obs, d2=rows[:, 4], status=status)


def jcbb(density: Gaussian | AssociationProblem, Y: ArrayLike | None, n_sigma: float = 3.0,
         max_nodes: int | None = None, trace: bool = False) -> Association:
    """JCBB association (module docstring) with the gates of ``n_sigma``. ``max_nodes``: expanded-node budget
    (None: unlimited); when hit, the best hypothesis so far is returned with ``budget_exhausted``. ``trace``:
    record the searched tree in ``stats["trace"]`` (a :class:`JCBBTrace`). stats: ``nodes`` (expanded, root
    included), ``levels`` (landmarks with an IC candidate) and ``level_order``."""
    max_nodes = integer(max_nodes, "max_nodes", minimum=1, allow_none=True)
    trace = boolean(trace, "trace")
    problem = prepare(density, Y, n_sigma)
    levels = level_order(problem.ic_d2 <= problem.ic_threshold)
    stats = {"nodes": 1, "levels": int(levels.size), "level_order": levels}
    if levels.size == 0:
        return empty_association(problem, "jcbb", stats)
    search = _Search(problem, levels, max_nodes, trace)
    search.run()
    stats["nodes"] = search.nodes
    if trace:
        stats["trace"] = search.trace_arrays()
    return finish(problem, search.best_idx, "jcbb", stats, budget_exhausted=search.exhausted,
                  d2=0.0 if search.best_a == 0 else search.best_d2)
