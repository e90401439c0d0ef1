"""Tests for helpers.drivebot.pruning: the selection rules on arrays and the hooks on a graph."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from helpers.drivebot import pruning as pr


# ---------------------------------------------------------------------------------------------- keep k
@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.integers(0, 10_000), st.integers(1, 4))
def test_keep_k_per_group_caps_and_is_idempotent(seed, k):
    rng = np.random.default_rng(seed)
    group = np.sort(rng.integers(0, 30, 200))
    keep = pr.keep_k_per_group(group, k, np.random.default_rng(seed))
    counts = np.bincount(group, minlength=30)
    kept = np.bincount(group[keep], minlength=30)
    np.testing.assert_array_equal(kept, np.minimum(counts, k))
    again = pr.keep_k_per_group(group[keep], k, np.random.default_rng(seed + 1))
    assert again.all()


def test_keep_k_per_group_is_seeded_and_random():
    group = np.repeat(np.arange(50), 6)
    a = pr.keep_k_per_group(group, 2, np.random.default_rng(7))
    b = pr.keep_k_per_group(group, 2, np.random.default_rng(7))
    c = pr.keep_k_per_group(group, 2, np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert not np.array_equal(a, c)
    # every position within a vertex is chosen sometimes (not always the first k)
    pos = np.tile(np.arange(6), 50)
    assert set(pos[a]) == set(range(6))


def test_keep_k_per_group_of_no_edge():
    rng = np.random.default_rng(0)
    assert pr.keep_k_per_group(np.zeros(0, int), 1, rng).shape == (0,)


# ---------------------------------------------------------------------------------------------- stride
def test_stride_mask():
    np.testing.assert_array_equal(pr.stride_mask(np.arange(6), 2), [1, 0, 1, 0, 1, 0])
    np.testing.assert_array_equal(pr.stride_mask(np.arange(6), 3, offset=1), [0, 1, 0, 0, 1, 0])


# ---------------------------------------------------------------------------------------------- straights
def test_straight_segment_mask_finds_turns():
    rng = np.random.default_rng(2)
    rate = np.zeros(600)
    rate[200:260] = 0.3        # a left turn (rad/s)
    rate[400:430] = -0.4       # a right turn
    psi = np.concatenate([[0.0], np.cumsum(0.1 * rate)]) + 0.1 * np.pi / 180 * rng.standard_normal(601)
    psi = (psi + np.pi) % (2 * np.pi) - np.pi
    straight = pr.straight_segment_mask(psi, 0.1, rate_threshold=0.05, window=11)
    assert straight.shape == (601,)
    assert not straight[210:250].any() and not straight[405:425].any()
    assert straight[20:180].all() and straight[280:390].all() and straight[450:590].all()


def test_straight_segment_mask_wraps_heading():
    psi = np.full(50, np.pi - 1e-3)
    psi[25:] = -np.pi + 1e-3      # crossing ±π on a straight
    assert pr.straight_segment_mask(psi, 0.1).all()


def test_straight_segment_mask_bad_inputs():
    with pytest.raises(ValueError, match="window must be odd"):
        pr.straight_segment_mask(np.zeros(4), 0.1, window=4)
    with pytest.raises(ValueError, match="rate_threshold"):
        pr.straight_segment_mask(np.zeros(4), 0.1, rate_threshold=0)
    assert pr.straight_segment_mask(np.zeros(1), 0.1).tolist() == [True]


# ---------------------------------------------------------------------------------------------- protect
def test_protect_landmarks_restores_first_edge():
    lm = np.array([5, 7, 5, 7, 9, 9])
    keep = np.array([False, True, False, False, False, True])
    out = pr.protect_landmarks(keep, lm)
    np.testing.assert_array_equal(out, [True, True, False, False, False, True])
    assert not keep[0]  # input not modified


# ---------------------------------------------------------------------------------------------- hook ctor
@pytest.mark.parametrize("make, match", [
    (lambda: pr.KeepKPerVertex(k=0), "k must"),
    (lambda: pr.KeyframePruning(stride=0), "stride"),
    (lambda: pr.KeyframePruning(rate_threshold=-1.0), "rate_threshold"),
    (lambda: pr.AlternateVertexPruning(stride=1), "stride"),
    (lambda: pr.KeyframePruning(window=4), "window must be odd"),
    (lambda: pr.q3b_hook(stride=0), "stride"),
])
def test_hook_constructor_bad_inputs(make, match):
    with pytest.raises(ValueError, match=match):
        make()


# ---------------------------------------------------------------------------------------------- hooks on a graph
def _synthetic_graph(n=120, n_landmarks=6, seed=0):
    """A chain of SE2 poses (first fixed) driving a quarter circle, landmarks seen from every pose in range."""
    from helpers.graph import EdgeRangeBearing, EdgeSE2, SparseOptimizer, VertexPointXY, VertexSE2

    rng = np.random.default_rng(seed)
    g = SparseOptimizer()
    rate = np.where((np.arange(n) > 40) & (np.arange(n) < 70), 0.5, 0.0)
    psi = np.concatenate([[0.0], np.cumsum(0.1 * rate[:-1])])
    x = np.concatenate([[0.0], np.cumsum(0.5 * np.cos(psi[:-1]))])
    y = np.concatenate([[0.0], np.cumsum(0.5 * np.sin(psi[:-1]))])
    poses = []
    for k in range(n):
        v = VertexSE2(estimate=[x[k], y[k], psi[k]], fixed=(k == 0))
        v.time = 0.1 * k
        g.add_vertex(v)
        poses.append(v)
        if k:
            g.add_edge(EdgeSE2([poses[k - 1], v], measurement=[0.5, 0, 0.1 * rate[k - 1]],
                               information=np.eye(3)))
    lms = rng.uniform([0, -10], [max(x), max(y) + 10], (n_landmarks, 2))
    lm_vertices = {}
    for k in range(1, n):
        d = lms - [x[k], y[k]]
        r = np.hypot(d[:, 0], d[:, 1])
        for i in np.flatnonzero(r < 25):
            if i not in lm_vertices:
                lm_vertices[i] = VertexPointXY(estimate=lms[i])
                g.add_vertex(lm_vertices[i])
            b = np.arctan2(d[i, 1], d[i, 0]) - psi[k]
            g.add_edge(EdgeRangeBearing([poses[k], lm_vertices[i]], measurement=[r[i], b],
                                        information=np.diag([100.0, 1000.0])))
    return g, poses


def _landmark_edges(g):
    return pr.landmark_edge_table(g)


@pytest.mark.parametrize("hook", [pr.KeepKPerVertex(k=2, seed=3), pr.KeyframePruning(stride=4),
                                  pr.AlternateVertexPruning(stride=2)])
def test_hooks_prune_landmark_edges_only_and_keep_graph_solvable(hook):
    g, poses = _synthetic_graph()
    before = _landmark_edges(g)
    n_vertices, n_kin = g.number_of_vertices(), g.number_of_edges() - len(before["edges"])
    removed = hook(g)
    after = _landmark_edges(g)
    assert removed > 0 and removed == len(before["edges"]) - len(after["edges"])
    assert g.number_of_vertices() == n_vertices               # nothing orphaned
    assert g.number_of_edges() - len(after["edges"]) == n_kin  # kinematics untouched
    assert set(after["landmark"]) == set(before["landmark"])   # every landmark keeps an edge
    assert hook(g) == 0                                        # idempotent on pruned vertices
    assert hook.calls == 2 and hook.removed == removed
    g.initialize_optimization()
    assert np.isfinite(g.optimize(10))


def test_keep_k_hook_caps_edges_per_vertex():
    g, _ = _synthetic_graph()
    pr.KeepKPerVertex(k=1, seed=0)(g)
    t = _landmark_edges(g)
    counts = np.bincount(t["vertex"] - t["vertex"].min())
    assert counts.max() == 1


def test_keyframe_hook_keeps_turn_vertices():
    g, poses = _synthetic_graph()
    before = _landmark_edges(g)
    pr.KeyframePruning(stride=1000, rate_threshold=0.2)(g)
    after = _landmark_edges(g)
    base = poses[0].id
    turn_ids = {p.id for p in poses[45:66]}
    kept_turn = {v for v in after["vertex"].tolist() if v in turn_ids}
    had_turn = {v for v in before["vertex"].tolist() if v in turn_ids}
    assert kept_turn == had_turn and had_turn
    straight_ids = {p.id for p in poses[5:35]} | {p.id for p in poses[80:115]}
    on_straight = np.isin(after["vertex"], list(straight_ids - {base + 1000 * j for j in range(2)}))
    # only protected edges (a landmark's single remaining edge) may survive on a straight non-keyframe
    lm, count = np.unique(after["landmark"], return_counts=True)
    single = set(lm[count == 1].tolist())
    assert set(after["landmark"][on_straight].tolist()) <= single
    assert on_straight.sum() < 0.1 * len(before["edges"])


def test_alternate_hook_drops_odd_vertices():
    g, _ = _synthetic_graph()
    pr.AlternateVertexPruning(stride=2)(g)
    t = _landmark_edges(g)
    odd = (t["vertex"] % 2) == 1
    # only the protected first edge of a landmark may survive on an odd vertex
    assert odd.sum() <= len(np.unique(t["landmark"]))


def test_hook_on_the_drivebot_system():
    from helpers.drivebot import run_question

    hook = pr.KeepKPerVertex(k=1, seed=0)
    res = run_question("q3_a", maximum_step_number=520, pre_optimization_hook=hook)
    t = pr.landmark_edge_table(res.system)
    assert hook.calls == 2 and hook.removed > 0
    assert np.bincount(t["vertex"]).max() == 1
    assert res.vehicle_in_graph.all()
    assert res.graph_statistics()["landmark_edges"] == len(t["edges"])


def test_q3b_hook_is_a_fresh_keyframe_rule():
    a, b = pr.q3b_hook(), pr.q3b_hook(stride=3, rate_threshold=0.1, window=7)
    assert isinstance(a, pr.KeyframePruning) and a is not pr.q3b_hook()
    assert (a.stride, a.rate_threshold, a.window) == (5, 0.05, 11)
    assert (b.stride, b.rate_threshold, b.window) == (3, 0.1, 7) and b.calls == 0
