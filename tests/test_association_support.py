"""Tests for helpers.advanced.hidden_ids_support (notebook 22): runs, the recorder, the closure analysis, the
table and the figures — on short runs (no loop closes in them; the closure analysis is checked on hand-made
recorder entries)."""
import copy
import math

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from helpers.advanced import hidden_ids_support as assoc  # noqa: E402
from helpers.drivebot import run_question  # noqa: E402

SHORT = {"maximum_step_number": 200}


@pytest.fixture(scope="module")
def runs():
    return assoc.Runs(seed=0, keep=("q2_b",), **SHORT)


@pytest.fixture(scope="module")
def jcbb(runs):
    return runs.case("q2_b", "jcbb")


def _with_recorder(case):
    """A copy of ``case`` whose recorder can be edited without touching the cached one."""
    out = copy.copy(case)
    out.recorder = copy.deepcopy(case.recorder)
    return out


# ---------------------------------------------------------------------------------------------- runs
def test_runs_run_each_setting_once_and_keep_what_they_should(runs, jcbb):
    assert runs.case("q2_b", "jcbb", 0.0) is jcbb
    res, rec = jcbb.results, jcbb.recorder
    assert jcbb.question == "q2_b" and jcbb.algorithm == "jcbb" and jcbb.clutter_rate == 0.0 and jcbb.seed == 0
    assert jcbb.label == "JCBB"
    r = jcbb.report
    assert r["precision"] == 1.0 and r["recall"] == 1.0 and r["n_landmarks"] == r["n_true_landmarks"] >= 2
    assert jcbb.dof == res.graph_statistics()["dof"] > 0
    assert jcbb.chi2_per_dof == pytest.approx(r["final_chi2"] / jcbb.dof)
    assert rec.poses.shape == (res.n_steps, 3)
    assert len(rec.scan_tick) == res.system.frontend.scan_count
    assert np.all(np.diff(rec.scan_tick) >= 0)
    assert set(jcbb.extra) == {"scans", "merges", "wrong_merges", "clutter_landmarks", "clutter_tracks",
                               "clutter_paired_again"}
    assert jcbb.extra["scans"] == res.system.frontend.scan_count and jcbb.extra["merges"] == 0


def test_runs_not_kept_have_numbers_only():
    runs = assoc.Runs(seed=1, keep=(), maximum_step_number=60)
    case = runs.case("q2_b", "nn")
    assert case.results is None and case.recorder is None and case.report["n_true_landmarks"] >= 1
    for fn in (assoc.revisits, assoc.closure_pairings, assoc.observation_ticks):
        with pytest.raises(ValueError, match="kept"):
            fn(case)
    with pytest.raises(ValueError, match="Case"):
        assoc.revisits("not a case")


def test_runs_bad_input(runs):
    with pytest.raises(ValueError, match="algorithm"):
        runs.case("q2_b", "hungarian")
    with pytest.raises(ValueError, match="clutter_rate"):
        runs.case("q2_b", "nn", -1.0)
    with pytest.raises(ValueError, match="keep"):
        assoc.Runs(keep="q2_b")
    with pytest.raises(ValueError, match="seed"):
        assoc.Runs(seed=-1)


def test_recorder_needs_hidden_ids():
    with pytest.raises(ValueError, match="ids hidden"):
        run_question("q2_b", seed=0, maximum_step_number=20, step_hook=assoc.AssociationRecorder())


# ---------------------------------------------------------------------------------------------- analysis
def test_true_sources_observation_ticks_and_born_positions(jcbb):
    res, rec = jcbb.results, jcbb.recorder
    src = assoc.true_sources(res)
    assert set(src) == {t.key for t in res.system.frontend.tracks}
    for key, true_id in jcbb.report["matching"].items():            # a perfect run: matching = first sources
        assert src[key] == true_id
    tick, truth = assoc.observation_ticks(jcbb)
    assert tick.shape == truth.shape == (jcbb.report["n_observations"],)
    assert np.all(np.diff(tick) >= 0) and tick.min() >= 0 and tick.max() < res.n_steps
    true_xy = {int(i): res.scenario.landmarks[:, k] for k, i in enumerate(res.scenario.landmark_ids)}
    for key, (k, position, _) in rec.born.items():                 # placed near the landmark (little drift yet)
        assert 0 <= k < res.n_steps and np.hypot(*(position - true_xy[src[key]])) < 2.0
    with pytest.raises(ValueError, match="data_association"):
        assoc.true_sources(run_question("q2_b", seed=0, maximum_step_number=20))


def test_no_revisit_in_a_short_run(jcbb):
    assert assoc.revisits(jcbb) == [] and assoc.closure_pairings(jcbb) == []
    assert assoc.closure_outcome(jcbb) == "none"


