"""NN, Mahalanobis NN, ML, SNN wrapper, the common interface, scenarios and evaluation."""
from types import SimpleNamespace

import numpy as np
import pytest

from helpers.association.common import Association, greedy_one_to_one, joint_sq_mahalanobis, prepare, problem_from_cov
from helpers.association.evaluation import run_trials
from helpers.association.jcbb import jcbb
from helpers.association.maximum_likelihood import maximum_likelihood, ml_scores
from helpers.association.nearest_neighbour import mahalanobis_nn, nearest_neighbour, surprisal_nn
from helpers.association.scenarios import lab_camera_scenario, observe_points, range_bearing_scenario
from helpers.gaussian import Gaussian, chi2inv, confidence_level

ALGORITHMS = [nearest_neighbour, mahalanobis_nn, maximum_likelihood, jcbb,
              lambda D, Y: surprisal_nn(D, Y, sU=5.0)]


def independent(mu, sigmas):
    """Independent isotropic 2-D landmarks: mu (n, 2), sigmas (n,)."""
    mu = np.asarray(mu, float)
    return Gaussian(mu.ravel(), np.diag(np.repeat(np.asarray(sigmas, float), 2)))


def test_easy_case_every_algorithm_is_right():
    density = independent([[0, 0], [5, 0], [0, 5]], [0.2, 0.2, 0.2])
    Y = np.array([[5.1, 0.05], [-0.1, 0.1]]).T            # obs 0 ← landmark 1, obs 1 ← landmark 0
    for alg in ALGORITHMS:
        res = alg(density, Y)
        assert isinstance(res, Association)
        assert res.idx.tolist() == [1, 0, -1], res.algorithm
        assert res.n_pairings == 2 and res.jointly_compatible
        assert res.pairs().tolist() == [[0, 1], [1, 0]]
        assert res.observation_labels(2).tolist() == [1, 0]


def test_euclidean_ignores_uncertainty_mahalanobis_does_not():
    # landmark 0 is very certain, landmark 1 very uncertain; the observation is nearer landmark 0 in
    # metres but far outside its gate, and well inside landmark 1's.
    density = independent([[0, 0], [3, 0]], [0.1, 2.0])
    Y = np.array([[1.2, 0.0]]).T
    assert nearest_neighbour(density, Y).idx.tolist() == [0, -1]
    assert mahalanobis_nn(density, Y).idx.tolist() == [-1, 0]
    assert nearest_neighbour(density, Y, max_distance=1.0).idx.tolist() == [-1, -1]


def test_ml_log_det_prefers_the_certain_landmark():
    # d²: 6.25 for the certain landmark, 1.36 for the uncertain one → Mahalanobis NN takes the uncertain
    # one; the log-det term of ML (½ log det 2πP) flips the choice.
    density = independent([[0, 0], [2, 0]], [0.1, 1.5])
    Y = np.array([[0.25, 0.0]]).T
    assert mahalanobis_nn(density, Y).idx.tolist() == [-1, 0]
    assert maximum_likelihood(density, Y).idx.tolist() == [0, -1]
    ell = ml_scores(density, Y)
    expected = 0.5 * np.array([6.25, (1.75 / 1.5) ** 2]) + 0.5 * np.log((2 * np.pi) ** 2 * np.array([0.1, 1.5]) ** 4)
    np.testing.assert_allclose(ell[:, 0], expected, rtol=1e-12)


def test_ml_new_landmark_threshold():
    density = independent([[0, 0]], [0.5])
    Y = np.array([[1.0, 0.0]]).T                          # p(y | 0) = N(1; 0, 0.25) ≈ 0.0433 per m²
    p = np.exp(-0.5 * 4.0) / (2 * np.pi * 0.25)
    assert maximum_likelihood(density, Y, alpha=0.5 * p).idx.tolist() == [0]
    assert maximum_likelihood(density, Y, alpha=2.0 * p).idx.tolist() == [-1]   # "new landmark"
    res = maximum_likelihood(density, Y, alpha=0.5 * p)
    assert res.stats["neg_log_alpha"] == pytest.approx(-np.log(0.5 * p))


def test_one_to_one_and_greedy_order():
    density = independent([[0, 0], [0.3, 0]], [0.5, 0.5])
    Y = np.array([[0.1, 0.0]]).T                           # one observation, two close landmarks
    for alg in ALGORITHMS:
        res = alg(density, Y)
        assert res.n_pairings == 1
    # global greedy: the cheapest pair first, ties → lower landmark then lower observation
    idx = greedy_one_to_one(np.array([[1.0, 1.0], [1.0, 0.5]]), np.ones((2, 2), bool))
    assert idx.tolist() == [0, 1]
    idx = greedy_one_to_one(np.array([[2.0, 1.0], [1.0, 3.0]]), np.array([[True, False], [True, True]]))
    assert idx.tolist() == [-1, 0]


