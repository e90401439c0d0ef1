"""Record the peer results that notebook 09 shows: GTSAM and g2o on W10000, GTSAM on Victoria Park.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/record_peers.py

Needs the pinned peers (environment-peers.txt: gtsam 4.3.0, g2opy 2.3.0). Runs, in one process and on the
workbook's shipped datasets, exactly the configurations notebook 09 describes:

- W10000: helpers (coursework Gauss–Newton, ≤ 50 iterations), GTSAM (LevenbergMarquardtOptimizer, default
  parameters, prior σ = 1e−6 on pose 0), g2o (Gauss–Newton, BlockSolverSE2 + Eigen, 15 iterations, pose 0 fixed);
- Victoria Park: helpers (``lm-gtsam`` on ``VertexSE2Exp``, ≤ 100 iterations), GTSAM LM (defaults), and GTSAM's
  pose covariances (every 10th pose) evaluated at helpers' solution.

Writes ``data/peer_results.json`` (iterations, χ², χ² per iteration, wall times) and ``data/peer_victoria_park.npz``
(the Victoria Park state and GTSAM's covariances there). ``tests/test_recorded_peers.py`` checks the recording
against a live run wherever the peers are installed.
"""
import datetime
import json
import os
import platform
import sys

import numpy as np

import peer_runs
from helpers import datasets
from helpers.graph import VertexSE2Exp
from helpers.recorded_peers import RESULTS_FILE, STATE_FILE
from helpers.paths import data_path

COMMAND = "OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/record_peers.py"
MARGINAL_EVERY = 10


def _summary(run):
    """The JSON-able part of a peer_runs result."""
    return {"solver": run["solver"], "config": run["config"], "iterations": int(run["iters"]),
            "chi2": float(run["chi2"]), "chi2_history": [float(c) for c in run["hist"]],
            "time_s": round(float(run["time"]), 3),
            "marginals_time_s": None if not np.isfinite(run["marg_time"]) else round(float(run["marg_time"]), 3)}


def record_w10000():
    data = datasets.read_dataset("w10000")
    runs = [peer_runs.run_helpers("w10000", "gn", 50, data=data), peer_runs.run_gtsam("w10000", marginal_every=0),
            peer_runs.run_g2o("w10000", data=data, marginals=False)]
    return {r["solver"]: _summary(r) for r in runs}


def record_victoria_park():
    data = datasets.read_dataset("victoria_park")
    ours = peer_runs.run_helpers("victoria_park", "lm-gtsam", 100, VertexSE2Exp, data=data)
    theirs = peer_runs.run_gtsam("victoria_park", marginal_every=0)
    cov = peer_runs.gtsam_marginals_at("victoria_park", ours["est"], ours["points"], MARGINAL_EVERY)
    pose_ids = np.array(sorted(ours["est"]), dtype=np.int64)
    point_ids = np.array(sorted(ours["points"]), dtype=np.int64)
    cov_ids = np.array(sorted(cov), dtype=np.int64)
    state = {"pose_ids": pose_ids, "poses": np.array([ours["est"][i] for i in pose_ids]),
             "point_ids": point_ids, "points": np.array([ours["points"][i] for i in point_ids]),
             "cov_pose_ids": cov_ids, "gtsam_cov": np.array([cov[i] for i in cov_ids])}
    return {r["solver"]: _summary(r) for r in (ours, theirs)}, state


def main():
    if peer_runs.gtsam is None or peer_runs.g2o is None:
        sys.exit("record_peers.py needs gtsam and g2opy (pip install -r environment-peers.txt)")
    import gtsam  # noqa: F401  (versions below)
    from importlib.metadata import version

    peer_runs.warm_up()
    results = {"recorded_with": {
        "command": COMMAND, "date": datetime.date.today().isoformat(),
        "gtsam": version("gtsam"), "g2opy": version("g2opy"), "numpy": np.__version__,
        "python": platform.python_version(), "machine": f"{platform.system()} {platform.machine()}, "
                                                        f"{os.cpu_count()} cores"}}
    results["w10000"] = record_w10000()
    results["victoria_park"], state = record_victoria_park()
    data_path(RESULTS_FILE).write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")
    np.savez_compressed(data_path(STATE_FILE), **state)
    for name in ("w10000", "victoria_park"):
        for solver, r in results[name].items():
            print(f"{name:14s} {solver:8s} {r['config']:26s} {r['iterations']:4d} it  chi2 {r['chi2']:.6f}  "
                  f"{r['time_s']:.3f} s")
    print(f"wrote data/{RESULTS_FILE} and data/{STATE_FILE}")


if __name__ == "__main__":
    main()
