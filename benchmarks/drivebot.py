"""DriveBot SLAM graphs: the workbook's optimiser against GTSAM on structurally equal graphs.

Run from the repository root:

    .venv/bin/python benchmarks/drivebot.py            # all three benchmarks, prints the three ratios
    .venv/bin/python benchmarks/drivebot.py --exact    # also an exact-model oracle (GTSAM CustomFactor)

Benchmarks (ratio = helpers time / GTSAM time; goal ≤ 1.0 for each):

1. **LM, one optimisation of the full q3_a graph** (5273 poses, 13 landmarks, 30 m laser). Both
   optimisers start from the same dead-reckoning initialisation (poses chained through the odometry,
   every landmark placed from its first observation) and run Levenberg–Marquardt to convergence. The ratio
   is like for like: helpers with ``algorithm="lm-gtsam"`` (GTSAM's damping schedule and its relative
   stopping rule 1e-5) against GTSAM's default LM; the coursework LM (ε = 1e-12, iterates far past GTSAM's
   stopping point) is timed and printed too.
2. **q2_b optimising every step**: the helpers' summed `optimize()` times of `run_question("q2_b",
   optimization_period=1, ...)` against GTSAM iSAM2 fed the same measurement stream one tick at a time (one
   `update` per tick, new values initialised exactly as the DriveBot system does: forward prediction from the
   current estimate, landmarks from their first observation). The judged ratio is like for like, incremental
   against incremental: ``optimization_algorithm="incremental"`` (``helpers.graph.incremental``: a Gauss–Newton
   solve per tick on a factor kept between ticks, another only while some step is over the relinearisation
   threshold; iSAM2's relinearisation rule with its defaults, threshold 0.1 and every 10th update; everything it
   does per tick is timed, the χ² it returns included). Printed beside it:
   a batch re-solve per tick with GTSAM's LM schedule (``"lm-gtsam"``) and with the coursework LM, each including
   the tick's structure update (``ensure_structure``).
3. **All pose marginals** of the optimised q3_a graph: `SparseOptimizer.compute_marginals` against
   `gtsam.Marginals(...).marginalCovariance` for every pose.

The GTSAM graph is structurally equal to the DriveBot graph (same variables, one factor per edge):

- vehicle kinematics edge (velocity form e = Mᵀ(ψ_k)Δ/ΔT − u, Ω) → `BetweenFactorPose2` with
  measured = (u₁ΔT, u₂ΔT, u₃ΔT) and information Ω/ΔT² (covariance ΔT²·R). The translation part of
  X_k⁻¹X_{k+1} is exactly R(ψ_k)ᵀΔp, so the two errors agree to first order; they differ by SE(2)'s log
  coupling (O(ψ̇ΔT) relative), which changes the optimum χ² slightly. `--exact` additionally runs LM on a
  graph whose kinematics factors are `CustomFactor`s with the DriveBot error itself (a Python callback per
  factor, so it is an oracle for the χ², not a timing reference).
- landmark range-bearing edge (z = [r, β], Ω) → `BearingRangeFactor2D` (GTSAM orders (bearing, range),
  so the information matrix is permuted accordingly).
- the fixed first vertex → a `PriorFactorPose2` with σ = 1e-6 (GTSAM has no fixed flag).

χ² convention: GTSAM's `graph.error` is ½χ², so it is doubled before printing.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import sys
import time

import numpy as np

import gtsam

X = gtsam.symbol_shorthand.X
L = gtsam.symbol_shorthand.L

PRIOR_SIGMA = 1e-6


# ----------------------------------------------------------------------------------------------------
# A DriveBot SLAM graph as plain arrays (vehicle vertices 0..N-1 in creation order, landmarks 0..L-1)
# ----------------------------------------------------------------------------------------------------
@dataclasses.dataclass
class GraphArrays:
    poses: np.ndarray          # (N, 3) current vehicle estimates
    fixed: np.ndarray          # (N,) bool
    landmarks: np.ndarray      # (L, 2) current landmark estimates
    landmark_ids: np.ndarray   # (L,) the scenario's 1-based landmark ids
    odo_i: np.ndarray          # (M,) index of x_k
    odo_j: np.ndarray          # (M,) index of x_{k+1}
    odo_u: np.ndarray          # (M, 3) odometry measurement [s, 0, ψ̇]
    odo_dt: np.ndarray         # (M,) ΔT
    odo_info: np.ndarray       # (M, 3, 3) Ω
    rb_pose: np.ndarray        # (K,) vehicle index
    rb_lm: np.ndarray          # (K,) landmark index
    rb_z: np.ndarray           # (K, 2) [range, bearing]
    rb_info: np.ndarray        # (K, 2, 2) Ω in (range, bearing) order

    @property
    def n_poses(self) -> int:
        return self.poses.shape[0]


def arrays_from_graph(graph) -> GraphArrays:
    """Read a DriveBot SLAM graph (a ``helpers.graph.SparseOptimizer``) into :class:`GraphArrays`.

    Vehicle vertices are the ``VertexSE2`` instances in creation order, landmarks the ``VertexPointXY``
    ones; kinematics edges are the SE2→SE2 edges with a ``dt`` parameter, landmark edges the
    SE2→PointXY ones. (Setup only — not timed.)"""
    from helpers.graph import VertexPointXY, VertexSE2

    vertices = graph.vertices()
    poses = [v for v in vertices if isinstance(v, VertexSE2)]
    points = [v for v in vertices if isinstance(v, VertexPointXY)]
    pidx = {id(v): i for i, v in enumerate(poses)}
    lidx = {id(v): i for i, v in enumerate(points)}
    odo, rb = [], []
    for e in graph.edges():
        vs = e.vertices()
        if len(vs) == 2 and isinstance(vs[0], VertexSE2) and isinstance(vs[1], VertexSE2):
            odo.append((pidx[id(vs[0])], pidx[id(vs[1])], e.measurement, e.parameter("dt"), e.information))
        elif len(vs) == 2 and isinstance(vs[0], VertexSE2) and isinstance(vs[1], VertexPointXY):
            rb.append((pidx[id(vs[0])], lidx[id(vs[1])], e.measurement, e.information))
        else:
            raise ValueError(f"graph: unexpected edge {type(e).__name__} in a DriveBot SLAM graph")
    return GraphArrays(
        poses=np.array([v.estimate for v in poses]), fixed=np.array([v.fixed for v in poses]),
        landmarks=np.array([v.estimate for v in points]).reshape(-1, 2),
        landmark_ids=np.array([getattr(v, "landmark_id", v.id) for v in points]),
        odo_i=np.array([o[0] for o in odo], int), odo_j=np.array([o[1] for o in odo], int),
        odo_u=np.array([o[2] for o in odo]).reshape(-1, 3), odo_dt=np.array([o[3] for o in odo], float),
        odo_info=np.array([o[4] for o in odo]).reshape(-1, 3, 3),
        rb_pose=np.array([r[0] for r in rb], int), rb_lm=np.array([r[1] for r in rb], int),
        rb_z=np.array([r[2] for r in rb]).reshape(-1, 2), rb_info=np.array([r[3] for r in rb]).reshape(-1, 2, 2))


def set_graph_estimates(graph, arrays: GraphArrays, poses, landmarks):
    """Write pose/landmark arrays (indexed as in ``arrays_from_graph``) back into the graph's vertices."""
    from helpers.graph import VertexPointXY, VertexSE2

    vertices = graph.vertices()
    for v, x in zip([v for v in vertices if isinstance(v, VertexSE2)], poses):
        v.set_estimate(x)
    for v, m in zip([v for v in vertices if isinstance(v, VertexPointXY)], landmarks):
        v.set_estimate(m)


