"""Lecture L09: joint compatibility branch and bound, the search _Search.visit (public tests).

The tests call ``jcbb`` (it runs your search) and check what it returns against definitions written out in this
file: the best hypothesis of the interpretation tree by exhaustive enumeration (the most pairings, then the
smallest joint distance D²_H = fᵀ C_H⁻¹ f, among the hypotheses whose every prefix in level order passes the joint
gate D² ≤ χ²_{d·a}(c)), and the recorded tree (``trace=True``) node by node: each node's D² from scratch, the
joint-gate failures, the nearest-first order of the children with the star last, the node count and the budget.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_true, fail
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, norm

from helpers.association.common import Association
from helpers.association.jcbb import TRACE_BEST, TRACE_BOUND, TRACE_EXPANDED, TRACE_JC_FAIL, jcbb
from helpers.gaussian import Gaussian

CODES = {TRACE_EXPANDED: "TRACE_EXPANDED", TRACE_JC_FAIL: "TRACE_JC_FAIL", TRACE_BOUND: "TRACE_BOUND",
         TRACE_BEST: "TRACE_BEST"}


# ------------------------------------------------------------------------------ the definitions, written out
def gate(n_sigma, dof):
    """χ²_dof(c) with c = 2Φ(n_σ) − 1, the probability mass within n_σ of a 1-D Gaussian."""
    return float(chi2.ppf(norm.cdf(n_sigma) - norm.cdf(-n_sigma), dof))


def individual_d2(mu, cov, Y):
    """d2[k, i] = (y_i − μ_k)ᵀ P_kk⁻¹ (y_i − μ_k), with P_kk landmark k's own block."""
    n, d = mu.shape
    d2 = np.empty((n, Y.shape[1]))
    for k in range(n):
        block = cov[d * k:d * k + d, d * k:d * k + d]
        for i in range(Y.shape[1]):
            nu = Y[:, i] - mu[k]
            d2[k, i] = nu @ np.linalg.solve(block, nu)
    return d2


def joint_d2(mu, cov, Y, idx):
    """D²_H = fᵀ C⁻¹ f of the pairings in idx: f stacks y_i − μ_k, C the rows of the paired landmarks."""
    d = Y.shape[0]
    k = np.flatnonzero(idx >= 0)
    if k.size == 0:
        return 0.0
    rows = (d * k[:, None] + np.arange(d)).ravel()
    f = (Y[:, idx[k]].T - mu[k]).ravel()
    return float(f @ np.linalg.solve(cov[np.ix_(rows, rows)], f))


def tree_levels(mu, cov, Y, n_sigma):
    """The landmarks that open a level: with at least one individually compatible observation, fewest first
    (ties → lower landmark); and the IC matrix."""
    ic = individual_d2(mu, cov, Y) <= gate(n_sigma, Y.shape[0])
    counts = ic.sum(axis=1)
    return sorted((k for k in range(mu.shape[0]) if counts[k] > 0), key=lambda k: (counts[k], k)), ic


def exhaustive(mu, cov, Y, n_sigma):
    """Every hypothesis of the tree: each level's landmark takes an unused IC observation or nothing, and every
    pairing, added in level order, keeps the hypothesis under the joint gate χ²_{d·a}. Returns the best (most
    pairings, then smallest D²) as (a, D², idx) and whether it is unique (no other with a and D² within 1e-9)."""
    n, d = mu.shape
    levels, ic = tree_levels(mu, cov, Y, n_sigma)
    found = []

    def extend(t, idx, a, d2):
        if t == len(levels):
            found.append((a, d2, idx.copy()))
            return
        k = levels[t]
        for i in np.flatnonzero(ic[k]):
            if i in idx:
                continue
            idx[k] = i
            d2_new = joint_d2(mu, cov, Y, idx)
            if d2_new <= gate(n_sigma, d * (a + 1)):
                extend(t + 1, idx, a + 1, d2_new)
            idx[k] = -1
        extend(t + 1, idx, a, d2)

    extend(0, np.full(n, -1), 0, 0.0)
    found.sort(key=lambda h: (-h[0], h[1]))
    a, d2, idx = found[0]
    unique = all(h[0] < a or h[1] - d2 > 1e-9 * max(1.0, d2) for h in found[1:])
    return a, d2, idx, unique


