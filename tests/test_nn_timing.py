"""O(K·N) nearest neighbour: distances equal the dense formula, blocks do not change the answer, timing API."""
import numpy as np
import pytest

from helpers.association.nn_timing import inverse_2x2, loglog_slope, pair_distances, per_observation_nn, time_nn


def random_nn_problem(rng, n_landmarks, n_observations):
    mu = rng.uniform(0.0, 100.0, (n_landmarks, 2))
    A = rng.normal(0.0, 0.5, (n_landmarks, 2, 2))
    Y = rng.uniform(0.0, 100.0, (2, n_observations))
    return mu, A @ np.swapaxes(A, 1, 2) + 0.01 * np.eye(2), Y


def test_distances_and_labels_match_the_dense_formula():
    rng = np.random.default_rng(1)
    mu, S, Y = random_nn_problem(rng, 37, 23)
    d2 = pair_distances(inverse_2x2(S), mu, Y).T
    ref = np.array([[nu @ np.linalg.solve(S[j], nu) for nu in (Y.T - mu[j])] for j in range(37)])
    np.testing.assert_allclose(d2, ref, rtol=1e-10)
    labels = per_observation_nn(mu, S, Y)
    assert labels.tolist() == np.argmin(ref, axis=0).tolist()
    assert per_observation_nn(mu, S, Y, block_pairs=1).tolist() == labels.tolist()
    gated = per_observation_nn(mu, S, Y, gate=5.0)
    assert np.all((gated == -1) == (ref.min(axis=0) > 5.0))


def test_timing_and_slope():
    K, N, t = time_nn([5, 10], [7], repeats=1)
    assert K.tolist() == [5, 10] and N.tolist() == [7, 7] and np.all(t > 0)
    assert loglog_slope([1, 10, 100], [2, 20, 200]) == pytest.approx(1.0)


def test_bad_inputs():
    rng = np.random.default_rng(0)
    mu, S, Y = random_nn_problem(rng, 3, 2)
    with pytest.raises(ValueError, match="mu"):
        per_observation_nn(mu[:, :1], S, Y)
    with pytest.raises(ValueError, match="S and Y must have shapes"):
        per_observation_nn(mu, S[:2], Y)
    with pytest.raises(ValueError, match="S and Y must have shapes"):
        per_observation_nn(mu, S, Y[:1])
    with pytest.raises(ValueError, match="^Y must be finite"):
        per_observation_nn(mu, S, np.full_like(Y, np.nan))
    with pytest.raises(ValueError, match="positive definite"):
        per_observation_nn(mu, -S, Y)
    with pytest.raises(ValueError, match="gate"):
        per_observation_nn(mu, S, Y, gate=0.0)
    with pytest.raises(ValueError, match="block_pairs"):
        per_observation_nn(mu, S, Y, block_pairs=0)
    with pytest.raises(ValueError, match="repeats"):
        time_nn([1], [1], repeats=0)
    with pytest.raises(ValueError, match="^Ks must"):
        time_nn([0], [1])
    with pytest.raises(ValueError, match="distinct"):
        loglog_slope([1, 1], [1, 2])