def wrap(a):
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


def dead_reckoning(arrays: GraphArrays) -> tuple[np.ndarray, np.ndarray]:
    """Initial values as the DriveBot system makes them: x_{k+1} = x_k + ΔT M(ψ_k) u_k from x_0,
    each landmark from its first observation m = p + r [cos(β+ψ), sin(β+ψ)]. Vectorised (cumsum).

    Requires the kinematics edges to form the chain 0→1→…→N−1 (the full SLAM graph)."""
    n = arrays.n_poses
    if not (np.array_equal(arrays.odo_i, np.arange(n - 1)) and np.array_equal(arrays.odo_j, np.arange(1, n))):
        raise ValueError("arrays: dead reckoning needs the full kinematics chain 0→1→…→N−1")
    x0 = arrays.poses[0]
    dpsi = arrays.odo_dt * arrays.odo_u[:, 2]
    psi = x0[2] + np.concatenate([[0.0], np.cumsum(dpsi)])
    c, s = np.cos(psi[:-1]), np.sin(psi[:-1])
    dx = arrays.odo_dt * (c * arrays.odo_u[:, 0] - s * arrays.odo_u[:, 1])
    dy = arrays.odo_dt * (s * arrays.odo_u[:, 0] + c * arrays.odo_u[:, 1])
    poses = np.column_stack([x0[0] + np.concatenate([[0.0], np.cumsum(dx)]),
                             x0[1] + np.concatenate([[0.0], np.cumsum(dy)]),
                             wrap(psi)])
    # first observation of each landmark (edges are in creation order)
    lm, first = np.unique(arrays.rb_lm, return_index=True)
    landmarks = arrays.landmarks.copy()
    p = poses[arrays.rb_pose[first]]
    r, b = arrays.rb_z[first, 0], arrays.rb_z[first, 1]
    landmarks[lm] = p[:, :2] + r[:, None] * np.column_stack([np.cos(b + p[:, 2]), np.sin(b + p[:, 2])])
    return poses, landmarks