def shifted_row(n, spacing=1.0, shift_sigma=1.0, sigma=0.05):
    """n landmarks on a line that share one uncertain translation (a pose error): strongly correlated."""
    mu = np.column_stack([spacing * np.arange(n), np.zeros(n)])
    J = np.tile(np.eye(2), (n, 1))
    return mu, shift_sigma ** 2 * J @ J.T + sigma ** 2 * np.eye(2 * n)


def run(mu, cov, Y, **options):
    res = jcbb(Gaussian.from_cov(mu.ravel(), cov), Y, **options)
    if not isinstance(res, Association):
        fail("the result of jcbb", note="expected an Association, got %s" % type(res).__name__)
    return res


def check_best(res, mu, cov, Y, n_sigma, given):
    """res is the exhaustive search's best hypothesis."""
    a, d2, idx, unique = exhaustive(mu, cov, Y, n_sigma)
    given = {**given, "best hypothesis (exhaustive search)": idx, "its D²": d2, "your idx": np.asarray(res.idx)}
    expect_equal(int(res.n_pairings), a, "the number of pairings of the best hypothesis (most pairings first)",
                 given=given)
    expect_close(res.d2, d2, "D² of the best hypothesis (the smallest among those with the most pairings)",
                 given=given, rtol=1e-8, atol=1e-10)
    if unique:
        expect_equal(np.asarray(res.idx).tolist(), idx.tolist(), "idx of the best hypothesis", given=given)
    expect_equal(bool(res.budget_exhausted), False, "budget_exhausted without a budget", given=given)


def check_trace(res, mu, cov, Y, n_sigma, given, complete=True):
    """The recorded tree is the tree of the definitions: node by node."""
    tr = res.stats.get("trace")
    if tr is None:
        fail("stats['trace'] with trace=True", given=given, note="jcbb returned no trace")
    d = Y.shape[0]
    parent, level, landmark, obs, d2, status = (np.asarray(getattr(tr, f)) for f in
                                                ("parent", "level", "landmark", "obs", "d2", "status"))
    expect_true(parent.size >= 1 and parent[0] == -1 and level[0] == -1, "entry 0 of the trace is the root "
                "(parent −1, level −1)", given=given)
    unknown = sorted(set(status.tolist()) - set(CODES))
    expect_true(not unknown, "every status is a TRACE_* code", given=given, actual=unknown)
    expanded = np.isin(status, [TRACE_EXPANDED, TRACE_BEST])
    counts = {CODES[c]: int(np.count_nonzero(status == c)) for c in CODES}
    expect_equal(int(res.stats["nodes"]), int(np.count_nonzero(expanded)), "stats['nodes'] counts the expanded "
                 "nodes only: the trace's TRACE_EXPANDED and TRACE_BEST entries", given={**given, "trace statuses":
                                                                                        counts})
    hyps = [np.full(mu.shape[0], -1)]
    for j in range(1, parent.size):
        p = int(parent[j])
        where = "trace entry %d (parent %d, level %d, landmark %d, obs %d, %s)" % (
            j, p, level[j], landmark[j], obs[j], CODES.get(int(status[j]), status[j]))
        expect_true(0 <= p < j and level[j] == level[p] + 1, where + ": its parent comes first, one level up",
                    given={**given, "parent's level": int(level[p]) if 0 <= p < j else None})
        expect_true(status[p] in (TRACE_EXPANDED, TRACE_BEST), where + ": its parent was expanded (not cut)",
                    given=given, actual=CODES.get(int(status[p]), status[p]))
        idx = hyps[p].copy()
        if obs[j] >= 0:
            idx[landmark[j]] = obs[j]
        hyps.append(idx)
        a = int(np.count_nonzero(idx >= 0))
        D2 = joint_d2(mu, cov, Y, idx)
        at = {**given, "the entry's hypothesis (idx)": idx, "its D² from scratch": D2, "gate χ²_{d·a}":
              gate(n_sigma, d * a)}
        if status[j] == TRACE_JC_FAIL:
            expect_true(obs[j] >= 0 and D2 > gate(n_sigma, d * a), where + ": a joint-gate failure is a pairing "
                        "whose hypothesis has D² > χ²_{d·a}", given=at)
            continue
        expect_close(d2[j], D2, where + ": the node's D² against the joint D² of its hypothesis from scratch",
                     given=at, rtol=1e-8, atol=1e-10)
        if obs[j] >= 0:
            expect_true(D2 <= gate(n_sigma, d * a), where + ": a visited pairing passes the joint gate", given=at)
    T = int(res.stats["levels"])
    for p in range(parent.size):
        kids = [j for j in range(parent.size) if parent[j] == p and status[j] != TRACE_JC_FAIL]
        pairs = [j for j in kids if obs[j] >= 0]
        stars = [j for j in kids if obs[j] < 0]
        node = "the root (trace entry 0)" if p == 0 else "trace entry %d (level %d of %d)" % (p, level[p], T)
        key = [(float(d2[j]), int(obs[j])) for j in pairs]
        expect_true(key == sorted(key), "the children of %s are visited nearest first (ascending D², ties → "
                    "lower observation)" % node, given={**given, "(D², obs) of its children in visiting order": key})
        expect_true(len(stars) <= 1 and (not stars or stars[0] == kids[-1]), "the star (obs −1) of %s comes once, "
                    "after its pairings" % node, given={**given, "obs of its children in visiting order":
                                                         [int(obs[j]) for j in kids]})
        if complete and status[p] in (TRACE_EXPANDED, TRACE_BEST) and level[p] + 1 < T:
            expect_true(len(stars) == 1, "%s was expanded and has a level below it: it has a star child (the "
                        "landmark left unpaired)" % node, given={**given, "obs of its children":
                                                                 [int(obs[j]) for j in kids]})
    best = np.flatnonzero(status == TRACE_BEST)
    expect_true(best.size > 0, "the trace marks the nodes that became Best (TRACE_BEST)", given=given)
    expect_equal(hyps[best[-1]].tolist(), np.asarray(res.idx).tolist(), "the hypothesis of the last TRACE_BEST "
                 "node (trace entry %d) against the returned idx" % best[-1], given=given)


