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


def test_keep_k_per_group_bad_inputs():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="group"):
        pr.keep_k_per_group(np.zeros((2, 2), int), 1, rng)
    with pytest.raises(ValueError, match="group must contain integers"):
        pr.keep_k_per_group(np.zeros(3), 1, rng)
    with pytest.raises(ValueError, match="k must"):
        pr.keep_k_per_group(np.zeros(3, int), -1, rng)
    with pytest.raises(ValueError, match="rng"):
        pr.keep_k_per_group(np.zeros(3, int), 1, 0)
    assert pr.keep_k_per_group(np.zeros(0, int), 1, rng).shape == (0,)


# ---------------------------------------------------------------------------------------------- stride
def test_stride_mask():
    np.testing.assert_array_equal(pr.stride_mask(np.arange(6), 2), [1, 0, 1, 0, 1, 0])
    np.testing.assert_array_equal(pr.stride_mask(np.arange(6), 3, offset=1), [0, 1, 0, 0, 1, 0])
    with pytest.raises(ValueError, match="stride"):
        pr.stride_mask(np.arange(3), 0)
    with pytest.raises(ValueError, match="offset"):
        pr.stride_mask(np.arange(3), 2, offset=0.5)


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
    with pytest.raises(ValueError, match="headings"):
        pr.straight_segment_mask(np.array([0.0, np.nan]), 0.1)
    with pytest.raises(ValueError, match="dt"):
        pr.straight_segment_mask(np.zeros(4), np.ones(2))
    with pytest.raises(ValueError, match="dt"):
        pr.straight_segment_mask(np.zeros(4), -0.1)
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
    with pytest.raises(ValueError, match="keep must"):
        pr.protect_landmarks(np.ones(3), np.arange(3))
    with pytest.raises(ValueError, match="keep must"):
        pr.protect_landmarks(np.ones(2, bool), np.arange(3))


# ---------------------------------------------------------------------------------------------- hook ctor
@pytest.mark.parametrize("make, match", [
    (lambda: pr.KeepKPerVertex(k=0), "k must"),
    (lambda: pr.KeyframePruning(stride=0), "stride"),
    (lambda: pr.KeyframePruning(rate_threshold=-1.0), "rate_threshold"),
    (lambda: pr.AlternateVertexPruning(stride=1), "stride"),
])
def test_hook_constructor_bad_inputs(make, match):
    with pytest.raises(ValueError, match=match):
        make()
