"""Record the peer results: GTSAM and g2o on W10000 and GTSAM on Victoria Park (notebooks 09 and 19), and GTSAM's LM on
every shipped dataset (the convergence references of ``tests/test_graph_convergence.py``).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/record_peers.py                 # everything
    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/record_peers.py --convergence   # the "convergence" part only

Needs the pinned peers (environment-peers.txt: gtsam 4.3.0, g2opy 2.3.0). Runs, in one process and on the
workbook's shipped datasets, exactly the configurations notebook 09 describes:

- W10000: helpers (coursework Gauss–Newton, ≤ 50 iterations), GTSAM (LevenbergMarquardtOptimizer, default
  parameters, prior σ = 1e−6 on pose 0), g2o (Gauss–Newton, BlockSolverSE2 + Eigen, 15 iterations, pose 0 fixed);
- Victoria Park: helpers (``lm-gtsam`` on ``VertexSE2Exp``, ≤ 100 iterations), GTSAM LM (defaults), and GTSAM's
  pose covariances (every 10th pose) evaluated at helpers' solution.

Writes ``data/peer_results.json`` (iterations, χ², χ² per iteration, wall times) and ``data/peer_victoria_park.npz``
(the Victoria Park state and GTSAM's covariances there). ``tests/test_recorded_peers.py`` checks the recording
against a live run wherever the peers are installed.

The ``convergence`` part (``--convergence`` re-records it alone and keeps the rest of the file as it is, so the numbers
notebook 09 prints stay put): for every dataset of ``helpers.datasets.DATASETS``, GTSAM's graph of the shipped file
(``load2D`` for the TORO-layout files and Victoria Park, ``readG2o`` otherwise; GTSAM's readers skip LANDMARK2 lines,
so for cityTrees_reduced_1k / victoriaPark_reduced_1k each is added as a ``CustomFactor`` with GTSAM's
``Pose2.transformTo`` error, the workbook's EdgeSE2PointXY), a prior σ = 1e−8 on each pose the workbook fixes, and
``LevenbergMarquardtOptimizer`` run
- "GTSAM": with its default parameters (its own stopping rules, ≤ 100 iterations);
- "GTSAM optimum": to convergence — relative and absolute tolerance 1e−15, ≤ 1000 iterations, so that it stops only
  when no λ ≤ 1e5 decreases the error any more: the recorded χ² is the optimum of the basin GTSAM's LM reaches
  (every dataset but W20000, where GTSAM's χ² still falls after 1000 iterations);
- W20000 also "GTSAM 200 iterations": tolerances 0, 200 iterations (GTSAM's default run stops after 28).
χ² is 2 × the error of the graph without the priors (the workbook's Σ eᵀΩe).
"""
import datetime
import gzip
import json
import os
import platform
import sys
import tempfile
import time

import numpy as np

try:  # as a script (benchmarks/ on sys.path) or imported by the tests (benchmarks.record_peers)
    import peer_runs
except ImportError:
    from benchmarks import peer_runs
from helpers import datasets
from helpers.advanced.fast_graph import VertexSE2Exp
from helpers.graph import VertexPointXY
from helpers.paths import data_path
from helpers.recorded_peers import CONVERGENCE, RESULTS_FILE, STATE_FILE, load_recorded_peers

COMMAND = "OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/record_peers.py"
MARGINAL_EVERY = 10
#: read with load2D (readG2o refuses their TORO information layout; Victoria Park is not a g2o file)
LOAD2D = {"w100", "w10000", "example", "victoria_park"}
#: datasets whose LANDMARK2 lines GTSAM's readers skip (added here as CustomFactors)
LANDMARK2 = {"cityTrees_reduced_1k", "victoriaPark_reduced_1k"}
OPTIMUM_TOLERANCE = 1e-15
OPTIMUM_MAX_ITERATIONS = 1000
W20000_ITERATIONS = 200


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


def _xy_factor(gtsam, pose_key, point_key, z, information):
    """GTSAM CustomFactor of the workbook's EdgeSE2PointXY: e = Pose2.transformTo(point) − z."""
    def error(this, values, jacobians):
        h_pose, h_point = np.zeros((2, 3), order="F"), np.zeros((2, 2), order="F")
        e = values.atPose2(this.keys()[0]).transformTo(values.atPoint2(this.keys()[1]), h_pose, h_point) - z
        if jacobians is not None:
            jacobians[0], jacobians[1] = h_pose, h_point
        return e
    return gtsam.CustomFactor(gtsam.noiseModel.Gaussian.Information(information), [pose_key, point_key], error)