# ------------------------------------------------------------------------------ hand-made scenes
def test_one_landmark_two_observations_the_whole_tree():
    """One landmark, two compatible observations: the root, the nearer observation (the best), the farther one
    and the star cut by the bound; 2 nodes expanded"""
    mu, cov = np.zeros((1, 2)), np.eye(2)
    Y = np.array([[1.0, 0.0], [0.5, 0.0]]).T                 # d² = 1 and 0.25: observation 1 is nearer
    given = {"scene": "one landmark at (0, 0) with P = I; observations (1, 0) and (0.5, 0)"}
    res = run(mu, cov, Y, trace=True)
    expect_equal(np.asarray(res.idx).tolist(), [1], "idx", given=given)
    expect_equal(int(res.stats["nodes"]), 2, "stats['nodes']: the root and the pairing with observation 1 are "
                 "expanded; the pairing with observation 0 (same pairings, larger D²) and the star (fewer "
                 "pairings) are cut by the bound", given=given)
    tr = res.stats["trace"]
    expect_equal(np.asarray(tr.obs).tolist(), [-1, 1, 0, -1], "trace obs: the root, then the children nearest "
                 "first, then the star", given=given)
    expect_equal([CODES.get(int(s), s) for s in tr.status], ["TRACE_BEST", "TRACE_BEST", "TRACE_BOUND",
                 "TRACE_BOUND"], "trace status (the root is the first Best: no pairing, D² = 0)", given=given)
    expect_close(np.asarray(tr.d2), [0.0, 0.25, 1.0, 0.0], "trace d2", given=given)


