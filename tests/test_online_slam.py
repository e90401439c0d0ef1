"""The online front-end on hand-made worlds: covariance columns, the window, the models, the confirmation rule,
every algorithm through the front-end, the report's metrics, bad input."""
import math

import numpy as np
import pytest

from helpers.graph import EdgeRangeBearing, EdgeSE2, VertexPointXY, VertexSE2
from helpers.advanced.fast_graph import FastOptimizer
from helpers.advanced.online_slam import (ALGORITHMS, ConfirmationRules, OnlineFrontEnd, RangeBearingModel,
                                 association_scores, best_matching)
from helpers.advanced.online_slam.covariance import MarginalColumns, hessian_factors, ldl_solve_columns
from helpers.advanced.online_slam.metrics import map_errors
from helpers.advanced.online_slam.models import motion_jacobians, unwrap_bearings
from helpers.advanced.online_slam.decisions import largest_sd
from helpers.advanced.online_slam.scan_kernels import block_largest_sd
from helpers.advanced.online_slam.window import LocalWindow

R = np.diag([0.05, 0.01]) ** 2
ODO_INFO = np.linalg.inv(np.diag([0.02, 0.02, 0.005]) ** 2)


class World:
    """A robot driving along x in steps of ``step`` m past point landmarks, with an online front-end."""

    def __init__(self, landmarks, algorithm="jcbb", rules=None, max_range=6.0, noise=0.0, seed=0, **options):
        self.landmarks = np.asarray(landmarks, dtype=float)
        self.graph = FastOptimizer()
        self.truth_pose = np.zeros(3)
        first = VertexSE2(None, np.zeros(3), fixed=True)
        self.graph.add_vertex(first)
        self.model = RangeBearingModel(max_range, range_margin=0.5)
        self.fe = OnlineFrontEnd(self.graph, self.model, algorithm, rules=rules, **options)
        self.fe.start(first)
        self.pose = first
        self.noise = noise
        self.rng = np.random.default_rng(seed)
        self.truth = []

    def move(self, step=0.5):
        z = np.array([step, 0.0, 0.0])
        v = VertexSE2(None, self.pose.estimate + z)
        self.graph.add_vertex(v)
        e = EdgeSE2([self.pose, v], measurement=z, information=ODO_INFO)
        self.graph.add_edge(e)
        self.fe.add_pose(e)
        self.pose = v
        self.truth_pose = self.truth_pose + z

    def scan(self, extra=None, drop=()):
        """Observe every landmark in range (except ``drop``), plus extra (2, k) spurious observations."""
        p = self.truth_pose
        d = self.landmarks - p[:2]
        r = np.hypot(d[:, 0], d[:, 1])
        seen = [i for i in np.flatnonzero(r <= self.model.max_range) if i not in drop]
        Z = np.vstack([r[seen], np.arctan2(d[seen, 1], d[seen, 0]) - p[2]])
        if self.noise:
            Z = Z + self.noise * np.sqrt(np.diag(R))[:, None] * self.rng.standard_normal(Z.shape)
        ids = list(np.asarray(seen) + 1)
        if extra is not None:
            Z = np.hstack([Z, np.asarray(extra, dtype=float)])
            ids += [0] * np.asarray(extra).shape[1]
        self.truth.extend(ids)
        return self.fe.process_scan(Z, R)

    def optimise(self):
        self.graph.initialize_optimization()
        self.graph.optimize(10, algorithm="lm-gtsam")
        self.fe.refresh()

    def run(self, steps, every=4, **scan_options):
        for k in range(steps):
            self.move()
            self.scan(**scan_options)
            if (k + 1) % every == 0:
                self.optimise()
        self.optimise()
        return association_scores(self.fe.observation_assignment(), np.array(self.truth))


LANDMARKS = [(1.0, 2.0), (3.0, -2.5), (5.0, 1.5), (7.5, -1.0), (9.0, 2.5), (11.0, -2.0)]


