"""The recorded peer results (data/peer_results.json, data/peer_victoria_park.npz): those notebook 09 shows, and
GTSAM's LM on every shipped dataset (the "convergence" part, the references of tests/test_graph_convergence.py).

Without the peers: the recording is complete, names the pinned peer versions, and the workbook's own covariances at
the recorded Victoria Park state equal GTSAM's recorded ones. With the peers installed (environment-peers.txt):
a live GTSAM / g2o run still gives the recorded values.
"""
import re

import numpy as np
import pytest

from helpers import datasets
from helpers.graph import VertexPointXY, VertexSE2
from helpers.paths import repository_root
from helpers.recorded_peers import (CONVERGENCE, covariance_agreement, load_recorded_peers,
                                    load_victoria_park_marginals, recorded_convergence)

SOLVERS = {"w10000": ("helpers", "GTSAM", "g2o"), "victoria_park": ("helpers", "GTSAM")}
#: the convergence runs recorded per dataset (W20000's χ² still falls after 1000 GTSAM iterations: no optimum)
CONVERGENCE_RUNS = {name: ("GTSAM", "GTSAM 200 iterations" if name == "w20000" else "GTSAM optimum")
                    for name in datasets.DATASETS}
#: the convergence runs a live GTSAM repeats in the tests (the large datasets take minutes)
LIVE_CONVERGENCE = sorted(set(datasets.DATASETS) - {"victoria_park", "w10000", "w20000"})


def _peer_pins():
    text = (repository_root() / "environment-peers.txt").read_text(encoding="utf-8")
    return dict(re.findall(r"^([A-Za-z0-9_.-]+)==([^\s;]+)", text, re.M))


def test_recording_is_complete_and_names_the_pinned_peers():
    rec = load_recorded_peers()
    pins = _peer_pins()
    assert rec["recorded_with"]["gtsam"] == pins["gtsam"] and rec["recorded_with"]["g2opy"] == pins["g2opy"]
    assert "benchmarks/record_peers.py" in rec["recorded_with"]["command"]
    for name, solvers in SOLVERS.items():
        assert set(rec[name]) == set(solvers)
        for solver in solvers:
            r = rec[name][solver]
            assert r["chi2_history"][-1] == pytest.approx(r["chi2"], rel=1e-12)
            assert len(r["chi2_history"]) >= r["iterations"] + 1  # GTSAM does not count a rejected last step
    # the reference optimum of W10000 (2 × GTSAM's error 144.87) and GTSAM's Victoria Park optimum
    assert rec["w10000"]["GTSAM"]["chi2"] == pytest.approx(289.73, abs=0.01)
    assert rec["victoria_park"]["GTSAM"]["chi2"] == pytest.approx(2.107e5, rel=1e-3)


def test_convergence_recording_covers_every_dataset():
    part = load_recorded_peers()[CONVERGENCE]
    pins = _peer_pins()
    assert part["recorded_with"]["gtsam"] == pins["gtsam"]
    assert "benchmarks/record_peers.py --convergence" in part["recorded_with"]["command"]
    assert set(part) - {"recorded_with"} == set(datasets.DATASETS)
    for name, runs in CONVERGENCE_RUNS.items():
        assert set(part[name]) == set(runs)
        for run in runs:
            r = recorded_convergence(name, run)
            assert r["chi2_history"][-1] == pytest.approx(r["chi2"], rel=1e-12)
            assert len(r["chi2_history"]) == r["iterations"] + 1
        # the run to convergence (or longer) ends at or below GTSAM's default run
        assert part[name][runs[1]]["chi2"] <= part[name]["GTSAM"]["chi2"] * (1 + 1e-12)
    assert recorded_convergence("w10000")["chi2"] == pytest.approx(289.7347632, rel=1e-8)
    assert recorded_convergence("w20000", "GTSAM")["iterations"] == 28          # GTSAM stops on its relative rule
    with pytest.raises(KeyError, match="GTSAM optimum"):
        recorded_convergence("w20000")
    with pytest.raises(KeyError, match="no convergence run recorded for dataset 'intel'"):
        recorded_convergence("intel")


