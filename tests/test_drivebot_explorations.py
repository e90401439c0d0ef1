"""helpers.drivebot.explorations: notebook 18's exploration of q2_d around its loop closure. What is drawn follows
the knobs (the closure collapses the ellipses, odometry alone does not; χ² follows (real / assumed noise)²), the
scaling by the assumed noise equals a run that assumes it, the runs are cached, and bad arguments are refused."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from helpers.drivebot import DriveBotSLAMSystem, Event, EventType, SimulatorConfiguration, run_question
from helpers.drivebot import explorations
from helpers.drivebot.explorations import (ASSUMED_SCALES, NOISE_SCALES, SENSOR_SETS, LoopClosureExplorer,
                                           Snapshot)
from helpers.explore import choice, explore, toggle

NOTEBOOK = {"seed": 0, "perturb_with_noise": True, "laser_detection_range": 10.0}   # notebook 18 with PERTURB
R0 = SimulatorConfiguration()


@pytest.fixture(scope="module")
def runs():
    """(an explorer that found the closure with the simulator alone, and notebook 18's two runs around it)."""
    plain = LoopClosureExplorer(seed=0)
    before = run_question("q2_d", maximum_step_number=plain.closure, **NOTEBOOK)
    after = run_question("q2_d", maximum_step_number=plain.closure + 1, **NOTEBOOK)
    return plain, before, after


@pytest.fixture(scope="module")
def explorer(runs):
    return LoopClosureExplorer.from_runs(runs[1], runs[2], seed=0)


def drawn(explorer, **knobs):
    """(the figure, what draw returned, {gid: widths of that ellipse collection})."""
    fig = Figure(figsize=(8, 5.6))
    out = explorer.draw(fig, **knobs)
    widths = {c.get_gid(): c.get_widths() for ax in fig.axes for c in ax.collections if c.get_gid()}
    return fig, out, widths


def test_adopted_runs_are_the_entry_and_equal_the_explorers_own_run(runs, explorer):
    plain, before, after = runs
    n = explorer.runs
    assert explorer.closure == plain.closure
    for closed, run in ((False, before), (True, after)):
        _, out, _ = drawn(explorer, noise=1.0, closed=closed)
        assert out["tick"] == run.n_steps - 1 and out["chi2"] == pytest.approx(run.final_chi2, rel=1e-9)
    assert explorer.runs == n                       # drawn from the adopted runs
    own, adopted = plain.run("laser", 1.0), explorer.run("laser", 1.0)   # one run, "before" from its step hook
    assert plain.runs == 1
    for when in ("before", "after"):
        a, b = own[when], adopted[when]
        assert a.tick == b.tick and a.dof == b.dof and a.chi2 == pytest.approx(b.chi2, rel=1e-6)
        np.testing.assert_allclose(a.path, b.path, atol=1e-5)
        np.testing.assert_allclose(a.current_P, b.current_P, rtol=1e-4, atol=1e-12)
        np.testing.assert_allclose(a.landmark_P, b.landmark_P, rtol=1e-4, atol=1e-12)


def test_the_loop_closure_collapses_the_drawn_ellipses(explorer):
    _, b, wb = drawn(explorer, noise=1.0, closed=False)
    _, a, wa = drawn(explorer, noise=1.0, closed=True)
    assert a["tick"] == b["tick"] + 1
    assert np.hypot(*a["sigma"][:2]) < 0.2 * np.hypot(*b["sigma"][:2])
    assert wa["current"][0] < 0.2 * wb["current"][0]
    # every ellipse shrinks or stays (near the anchor the estimate moves a little, and its linearisation with it)
    assert np.all(wa["vehicle"] <= 1.001 * wb["vehicle"]) and np.all(wa["landmarks"] <= 1.001 * wb["landmarks"])
    assert wa["vehicle"].max() < 0.7 * wb["vehicle"].max()
    assert wa["landmarks"][-1] < 0.3 * wb["landmarks"][-1]       # landmark 7, mapped last, most of all


def test_without_the_laser_nothing_closes_the_loop_and_each_combination_runs_once(explorer, monkeypatch):
    calls = []

    def counted(*args, **kwargs):
        calls.append(kwargs)
        return run_question(*args, **kwargs)
    monkeypatch.setattr(explorations, "run_question", counted)
    _, b, wb = drawn(explorer, sensors="odometry", noise=1.0, closed=False)
    _, a, wa = drawn(explorer, sensors="odometry", noise=1.0, closed=True)
    _, laser, _ = drawn(explorer, noise=1.0, closed=True)
    assert a["dof"] == b["dof"] == 0 and a["chi2"] < 1e-9 and "landmarks" not in wa
    assert wa["current"][0] >= wb["current"][0]                   # one more tick of drift, no collapse
    assert np.hypot(*a["sigma"][:2]) > 10 * np.hypot(*laser["sigma"][:2])
    # the cache: one run for ("odometry", 1.0), none for the other knobs or for the adopted entry
    first = explorer.run("odometry", 1.0)
    for assumed in ASSUMED_SCALES:
        drawn(explorer, sensors="odometry", noise=1.0, assumed=assumed)
    assert len(calls) == 1 and calls[0]["maximum_step_number"] == explorer.closure + 1
    assert explorer.run("odometry", 1.0) is first and isinstance(first["after"], Snapshot)
    assert explorer.seconds[("odometry", 1.0)] > 0


def test_chi2_follows_real_over_assumed_noise(explorer):
    _, one, w1 = drawn(explorer, noise=1.0, closed=True)
    lo, hi = one["band"]
    assert lo <= one["chi2"] <= hi and one["dof"] > 1000
    _, half, w2 = drawn(explorer, noise=1.0, assumed=2.0, closed=True)      # the graph assumes twice the σ
    assert half["chi2"] == pytest.approx(one["chi2"] / 4) and half["chi2"] < lo
    np.testing.assert_allclose(w2["landmarks"], 2 * w1["landmarks"])
    _, noisy, wn = drawn(explorer, noise=2.0, closed=True)                 # the sensors twice as noisy as assumed
    assert 3.6 < noisy["chi2"] / one["chi2"] < 4.4 and noisy["chi2"] > hi
    np.testing.assert_allclose(wn["landmarks"], w1["landmarks"], rtol=0.2)  # the covariances do not see it
    _, right, _ = drawn(explorer, noise=2.0, assumed=2.0, closed=True)
    assert lo <= right["chi2"] <= hi


class AssumeTheCoursework:
    """A run_question setup: the coursework's system, every event's covariance replaced by the coursework's R."""
    system = staticmethod(DriveBotSLAMSystem)

    @staticmethod
    def filter(events, simulator):
        R = {EventType.VEHICLE_ODOMETRY: R0.r_odometry, EventType.LANDMARK: R0.r_laser}
        return [Event(e.time, e.type, e.data, R[e.type], e.landmark_ids) if e.type in R else e for e in events]


def test_the_assumed_scale_equals_a_run_that_assumes_it():
    """The model the explorer's ``assumed`` knob relies on: a graph whose edges assume (2σ)² instead of σ² has the
    same optimum, 4× its covariances and a quarter of its χ²."""
    noisy = {"seed": 0, "maximum_step_number": 300, "r_odometry": 4 * R0.r_odometry, "r_laser": 4 * R0.r_laser}
    assumes_2 = run_question("q2_d", perturb_with_noise=True, **noisy)
    assumes_1 = run_question("q2_d", perturb_with_noise=True, setup=AssumeTheCoursework(), **noisy)
    np.testing.assert_allclose(assumes_1.vehicle_state_history, assumes_2.vehicle_state_history, atol=1e-6)
    assert assumes_2.final_chi2 == pytest.approx(assumes_1.final_chi2 / 4, rel=1e-6) and assumes_2.final_chi2 > 100
    P1, P2 = assumes_1.landmark_estimates()[1], assumes_2.landmark_estimates()[1]
    np.testing.assert_allclose(P2, 4 * P1, rtol=1e-5)


def test_explore_draws_the_defaults_and_redraws(explorer):
    before = plt.get_fignums()
    ex = explore(explorer.draw, figsize=(8.0, 5.6), sensors=choice(SENSOR_SETS, "laser"),
                 noise=choice(NOISE_SCALES, 1.0), assumed=choice(ASSUMED_SCALES, 1.0), closed=toggle(False))
    title = ex.figure.axes[0].get_title()
    assert len(ex.figure.axes) == 2 and "just before the loop closure" in title and plt.get_fignums() == before
    ex.redraw(closed=True)
    first, sigmas = ex.figure.axes[0].get_title().split("\n")
    assert first == title.split("\n")[0].replace("before", "after") and sigmas != title.split("\n")[1]


def test_bad_arguments_name_the_argument(runs, explorer):
    fig = Figure()
    for knobs, name in (({"sensors": "gps"}, "sensors"), ({"noise": -1.0}, "noise"), ({"noise": np.nan}, "noise"),
                        ({"assumed": 0.0}, "assumed"), ({"closed": 1}, "closed")):
        with pytest.raises(ValueError, match=name):
            explorer.draw(fig, **knobs)
    with pytest.raises(ValueError, match="fig"):
        explorer.draw(None)
    for kwargs, name in (({"seed": -1}, "seed"), ({"laser_range": 0.0}, "laser_range"), ({"min_gap": 0}, "min_gap"),
                         ({"n_sigma": -3.0}, "n_sigma"), ({"ellipse_every": 0}, "ellipse_every")):
        with pytest.raises(ValueError, match=name):
            LoopClosureExplorer(**kwargs)
    with pytest.raises(ValueError, match="no loop closure"):
        _ = LoopClosureExplorer(min_gap=5000).closure
    _, before, after = runs
    with pytest.raises(ValueError, match="after must end at the loop-closing tick"):
        LoopClosureExplorer.from_runs(after, before)
    with pytest.raises(ValueError, match="before must be the Results"):
        LoopClosureExplorer.from_runs(None, after)