# ----------------------------------------------------------------------------------------------------
# GTSAM graph construction
# ----------------------------------------------------------------------------------------------------
_RB_PERM = np.array([1, 0])  # DriveBot (range, bearing) → GTSAM (bearing, range)


def _odometry_factor(i, j, u, dt, info):
    measured = gtsam.Pose2(u[0] * dt, u[1] * dt, u[2] * dt)
    noise = gtsam.noiseModel.Gaussian.Information(info / dt ** 2)
    return gtsam.BetweenFactorPose2(X(i), X(j), measured, noise)


def _exact_odometry_factor(i, j, u, dt, info):
    """The DriveBot velocity-form kinematics error as a GTSAM CustomFactor (spec §8.3)."""
    u = np.array(u, dtype=float)

    def error(this, values, jacobians):
        a = values.atPose2(this.keys()[0])
        b = values.atPose2(this.keys()[1])
        psi = a.theta()
        c, s = math.cos(psi), math.sin(psi)
        ddx, ddy = b.x() - a.x(), b.y() - a.y()
        dpsi = (b.theta() - psi + math.pi) % (2 * math.pi) - math.pi
        e = np.array([(c * ddx + s * ddy) / dt, (-s * ddx + c * ddy) / dt, dpsi / dt]) - u
        if jacobians is not None:
            # GTSAM Pose2 retract: local (body-frame) translation increment, so ∂/∂ξ = (∂/∂x) · [R 0; 0 1].
            ja = np.array([[-c, -s, -ddx * s + ddy * c], [s, -c, -ddx * c - ddy * s], [0, 0, -1.0]]) / dt
            jb = np.array([[c, s, 0], [-s, c, 0], [0, 0, 1.0]]) / dt
            ra = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
            cb, sb = math.cos(b.theta()), math.sin(b.theta())
            rb = np.array([[cb, -sb, 0], [sb, cb, 0], [0, 0, 1.0]])
            jacobians[0] = ja @ ra
            jacobians[1] = jb @ rb
        return e

    return gtsam.CustomFactor(gtsam.noiseModel.Gaussian.Information(info), [X(i), X(j)], error)


