"""Tests for helpers.drivebot.q3_support: metrics of a run, the multi-seed evaluation, tables and plots."""
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from helpers.drivebot import pruning, run_question  # noqa: E402
from helpers.drivebot import q3_support as q3  # noqa: E402

VARIANTS = {
    "full": {},
    "keep 1": lambda s: {"pre_optimization_hook": pruning.KeepKPerVertex(1, seed=s)},
    "remove all": {"remove_prediction_edges": True, "keep_first_prediction_edge": False},
}


@pytest.fixture(scope="module")
def evaluation():
    return q3.evaluate_seeds("q3_a", VARIANTS, [0, 1], keep=[1], maximum_step_number=520)


def test_run_metrics_of_one_run():
    res = run_question("q3_a", seed=0, maximum_step_number=300)
    m = q3.run_metrics(res)
    st = res.graph_statistics()
    assert m["vehicle_vertices"] == 300 and m["kinematics_edges"] == 299
    assert m["edges"] == sum(st["edges_by_type"].values()) and m["landmark_edges"] == st["landmark_edges"]
    assert m["hessian_nnz"] == res.system.graph.hessian().nnz > 0
    assert m["chi2_per_dof"] == pytest.approx(m["chi2"] / m["dof"])
    assert m["pose_rms"] > 0 and m["landmark_rms"] > 0 and m["pos_var_median"] > 0 and m["psi_var_median"] > 0
    assert set(q3.METRIC_LABELS) <= set(m) | {"chi2_in_band"}


def test_evaluate_seeds_records_failures_and_keeps_results(evaluation):
    ev, kept = evaluation
    assert list(ev) == list(VARIANTS) and all(list(per) == [0, 1] for per in ev.values())
    assert q3.failures(ev) == {"full": [], "keep 1": [], "remove all": [0, 1]}
    assert ev["remove all"][0]["failed"].startswith("GaugeFreedomError")
    assert set(kept) == {("full", 1), ("keep 1", 1)}
    assert ev["keep 1"][0]["landmark_edges"] < ev["full"][0]["landmark_edges"]
    alone = q3.run_metrics(run_question("q3_a", seed=1, maximum_step_number=520))
    assert alone["chi2"] == ev["full"][1]["chi2"] and alone["edges"] == ev["full"][1]["edges"]


def test_seed_summary_and_table(evaluation):
    ev, _ = evaluation
    summ = q3.seed_summary(ev, "edges")
    vals = [ev["full"][s]["edges"] for s in (0, 1)]
    mean, sd, lo, hi, n = summ["full"]
    assert mean == pytest.approx(np.mean(vals)) and sd == pytest.approx(np.std(vals, ddof=1))
    assert (lo, hi, n) == (min(vals), max(vals), 2)
    assert summ["remove all"][4] == 0 and np.isnan(summ["remove all"][0])
    table = q3.format_seed_table(ev, [("edges", "edges", ".0f"), ("pose_rms", "RMS", ".2f")])
    lines = table.splitlines()
    assert len(lines) == 4 and "edges" in lines[0] and "failed" in lines[3] and "±" in lines[1]


def test_paired_and_relative_table(evaluation):
    ev, _ = evaluation
    pairs = q3.paired(ev, "keep 1", "full", "landmark_edges")
    assert pairs == [(ev["keep 1"][s]["landmark_edges"], ev["full"][s]["landmark_edges"]) for s in (0, 1)]
    assert q3.paired(ev, "remove all", "full", "edges") == []          # every run of the variant failed
    lines = q3.format_relative(ev, "full").splitlines()
    assert len(lines) == 3 and lines[0] == f"{'full':>24}: edges removed     0, landmark edges 1.00, " \
                                           "nnz(H) 1.00, median position variance ×1.0"
    ratio = np.mean([p for p, _ in pairs]) / np.mean([f for _, f in pairs])
    assert f"landmark edges {ratio:.2f}" in lines[1]


def test_plots(evaluation):
    ev, _ = evaluation
    ok = {k: v for k, v in ev.items() if k != "remove all"}
    fig, axes = plt.subplots(2, 2)
    q3.plot_seed_bars(axes, ok, ["edges", "hessian_nnz", "pose_rms", "chi2_per_dof"])
    assert [t.get_text() for t in axes[0, 0].get_yticklabels()] == list(ok)      # first variant on top
    assert all(t.get_text() == "" for t in axes[0, 1].get_yticklabels())
    fig2, ax = plt.subplots()
    H = np.eye(5)
    assert q3.spy_hessian(ax, H, np.array([0, 3]), 1, "t") == 5
    plt.close("all")


@pytest.mark.parametrize("seeds", [[], [0, 0], [-1], [1.5], "01", [True]])
def test_evaluate_seeds_bad_seeds(seeds):
    with pytest.raises(ValueError, match="seeds"):
        q3.evaluate_seeds("q3_a", {"full": {}}, seeds)


def test_evaluate_seeds_bad_variants():
    with pytest.raises(ValueError, match="variants"):
        q3.evaluate_seeds("q3_a", {}, [0])