def test_revisits_and_closure_pairings_on_hand_made_entries(jcbb):
    case = _with_recorder(jcbb)
    rec, src = case.recorder, assoc.true_sources(case.results)
    a, b = sorted(src)[:2]
    assert src[a] != src[b] and src[a] and src[b]
    est = {a: np.array([2.0, 2.0]), b: np.array([5.0, 3.0])}
    rec.born[b] = (150, np.array([6.0, 6.0]), est)                   # b "seen again" 3.16 m from its map estimate
    seen = assoc.revisits(case)
    assert [v["key"] for v in seen] == [b]
    v = seen[0]
    assert v["source"] == src[b] and v["mapped_key"] == b and v["tick"] == 150
    np.testing.assert_allclose(v["innovation"], [1.0, 3.0])
    assert v["distances"][a] == pytest.approx(math.hypot(4.0, 4.0)) and v["fate"] == "confirmed"
    assert assoc.revisits(case, min_innovation=3.2) == []
    with pytest.raises(ValueError, match="min_innovation"):
        assoc.revisits(case, min_innovation=-1)

    rec.merges = [(150, b, a, est)]                                  # merged into the other landmark: wrong
    (p,) = assoc.closure_pairings(case)
    assert (p["key"], p["old_key"], p["source"], p["old_source"], p["right"]) == (b, a, src[b], src[a], False)
    np.testing.assert_array_equal(p["old"], est[a])
    np.testing.assert_array_equal(p["position"], [6.0, 6.0])
    assert assoc.closure_outcome(case) == "wrong"
    rec.merges = [(150, b, b, est)]
    assert assoc.closure_pairings(case)[0]["right"] and assoc.closure_outcome(case) == "right"


def test_run_summary_counts_clutter(runs):
    case = runs.case("q2_b", "nn", 2.0)
    x = case.extra
    assert x["clutter_tracks"] > 100 and 0 <= x["clutter_paired_again"] <= x["clutter_tracks"]
    assert x["clutter_landmarks"] == sum(s == 0 for k, s in assoc.true_sources(case.results).items()
                                         if k in {t.key for t in case.results.system.frontend.confirmed_tracks()})
    assert assoc.run_summary(case.results) == x


def test_nn_gate(jcbb):
    cfg = jcbb.results.config
    sr2, sb2 = cfg.r_laser[0, 0], cfg.r_laser[1, 1]
    assert assoc.nn_gate(cfg) == pytest.approx(3 * math.sqrt(sr2 + cfg.laser_detection_range ** 2 * sb2))
    assert assoc.nn_gate(cfg, 2.0, r=0.0) == pytest.approx(2 * math.sqrt(sr2))
    with pytest.raises(ValueError, match="n_sigma"):
        assoc.nn_gate(cfg, 0.0)
    with pytest.raises(ValueError, match="r"):
        assoc.nn_gate(cfg, 3.0, r=-1.0)


# ---------------------------------------------------------------------------------------------- tables
@pytest.mark.parametrize("x, n, text", [(1654.4, 3, "1650"), (0.08974, 3, "0.0897"), (9.96, 2, "10"),
                                        (99.96, 3, "100"), (-1234.0, 3, "-1230"), (5.0, 2, "5.0"), (0.0, 2, "0"),
                                        (60.67, 2, "61"), (float("nan"), 3, "nan"), (float("inf"), 3, "inf")])
def test_sig(x, n, text):
    assert assoc.sig(x, n) == text


def test_sig_bad_input():
    with pytest.raises(ValueError, match="x"):
        assoc.sig(True)
    with pytest.raises(ValueError, match="n"):
        assoc.sig(1.0, 0)


def test_association_table(runs, jcbb):
    nn = runs.case("q2_b", "nn")
    text = assoc.association_table([nn, jcbb])
    lines = text.splitlines()
    assert len(lines) == 4 and "precision" in lines[0] and "χ²/dof" in lines[0]
    assert "JCBB" in lines[3] and "1.000" in lines[3] and f"{jcbb.chi2_per_dof:.2f}" in lines[3]
    assert assoc.sig(jcbb.report["final_chi2"]) in lines[3]


# ---------------------------------------------------------------------------------------------- figures
def test_plot_final_map_and_closure(jcbb):
    fig, (a1, a2, a3) = plt.subplots(1, 3)
    assoc.plot_final_map(a1, jcbb)
    labels = a1.get_legend_handles_labels()[1]
    assert "true path" in labels and "estimated landmark (the id it was started for)" in labels
    assert a1.get_xlabel() == "x (m)" and a1.get_ylabel() == "y (m)"
    assert assoc.plot_closure(a2, jcbb) == [] and a2.texts                # nothing came back: a note instead
    case = _with_recorder(jcbb)
    src = assoc.true_sources(case.results)
    a, b = sorted(src)[:2]
    est = {a: np.array([2.0, 2.0]), b: np.array([5.0, 3.0])}
    case.recorder.born[a] = (150, np.array([5.5, 4.0]), est)
    case.recorder.born[b] = (151, np.array([8.5, 5.0]), est)
    case.recorder.merges = [(152, a, b, est), (152, b, a, est)]        # swapped
    drawn = assoc.plot_closure(a3, case)
    assert [v["key"] for v in drawn] == [a, b]
    labels = a3.get_legend_handles_labels()[1]
    assert "pairing made: wrong" in labels and "pairing made: right" not in labels
    x0, x1 = a3.get_xlim()
    assert x0 < 2.0 and x1 > 8.5
    plt.close(fig)