def test_joint_distance_matches_dense_formula():
    sc = range_bearing_scenario(seed=11, n_landmarks=40, n_visible=6)
    res = mahalanobis_nn(sc.density, sc.Y)
    k = np.flatnonzero(res.idx >= 0)
    rows = (2 * k[:, None] + np.arange(2)).ravel()
    f = (sc.Y[:, res.idx[k]].T - sc.density.mean.reshape(-1, 2)[k]).ravel()
    C = sc.density.cov[np.ix_(rows, rows)]
    assert res.d2 == pytest.approx(f @ np.linalg.solve(C, f), rel=1e-9)
    assert res.jointly_compatible == (res.d2 <= chi2inv(confidence_level(3.0), 2 * k.size))
    assert joint_sq_mahalanobis(prepare(sc.density, sc.Y), np.full(sc.n, -1)) == 0.0


def test_empty_observations_give_all_unassociated():
    density = independent([[0, 0], [1, 1]], [0.3, 0.3])
    for alg in ALGORITHMS:
        res = alg(density, np.zeros((2, 0)))
        assert res.idx.tolist() == [-1, -1] and res.n_pairings == 0 and res.d2 == 0.0
        assert res.observation_labels(0).size == 0


@pytest.mark.parametrize("alg", ALGORITHMS)
@pytest.mark.parametrize("Y, match", [
    (np.zeros(2), "Y must be a 2-D"),
    (np.zeros((3, 1)), "multiple of the observation dimension"),
    (np.array([[np.inf], [0.0]]), "finite"),
])
def test_bad_inputs(alg, Y, match):
    with pytest.raises(ValueError, match=match):
        alg(independent([[0, 0], [1, 1]], [0.3, 0.3]), Y)


def test_bad_density_and_options():
    Y = np.zeros((2, 1))
    with pytest.raises(ValueError, match="density must be"):
        mahalanobis_nn(np.eye(2), Y)
    with pytest.raises(ValueError, match="n_sigma"):
        mahalanobis_nn(independent([[0, 0]], [1.0]), Y, n_sigma=0.0)
    with pytest.raises(ValueError, match="max_distance"):
        nearest_neighbour(independent([[0, 0]], [1.0]), Y, max_distance=-1.0)
    with pytest.raises(ValueError, match="alpha"):
        maximum_likelihood(independent([[0, 0]], [1.0]), Y, alpha=0.0)
    singular = Gaussian(np.zeros(2), np.zeros((2, 2)))
    with pytest.raises(ValueError, match="positive definite"):
        prepare(singular, Y)
    with pytest.raises(ValueError, match="m must be"):
        mahalanobis_nn(independent([[0, 0]], [1.0]), Y).observation_labels(-1)


# ---------------------------------------------------------------------------------------------------------
# scenarios
# ---------------------------------------------------------------------------------------------------------
def test_observation_jacobians_match_central_differences():
    rng = np.random.default_rng(0)
    for _ in range(5):
        pose = np.array([*rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)])
        lms = rng.uniform(-10, 10, (4, 2))
        z, J_pose, J_lm = observe_points(pose, lms)
        h = 1e-6
        for a in range(3):
            e = np.zeros(3)
            e[a] = h
            fd = (observe_points(pose + e, lms)[0] - observe_points(pose - e, lms)[0]) / (2 * h)
            np.testing.assert_allclose(J_pose[:, :, a], fd, atol=1e-7)
        for a in range(2):
            e = np.zeros(2)
            e[a] = h
            fd = (observe_points(pose, lms + e)[0] - observe_points(pose, lms - e)[0]) / (2 * h)
            np.testing.assert_allclose(np.broadcast_to(J_lm[:, a], fd.shape), fd, atol=1e-7)