def build_gtsam(arrays: GraphArrays, poses=None, landmarks=None, exact=False):
    """(NonlinearFactorGraph, Values) structurally equal to the DriveBot graph in ``arrays``."""
    poses = arrays.poses if poses is None else poses
    landmarks = arrays.landmarks if landmarks is None else landmarks
    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    prior = gtsam.noiseModel.Isotropic.Sigma(3, PRIOR_SIGMA)
    for i in np.flatnonzero(arrays.fixed):
        graph.add(gtsam.PriorFactorPose2(X(int(i)), gtsam.Pose2(*poses[i]), prior))
    make = _exact_odometry_factor if exact else _odometry_factor
    for i, j, u, dt, info in zip(arrays.odo_i.tolist(), arrays.odo_j.tolist(), arrays.odo_u,
                                 arrays.odo_dt.tolist(), arrays.odo_info):
        graph.add(make(i, j, u, dt, info))
    rb_info = arrays.rb_info[:, _RB_PERM][:, :, _RB_PERM]
    shared = np.all(rb_info == rb_info[:1]) if len(rb_info) else True
    shared_noise = gtsam.noiseModel.Gaussian.Information(rb_info[0]) if len(rb_info) and shared else None
    for k, (i, l) in enumerate(zip(arrays.rb_pose.tolist(), arrays.rb_lm.tolist())):
        noise = shared_noise if shared else gtsam.noiseModel.Gaussian.Information(rb_info[k])
        graph.add(gtsam.BearingRangeFactor2D(X(i), L(l), gtsam.Rot2(arrays.rb_z[k, 1]),
                                             float(arrays.rb_z[k, 0]), noise))
    used_poses = np.zeros(arrays.n_poses, bool)
    used_poses[arrays.odo_i] = used_poses[arrays.odo_j] = used_poses[arrays.rb_pose] = True
    used_poses |= arrays.fixed
    for i in np.flatnonzero(used_poses):
        values.insert(X(int(i)), gtsam.Pose2(*poses[i]))
    for l in np.unique(arrays.rb_lm):
        values.insert(L(int(l)), gtsam.Point2(*landmarks[l]))
    return graph, values


def gtsam_lm(graph, values, max_iterations=100):
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    t0 = time.perf_counter()
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    result = optimizer.optimize()
    elapsed = time.perf_counter() - t0
    return result, elapsed, optimizer.iterations()


def values_to_arrays(result, arrays: GraphArrays):
    poses = arrays.poses.copy()
    for i in range(arrays.n_poses):
        if result.exists(X(i)):
            p = result.atPose2(X(i))
            poses[i] = (p.x(), p.y(), p.theta())
    landmarks = arrays.landmarks.copy()
    for l in np.unique(arrays.rb_lm):
        landmarks[l] = result.atPoint2(L(int(l)))
    return poses, landmarks


def gtsam_isam2_stream(arrays: GraphArrays):
    """Feed the DriveBot stream to iSAM2 tick by tick; returns (total update time, final estimate).

    Tick k brings pose k (initialised by forward prediction from iSAM2's current estimate of pose k−1),
    its kinematics factor, its landmark factors and any new landmarks (initialised from the first
    observation at pose k's initial value). Only the ``update`` and ``calculateEstimate`` calls of the
    new pose are timed, which is what one DriveBot ``optimize()`` per tick corresponds to."""
    params = gtsam.ISAM2Params()
    isam = gtsam.ISAM2(params)
    n = arrays.n_poses
    rb_info = arrays.rb_info[:, _RB_PERM][:, :, _RB_PERM]
    rb_noise = gtsam.noiseModel.Gaussian.Information(rb_info[0])
    prior = gtsam.noiseModel.Isotropic.Sigma(3, PRIOR_SIGMA)
    odo_of = np.full(n, -1)
    odo_of[arrays.odo_j] = np.arange(len(arrays.odo_j))
    order = np.argsort(arrays.rb_pose, kind="stable")
    starts = np.searchsorted(arrays.rb_pose[order], np.arange(n + 1))
    seen = np.zeros(len(arrays.landmarks), bool)
    total = 0.0
    current = gtsam.Pose2(*arrays.poses[0])
    for k in range(n):
        graph = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        if k == 0:
            graph.add(gtsam.PriorFactorPose2(X(0), current, prior))
            pose = current
        else:
            m = odo_of[k]
            u, dt = arrays.odo_u[m], arrays.odo_dt[m]
            c, s = math.cos(current.theta()), math.sin(current.theta())
            pose = gtsam.Pose2(current.x() + dt * (c * u[0] - s * u[1]),
                               current.y() + dt * (s * u[0] + c * u[1]),
                               float(wrap(current.theta() + dt * u[2])))
            graph.add(_odometry_factor(k - 1, k, u, dt, arrays.odo_info[m]))
        values.insert(X(k), pose)
        for e in order[starts[k]:starts[k + 1]]:
            l = int(arrays.rb_lm[e])
            r, b = arrays.rb_z[e]
            if not seen[l]:
                seen[l] = True
                a = b + pose.theta()
                values.insert(L(l), gtsam.Point2(pose.x() + r * math.cos(a), pose.y() + r * math.sin(a)))
            graph.add(gtsam.BearingRangeFactor2D(X(k), L(l), gtsam.Rot2(b), float(r), rb_noise))
        t0 = time.perf_counter()
        isam.update(graph, values)
        current = isam.calculateEstimatePose2(X(k))
        total += time.perf_counter() - t0
    return total, isam.calculateEstimate()