def gtsam_problem(name):
    """(graph, graph with the priors, initial values) of a shipped dataset, checked against the workbook's χ²."""
    import gtsam

    data = datasets.read_dataset(name)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, datasets.DATASETS[name].removesuffix(".gz"))
        with gzip.open(datasets.dataset_path(name), "rb") as src, open(path, "wb") as dst:
            dst.write(src.read())
        graph, initial = gtsam.load2D(path) if name in LOAD2D else gtsam.readG2o(path, False)
    ours = datasets.build_optimizer(data)
    if name in LANDMARK2:
        for v in ours.vertices():
            if isinstance(v, VertexPointXY):
                initial.insert(gtsam.symbol("l", v.id), v.estimate)
        for kind, i, j, z, info in data.edges:
            if kind == "xy":
                graph.add(_xy_factor(gtsam, i, gtsam.symbol("l", j), np.asarray(z, float), np.asarray(info, float)))
    if abs(2 * graph.error(initial) / ours.chi2() - 1) > 1e-9:
        raise RuntimeError(f"{name}: GTSAM's initial χ² {2 * graph.error(initial)} is not the workbook's {ours.chi2()}")
    with_priors = gtsam.NonlinearFactorGraph(graph)
    for v in ours.vertices():
        if v.fixed:
            prior = gtsam.noiseModel.Isotropic.Sigma(3, 1e-8)
            with_priors.add(gtsam.PriorFactorPose2(v.id, initial.atPose2(v.id), prior))
    return graph, with_priors, initial


def gtsam_lm(problem, config, tolerance=None, max_iterations=100):
    """GTSAM's LM one iterate() at a time: defaults (``tolerance`` None) or relative = absolute = ``tolerance``; stops
    on GTSAM's own convergence test, after ``max_iterations``, or when an iterate() gives up (no λ decreases)."""
    import gtsam

    graph, with_priors, initial = problem
    params = gtsam.LevenbergMarquardtParams()
    if tolerance is not None:
        params.setRelativeErrorTol(tolerance)
        params.setAbsoluteErrorTol(tolerance)
        params.setErrorTol(0.0)
    params.setMaxIterations(max_iterations)
    optimizer = gtsam.LevenbergMarquardtOptimizer(with_priors, initial, params)
    hist, elapsed = [2 * graph.error(initial)], 0.0
    while optimizer.iterations() < max_iterations:
        before, done = optimizer.error(), optimizer.iterations()
        t = time.perf_counter()
        optimizer.iterate()
        elapsed += time.perf_counter() - t
        if optimizer.iterations() == done:
            break
        hist.append(2 * graph.error(optimizer.values()))
        if gtsam.checkConvergence(params.getRelativeErrorTol(), params.getAbsoluteErrorTol(), params.getErrorTol(),
                                  before, optimizer.error()):
            break
    return {"solver": "GTSAM", "config": config, "iterations": optimizer.iterations(), "chi2": hist[-1],
            "chi2_history": hist, "time_s": round(elapsed, 3), "marginals_time_s": None}


def record_convergence():
    """The ``convergence`` part of the file (module docstring)."""
    part = {"recorded_with": _recorded_with(f"{COMMAND} --convergence")}
    for name in sorted(datasets.DATASETS):
        problem = gtsam_problem(name)
        runs = {"GTSAM": gtsam_lm(problem, "LM defaults")}
        if name == "w20000":
            runs["GTSAM 200 iterations"] = gtsam_lm(problem, "LM, tolerances 0, 200 iterations", 0.0,
                                                    W20000_ITERATIONS)
        else:
            runs["GTSAM optimum"] = gtsam_lm(problem, "LM to convergence (tolerances 1e-15)", OPTIMUM_TOLERANCE,
                                             OPTIMUM_MAX_ITERATIONS)
        part[name] = runs
        print("  ".join(f"{name:26s} {label:22s} {r['iterations']:4d} it  chi2 {r['chi2']:.12g}"
                        for label, r in runs.items()), flush=True)
    return part


def _recorded_with(command):
    from importlib.metadata import version

    return {"command": command, "date": datetime.date.today().isoformat(), "gtsam": version("gtsam"),
            "g2opy": version("g2opy"), "numpy": np.__version__, "python": platform.python_version(),
            "machine": f"{platform.system()} {platform.machine()}, {os.cpu_count()} cores"}


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    if argv not in ([], ["--convergence"]):
        sys.exit("usage: record_peers.py [--convergence]")
    if peer_runs.gtsam is None or peer_runs.g2o is None:
        sys.exit("record_peers.py needs gtsam and g2opy (pip install -r environment-peers.txt)")
    if argv == ["--convergence"]:
        results = load_recorded_peers()
        results[CONVERGENCE] = record_convergence()
        data_path(RESULTS_FILE).write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")
        print(f"wrote the {CONVERGENCE!r} part of data/{RESULTS_FILE}")
        return
    peer_runs.warm_up()
    results = {"recorded_with": _recorded_with(COMMAND)}
    results["w10000"] = record_w10000()
    results["victoria_park"], state = record_victoria_park()
    results[CONVERGENCE] = record_convergence()
    data_path(RESULTS_FILE).write_text(json.dumps(results, indent=1) + "\n", encoding="utf-8")
    np.savez_compressed(data_path(STATE_FILE), **state)
    for name in ("w10000", "victoria_park"):
        for solver, r in results[name].items():
            print(f"{name:14s} {solver:8s} {r['config']:26s} {r['iterations']:4d} it  chi2 {r['chi2']:.6f}  "
                  f"{r['time_s']:.3f} s")
    print(f"wrote data/{RESULTS_FILE} and data/{STATE_FILE}")


if __name__ == "__main__":
    main()