# ------------------------------------------------------------------------------------------ covariance
def _small_graph():
    g = FastOptimizer()
    poses = [VertexSE2(None, [k * 1.0, 0.1 * k, 0.05 * k], fixed=(k == 0)) for k in range(5)]
    for v in poses:
        g.add_vertex(v)
    for a, b in zip(poses, poses[1:]):
        g.add_edge(EdgeSE2([a, b], measurement=[1.0, 0.1, 0.05], information=ODO_INFO))
    lms = [VertexPointXY(None, [2.0, 3.0]), VertexPointXY(None, [4.0, -2.0])]
    for m in lms:
        g.add_vertex(m)
    for v in poses[1:]:
        for m in lms:
            d = m.estimate - v.estimate[:2]
            z = [math.hypot(*d), math.atan2(d[1], d[0]) - v.estimate[2] + 0.01]
            g.add_edge(EdgeRangeBearing([v, m], measurement=z, information=np.linalg.inv(R)))
    g.initialize_optimization()
    g.optimize(5)
    return g, poses, lms


def test_columns_give_the_joint_covariance_of_the_dense_inverse():
    g, poses, lms = _small_graph()
    cols = MarginalColumns()
    verts = [poses[4], lms[1], poses[2], lms[0], poses[0]]
    assert cols.refresh(g, verts)
    J = cols.joint(verts)
    dense = np.linalg.inv(g.hessian().toarray())
    idx = np.concatenate([v.hessian_index + np.arange(type(v).dimension) for v in verts[:-1]])
    np.testing.assert_allclose(J[:-3, :-3], dense[np.ix_(idx, idx)], rtol=1e-9, atol=1e-12)
    assert np.all(J[-3:] == 0) and np.all(J[:, -3:] == 0)          # the fixed pose has no covariance
    assert cols.columns_solved == 3 + 2 + 3 + 2
    factors = hessian_factors(g)
    np.testing.assert_allclose(ldl_solve_columns(factors, [0, 5]), dense[:, [0, 5]], rtol=1e-9, atol=1e-12)
    given = MarginalColumns()                          # the caller's factorisation: the same numbers, none made
    assert given.refresh(g, verts, factors) and np.array_equal(given.joint(verts), J)
    assert not given.refresh(g, verts, None)          # not positive definite: the previous columns stay
    assert np.array_equal(given.joint(verts), J)


@pytest.mark.parametrize("seed", range(4))
def test_columns_on_the_ancestor_closure_equal_the_full_sweep(seed):
    """The restricted solve reads only the elimination-tree ancestors of the registered rows, and gives the same
    numbers, to the last bit, as the sweep over the whole factor (and H⁻¹ to round-off)."""
    import qdldl
    import scipy.sparse as sp

    from helpers.advanced.online_slam.covariance import _ancestor_closure, _solve_unit_columns_on

    rng = np.random.default_rng(seed)
    n = 60
    A = sp.random(n, n, density=0.04, random_state=np.random.RandomState(seed))
    H = (A @ A.T + sp.eye(n) * 0.5).tocsc()
    solver = qdldl.Solver(sp.triu(H, format="csc"), upper=True)
    lower, d, perm = solver.factors()
    rows = rng.choice(n, size=5, replace=False)
    full = ldl_solve_columns((lower, d, perm), rows)
    pinv = np.empty(n, dtype=np.int64)
    pinv[perm] = np.arange(n)
    lp, li = lower.indptr.astype(np.int64), lower.indices.astype(np.int64)
    keep = _ancestor_closure(n, lp, li, pinv[rows])
    assert 0 < keep.size < n
    slot = np.full(n, -1, dtype=np.int64)
    slot[keep] = np.arange(keep.size)
    part = _solve_unit_columns_on(lp, li, np.ascontiguousarray(lower.data), np.asarray(d, dtype=float), pinv,
                                  rows.astype(np.int64), keep, slot)
    assert np.array_equal(part, full[perm[keep]])
    np.testing.assert_allclose(part, np.linalg.inv(H.toarray())[np.ix_(perm[keep], rows)], rtol=1e-9, atol=1e-12)