def gtsam_pose_marginals(graph, result, pose_indices):
    """(time, covariances (N, 3, 3) in the world frame) of the given poses from gtsam.Marginals.

    GTSAM expresses a Pose2 covariance in the pose's tangent space (translation in the body frame);
    it is rotated to the world frame, Σ_w = B Σ Bᵀ with B = blkdiag(R(θ), 1), after the timed section."""
    t0 = time.perf_counter()
    marginals = gtsam.Marginals(graph, result)
    covs = np.array([marginals.marginalCovariance(X(int(i))) for i in pose_indices])
    elapsed = time.perf_counter() - t0
    th = np.array([result.atPose2(X(int(i))).theta() for i in pose_indices])
    B = np.zeros((len(th), 3, 3))
    B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1], B[:, 2, 2] = np.cos(th), -np.sin(th), np.sin(th), np.cos(th), 1
    return elapsed, B @ covs @ np.swapaxes(B, 1, 2)


def gtsam_chi2(graph, values) -> float:
    return 2.0 * graph.error(values)


# ----------------------------------------------------------------------------------------------------
# the three benchmarks
# ----------------------------------------------------------------------------------------------------
def _best(fn, repeats):
    best, out = math.inf, None
    for _ in range(repeats):
        t, out = fn()
        best = min(best, t)
    return best, out


def bench_lm(graph, repeats=3, exact=False):
    """Benchmark 1 on a full DriveBot graph: both optimisers from the dead-reckoning initialisation."""
    arrays = arrays_from_graph(graph)
    p0, l0 = dead_reckoning(arrays)

    def helpers_run():
        set_graph_estimates(graph, arrays, p0, l0)
        t0 = time.perf_counter()
        graph.initialize_optimization()
        chi2 = graph.optimize(50, algorithm="lm")
        return time.perf_counter() - t0, (chi2, graph.iterations, list(graph.statistics))

    t_h, (chi2_h, it_h, stats) = _best(helpers_run, repeats)

    def helpers_gtsam_schedule_run():
        set_graph_estimates(graph, arrays, p0, l0)
        t0 = time.perf_counter()
        graph.initialize_optimization()
        chi2 = graph.optimize(100, algorithm="lm-gtsam")
        return time.perf_counter() - t0, (chi2, graph.iterations)

    t_hs, (chi2_hs, it_hs) = _best(helpers_gtsam_schedule_run, repeats)
    # time at which the helpers' LM met GTSAM's stopping rule (relative χ² decrease < 1e-5)
    t_conv = None
    for prev, cur in zip(stats[:-1], stats[1:]):
        if prev["chi2"] - cur["chi2"] < 1e-5 * prev["chi2"]:
            t_conv = cur["time"]
            break
    gg, values = build_gtsam(arrays, p0, l0)

    def gtsam_run():
        result, t, it = gtsam_lm(gg, values)
        return t, (result, it)

    t_g, (result, it_g) = _best(gtsam_run, repeats)
    out = {"n_poses": arrays.n_poses, "n_landmarks": len(arrays.landmarks), "n_odo": len(arrays.odo_i),
           "n_rb": len(arrays.rb_pose), "helpers_time": t_h, "helpers_iterations": it_h, "helpers_chi2": chi2_h,
           "helpers_time_to_converge": t_conv, "helpers_sched_time": t_hs, "helpers_sched_iterations": it_hs,
           "helpers_sched_chi2": chi2_hs, "gtsam_time": t_g, "gtsam_iterations": it_g,
           "gtsam_chi2": gtsam_chi2(gg, result), "gtsam_graph": gg, "gtsam_result": result, "arrays": arrays}
    if exact:
        ge, ve = build_gtsam(arrays, p0, l0, exact=True)
        res_e, t_e, it_e = gtsam_lm(ge, ve)
        out.update(exact_time=t_e, exact_iterations=it_e, exact_chi2=gtsam_chi2(ge, res_e))
    return out