def test_the_constellation_beats_the_stars():
    """A row of correlated landmarks seen all shifted by 0.6 spacing: each observation is nearer the wrong
    landmark, but only the true constellation is jointly compatible and JCBB finds it"""
    mu, cov = shifted_row(4)
    Y = (mu + [0.6, 0.0]).T
    given = {"scene": "shifted_row(4) observed at μ_k + (0.6, 0)"}
    res = run(mu, cov, Y)
    expect_equal(np.asarray(res.idx).tolist(), [0, 1, 2, 3], "idx (observation k is landmark k shifted)",
                 given=given)
    check_best(res, mu, cov, Y, 3.0, given)
    expect_equal(bool(res.jointly_compatible), True, "jointly_compatible", given=given)


def test_clutter_is_left_out():
    """A clutter observation individually compatible with two landmarks is left out: the shifted row is jointly
    compatible without it"""
    mu, cov = shifted_row(3)
    Y = np.column_stack([mu[0] + [0.6, 0], mu[1] + [0.6, 0], mu[2] + [0.6, 0], [0.3, 0.05]])
    given = {"scene": "shifted_row(3) observed at μ_k + (0.6, 0), and clutter at (0.3, 0.05)"}
    res = run(mu, cov, Y)
    expect_equal(np.asarray(res.idx).tolist(), [0, 1, 2], "idx (observation 3 is clutter)", given=given)
    check_best(res, mu, cov, Y, 3.0, given)


def test_no_observations_and_no_candidates():
    """No observations, or none individually compatible: every landmark is unpaired, D² = 0"""
    mu, cov = shifted_row(3)
    for Y, what in ((np.zeros((2, 0)), "Y of shape (2, 0)"), (np.full((2, 2), 100.0), "observations 100 m away")):
        res = run(mu, cov, Y)
        expect_equal(np.asarray(res.idx).tolist(), [-1, -1, -1], "idx with " + what, given={"Y": Y})
        expect_equal(float(res.d2), 0.0, "D² with " + what, given={"Y": Y})


def test_the_result_is_the_common_association():
    """jcbb returns the Association named "jcbb" with stats nodes, levels and level_order (fewest candidates
    first), not exhausted without a budget"""
    mu, cov = shifted_row(3, spacing=2.0, shift_sigma=0.3)
    Y = np.column_stack([mu[2] + [0.1, 0.0], mu[0] + [0.1, 0.1], mu[1] + [0.0, 0.1]])
    given = {"scene": "shifted_row(3, spacing=2, shift_sigma=0.3), each landmark seen once"}
    res = run(mu, cov, Y)
    expect_equal(res.algorithm, "jcbb", "Association.algorithm", given=given)
    levels, _ = tree_levels(mu, cov, Y, 3.0)
    expect_equal(np.asarray(res.stats["level_order"]).tolist(), levels, "stats['level_order']", given=given)
    expect_equal(int(res.stats["levels"]), len(levels), "stats['levels']", given=given)
    expect_equal(np.asarray(res.idx).tolist(), [1, 2, 0], "idx", given=given)
    expect_equal(bool(res.budget_exhausted), False, "budget_exhausted without a budget", given=given)


# ------------------------------------------------------------------------------ the node budget
def busy_scene():
    """Five correlated landmarks, their shifted observations and two clutter points: a tree of some size."""
    mu, cov = shifted_row(5, spacing=0.8, shift_sigma=0.8, sigma=0.1)
    Y = np.column_stack([mu[3] + [0.5, 0.05], mu[0] + [0.5, -0.05], [1.9, 0.1], mu[4] + [0.5, 0.0],
                         mu[1] + [0.5, 0.1], [0.2, 0.2], mu[2] + [0.5, 0.0]])
    return mu, cov, Y