def test_columns_only_for_registered_vertices():
    g, poses, lms = _small_graph()
    cols = MarginalColumns()
    cols.refresh(g, [poses[1]])
    with pytest.raises(ValueError, match="vertices"):
        cols.joint([lms[0]])


# ------------------------------------------------------------------------------------------ window, models
def test_window_is_the_linear_gaussian_propagation():
    rng = np.random.default_rng(3)
    w = LocalWindow()
    w.reset([3])
    F1, F2 = np.eye(3) + 0.1 * rng.standard_normal((3, 3)), np.eye(3) + 0.1 * rng.standard_normal((3, 3))
    Q1, Q2 = np.diag([0.01, 0.02, 0.003]), np.diag([0.02, 0.01, 0.001])
    Gx, Gz = rng.standard_normal((2, 3)), rng.standard_normal((2, 2))
    w.predict(F1, Q1)
    w.add_landmark("m", np.zeros(2), Gx, Gz, R)
    w.predict(F2, Q2)
    # x2 = F2 F1 a + F2 n1 + n2;  m = Gx (F1 a + n1) + Gz v
    Saa = np.diag([0.5, 0.4, 0.1])
    A_x, A_m = F2 @ F1, Gx @ F1
    P_xx = A_x @ Saa @ A_x.T + F2 @ Q1 @ F2.T + Q2
    P_mm = A_m @ Saa @ A_m.T + Gx @ Q1 @ Gx.T + Gz @ R @ Gz.T
    P_xm = A_x @ Saa @ A_m.T + F2 @ Q1 @ Gx.T
    got = w.covariance(["m"], Saa)
    np.testing.assert_allclose(got[:3, :3], P_xx, atol=1e-12)
    np.testing.assert_allclose(got[3:, 3:], P_mm, atol=1e-12)
    np.testing.assert_allclose(got[:3, 3:], P_xm, atol=1e-12)
    w.remove("m")
    assert w.keys == [] and w.P.shape == (3, 3)