def bench_marginals(graph, lm, repeats=3):
    """Benchmark 3: every free pose's covariance, helpers (Takahashi on the LDLᵀ factor) vs gtsam.Marginals."""
    from helpers.graph import VertexSE2

    poses = [v for v in graph.vertices() if isinstance(v, VertexSE2)]
    free = [v for v in poses if not v.fixed]
    idx = np.array([i for i, v in enumerate(poses) if not v.fixed])

    def helpers_run():
        t0 = time.perf_counter()
        m = graph.compute_marginals(free)
        return time.perf_counter() - t0, m

    t_h, m = _best(helpers_run, repeats)
    t_g, covs = _best(lambda: gtsam_pose_marginals(lm["gtsam_graph"], lm["gtsam_result"], idx), repeats)
    H = np.array([m[v] for v in free])
    rel = float(np.max(np.abs(H - covs)) / np.max(np.abs(covs)))
    return {"n": len(free), "helpers_time": t_h, "gtsam_time": t_g, "max_rel_diff": rel}


def bench_isam2(seed=0):
    """Benchmark 2: q2_b optimising every tick (helpers) vs iSAM2 fed the same stream."""
    from helpers.drivebot import run_question

    t0 = time.perf_counter()
    res = run_question("q2_b", seed=seed, optimization_period=1)
    wall = time.perf_counter() - t0
    times = np.asarray(res.optimization_times, dtype=float)
    helpers_total = float(np.nansum(times))
    sched = run_question("q2_b", seed=seed, optimization_period=1, optimization_algorithm="lm-gtsam")
    sched_total = float(np.nansum(np.asarray(sched.optimization_times, dtype=float)))
    run_question("q2_b", seed=seed, optimization_period=5, optimization_algorithm="incremental")  # compiled kernels loaded
    inc = run_question("q2_b", seed=seed, optimization_period=1, optimization_algorithm="incremental")
    inc_total = float(np.nansum(np.asarray(inc.optimization_times, dtype=float)))
    arrays = arrays_from_graph(res.system.graph)
    t_g, est = gtsam_isam2_stream(arrays)
    graph, _ = build_gtsam(arrays)
    return {"steps": arrays.n_poses, "optimisations": int(np.sum(np.isfinite(times))),
            "helpers_total": helpers_total, "helpers_run_wall": wall, "gtsam_total": t_g,
            "helpers_sched_total": sched_total, "helpers_sched_final_chi2": float(np.asarray(sched.chi2_history)[-1]),
            "helpers_sched_iterations": float(np.nanmean(np.asarray(sched.optimization_iterations, dtype=float))),
            "helpers_iterations": float(np.nanmean(np.asarray(res.optimization_iterations, dtype=float))),
            "incremental_total": inc_total, "incremental_final_chi2": float(np.asarray(inc.chi2_history)[-1]),
            "incremental_restarts": inc.system._smoother.restarts,
            "incremental_solves": float(np.mean(inc.optimization_iterations)),
            "helpers_final_chi2": float(np.asarray(res.chi2_history)[-1]),
            "gtsam_final_chi2": gtsam_chi2(graph, est)}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--exact", action="store_true", help="also run GTSAM LM with the exact velocity-form "
                        "kinematics error (CustomFactor) as a χ² oracle")
    args = parser.parse_args(argv)
    from helpers.drivebot import run_question

    print(f"# DriveBot benchmark  {datetime.datetime.now(datetime.timezone.utc):%Y-%m-%d %H:%M} UTC  "
          f"seed={args.seed}  best of {args.repeats}")
    full = run_question("q3_a", seed=args.seed)
    graph = full.system.graph
    lm = bench_lm(graph, args.repeats, args.exact)
    print(f"\n(1) q3_a full graph, one LM optimisation from dead reckoning: {lm['n_poses']} poses, "
          f"{lm['n_landmarks']} landmarks, {lm['n_odo']} kinematics + {lm['n_rb']} range-bearing edges")
    conv = lm["helpers_time_to_converge"]
    print(f"    helpers  optimize(50): {lm['helpers_time']:.3f} s  {lm['helpers_iterations']} iterations  "
          f"χ² {lm['helpers_chi2']:.3f}" + (f"  (GTSAM's stopping rule met after {conv:.3f} s)" if conv else ""))
    print(f"    helpers  optimize(algorithm='lm-gtsam'): {lm['helpers_sched_time']:.3f} s  "
          f"{lm['helpers_sched_iterations']} iterations  χ² {lm['helpers_sched_chi2']:.3f}  (GTSAM's LM schedule and "
          f"stopping rule: the like-for-like run)")
    print(f"    GTSAM LM             : {lm['gtsam_time']:.3f} s  {lm['gtsam_iterations']} iterations  "
          f"χ² {lm['gtsam_chi2']:.3f}  (BetweenFactorPose2 kinematics: a slightly different error model)")
    if args.exact:
        print(f"    GTSAM LM exact model : {lm['exact_time']:.3f} s  {lm['exact_iterations']} iterations  "
              f"χ² {lm['exact_chi2']:.6f}  (CustomFactor; |Δχ²|/χ² = "
              f"{abs(lm['exact_chi2'] - lm['helpers_chi2']) / lm['helpers_chi2']:.1e} vs helpers)")
    r1 = lm["helpers_sched_time"] / lm["gtsam_time"]
    r1_coursework = lm["helpers_time"] / lm["gtsam_time"]
    mg = bench_marginals(graph, lm, args.repeats)
    print(f"\n(3) all {mg['n']} free pose marginals of the optimised q3_a graph")
    print(f"    helpers compute_marginals: {mg['helpers_time']:.3f} s   GTSAM Marginals: {mg['gtsam_time']:.3f} s   "
          f"max relative difference {mg['max_rel_diff']:.1e} (different kinematics error model)")
    r3 = mg["helpers_time"] / mg["gtsam_time"]
    it = bench_isam2(args.seed)
    print(f"\n(2) q2_b optimising every step: {it['steps']} ticks, {it['optimisations']} optimisations")
    print(f"    helpers Σ optimize() incl. structure updates: {it['helpers_total']:.3f} s  (whole run incl. simulation "
          f"{it['helpers_run_wall']:.1f} s)  final χ² {it['helpers_final_chi2']:.3f}  "
          f"(coursework LM, {it['helpers_iterations']:.1f} iterations per tick)")
    print(f"    helpers Σ optimize(), algorithm 'lm-gtsam': {it['helpers_sched_total']:.3f} s  final χ² "
          f"{it['helpers_sched_final_chi2']:.3f}  ({it['helpers_sched_iterations']:.1f} iterations per tick)")
    print(f"    helpers Σ optimize(), algorithm 'incremental': {it['incremental_total']:.3f} s  final χ² "
          f"{it['incremental_final_chi2']:.3f}  ({it['incremental_solves']:.2f} Gauss–Newton solves per tick on the "
          f"kept factor, iSAM2's relinearisation rule; {it['incremental_restarts']} restarts)")
    print(f"    GTSAM iSAM2 Σ update: {it['gtsam_total']:.3f} s  final χ² {it['gtsam_final_chi2']:.3f}")
    r2 = it["incremental_total"] / it["gtsam_total"]
    r2_batch = it["helpers_sched_total"] / it["gtsam_total"]
    r2_coursework = it["helpers_total"] / it["gtsam_total"]
    print("\nratios helpers/GTSAM (goal ≤ 1.0 each):")
    print(f"    (1) LM q3_a           {r1:6.2f}x  {'met' if r1 <= 1 else 'NOT met'}  (same LM schedule and stopping "
          f"rule as GTSAM; the coursework's LM with its 1e-12 tolerances: {r1_coursework:.2f}x)")
    print(f"    (2) q2_b every step   {r2:6.2f}x  {'met' if r2 <= 1 else 'NOT met'}  (helpers 'incremental' vs iSAM2, "
          f"both incremental; a batch re-solve per tick with GTSAM's LM schedule: {r2_batch:.2f}x, "
          f"coursework LM: {r2_coursework:.2f}x)")
    print(f"    (3) pose marginals    {r3:6.2f}x  {'met' if r3 <= 1 else 'NOT met'}")
    return r1, r2, r3


if __name__ == "__main__":
    main(sys.argv[1:])
