"""A DriveBot SLAM graph for GTSAM: plain arrays from the workbook's graph, the structurally equal GTSAM
graph, GTSAM's LM, iSAM2 fed tick by tick, pose marginals and χ² (used by ``benchmarks/drivebot.py``).

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

import dataclasses
import math
import time

import gtsam
import numpy as np

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