def test_compiled_window_prediction_equals_the_numpy_reference():
    rng = np.random.default_rng(5)
    for trial in range(50):
        compiled, reference = LocalWindow(), LocalWindow()
        for w in (compiled, reference):
            w.reset([3, 3] if trial % 2 else [3], pose_anchor=trial % 2)
        for i in range(int(rng.integers(0, 4))):
            Gx, Gz = rng.standard_normal((2, 3)), rng.standard_normal((2, 2))
            for w in (compiled, reference):
                w.add_landmark(i, rng.standard_normal(2), Gx, Gz, R)
        for _ in range(5):
            F = np.eye(3) + 0.1 * rng.standard_normal((3, 3))
            B = rng.standard_normal((3, 3))
            compiled.predict(F, 0.01 * B @ B.T)
            reference.predict_reference(F, 0.01 * B @ B.T)
        np.testing.assert_allclose(compiled.A, reference.A, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(compiled.P, reference.P, rtol=1e-13, atol=1e-14)
        assert np.array_equal(compiled.P, compiled.P.T)
        na = sum(compiled.anchor_dims)
        M = rng.standard_normal((na + 4, na + 4))
        sigma = M @ M.T
        for keys in ([], list(compiled.keys), list(compiled.keys)[::-1]):
            got, ref = compiled.covariance(keys, sigma), compiled.covariance_reference(keys, sigma)
            np.testing.assert_allclose(got, ref, rtol=1e-12, atol=1e-12)
            assert np.array_equal(got, got.T)
        np.testing.assert_allclose(compiled.pose_covariance(sigma[:na, :na]),
                                   compiled.covariance_reference([], sigma[:na, :na]), rtol=1e-12, atol=1e-12)


def test_models_inverse_prediction_and_spaces():
    model = RangeBearingModel(10.0)
    x = np.array([1.0, -2.0, 0.7])
    z = np.array([4.0, -2.9])
    m, Gx, Gz = model.inverse(x, z)
    zhat = model.predict(x, m[None], jacobians=False)[0][0]
    assert zhat[0] == pytest.approx(4.0) and math.remainder(zhat[1] - z[1], 2 * math.pi) == pytest.approx(0.0)
    h = 1e-6
    num = np.column_stack([(model.inverse(x, z + h * e)[0] - model.inverse(x, z - h * e)[0]) / (2 * h)
                           for e in np.eye(2)])
    np.testing.assert_allclose(Gz, num, atol=1e-6)
    q, _, _, Rk = model.association_terms(x, m[None], R)
    _, Y = model.association_observations(z[:, None], q)
    np.testing.assert_allclose(q[0], Y[:, 0], atol=1e-9)          # Cartesian space: the same point
    polar = RangeBearingModel(10.0, association_space="polar")
    zh, hx, hm, Rp = polar.association_terms(x, m[None], R)
    np.testing.assert_allclose(Rp[0], R)
    p, o = unwrap_bearings(np.array([[1.0, 3.1], [1.0, 0.0]]), np.array([[1.0, 1.0], [-3.1, 0.1]]))
    assert abs(o[1, 0] - p[0, 1]) == pytest.approx(2 * math.pi - 6.2)   # wrapped difference across ±π
    assert o[1, 1] - p[1, 1] == pytest.approx(0.1)


@pytest.mark.parametrize("fov", [2 * math.pi, math.pi, 0.5])
def test_compiled_footprint_and_density_equal_their_numpy_references(fov):
    rng = np.random.default_rng(11)
    model = RangeBearingModel(10.0, field_of_view=fov)
    for _ in range(100):
        k = int(rng.integers(0, 30))
        x, points = rng.normal(size=3) * [5.0, 5.0, 3.0], rng.normal(size=(k, 2)) * 8.0
        widen = (abs(rng.normal()), 0.2 * abs(rng.normal()))
        # the two paths decide r ≤ r_max + dr and |β| ≤ fov/2 + db with their own round-off: no point of these draws
        # lies within 1e-9 of the footprint's edge (the closest is 6e-4 away), so the decisions are not a coin flip
        q = points - x[:2]
        beta = np.abs(np.angle(np.exp(1j * (np.arctan2(q[:, 1], q[:, 0]) - x[2]))))
        assert np.all(np.abs(np.hypot(q[:, 0], q[:, 1]) - (10.0 + widen[0])) > 1e-9)
        assert fov == 2 * math.pi or np.all(np.abs(beta - (0.5 * fov + widen[1])) > 1e-9)
        assert np.array_equal(model.candidates(x, points, widen), model.footprint_reference(x, points, widen))
        k = max(k // 3, 1)
        A = rng.normal(size=(3 + 2 * k, 3 + 2 * k))
        B = rng.normal(size=(2, 2))
        sig_v, R_obs = 0.01 * A @ A.T, B @ B.T + 0.01 * np.eye(2)
        means = rng.normal(size=(k, 2)) * 8.0
        got, ref = model.scan_density(x, means, sig_v, R_obs), model.scan_density_reference(x, means, sig_v, R_obs)
        for a, b in zip(got, ref, strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
        C, Rk = got[1], got[2]
        blocks = C.reshape(k, 2, k, 2)[np.arange(k), :, np.arange(k), :] - Rk
        # bit for bit by construction: the kernel does largest_sd's IEEE operations in the same order (no fastmath,
        # so no FMA contraction or reassociation), and sqrt is correctly rounded on both paths
        assert np.array_equal(block_largest_sd(C, Rk), largest_sd(blocks))
    polar = RangeBearingModel(10.0, association_space="polar")        # no kernel: the reference itself
    got = polar.scan_density(x, means, sig_v, R_obs)
    for a, b in zip(got, polar.scan_density_reference(x, means, sig_v, R_obs), strict=True):
        assert np.array_equal(a, b)


def test_motion_jacobians_of_a_between_edge():
    a, b = VertexSE2(None, [0.0, 0.0, 0.3]), VertexSE2(None, [0.0, 0.0, 0.0])
    z = np.array([1.0, 0.2, 0.1])
    c, s = math.cos(0.3), math.sin(0.3)
    b.set_estimate([c - 0.2 * s, s + 0.2 * c, 0.4])
    g = FastOptimizer()
    g.add_vertex(a)
    g.add_vertex(b)
    e = EdgeSE2([a, b], measurement=z, information=ODO_INFO)
    g.add_edge(e)
    F, Q = motion_jacobians(e)
    jk, jn = e.jacobians()
    np.testing.assert_allclose(jn @ F, -jk, atol=1e-12)
    np.testing.assert_allclose(jn @ Q @ jn.T, np.linalg.inv(ODO_INFO), atol=1e-12)

    class Frozen(EdgeSE2):                       # the new pose does not enter the error: nothing to propagate
        @staticmethod
        def evaluate(states, z, params, jacobians=True):
            err, (ji, jj) = EdgeSE2.evaluate(states, z, params)
            return err, [ji, 0.0 * jj]

    with pytest.raises(ValueError, match="Frozen cannot propagate a pose"):
        motion_jacobians(Frozen([a, b], measurement=z, information=ODO_INFO))


# ------------------------------------------------------------------------------------------ through the front-end
@pytest.mark.parametrize("algorithm", sorted(ALGORITHMS))
def test_every_algorithm_maps_a_noise_free_world(algorithm):
    w = World(LANDMARKS, algorithm)
    scores = w.run(24)
    assert scores["precision"] == 1.0 and scores["recall"] == 1.0
    assert scores["n_landmarks"] == len(LANDMARKS) == len(w.fe.confirmed_tracks())
    est = {t.key: t.vertex.estimate for t in w.fe.confirmed_tracks()}
    true = {i + 1: np.array(p) for i, p in enumerate(LANDMARKS)}
    assert map_errors(best_matching(w.fe.observation_assignment(), np.array(w.truth)), est, true).max() < 1e-6


@pytest.mark.parametrize("algorithm", ["mahalanobis", "jcbb"])
def test_noisy_world_with_clutter(algorithm):
    rng = np.random.default_rng(5)
    w = World(LANDMARKS, algorithm, noise=1.0, seed=5)
    for k in range(24):
        w.move()
        r, b = 6.0 * np.sqrt(rng.random(2)), rng.uniform(-math.pi, math.pi, 2)
        w.scan(extra=np.vstack([r, b]))
        if (k + 1) % 4 == 0:
            w.optimise()
    s = association_scores(w.fe.observation_assignment(), np.array(w.truth))
    assert s["precision"] == 1.0 and s["recall"] > 0.9 and s["n_matched"] == len(LANDMARKS)


def test_confirmation_rule_on_hand_made_scans():
    rules = ConfirmationRules(n_confirm=3, n_miss=2, max_age=None)
    w = World([(2.0, 1.0)], "jcbb", rules=rules)
    res = [w.scan() for _ in range(2)]
    assert res[0].new == [0] and w.fe.tracks[0].status == "tentative" and w.graph.number_of_edges() == 0
    assert res[1].labels.tolist() == [0] and res[1].confirmed == []
    third = w.scan()
    assert third.confirmed == [0] and w.fe.tracks[0].status == "confirmed"
    assert w.graph.number_of_edges() == 3                       # the two waiting observations and this one
    # a spurious observation starts a tentative landmark that is dropped after n_miss scans without it
    spurious = w.scan(extra=[[3.0], [-1.5]])
    key = spurious.new[0]
    w.scan()
    assert w.fe.tracks[key].status == "tentative"
    gone = w.scan()
    assert gone.dropped == [key] and w.fe.tracks[key].status == "dropped"
    assert w.graph.number_of_edges() == 6                        # nothing of the spurious one reached the graph


def test_tentative_landmarks_expire_and_n_confirm_one_is_immediate():
    w = World([(2.0, 1.0)], "jcbb", rules=ConfirmationRules(n_confirm=3, n_miss=5, max_age=2))
    w.scan()
    w.scan(drop=[0])
    res = w.scan(drop=[0])
    assert res.dropped == [0]
    w1 = World([(2.0, 1.0)], "jcbb", rules=ConfirmationRules(n_confirm=1))
    first = w1.scan()
    assert first.confirmed == [0] and w1.graph.number_of_edges() == 1


def test_exclusion_gate_discards_an_observation_next_to_a_landmark():
    w = World([(2.0, 1.0)], "jcbb", rules=ConfirmationRules(n_confirm=1, exclusion_n_sigma=5.0))
    w.scan()
    w.optimise()
    z = w.model.predict(w.truth_pose, np.array([[2.0, 1.0]]), jacobians=False)[0][0]
    out = w.scan(extra=[[z[0] + 0.2], [z[1]]])                  # 4σ in range from the landmark
    assert out.labels[-1] == -1 and out.new == []
    far = w.scan(extra=[[z[0] + 2.0], [z[1]]])
    assert far.new and far.labels[-1] == far.new[0]


def test_empty_scans_and_scans_without_candidates_are_normal():
    w = World([(2.0, 1.0)], "jcbb")
    out = w.fe.process_scan(np.zeros((2, 0)), R)
    assert out.labels.size == 0 and out.candidates == []
    w.scan()
    out = w.fe.process_scan(np.zeros((2, 0)), R)                  # a candidate, no observation
    assert out.candidates == [0] and out.association is None
    far = World([(50.0, 1.0)], "jcbb")
    assert far.fe.process_scan(np.array([[3.0], [0.5]]), R).new == [0]   # an observation, no candidate


# ------------------------------------------------------------------------------------------ metrics
def test_metrics_on_hand_made_cases():
    truth = np.array([1, 1, 1, 2, 2, 0, 3, 3])
    assigned = np.array([7, 7, 8, 9, 9, 9, -1, 8])
    assert best_matching(assigned, truth) == {7: 1, 9: 2, 8: 3}
    s = association_scores(assigned, truth)
    assert s["n_pairings"] == 7 and s["n_correct"] == 5           # 8↔3 holds one of obs 2 / obs 7 rightly
    assert s["precision"] == pytest.approx(5 / 7) and s["recall"] == pytest.approx(5 / 7)
    assert s["agreement"] == pytest.approx(5 / 8) and s["n_clutter_paired"] == 1
    assert s["n_landmarks"] == 3 and s["n_true_landmarks"] == 3
    none = association_scores(np.full(3, -1), np.array([1, 2, 0]))
    assert math.isnan(none["precision"]) and none["recall"] == 0.0
    np.testing.assert_allclose(map_errors({7: 1}, {7: [1.0, 1.0]}, {1: [1.0, 4.0]}), [3.0])
    with pytest.raises(ValueError, match="same length"):
        best_matching([1, 2], [1])


# ------------------------------------------------------------------------------------------ bad input
def test_bad_input_names_the_argument():
    g = FastOptimizer()
    model = RangeBearingModel(5.0)
    with pytest.raises(ValueError, match="data_association"):
        OnlineFrontEnd(g, model, "icp")
    with pytest.raises(ValueError, match="algorithm_options"):
        OnlineFrontEnd(g, model, "jcbb", algorithm_options={"alpha": 0.1})
    with pytest.raises(ValueError, match="n_sigma"):
        OnlineFrontEnd(g, model, "jcbb", n_sigma=-1)
    with pytest.raises(ValueError, match="n_confirm"):
        ConfirmationRules(n_confirm=0)
    with pytest.raises(ValueError, match="exclusion_n_sigma"):
        ConfirmationRules(exclusion_n_sigma=0.0)
    with pytest.raises(ValueError, match="max_range"):
        RangeBearingModel(-1.0)
    with pytest.raises(ValueError, match="association_space"):
        RangeBearingModel(5.0, association_space="spherical")
    w = World([(2.0, 1.0)], "jcbb")
    with pytest.raises(ValueError, match="Z"):
        w.fe.process_scan(np.zeros((3, 1)), R)
    with pytest.raises(ValueError, match="R"):
        w.fe.process_scan(np.array([[1.0], [0.0]]), -R)
    with pytest.raises(ValueError, match="information"):
        w.fe.process_scan(np.array([[1.0], [0.0]]), R, information=np.eye(3))
    # the compiled paths read exactly the shapes they expect: anything else is refused before them
    x = np.zeros(3)
    with pytest.raises(ValueError, match="points must be a"):
        model.candidates(x, np.zeros((4, 3)), (1.0, 0.1))
    with pytest.raises(ValueError, match="x must be a pose"):
        model.candidates(np.zeros(2), np.zeros((4, 2)), (1.0, 0.1))
    with pytest.raises(ValueError, match="sig_v must be"):
        model.scan_density(x, np.zeros((2, 2)), np.eye(5), R)
    with pytest.raises(ValueError, match="means must be a"):
        model.scan_density(x, np.zeros(4), np.eye(7), R)
    window = LocalWindow()
    window.reset([3, 3])
    with pytest.raises(ValueError, match="F and Q must be"):
        window.predict(np.eye(2), np.eye(3))
    with pytest.raises(ValueError, match="sigma must be a square covariance of the 6 anchor rows"):
        window.covariance([], np.eye(4))
    with pytest.raises(ValueError, match="sigma must be a square"):
        window.pose_covariance(np.zeros((6, 5)))
    assert window.P.shape == (3, 3) and np.array_equal(window.A[:, 3:], np.zeros((3, 3)))   # nothing changed


def test_relative_sigma_from_the_density_equals_the_state_form():
    from helpers.advanced.online_slam.decisions import relative_sigma
    w = World(LANDMARKS, "jcbb")
    checked = 0
    for k in range(12):
        w.move()
        w.scan()
        if (k + 1) % 4 == 0:
            w.optimise()
        x = w.fe.pose.estimate
        wkeys, gidx = w.fe._candidates(x)
        if not len(wkeys) + len(gidx):
            continue
        yhat, C, Rk, sig_v, means = w.fe._density(x, wkeys, gidx, R)
        np.testing.assert_allclose(w.fe._relative_sigma(x, means, sig_v, C, Rk), relative_sigma(x, means, sig_v),
                                   rtol=1e-9, atol=1e-12)
        checked += 1
    assert checked >= 10


def test_largest_sd_is_the_root_of_the_largest_eigenvalue_and_rejects_bad_shapes():
    from helpers.advanced.online_slam.decisions import largest_sd
    A = np.random.default_rng(2).normal(size=(6, 2, 2))
    P = A @ A.transpose(0, 2, 1)
    np.testing.assert_allclose(largest_sd(P), np.sqrt(np.linalg.eigvalsh(P)[:, -1]), rtol=1e-12)
    for bad in (np.eye(2), np.zeros((3, 3, 3)), np.zeros((2, 2, 1))):
        with pytest.raises(ValueError, match="P must be a"):
            largest_sd(bad)


def test_wrap_angle_scalar_is_bit_identical_to_wrap_angle():
    from helpers.advanced.online_slam.scan_kernels import wrap_angle_scalar
    from helpers.graph import wrap_angle
    rng = np.random.default_rng(7)
    values = np.r_[rng.uniform(-20, 20, 2000), [np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 0.0, np.nextafter(np.pi, 0)]]
    compiled = np.array([wrap_angle_scalar(v) for v in values])
    assert compiled.tobytes() == wrap_angle(values).tobytes()
