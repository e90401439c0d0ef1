"""helpers.association.explorations: the nested clutter, the heading error as a rigid rotation of the prediction,
the outcomes against the truth, and a figure whose counts follow the knobs (notebook 08's exploration)."""
import matplotlib

matplotlib.use("Agg")

import IPython  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from helpers.association.common import finish, prepare  # noqa: E402
from helpers.association.evaluation import trial_counts  # noqa: E402
from helpers.association.explorations import (PairingExplorer, clutter_subset, outcomes,  # noqa: E402
                                              with_heading_error)
from helpers.association.jcbb import jcbb  # noqa: E402
from helpers.association.nearest_neighbour import mahalanobis_nn, nearest_neighbour  # noqa: E402
from helpers.association.scenarios import range_bearing_scenario  # noqa: E402
from helpers.exercises import ExerciseNotImplemented  # noqa: E402
from helpers.explore import choice, explore, slider  # noqa: E402

SIGMA = np.deg2rad(8.0)
SCENE = dict(n_landmarks=60, size=30.0, n_visible=12, pose_sigma=(0.5, 0.5, SIGMA), landmark_sigma=0.05,
             meas_sigma=0.1, candidate_range=12.0)            # notebook 08's base scene
ALGS = {"NN": lambda D, Y: nearest_neighbour(D, Y, max_distance=2.0), "ICNN": mahalanobis_nn,
        "JCBB": lambda D, Y: jcbb(D, Y, max_nodes=20_000),
        "none": lambda D, Y: finish(prepare(D, Y), np.full(D.size // 2, -1), "none")}
ORACLE = {}                                   # the scene whose truth the "truth" algorithm returns


def oracle(D, Y):
    """Every landmark paired right: the truth of ORACLE["scene"] (set by drawn(); unpaired before)."""
    sc = ORACLE.get("scene")
    return finish(prepare(D, Y), np.full(D.size // 2, -1) if sc is None else sc.truth, "truth")


@pytest.fixture(scope="module")
def explorer():
    return PairingExplorer({**ALGS, "truth": oracle}, SCENE, seed=81, max_clutter=20)   # trial 18: notebook 08's


def drawn(ex, **knobs):
    """(summary, {legend label: line}, the text beside the axes) of one draw."""
    fig = Figure()
    ORACLE["scene"] = ex.trial_scene(knobs["trial"], knobs["n_clutter"], knobs["heading_error"])
    s = ex.draw(fig, **knobs)
    ax = fig.axes[0]
    return s, {line.get_label(): line for line in ax.get_lines()}, fig.texts[0].get_text()


def test_clutter_is_nested_and_the_truth_follows_the_columns():
    full = range_bearing_scenario((81, 3), n_clutter=6, **SCENE)
    prev = None
    for n in range(7):
        sc = clutter_subset(full, n)
        assert sc.is_clutter.sum() == n and sc.m == full.m - 6 + n
        k = sc.truth >= 0
        assert np.array_equal(sc.Y[:, sc.truth[k]], full.Y[:, full.truth[k]])      # same observation per landmark
        assert not sc.is_clutter[sc.truth[k]].any()
        cols = {tuple(y) for y in sc.Y.T}
        assert prev is None or prev < cols                                           # adds points, moves none
        prev = cols
    for bad in (-1, 7, 2.5, True):
        with pytest.raises(ValueError, match="n_clutter"):
            clutter_subset(full, bad)


def test_the_heading_error_rotates_predictions_and_gates_rigidly():
    sc = range_bearing_scenario((81, 3), n_clutter=2, **SCENE)
    drawn_error = sc.pose_est[2] - sc.pose_true[2]
    same = with_heading_error(sc, drawn_error)                     # the drawn error: the scenario's own density
    assert np.allclose(same.density.mean, sc.density.mean) and np.allclose(same.density.cov, sc.density.cov)
    delta = 2.0 * SIGMA - drawn_error
    rot = with_heading_error(sc, 2.0 * SIGMA)
    c, s = np.cos(delta), np.sin(delta)
    B = np.kron(np.eye(sc.n), np.array([[c, s], [-s, c]]))        # R(−Δ) on every landmark's block
    assert np.allclose(rot.density.mean, B @ sc.density.mean)
    assert np.allclose(rot.density.cov, B @ sc.density.cov @ B.T)
    assert np.array_equal(rot.Y, sc.Y) and np.array_equal(rot.truth, sc.truth)
    assert np.isclose(rot.pose_est[2] - rot.pose_true[2], 2.0 * SIGMA)
    with pytest.raises(ValueError, match="error"):
        with_heading_error(sc, np.nan)


def test_outcomes_on_a_hand_made_case():
    truth = np.array([0, 1, 2, -1, 3, -1])
    idx = np.array([0, 2, -1, 1, 4, -1])                  # right, wrong, unpaired, wrong, clutter, unpaired
    is_clutter = np.array([False, False, False, False, True])
    out = outcomes(idx, truth, is_clutter)
    assert {k: v.tolist() for k, v in out.items()} == {"right": [0], "wrong": [1, 3], "clutter paired": [4],
                                                       "missed": [1, 2, 4]}


@pytest.mark.parametrize("algorithm", ["NN", "ICNN", "JCBB", "truth", "none"])
@pytest.mark.parametrize("n_clutter, heading_error", [(0, 0.0), (2, 1.0), (10, 1.0), (10, -2.5)])
def test_the_drawn_counts_are_the_truths_counts(explorer, algorithm, n_clutter, heading_error):
    knobs = dict(trial=18, n_clutter=n_clutter, heading_error=heading_error, algorithm=algorithm)
    s, lines, text = drawn(explorer, **knobs)
    sc = explorer.trial_scene(18, n_clutter, heading_error)
    idx = explorer.associate(18, n_clutter, heading_error, algorithm).idx
    c = trial_counts(idx, sc.truth, sc.m)
    assert (s["right"], s["pairings"], s["true"]) == (c["tp"], c["n_pred"], c["n_true"])
    assert s["right"] + s["wrong"] + s["clutter paired"] == s["pairings"] and s["missed"] == c["n_true"] - c["tp"]
    for name in ("right", "wrong", "clutter paired", "missed"):
        line = lines[f"{name}: {s[name]}"]
        assert np.count_nonzero(np.isnan(line.get_xdata())) == s[name]             # one segment per landmark
    assert len(lines["clutter"].get_xdata()) == n_clutter
    ends = lines[f"clutter paired: {s['clutter paired']}"].get_xydata()[1::3]     # every orange line ends on a ×
    assert all(any(np.allclose(e, y) for y in lines["clutter"].get_xydata()) for e in ends)
    precision = "n/a" if c["n_pred"] == 0 else f"{c['tp'] / c['n_pred']:.2f}"
    assert text.startswith(f"precision {precision}, recall {c['tp'] / c['n_true']:.2f}")
    assert ("not jointly compatible" in text) == (s["d2"] > s["gate"])
    if algorithm == "truth":
        assert (s["right"], s["wrong"], s["missed"]) == (s["true"], 0, 0)
    if algorithm == "none":
        assert "precision n/a, recall 0.00" in text


def test_the_lecture_points_show_on_the_default_scene(explorer):
    icnn, jcbb_ = (explorer.summary(18, 2, 1.0, a) for a in ("ICNN", "JCBB"))
    assert icnn["individual"] == icnn["pairings"] and icnn["d2"] > icnn["gate"]   # IC lets through, JC rejects
    assert icnn["wrong"] + icnn["clutter paired"] > 0
    assert jcbb_["right"] == jcbb_["pairings"] == jcbb_["true"] and jcbb_["d2"] <= jcbb_["gate"]
    greedy = [explorer.summary(18, n, 1.0, "ICNN")["clutter paired"] for n in (0, 2, 10)]
    assert greedy[0] == 0 < greedy[1] < greedy[2]                                   # more clutter, more paired
    assert explorer.summary(18, 10, 1.0, "JCBB")["clutter paired"] == 0
    at2, at3 = (explorer.summary(18, 2, e, "JCBB") for e in (2.0, 3.0))
    assert at2["wrong"] == at2["clutter paired"] == 0 and at2["pairings"] < at2["true"]
    assert at3["wrong"] + at3["clutter paired"] > 0                                 # a broken gate fools JCBB too


def test_the_view_is_the_same_for_every_knob_but_the_trial(explorer):
    limits = set()
    for knobs in ({"n_clutter": 0, "heading_error": 0.0}, {"n_clutter": 10, "heading_error": -3.0}):
        fig = Figure()
        explorer.draw(fig, trial=18, algorithm="ICNN", **knobs)
        limits.add(fig.axes[0].get_xlim() + fig.axes[0].get_ylim())
    assert len(limits) == 1


def test_the_knobs_redraw_the_figure_through_explore(explorer, monkeypatch):
    monkeypatch.setattr(IPython, "get_ipython", lambda: None)
    ex = explore(explorer.draw, n_clutter=slider(0, 20, 1, 2), heading_error=slider(-3.0, 3.0, 0.25, 1.0),
                 algorithm=choice(["ICNN", "JCBB"], "ICNN"), trial=slider(0, 19, 1, 18))
    title = ex.figure.axes[0].get_title()
    assert title.startswith("ICNN · trial 18 · 2 clutter points · heading error +1.00σ (+8.0°)")
    ex.redraw(algorithm="JCBB", heading_error=-0.5)
    assert ex.figure.axes[0].get_title().startswith("JCBB · trial 18 · 2 clutter points · heading error -0.50σ")
    assert "→ jointly compatible" in ex.figure.texts[0].get_text()
    ex.close()


def test_bad_knobs_and_arguments_name_themselves(explorer):
    for knobs, word in [({"n_clutter": 21}, "n_clutter"), ({"n_clutter": -1}, "n_clutter"),
                        ({"heading_error": np.nan}, "heading_error"), ({"heading_error": "1"}, "heading_error"),
                        ({"algorithm": "SNN"}, "algorithm"), ({"trial": -1}, "trial"), ({"trial": 1.5}, "trial")]:
        with pytest.raises(ValueError, match=word):
            explorer.draw(Figure(), **{"trial": 18, "n_clutter": 2, "heading_error": 1.0, "algorithm": "ICNN",
                                       **knobs})
    with pytest.raises(ValueError, match="fig"):
        explorer.draw(None, trial=18, n_clutter=2, heading_error=1.0, algorithm="ICNN")
    for kwargs, word in [({"algorithms": {}}, "algorithms"), ({"algorithms": {"a": 1}}, "algorithms"),
                         ({"scene": {**SCENE, "seed": 1}}, "scene"), ({"seed": -1}, "seed"),
                         ({"n_sigma": 0.0}, "n_sigma"), ({"max_clutter": -1}, "max_clutter")]:
        with pytest.raises(ValueError, match=word):
            PairingExplorer(**{"algorithms": {"ICNN": mahalanobis_nn}, "scene": SCENE, "seed": 1, **kwargs})


def test_unwritten_exercises_are_left_out():
    def stub(D, Y):
        raise ExerciseNotImplemented("l09_jcbb")
    ex = PairingExplorer({"ICNN": mahalanobis_nn, "JCBB": stub}, SCENE, seed=1, max_clutter=2)
    assert list(ex.algorithms) == ["ICNN"] and ex.missing == {"JCBB": "l09_jcbb"}
    with pytest.raises(ValueError, match="algorithm"):
        ex.draw(Figure(), trial=0, n_clutter=1, heading_error=0.0, algorithm="JCBB")
    with pytest.raises(ExerciseNotImplemented, match="l09_jcbb"):
        PairingExplorer({"JCBB": stub}, SCENE, seed=1, max_clutter=2)