def test_scenario_is_seeded_and_consistent():
    a = range_bearing_scenario(seed=4, n_clutter=3, p_detect=0.8)
    b = range_bearing_scenario(seed=4, n_clutter=3, p_detect=0.8)
    np.testing.assert_array_equal(a.Y, b.Y)
    np.testing.assert_array_equal(a.truth, b.truth)
    assert a.density.size == 2 * a.n and a.n == 150 and a.is_clutter.sum() == 3
    # every true observation is close to the noiseless observation of its landmark from the true pose
    k = np.flatnonzero(a.truth >= 0)
    z, _, _ = observe_points(a.pose_true, a.landmarks_true[a.candidates[k]])
    assert np.max(np.abs(a.Y[:, a.truth[k]].T - z)) < 0.6
    assert np.array_equal(a.observation_truth()[a.truth[k]], k)
    assert np.all(a.observation_truth()[a.is_clutter] == -1)
    c = range_bearing_scenario(seed=4, n_landmarks=60, n_visible=10, candidate_range=12.0)
    assert c.n < 60 and c.density.size == 2 * c.n


def test_scenario_density_is_the_linearised_state_plus_noise():
    # C = G Σ Gᵀ + σ² I with G = ∂h/∂y at the estimate: the joint innovation covariance of the lecture
    sc = range_bearing_scenario(seed=2, n_landmarks=40, n_visible=6, candidate_range=10.0, meas_sigma=0.2)
    y = sc.state.mean
    assert sc.meas_sigma == 0.2 and y.size == 3 + 2 * sc.n
    np.testing.assert_allclose(y[:3], sc.pose_est)
    np.testing.assert_allclose(y[3:].reshape(-1, 2), sc.landmarks_est[sc.candidates])
    z, J_pose, J_lm = observe_points(y[:3], y[3:].reshape(-1, 2))
    G = np.zeros((2 * sc.n, y.size))
    for k in range(sc.n):
        G[2 * k:2 * k + 2, :3] = J_pose[k]
        G[2 * k:2 * k + 2, 3 + 2 * k:5 + 2 * k] = J_lm
    np.testing.assert_allclose(sc.density.mean, z.ravel(), atol=1e-12)
    np.testing.assert_allclose(sc.density.cov, G @ sc.state.cov @ G.T + 0.04 * np.eye(2 * sc.n), atol=1e-10)


@pytest.mark.parametrize("kwargs, match", [
    ({"seed": -1}, "seed"), ({"seed": 1, "n_landmarks": 0}, "n_landmarks"),
    ({"seed": 1, "n_visible": 500}, "n_visible"), ({"seed": 1, "p_detect": 1.5}, "p_detect"),
    ({"seed": 1, "pose_sigma": (1, 1)}, "pose_sigma"), ({"seed": 1, "pose_sigma": (1, 1, 0)}, "pose_sigma"),
    ({"seed": 1, "meas_sigma": 0}, "meas_sigma"), ({"seed": 1, "n_visible": None}, "n_visible"),
])
def test_scenario_bad_inputs(kwargs, match):
    with pytest.raises(ValueError, match=match):
        range_bearing_scenario(**kwargs)


def test_lab_camera_scenario():
    a = lab_camera_scenario(seed=3, n_clutter=50, p_detect=0.8)
    b = lab_camera_scenario(seed=3, n_clutter=50, p_detect=0.8)
    np.testing.assert_array_equal(a.Y, b.Y)
    assert a.n == 9 and a.density.size == 18 and a.is_clutter.sum() == 50
    assert a.m == 50 + np.count_nonzero(a.truth >= 0)
    k = np.flatnonzero(a.truth >= 0)
    mu = a.density.mean.reshape(9, 2)
    d2 = prepare(a.density, a.Y).ic_d2[k, a.truth[k]]
    assert np.all(d2 < 30.0)                        # true features sit near their predictions
    assert np.all((a.Y[0] >= 0) & (a.Y[0] <= 1920 + 50) & (a.Y[1] >= -50) & (a.Y[1] <= 1440 + 50))
    res = jcbb(a.density, a.Y)
    assert np.array_equal(res.idx, a.truth) and np.all(np.isfinite(mu))
    for kwargs, match in (({"seed": 1.5}, "seed"), ({"seed": 1, "n_clutter": -1}, "n_clutter"),
                          ({"seed": 1, "p_detect": 2.0}, "p_detect"), ({"seed": 1, "pixel_sigma": 0.0}, "pixel_sigma")):
        with pytest.raises(ValueError, match=match):
            lab_camera_scenario(**kwargs)


def test_observe_points_bad_inputs():
    with pytest.raises(ValueError, match="pose"):
        observe_points(np.zeros(2), np.zeros((1, 2)))
    with pytest.raises(ValueError, match="landmarks"):
        observe_points(np.zeros(3), np.zeros((2, 3)))