def _our_covariances_at(state):
    opt = datasets.build_optimizer(datasets.read_dataset("victoria_park"))
    for pid, pose in zip(state["pose_ids"], state["poses"]):
        opt.vertex(int(pid), VertexSE2).set_estimate(pose)
    for lid, point in zip(state["point_ids"], state["points"]):
        opt.vertex(int(lid), VertexPointXY).set_estimate(point)
    opt.initialize_optimization()
    wanted = [opt.vertex(int(i), VertexSE2) for i in state["cov_pose_ids"]]
    marginals = opt.compute_marginals(wanted)
    return {int(v.id): marginals[v] for v in wanted}


def test_our_covariances_equal_the_recorded_gtsam_marginals():
    state = load_victoria_park_marginals()
    assert len(state["cov_pose_ids"]) == len(state["gtsam_cov"]) > 600
    ours = _our_covariances_at(state)
    reference = {int(i): c for i, c in zip(state["cov_pose_ids"], state["gtsam_cov"])}
    assert covariance_agreement(ours, reference) < 1e-5


@pytest.fixture(scope="module")
def peer_runs():
    from benchmarks import peer_runs as module

    return module


def test_live_gtsam_matches_the_recording(peer_runs):
    pytest.importorskip("gtsam", reason="GTSAM is an optional peer (environment-peers.txt; no Windows wheel)")
    rec = load_recorded_peers()
    for name in ("w10000", "victoria_park"):
        live = peer_runs.run_gtsam(name, marginal_every=0)
        assert live["iters"] == rec[name]["GTSAM"]["iterations"]
        np.testing.assert_allclose(live["hist"], rec[name]["GTSAM"]["chi2_history"], rtol=1e-6)


def test_live_gtsam_marginals_match_the_recording(peer_runs):
    pytest.importorskip("gtsam", reason="GTSAM is an optional peer (environment-peers.txt; no Windows wheel)")
    state = load_victoria_park_marginals()
    est = {int(i): p for i, p in zip(state["pose_ids"], state["poses"])}
    points = {int(i): p for i, p in zip(state["point_ids"], state["points"])}
    live = peer_runs.gtsam_marginals_at("victoria_park", est, points, 10)
    assert sorted(live) == [int(i) for i in state["cov_pose_ids"]]
    np.testing.assert_allclose(np.array([live[int(i)] for i in state["cov_pose_ids"]]), state["gtsam_cov"],
                               rtol=1e-6, atol=1e-12)


def test_live_g2o_matches_the_recording(peer_runs):
    pytest.importorskip("g2opy", reason="g2o's Python bindings are an optional peer (environment-peers.txt)")
    rec = load_recorded_peers()["w10000"]["g2o"]
    live = peer_runs.run_g2o("w10000", iters=rec["iterations"], marginals=False)
    np.testing.assert_allclose(live["hist"], rec["chi2_history"], rtol=1e-6)


@pytest.fixture(scope="module")
def recorder():
    from benchmarks import record_peers

    return record_peers


@pytest.mark.parametrize("name", LIVE_CONVERGENCE)
def test_live_gtsam_matches_the_convergence_recording(recorder, name):
    pytest.importorskip("gtsam", reason="GTSAM is an optional peer (environment-peers.txt; no Windows wheel)")
    problem = recorder.gtsam_problem(name)
    live = {"GTSAM": recorder.gtsam_lm(problem, "LM defaults"),
            "GTSAM optimum": recorder.gtsam_lm(problem, "", recorder.OPTIMUM_TOLERANCE,
                                               recorder.OPTIMUM_MAX_ITERATIONS)}
    for run, r in live.items():
        rec = recorded_convergence(name, run)
        assert r["iterations"] == rec["iterations"]
        np.testing.assert_allclose(r["chi2_history"], rec["chi2_history"], rtol=1e-6)
