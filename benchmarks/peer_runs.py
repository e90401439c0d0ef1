"""Peer runs for the benchmarks and the recorded peer results: helpers.graph, GTSAM and g2o (g2opy) on one dataset.

Each ``run_*`` returns a dict: solver, time (wall time of the optimisation call only; loading is not timed),
iters, chi2 (GTSAM: 2 × error), hist (χ² per iteration, starting with the initial value), marg_time (all pose
covariances), cov {pose id: 3×3 world-frame (x, y, ψ) covariance}, est {pose id: [x, y, ψ]}; helpers' run also
build_time (``initialize_optimization()``: the structure; the ordering and symbolic analysis follow at the first
factorisation, inside the timed optimisation — GTSAM's timed optimiser construction and iterations include both)
and backend (the linear solver's backend for the pattern).
helpers and GTSAM also give cpu_time (and helpers build_cpu_time): the process CPU time of the same regions — both
run single-threaded (GTSAM's wheel has no TBB; OPENBLAS_NUM_THREADS=1), so on a shared machine the CPU-time ratio
is the steadier one.

GTSAM's Pose2 covariance lives in the body-frame tangent space; it is rotated to the world-frame additive
parameterisation of VertexSE2 (Σ_w = M Σ_b Mᵀ, M = blockdiag(R(ψ), 1)) before any comparison.
g2opy 2.3.0: no range-bearing edge (pose graphs only); ``compute_marginals`` cannot return its result to Python
("Unable to convert function return value"), so its marginal time is NaN. g2o's EdgeSE2 error is [t_d, θ_d]
rather than GTSAM's Log(d), so its χ² is a slightly different cost (≈ 289.726 vs 289.735 on W10000).
"""

import gzip
import os
import tempfile
import time

import numpy as np

try:  # each peer is optional (GTSAM has no Windows wheel): a run needs only its own library
    import gtsam
except ImportError:
    gtsam = None
try:
    from g2opy import g2opy as g2o
except ImportError:
    g2o = None

from helpers import datasets
from helpers.advanced.fast_graph import FastOptimizer, VertexSE2Exp, cholmod_backend
from helpers.datasets.graph_data import initial_values
from helpers.graph import EdgeRangeBearing, EdgeSE2, SparseOptimizer, VertexPointXY, VertexSE2
from helpers.recorded_peers import covariance_agreement