# ---------------------------------------------------------------------------------------------------------
# evaluation
# ---------------------------------------------------------------------------------------------------------
def _scored(idx, truth, m):
    """The summary of one trial whose scene has ``truth`` and whose algorithm returns ``idx``."""
    scene = SimpleNamespace(density=None, Y=np.zeros((2, m)), truth=np.asarray(truth))
    fixed = Association(idx=np.asarray(idx), d2=0.0, n_pairings=int(np.sum(np.asarray(idx) >= 0)),
                        jointly_compatible=True, algorithm="fixed")
    res = run_trials({"fixed": lambda D, Y: fixed}, 1, 0, scenario=lambda seed: scene)
    return {**{key: int(v[0]) for key, v in res.counts["fixed"].items()}, **res.summary()["fixed"]}


def test_scores_by_hand():
    truth = np.array([0, 1, -1, 2])          # landmark 3's observation is column 2; column 3 is clutter
    idx = np.array([0, 3, 1, 2])             # right, wrong (clutter), wrong (unobserved), right
    s = _scored(idx, truth, m=4)
    assert (s["tp"], s["n_pred"], s["n_true"]) == (2, 4, 3)
    assert s["precision"] == 0.5 and s["recall"] == pytest.approx(2 / 3)
    # observation labels: col0 → 0 ✓, col1 → 2 (truth 1) ✗, col2 → 3 ✓, col3 → 1 (truth none) ✗
    assert s["correct"] == 2 and s["accuracy"] == 0.5
    assert _scored(np.full(3, -1), np.full(3, -1), m=2)["accuracy"] == 1.0


def test_run_trials_is_deterministic_and_jcbb_wins():
    algs = {"ICNN": mahalanobis_nn, "JCBB": jcbb}
    kw = dict(n_landmarks=60, n_visible=12, n_clutter=4)
    a = run_trials(algs, 12, seed=1, **kw)
    b = run_trials(algs, 12, seed=1, **kw)
    assert a.summary() == b.summary()
    assert a.summary()["JCBB"]["accuracy"] > a.summary()["ICNN"]["accuracy"]
    assert a.counts["JCBB"]["nodes"].min() >= 1 and a.counts["ICNN"]["nodes"].max() == 0
    with pytest.raises(ValueError, match="algorithms"):
        run_trials({}, 1, 0)
    with pytest.raises(ValueError, match="n_trials"):
        run_trials(algs, 0, 0)
    with pytest.raises(ValueError, match="seed"):
        run_trials(algs, 1, -1)


# ------------------------------------------------------------------------------------------ a prepared problem
def _random_problem(rng, n=5, m=4, d=2):
    A = rng.normal(size=(d * n, d * n))
    P = A @ A.T / (d * n) + 0.05 * np.eye(d * n)
    mu = rng.normal(size=(n, d))
    seen = mu[rng.integers(0, n, size=m)] if n else np.zeros((m, d))
    Y = (seen + 0.1 * rng.normal(size=(m, d))).T
    return mu, P, Y


