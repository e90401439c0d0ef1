"""Evaluation harness (Wilson intervals, sweeps, tables) and the evaluation figures of helpers.association."""
import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from scipy.stats import binomtest  # noqa: E402

from helpers.association.evaluation import RATES, run_trials, sweep, sweep_table, wilson_interval  # noqa: E402
from helpers.association.jcbb import jcbb  # noqa: E402
from helpers.association.nearest_neighbour import mahalanobis_nn  # noqa: E402
from helpers.association.plots import ALGORITHM_STYLE, draw_node_counts, draw_times, plot_rate_sweep  # noqa: E402
from helpers.figures import COLORS  # noqa: E402

ALGS = {"ICNN": mahalanobis_nn, "JCBB": lambda D, Y: jcbb(D, Y, max_nodes=50)}
SCENE = dict(n_landmarks=30, n_visible=6, n_clutter=1, candidate_range=12.0)


@pytest.fixture(scope="module")
def small_sweep():
    cache = {}
    res = sweep(ALGS, 3, 5, SCENE, [0, 2], lambda v: {"n_clutter": v}, cache=cache)
    return res, cache


@pytest.mark.parametrize("k, n", [(0, 10), (3, 10), (10, 10), (57, 200), (1, 1), (999, 1000)])
def test_wilson_matches_scipy(k, n):
    lo, hi = wilson_interval(k, n)
    ref = binomtest(k, n).proportion_ci(confidence_level=0.95, method="wilson")
    assert abs(lo - ref.low) < 1e-12 and abs(hi - ref.high) < 1e-12
    lo99, hi99 = wilson_interval(k, n, confidence=0.99)
    assert lo99 <= lo and hi99 >= hi                       # wider at a higher confidence


def test_wilson_bounds():
    for k in (0, 5, 20):
        lo, hi = wilson_interval(k, 20)
        assert 0 <= lo <= k / 20 <= hi <= 1
    assert wilson_interval(0, 20)[0] == 0.0 and wilson_interval(0, 20)[1] > 0.0     # no zero width at p̂ = 0
    assert wilson_interval(0, 0) == (0.0, 1.0)              # no data: uninformative


@pytest.mark.parametrize("args, word", [((-1, 5), "successes"), ((2.5, 5), "successes"), ((1, -2), "trials"),
                                        ((6, 5), "trials must be an integer ≥ 6"), ((1, 5, 1.0), "confidence"),
                                        ((1, 5, True), "confidence")])
def test_wilson_rejects_bad_input(args, word):
    with pytest.raises(ValueError, match=word):
        wilson_interval(*args)


def test_interval_uses_summed_counts(small_sweep):
    res, _ = small_sweep
    r = res[2]
    for key, (num, den) in RATES.items():
        lo, hi = r.interval("JCBB", key)
        k, n = int(r.counts["JCBB"][num].sum()), int(r.counts["JCBB"][den].sum())
        assert (lo, hi) == tuple(float(x) for x in wilson_interval(k, n))
        assert lo <= r.summary()["JCBB"][key] <= hi
    with pytest.raises(ValueError, match="name"):
        r.interval("nope", "recall")
    with pytest.raises(ValueError, match="key"):
        r.interval("JCBB", "f1")


def test_sweep_caches_shared_settings(small_sweep):
    res, cache = small_sweep
    assert list(res) == [0, 2] and len(cache) == 2
    again = sweep(ALGS, 3, 5, SCENE, [2, 3], lambda v: {"n_clutter": v}, cache=cache)
    assert again[2] is res[2] and len(cache) == 3           # the shared setting ran once
    direct = run_trials(ALGS, 3, seed=5, **{**SCENE, "n_clutter": 2})
    for name in ALGS:
        np.testing.assert_array_equal(direct.counts[name]["tp"], res[2].counts[name]["tp"])
    with pytest.raises(ValueError, match="make_kwargs"):
        sweep(ALGS, 3, 5, SCENE, [0], None)
    with pytest.raises(ValueError, match="values"):
        sweep(ALGS, 3, 5, SCENE, [], lambda v: {})


