"""Tests for helpers.drivebot.q2_support (no-observation intervals, landmark facts, online recorder, rates)."""
import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from helpers.drivebot import analysis, run_question  # noqa: E402
from helpers.drivebot import q2_support as q2  # noqa: E402


# ---------------------------------------------------------------------------------------------- intervals
def test_no_observation_intervals_skips_single_ticks():
    # observations at 1..4, 6..9 (tick 5 is a dither gap), nothing at 10..14, then 15; tick 0 empty too
    tick = np.r_[np.arange(1, 5), np.arange(6, 10), 15]
    iv = q2.no_observation_intervals(tick, 18)
    np.testing.assert_array_equal(iv, [[10, 14], [16, 17]])
    np.testing.assert_array_equal(q2.no_observation_intervals(tick, 18, min_ticks=1),
                                  [[0, 0], [5, 5], [10, 14], [16, 17]])
    assert q2.no_observation_intervals(np.arange(5), 5).shape == (0, 2)
    np.testing.assert_array_equal(q2.no_observation_intervals(np.zeros(0, int), 4), [[0, 3]])


def test_no_observation_intervals_bad_inputs():
    with pytest.raises(ValueError, match="tick must"):
        q2.no_observation_intervals(np.arange(3.0), 5)
    with pytest.raises(ValueError, match="n_steps"):
        q2.no_observation_intervals(np.arange(3), 0)
    with pytest.raises(ValueError, match="min_ticks"):
        q2.no_observation_intervals(np.arange(3), 5, min_ticks=0)
    with pytest.raises(ValueError, match="tick values"):
        q2.no_observation_intervals(np.array([7]), 5)


def test_interval_mask_and_shading():
    iv = np.array([[2, 3], [7, 7]])
    np.testing.assert_array_equal(q2.interval_mask(np.arange(9), iv),
                                  [0, 0, 1, 1, 0, 0, 0, 1, 0])
    assert not q2.interval_mask(np.arange(3), np.zeros((0, 2), int)).any()
    with pytest.raises(ValueError, match="intervals"):
        q2.interval_mask(np.arange(3), np.arange(3))
    fig, ax = plt.subplots()
    q2.mark_gaps_and_closure([ax], iv, 0.1)
    assert len(ax.patches) == 2
    assert [h.get_label() for h in ax.get_legend_handles_labels()[0]] == ["no landmark in range"]
    with pytest.raises(ValueError, match="dt"):
        q2.mark_gaps_and_closure([ax], iv, 0.0)
    plt.close(fig)


def test_mark_gaps_and_closure_on_every_axis():
    fig, axes = plt.subplots(2, 1)
    q2.mark_gaps_and_closure(axes, np.array([[2, 3], [7, 7]]), 0.1, closure=5)
    for ax in axes:
        assert len(ax.patches) == 2 and len(ax.lines) == 1
        assert ax.lines[0].get_xdata()[0] == pytest.approx(0.5)
        assert ax.get_legend_handles_labels()[1] == ["no landmark in range", "loop closure"]
    q2.mark_gaps_and_closure(axes[0], np.zeros((0, 2), int), 0.1)      # no gaps, no closure: nothing drawn
    assert len(axes[0].patches) == 2 and len(axes[0].lines) == 1
    plt.close(fig)


def test_mean_rate():
    t = np.arange(6.0)
    y = np.r_[0, 1, 2, 2, 2, 5]
    m = np.array([1, 1, 1, 0, 1, 1], bool)
    assert q2.mean_rate(t, y, m) == pytest.approx((1 + 1 + 3) / 3)
    assert np.isnan(q2.mean_rate(t, y, np.zeros(6, bool)))
    with pytest.raises(ValueError, match="increasing"):
        q2.mean_rate(t[::-1], y, m)


# ---------------------------------------------------------------------------------------------- on a short run
@pytest.fixture(scope="module")
def short_run():
    rec = q2.OnlineRecorder(every=10)
    res = run_question("q2_b", maximum_step_number=400, step_hook=rec)
    return res, rec


def test_landmark_facts_of_a_short_run(short_run):
    res, _ = short_run
    tick, lm = analysis.landmark_observations(res.system)
    f = q2.landmark_facts(res, tick, lm)
    assert f["id"].tolist() == sorted(set(lm.tolist()))
    assert f["n_obs"].sum() == tick.size
    i1 = f["id"].tolist().index(1)
    np.testing.assert_allclose(f["xy"][i1], [2, 2])
    np.testing.assert_allclose(f["corner"][i1], [0, 0])
    assert f["corner_distance"][i1] == pytest.approx(np.hypot(2, 2))
    assert f["first_tick"][i1] == 1                      # nothing is observed at tick 0
    assert np.all(f["mean_speed"] > 0) and np.all(f["mean_speed"] <= res.config.max_speed + 1e-9)
    with pytest.raises(ValueError, match="one shape"):
        q2.landmark_facts(res, tick, lm[:-1])


def test_waypoint_ticks(short_run):
    res, _ = short_run
    k = q2.waypoint_ticks(res)
    assert k.size == 1                                   # only (70, 0) is reached within 400 ticks
    p = res.vehicle_true_state_history[:2, k[0]]
    assert np.linalg.norm(p - res.scenario.waypoints[:, 0]) < 1.0
    with pytest.raises(ValueError, match="radius"):
        q2.waypoint_ticks(res, radius=0)


def test_online_recorder(short_run):
    res, rec = short_run
    assert rec.ticks.size == res.n_steps // 10
    assert np.all((rec.ticks + 1) % 10 == 0)
    assert rec.variances.shape == (3, rec.ticks.size) and np.all(rec.variances > 0)
    # later measurements can only add information: up to linearisation differences the online position
    # variance of the newest vertex is at least its smoothed (final-graph) one
    smooth = res.vehicle_covariance_history[:, rec.ticks]
    assert np.all(rec.variances[:2].sum(0) >= 0.9 * smooth[:2].sum(0))
    assert rec.factor_nnz and set(rec.factor_nnz) <= set(np.flatnonzero(np.isfinite(res.optimization_times)).tolist())
    assert all(n > 0 for n in rec.factor_nnz.values())
    with pytest.raises(ValueError, match="every"):
        q2.OnlineRecorder(every=0)


def test_online_recorder_does_not_change_the_run():
    a = run_question("q2_b", maximum_step_number=120)
    b = run_question("q2_b", maximum_step_number=120, step_hook=q2.OnlineRecorder(5))
    np.testing.assert_array_equal(a.chi2_history, b.chi2_history)
    np.testing.assert_array_equal(a.vehicle_covariance_history, b.vehicle_covariance_history)