@pytest.mark.parametrize("d", [2, 3])
def test_problem_from_cov_equals_prepare_and_every_algorithm_takes_it(d):
    rng = np.random.default_rng(7 + d)
    for _ in range(20):
        mu, P, Y = _random_problem(rng, n=int(rng.integers(1, 7)), m=int(rng.integers(0, 6)), d=d)
        ref = prepare(Gaussian.from_cov(mu.ravel(), P), Y, 2.5)
        got = problem_from_cov(mu, P, Y, 2.5)
        for name in ("mu", "P", "Y"):
            np.testing.assert_allclose(getattr(got, name), getattr(ref, name), rtol=0, atol=1e-12)
        np.testing.assert_allclose(got.ic_d2, ref.ic_d2, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(got.logdet, ref.logdet, rtol=0, atol=1e-10)
        assert got.ic_threshold == ref.ic_threshold and got.n_sigma == 2.5
        assert prepare(got, None, 2.5) is got and prepare(got, Y.copy(), 2.5) is got
        if d == 2:
            for alg in (nearest_neighbour, mahalanobis_nn, maximum_likelihood, jcbb):
                a, b = alg(got, None, n_sigma=2.5), alg(Gaussian.from_cov(mu.ravel(), P), Y, n_sigma=2.5)
                assert a.idx.tolist() == b.idx.tolist() and abs(a.d2 - b.d2) <= 1e-9 * max(1.0, b.d2)


def test_a_prepared_problem_gets_its_gate_from_n_sigma():
    mu, P, Y = _random_problem(np.random.default_rng(3), n=6, m=5)
    full = problem_from_cov(mu, P, Y)
    wider = prepare(full, None, 4.0)
    assert wider.n_sigma == 4.0 and wider.ic_threshold == chi2inv(confidence_level(4.0), 2)
    assert np.array_equal(wider.ic_d2, full.ic_d2) and full.n_sigma == 3.0


def test_a_prepared_problem_rejects_bad_input_by_name():
    mu, P, Y = _random_problem(np.random.default_rng(4), n=3, m=2)
    with pytest.raises(ValueError, match="mu must be a finite"):
        problem_from_cov(mu[:, :1], P, Y)
    with pytest.raises(ValueError, match="mu must be a finite"):
        problem_from_cov(np.where(mu > 0, np.nan, mu), P, Y)
    with pytest.raises(ValueError, match="P must be a finite"):
        problem_from_cov(mu, P[:4, :4], Y)
    with pytest.raises(ValueError, match="P must be symmetric"):
        problem_from_cov(mu, P + np.triu(np.ones_like(P), 1), Y)
    with pytest.raises(ValueError, match="P must be a finite"):
        problem_from_cov(mu, np.where(P == P.max(), np.nan, P), Y)
    assert problem_from_cov(mu, P + 1e-15 * np.triu(np.ones_like(P), 1), Y).P.shape == P.shape   # round-off passes
    with pytest.raises(ValueError, match="P: a landmark's covariance block is not positive definite"):
        problem_from_cov(mu, -P, Y)
    with pytest.raises(ValueError, match="Y must be finite"):
        problem_from_cov(mu, P, np.full((2, 2), np.inf))
    with pytest.raises(ValueError, match="n_sigma"):
        problem_from_cov(mu, P, Y, n_sigma=-1.0)
    problem = problem_from_cov(mu, P, Y)
    with pytest.raises(ValueError, match="Y must be None or the observations"):
        jcbb(problem, Y + 1.0)


def test_true_hypothesis_on_hand_made_scenes():
    from helpers.association.evaluation import true_hypothesis

    c = confidence_level(3.0)
    # two independent landmarks observed exactly at their predictions: D² = 0, jointly compatible
    mu = np.array([[0.0, 0.0], [5.0, 0.0]])
    ok = true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), mu.T.copy(), np.array([0, 1]))
    assert ok == {"n_true": 2, "n_individual": 2, "d2": 0.0, "gate": pytest.approx(float(chi2inv(c, 4))),
                  "dof": 4, "jointly_compatible": True}
    # a shared error (cross-covariance 1, own variance 1.01): displaced 2 m in opposite directions, each
    # pairing passes alone (d² = 4/1.01 < χ²_2 = 11.8) but the pair needs a 4 m difference of variance 0.02
    P = np.kron(np.array([[1.01, 1.0], [1.0, 1.01]]), np.eye(2))
    Y = np.array([[2.0, 3.0], [0.0, 0.0]])
    bad = true_hypothesis(Gaussian.from_cov(mu.ravel(), P), Y, np.array([0, 1]))
    assert bad["n_individual"] == 2 and not bad["jointly_compatible"]
    assert bad["d2"] == pytest.approx(16.08 / 0.0201)      # fᵀP⁻¹f on the x axis, f = (2, −2): 800
    # a true pairing that fails its individual gate is left out of H
    far = true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), np.array([[0.0, 25.0], [0.0, 0.0]]),
                          np.array([0, 1]))
    assert (far["n_true"], far["n_individual"], far["dof"], far["d2"]) == (2, 1, 2, 0.0)
    assert far["jointly_compatible"]
    # no true pairing at all (clutter only): nothing to test
    none = true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), Y, np.array([-1, -1]))
    assert (none["n_individual"], none["d2"], none["gate"], none["jointly_compatible"]) == (0, 0.0, 0.0, True)
    with pytest.raises(ValueError, match="truth"):
        true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), Y, np.array([0]))
    with pytest.raises(ValueError, match="truth"):
        true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), Y, np.array([0, 0]))
    with pytest.raises(ValueError, match="truth must contain integers"):
        true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), Y, np.array([0.5, 1.0]))
    with pytest.raises(ValueError, match="truth entries"):
        true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), Y, np.array([0, 5]))
    with pytest.raises(ValueError, match="n_sigma"):
        true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), Y, np.array([0, 1]), n_sigma=-1.0)
    with pytest.raises(ValueError, match="observation dimension"):
        true_hypothesis(Gaussian.from_cov(mu.ravel(), np.eye(4)), np.zeros((3, 2)), np.array([0, 1]))