def test_a_budget_returns_the_best_so_far_and_says_so():
    """With max_nodes smaller than the search needs, the search stops after max_nodes expanded nodes and returns
    the best hypothesis found so far, with budget_exhausted"""
    mu, cov, Y = busy_scene()
    given = {"scene": "busy_scene() in test_l09_jcbb.py"}
    full = run(mu, cov, Y)
    nodes = int(full.stats["nodes"])
    expect_true(nodes > 6, "the full search of this scene (no budget) expands more than 6 nodes; fewer means it "
                "misses part of the tree (see the exhaustive-search checks)", given=given, actual=nodes)
    for budget in (1, 3, nodes - 1):
        cut = run(mu, cov, Y, max_nodes=budget, trace=True)
        where = "max_nodes = %d (the full search expands %d)" % (budget, nodes)
        expect_equal(bool(cut.budget_exhausted), True, "budget_exhausted with " + where, given=given)
        expect_equal(int(cut.stats["nodes"]), budget, "stats['nodes'] with " + where, given=given)
        expect_close(cut.d2, joint_d2(mu, cov, Y, np.asarray(cut.idx)), "D² of the returned hypothesis with "
                     + where, given={**given, "idx": np.asarray(cut.idx)}, rtol=1e-8, atol=1e-10)
        expect_true(cut.n_pairings <= full.n_pairings, "no more pairings than the full search with " + where,
                    given=given, actual=cut.n_pairings)
        check_trace(cut, mu, cov, Y, 3.0, {**given, "max_nodes": budget}, complete=False)
    root = run(mu, cov, Y, max_nodes=1)
    expect_equal(np.asarray(root.idx).tolist(), [-1] * 5, "idx with max_nodes = 1 (only the root)", given=given)
    enough = run(mu, cov, Y, max_nodes=nodes)
    expect_equal(bool(enough.budget_exhausted), False, "budget_exhausted with max_nodes = the nodes the full search "
                 "expands (%d)" % nodes, given=given)
    expect_equal(np.asarray(enough.idx).tolist(), np.asarray(full.idx).tolist(), "idx with max_nodes = %d" % nodes,
                 given=given)


def test_the_trace_records_the_tree():
    """The recorded tree (trace=True) of a scene with clutter: each node's D² from scratch, the joint-gate
    failures, children nearest first and the star last, the node count, and the best's path"""
    mu, cov, Y = busy_scene()
    given = {"scene": "busy_scene() in test_l09_jcbb.py"}
    check_trace(run(mu, cov, Y, trace=True), mu, cov, Y, 3.0, given)


# ------------------------------------------------------------------------------ random scenes
def random_scene(seed, n, m_clutter, d):
    """n landmarks with a shared (pose-like) error and their own, some of them observed, and clutter."""
    rng = np.random.default_rng(seed)
    A = 0.3 * rng.normal(size=(d * n, d * n))
    shared = np.tile(np.eye(d), (n, 1)) * rng.uniform(0.2, 1.5)
    cov = A @ A.T + shared @ shared.T + 0.05 * np.eye(d * n)
    mu = rng.uniform(-3.0, 3.0, (n, d))
    x = mu + (np.linalg.cholesky(cov) @ rng.normal(size=d * n)).reshape(n, d)
    seen = rng.permutation(n)[: rng.integers(0, n + 1)]
    cols = [x[k] for k in seen] + [rng.uniform(-3.0, 3.0, d) for _ in range(m_clutter)]
    Y = np.array(cols).T if cols else np.zeros((d, 0))
    return mu, cov, Y[:, rng.permutation(Y.shape[1])]


@settings(max_examples=50, deadline=None, derandomize=True, database=None, report_multiple_bugs=False)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 4), m_clutter=st.integers(0, 2),
       n_sigma=st.sampled_from([1.5, 2.0, 3.0]), d=st.sampled_from([1, 2, 2, 3]))
def test_random_scenes_equal_the_exhaustive_search(seed, n, m_clutter, n_sigma, d):
    """On random correlated scenes (d = 1, 2, 3) JCBB returns the exhaustive search's best hypothesis, and its
    recorded tree is the tree of the definitions"""
    mu, cov, Y = random_scene(seed, n, m_clutter, d)
    given = {"scene": "random_scene(seed=%d, n=%d, m_clutter=%d, d=%d) in test_l09_jcbb.py" % (seed, n, m_clutter, d),
             "n_sigma": n_sigma}
    res = run(mu, cov, Y, n_sigma=n_sigma, trace=True)
    if Y.shape[1] == 0:
        expect_equal(int(res.n_pairings), 0, "pairings with no observations", given=given)
        return
    check_best(res, mu, cov, Y, n_sigma, given)
    if int(res.stats["levels"]) > 0:                      # with no level there is no tree to record
        check_trace(res, mu, cov, Y, n_sigma, given)