def load2d(name):
    """GTSAM's ``load2D`` on the workbook's shipped copy of a dataset (decompressed to a temporary file)."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, datasets.DATASETS[name].removesuffix(".gz"))
        with gzip.open(datasets.dataset_path(name), "rb") as src, open(path, "wb") as dst:
            dst.write(src.read())
        return gtsam.load2D(path)


def warm_up():
    """Compile (or load from numba's cache) every kernel on tiny graphs — pose-only and mixed graphs, both
    vertex updates, all algorithms, marginals — so timings exclude compilation."""
    cases = [(SparseOptimizer, VertexSE2, ("lm", "gn"))] + [(FastOptimizer, pose_class, ("lm", "gn", "lm-gtsam"))
                                                         for pose_class in (VertexSE2, VertexSE2Exp)]
    for optimizer_class, pose_class, algorithms in cases:
        for with_point in (False, True):
            g = optimizer_class()
            a, b = pose_class(0, fixed=True), pose_class(1, [1, 0.1, 0])
            g.add_vertex(a)
            g.add_vertex(b)
            g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0]))
            if with_point:
                p = VertexPointXY(0, [2, 1])
                g.add_vertex(p)
                g.add_edge(EdgeRangeBearing([a, p], measurement=[2.2, 0.4]))
                g.add_edge(EdgeRangeBearing([b, p], measurement=[1.4, 0.8]))
            g.initialize_optimization()
            for algorithm in algorithms:
                g.optimize(3, algorithm=algorithm)
            g.compute_marginals()
    if cholmod_backend.AVAILABLE:  # the decision's kernels (only large patterns reach them)
        pattern = g._structure.pattern
        cholmod_backend.column_counts(pattern, cholmod_backend.amd_ordering(cholmod_backend.pattern_matrix(pattern)))


def run_helpers(name, algorithm="gn", iters=100, pose_class=VertexSE2, data=None, backend="auto",
                optimizer_class=FastOptimizer):
    """Load and solve a dataset with the workbook's optimiser ``optimizer_class`` (the advanced ``FastOptimizer``, or
    the course's ``SparseOptimizer``); time the structure build, the optimise call and all pose marginals.

    ``data``: the parsed dataset (``datasets.read_dataset(name)``) when the caller already has it; ``backend``:
    FastOptimizer's ``LDLSolver`` backend ("auto", "qdldl" — the solver before CHOLMOD was added —, "cholmod")."""
    if data is None:
        data = datasets.read_dataset(name)
    opt = datasets.build_optimizer(data, pose_class=pose_class, optimizer_class=optimizer_class)
    fast = optimizer_class is FastOptimizer
    if fast:
        opt.linear_solver.backend = backend
    t, c = time.perf_counter(), time.process_time()
    opt.initialize_optimization()
    t_build, c_build = time.perf_counter() - t, time.process_time() - c
    chi2_0 = opt.chi2()
    est0 = {v.id: v.estimate for v in opt.vertices() if isinstance(v, VertexSE2)}
    t, c = time.perf_counter(), time.process_time()
    chi2 = opt.optimize(iters, algorithm=algorithm)
    t_opt, c_opt = time.perf_counter() - t, time.process_time() - c
    poses = [v for v in opt.vertices() if isinstance(v, VertexSE2)]
    t = time.perf_counter()
    marg = opt.compute_marginals(poses)
    t_marg = time.perf_counter() - t
    cov = {v.id: marg[v] for v in poses}
    if pose_class.oplus_jacobian_batch is not None:  # covariance of the update δ → of the coordinates (x, y, ψ)
        ms = pose_class.oplus_jacobian_batch(np.array([v.estimate for v in poses]))
        cov = {v.id: m @ marg[v] @ m.T for v, m in zip(poses, ms)}
    est = {v.id: v.estimate for v in poses}
    points = {v.id: v.estimate for v in opt.vertices() if not isinstance(v, VertexSE2)}
    label = f"{algorithm}, {pose_class.__name__}" + ("" if fast else " (course)")
    return {"solver": "helpers", "config": label, "time": t_opt, "iters": opt.iterations, "chi2": chi2,
            "marg_time": t_marg,
            "cov": cov, "est": est, "est0": est0, "points": points,
            "hist": [chi2_0] + opt.chi2_history, "build_time": t_build,
            "backend": opt.linear_solver.active_backend if fast else "qdldl",
            "cpu_time": c_opt, "build_cpu_time": c_build}


def run_gtsam(name, marginal_every=1):
    """GTSAM LevenbergMarquardtOptimizer (default parameters, 1e−6 prior on pose 0) and Marginals for all poses
    (or every ``marginal_every``-th pose; 0 skips them, to keep a notebook short)."""
    graph, initial = load2d(name)
    graph.add(gtsam.PriorFactorPose2(0, initial.atPose2(0), gtsam.noiseModel.Isotropic.Sigma(3, 1e-6)))
    params = gtsam.LevenbergMarquardtParams()
    t, c = time.perf_counter(), time.process_time()
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, initial, params)
    hist = [2 * graph.error(initial)]
    t_hist = c_hist = 0.0
    while True:  # iterate() one step at a time to record χ² per iteration (the recording itself is not timed)
        before = optimizer.error()
        optimizer.iterate()
        t0, c0 = time.perf_counter(), time.process_time()
        hist.append(2 * optimizer.error())
        t_hist += time.perf_counter() - t0
        c_hist += time.process_time() - c0
        if optimizer.iterations() >= params.getMaxIterations() or gtsam.checkConvergence(
                params.getRelativeErrorTol(), params.getAbsoluteErrorTol(), params.getErrorTol(), before,
                optimizer.error()):
            break
    result = optimizer.values()
    t_opt = time.perf_counter() - t - t_hist
    c_opt = time.process_time() - c - c_hist
    pose_keys = [k for k in result.keys() if gtsam.Symbol(k).chr() == 0]
    cov, t_marg = {}, float("nan")
    if marginal_every:  # 0: skip the marginals
        t = time.perf_counter()
        marginals = gtsam.Marginals(graph, result)
        cov = {int(k): marginals.marginalCovariance(k) for k in pose_keys[::marginal_every]}
        t_marg = time.perf_counter() - t
    est = {}
    for k in pose_keys:
        p = result.atPose2(k)
        est[int(k)] = np.array([p.x(), p.y(), p.theta()])
    # body-frame tangent (GTSAM Pose2) → world-frame additive (x, y, ψ): Σ_w = M Σ_b Mᵀ, M = blockdiag(R(ψ), 1)
    for k, c in cov.items():
        psi = est[k][2]
        m = np.eye(3)
        m[:2, :2] = [[np.cos(psi), -np.sin(psi)], [np.sin(psi), np.cos(psi)]]
        cov[k] = m @ c @ m.T
    return {"solver": "GTSAM", "config": "LM defaults", "time": t_opt, "iters": optimizer.iterations(),
            "chi2": 2 * graph.error(result),
            "marg_time": t_marg, "cov": cov, "est": est, "hist": hist, "cpu_time": c_opt}