def test_sweep_table_layout(small_sweep):
    res, _ = small_sweep
    text = sweep_table("clutter", res, unit=" pts")
    lines = text.splitlines()
    assert lines[0] == "clutter" and "ICNN" in lines[1] and "JCBB" in lines[1]
    assert len(lines) == 3 + len(res) and lines[3].strip().startswith("0 pts")
    s = res[0].summary()
    assert f"{s['JCBB']['accuracy']:5.3f}" in lines[3]
    two = sweep_table("t", res, keys=("precision", "recall")).splitlines()
    assert len(two[3].split()) == 1 + 2 * len(ALGS)
    with pytest.raises(ValueError, match="keys"):
        sweep_table("t", res, keys=("f1",))
    with pytest.raises(ValueError, match="results"):
        sweep_table("t", {})


def test_algorithm_style_uses_the_palette():
    assert {st["color"] for st in ALGORITHM_STYLE.values()} <= set(COLORS.values())
    assert len({st["color"] for st in ALGORITHM_STYLE.values()}) == len(ALGORITHM_STYLE)


def test_evaluation_figures_draw(small_sweep):
    res, _ = small_sweep
    fig, axes = plt.subplots(1, 3)
    plot_rate_sweep(axes[0], res, "recall", jitter=0.05)
    assert len(axes[0].containers) == len(ALGS)             # one errorbar per algorithm
    with pytest.raises(ValueError, match="results"):
        plot_rate_sweep(axes[0], {}, "recall")
    cost = {m: run_trials(ALGS, 2, seed=1, n_landmarks=40, n_visible=m) for m in (4, 8)}
    draw_node_counts(axes[1], cost, max_nodes=50)
    labels = [t.get_text() for t in axes[1].get_legend().get_texts()]
    assert any(lab.startswith("node budget 50") and "of 4 searches" in lab for lab in labels)
    assert axes[1].get_yscale() == "log"
    draw_times(axes[2], cost, ["ICNN", "JCBB"])
    assert len(axes[2].get_lines()) == 4
    drawn = np.concatenate([line.get_ydata() for line in axes[2].get_lines()])       # medians and maxima
    np.testing.assert_allclose(np.sort(drawn), np.sort(np.concatenate(
        [[f(1e3 * cost[m].counts[a]["time"]) for m in cost] for a in ("ICNN", "JCBB") for f in (np.median, np.max)])))
    t_min = drawn.min()
    assert axes[2].get_ylim()[0] <= 10.0 ** np.floor(np.log10(t_min))   # a labelled decade below the data
    assert [float(t) for t in axes[2].get_xticks()] == [4.0, 8.0]        # ticks at the m values
    plt.close(fig)


def test_node_count_axis_labels_plain_numbers():
    cost = {m: run_trials(ALGS, 2, seed=1, n_landmarks=40, n_visible=m) for m in (4, 8)}
    cost[4].counts["JCBB"]["nodes"], cost[8].counts["JCBB"]["nodes"] = np.array([3, 3]), np.array([25_000] * 2)
    fig, ax = plt.subplots()
    draw_node_counts(ax, cost)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert "10 000" in labels and "100" in labels
    assert ax.get_ylim()[0] == 1.0
    plt.close(fig)


def test_run_trials_repeat_keeps_results_and_times_best_call():
    calls = []

    def counting(D, Y):
        calls.append(1)
        return mahalanobis_nn(D, Y)

    one = run_trials({"ICNN": mahalanobis_nn}, 2, seed=3, **SCENE)
    three = run_trials({"ICNN": counting}, 2, seed=3, repeat=3, **SCENE)
    assert len(calls) == 6
    for key in ("tp", "n_pred", "correct"):
        np.testing.assert_array_equal(one.counts["ICNN"][key], three.counts["ICNN"][key])
    assert three.counts["ICNN"]["time"].shape == (2,) and np.all(three.counts["ICNN"]["time"] > 0)
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="repeat"):
            run_trials(ALGS, 1, 0, repeat=bad, **SCENE)


def test_wilson_interval_contains_the_estimate_at_the_ends():
    # at p̂ = 1 the formula's upper end is 1 − ε for some n (e.g. n = 30); error bars need lo ≤ p̂ ≤ hi exactly
    for n in range(1, 400):
        for k in (n, 0, n // 2):
            lo, hi = wilson_interval(k, n)
            assert lo <= k / n <= hi