def gtsam_marginals_at(name, est, points, marginal_every=1):
    """GTSAM's pose covariances (world-frame (x, y, ψ)) evaluated at a given solution — the oracle for checking
    helpers' marginals at the same state."""
    graph, _ = load2d(name)
    first = min(est)
    graph.add(gtsam.PriorFactorPose2(first, gtsam.Pose2(*est[first]), gtsam.noiseModel.Isotropic.Sigma(3, 1e-9)))
    values = gtsam.Values()
    for k, x in est.items():
        values.insert(int(k), gtsam.Pose2(*x))
    for k, m in points.items():
        values.insert(gtsam.symbol("l", int(k)), np.asarray(m, dtype=float))
    marginals = gtsam.Marginals(graph, values)
    out = {}
    for k in sorted(est)[::marginal_every]:
        c = marginals.marginalCovariance(int(k))
        m = np.eye(3)
        psi = est[k][2]
        m[:2, :2] = [[np.cos(psi), -np.sin(psi)], [np.sin(psi), np.cos(psi)]]
        out[k] = m @ c @ m.T
    return out


def run_g2o(name, iters=15, data=None, marginals=True):
    """g2opy Gauss–Newton (BlockSolverSE2 + Eigen), first pose fixed; pose-graph datasets only.

    ``data``: the parsed dataset (``datasets.read_dataset(name)``) when the caller already has it; ``marginals``
    False skips the (in g2opy 2.3.0 always failing) marginal computation, to keep a notebook short."""
    if data is None:
        data = datasets.read_dataset(name)
    if any(e[0] != "se2" for e in data.edges):
        raise ValueError(f"g2opy has no range-bearing edge; {name} is not a pose graph")
    poses, _ = initial_values(data)
    opt = g2o.SparseOptimizer()
    opt.set_algorithm(g2o.OptimizationAlgorithmGaussNewton(g2o.BlockSolverSE2(g2o.LinearSolverEigenSE2())))
    first = min(poses)
    # building 64k edges through the bindings one call at a time takes ~15 s; g2o's own .g2o parser is fast
    ids = np.array(sorted(poses))
    vert = np.column_stack([ids, np.array([poses[p] for p in ids])])
    a, b = np.triu_indices(3)
    edges = np.column_stack([np.array([(e[1], e[2]) for e in data.edges]), np.array([e[3] for e in data.edges]),
                             np.array([e[4] for e in data.edges])[:, a, b]])
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "graph.g2o")
        with open(path, "w", encoding="utf-8") as fh:
            np.savetxt(fh, vert, fmt="VERTEX_SE2 %d" + " %.17g" * 3)
            np.savetxt(fh, edges, fmt="EDGE_SE2 %d %d" + " %.17g" * 9)
        if not opt.load(path):
            raise RuntimeError("g2o could not load the converted graph")
    vs = {p: opt.vertex(int(p)) for p in poses}
    vs[first].set_fixed(True)
    opt.initialize_optimization()
    opt.compute_active_errors()
    chi2_0 = opt.chi2()
    opt.set_compute_batch_statistics(True)
    t = time.perf_counter()
    opt.optimize(iters)
    t_opt = time.perf_counter() - t
    opt.compute_active_errors()
    chi2 = opt.chi2()
    hist = [chi2_0] + [float(s.chi2) for s in opt.batch_statistics()]  # g2o records χ² after each iteration
    free = [vs[p] for p in sorted(poses) if p != first]
    cov, t_marg = {}, float("nan")
    if marginals:
        t = time.perf_counter()
        try:
            spinv, ok = opt.compute_marginals(free)
            for p in sorted(poses):
                if p != first:
                    hi = vs[p].hessian_index()
                    cov[p] = np.array(spinv.block(hi, hi))
            t_marg = time.perf_counter() - t
        except TypeError:  # g2opy 2.3.0: "Unable to convert function return value" (SparseBlockMatrix* not bound)
            cov = {}
    est = {p: np.array(vs[p].estimate().vector()) for p in poses}
    return {"solver": "g2o", "config": f"GN x{iters}", "time": t_opt, "iters": iters, "chi2": chi2,
            "marg_time": t_marg, "cov": cov,
            "est": est, "hist": hist}


def agreement(a, b):
    """Covariance agreement (helpers.recorded_peers.covariance_agreement); NaN when ``a`` has no covariances."""
    return float("nan") if not a else covariance_agreement(a, b)
