"""Lecture L09: Euclidean nearest neighbour, greedy and one-to-one (public tests).

Small hand-made scenes whose answers follow from the definition: every (landmark k, observation i) pair with
distance ‖y_i − μ_k‖₂ (within max_distance) is visited in increasing distance (ties → lower landmark, then lower
observation) and accepted while both ends are free. The random scenes are checked against that rule written out
in this file.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_close, expect_equal, expect_raises, expect_true, fail
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, norm

from helpers.association.common import Association
from helpers.association.nearest_neighbour import nearest_neighbour
from helpers.gaussian import Gaussian


# ------------------------------------------------------------------------------ the definition, written out
def density_of(mu, cov):
    """The predicted measurements N(mu, cov) of n landmarks: mu (n, d), cov (d·n, d·n)."""
    mu = np.asarray(mu, float)
    return Gaussian.from_cov(mu.ravel(), np.asarray(cov, float))


def isotropic(mu, variances):
    """Independent landmarks mu (n, d), landmark k with covariance variances[k]·I."""
    mu = np.asarray(mu, float)
    return density_of(mu, np.diag(np.repeat(np.asarray(variances, float), mu.shape[1])))


def greedy(cost, allowed):
    """The global greedy one-to-one rule: the allowed pairs sorted by (cost, landmark, observation), each
    accepted while its landmark and its observation are both free. Returns idx (n,)."""
    n, m = cost.shape
    idx, taken = [-1] * n, set()
    for _, k, i in sorted((cost[k, i], k, i) for k in range(n) for i in range(m) if allowed[k, i]):
        if idx[k] < 0 and i not in taken:
            idx[k] = i
            taken.add(i)
    return np.array(idx)


def joint_d2(mu, cov, Y, idx):
    """D²_H = fᵀ C⁻¹ f of the pairings in idx: f stacks y_i − μ_k, C the rows of the paired landmarks."""
    d = Y.shape[0]
    k = np.flatnonzero(idx >= 0)
    if k.size == 0:
        return 0.0
    rows = (d * k[:, None] + np.arange(d)).ravel()
    f = (Y[:, idx[k]].T - mu[k]).ravel()
    return float(f @ np.linalg.solve(cov[np.ix_(rows, rows)], f))


def euclidean(mu, Y):
    """dist[k, i] = ‖y_i − μ_k‖₂."""
    return np.sqrt(((Y.T[None, :, :] - mu[:, None, :]) ** 2).sum(axis=-1))


def check_idx(res, expected, what, given):
    """res is an Association whose idx equals expected."""
    if not isinstance(res, Association):
        fail(what, given=given, note="expected an Association (from finish), got %s" % type(res).__name__)
    expect_equal(np.asarray(res.idx).tolist(), list(expected), what + ": idx (each landmark's observation, or -1)",
                 given=given)


# ------------------------------------------------------------------------------ hand-made scenes
def test_each_observation_goes_to_the_closest_landmark():
    """Well-separated landmarks: each observation is paired with the landmark nearest to it"""
    mu = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    Y = np.array([[9.6, 0.3], [0.2, -0.4]]).T            # observation 0 near landmark 1, observation 1 near 0
    given = {"distances (row k: landmark, column i: observation)": euclidean(mu, Y)}
    res = nearest_neighbour(isotropic(mu, [1.0, 1.0, 1.0]), Y)
    check_idx(res, [1, 0, -1], "three landmarks, two observations", given)
    expect_equal(int(res.n_pairings), 2, "the number of pairings", given=given)


def test_the_covariance_plays_no_part():
    """Euclidean NN ignores the uncertainty: the observation goes to the nearer landmark even when it lies far
    outside that landmark's covariance"""
    mu = np.array([[0.0, 0.0], [3.0, 0.0]])
    Y = np.array([[1.2, 0.0]]).T                           # 1.2 m from landmark 0 (σ = 0.1 m), 1.8 m from 1 (σ = 2 m)
    given = {"distances": euclidean(mu, Y).ravel(), "σ of the landmarks": [0.1, 2.0]}
    check_idx(nearest_neighbour(isotropic(mu, [0.01, 4.0]), Y), [0, -1], "a certain and an uncertain landmark",
              given)


def test_pairs_are_taken_in_increasing_distance_one_to_one():
    """Both observations are nearest to landmark 0: the closer pair wins it and the other observation takes the
    next free landmark (greedy over all pairs, not per observation, and not the smallest total distance)"""
    mu = np.array([[0.0, 0.0], [2.0, 0.0]])
    Y = np.array([[0.9, 0.0], [-1.5, 0.0]]).T
    # distances: (0,0) 0.9, (1,0) 1.1, (0,1) 1.5, (1,1) 3.5 → accept (0,0), skip (1,0) and (0,1), accept (1,1);
    # the assignment with the smallest total, 1.5 + 1.1, would be [1, 0]
    given = {"distances (row k: landmark, column i: observation)": euclidean(mu, Y)}
    check_idx(nearest_neighbour(isotropic(mu, [1.0, 1.0]), Y), [0, 1], "two observations wanting landmark 0",
              given)


def test_ties_go_to_the_lower_landmark_then_the_lower_observation():
    """Equal distances: the lower landmark index wins, then the lower observation index"""
    mu = np.array([[-1.0, 0.0], [1.0, 0.0]])
    Y = np.array([[0.0, 0.0]]).T                           # exactly 1 from both landmarks
    check_idx(nearest_neighbour(isotropic(mu, [1.0, 1.0]), Y), [0, -1], "one observation halfway between two "
              "landmarks", {"distances": euclidean(mu, Y).ravel()})
    mu = np.array([[0.0, 0.0]])
    Y = np.array([[1.0, 0.0], [0.0, 1.0]]).T               # both exactly 1 from the landmark
    check_idx(nearest_neighbour(isotropic(mu, [1.0]), Y), [0], "two observations at the same distance",
              {"distances": euclidean(mu, Y).ravel()})


def test_max_distance_gates_the_pairs():
    """A pair farther than max_distance is never made; a pair exactly at max_distance is (distance ≤ gate)"""
    mu = np.array([[0.0, 0.0], [2.0, 0.0]])
    Y = np.array([[0.9, 0.0], [-1.5, 0.0]]).T              # distances 0.9, 1.1 / 1.5, 3.5 (see the greedy test)
    given = {"distances (row k: landmark, column i: observation)": euclidean(mu, Y)}
    for gate, expected in ((None, [0, 1]), (2.0, [0, -1]), (0.5, [-1, -1])):
        check_idx(nearest_neighbour(isotropic(mu, [1.0, 1.0]), Y, max_distance=gate), expected,
                  "max_distance = %s" % gate, given)
    mu = np.array([[0.0, 0.0]])
    Y = np.array([[3.0, 4.0]]).T                           # exactly 5 away
    check_idx(nearest_neighbour(isotropic(mu, [1.0]), Y, max_distance=5.0), [0],
              "a pair exactly at max_distance = 5", {"mu": mu[0], "y": Y[:, 0]})


def test_no_observations_leave_every_landmark_unpaired():
    """With no observations (Y of shape (d, 0)) every landmark is unpaired and D² is 0"""
    res = nearest_neighbour(isotropic([[0.0, 0.0], [1.0, 1.0]], [1.0, 1.0]), np.zeros((2, 0)))
    check_idx(res, [-1, -1], "Y of shape (2, 0)", {"Y shape": (2, 0)})
    expect_equal(float(res.d2), 0.0, "D² with nothing paired")


def test_the_result_is_the_common_association():
    """The result is the Association of finish: named "nearest_neighbour", stats {"gate": max_distance}, and
    the joint distance D² of its pairings with the full covariance"""
    mu = np.array([[0.0, 0.0], [4.0, 0.0]])
    cov = np.array([[1.0, 0.2, 0.5, 0.1], [0.2, 1.0, 0.0, 0.4], [0.5, 0.0, 2.0, 0.3], [0.1, 0.4, 0.3, 1.5]])
    Y = np.array([[0.5, -0.2], [3.1, 0.7]]).T
    given = {"mu": mu, "Y": Y}
    res = nearest_neighbour(density_of(mu, cov), Y, max_distance=2.0, n_sigma=2.0)
    check_idx(res, [0, 1], "two landmarks, two observations", given)
    expect_equal(res.algorithm, "nearest_neighbour", "Association.algorithm", given=given)
    expect_equal(res.stats, {"gate": 2.0}, "Association.stats", given=given)
    expect_close(res.d2, joint_d2(mu, cov, Y, np.array([0, 1])), "Association.d2, the joint D² of the pairings "
                 "with their cross-covariance", given={"P": cov}, rtol=1e-9)
    gate = chi2.ppf(norm.cdf(2.0) - norm.cdf(-2.0), 4)
    expect_equal(bool(res.jointly_compatible), bool(res.d2 <= gate), "jointly_compatible at n_sigma = 2 "
                 "(D² ≤ χ²₄)", given=given)


@pytest.mark.parametrize("bad", [-1.0, 0.0, float("nan"), float("inf")])
def test_bad_max_distance_is_a_value_error_naming_it(bad):
    """max_distance that is not a positive finite number (or None) is a ValueError naming max_distance"""
    expect_raises(ValueError, nearest_neighbour, isotropic([[0.0, 0.0]], [1.0]), np.zeros((2, 1)),
                  max_distance=bad, what="max_distance = %r" % bad, mentions=["max_distance"])


def test_bad_observations_are_a_value_error_naming_Y():
    """Y that is not a 2-D (d, m) array is a ValueError naming Y (prepare checks it)"""
    expect_raises(ValueError, nearest_neighbour, isotropic([[0.0, 0.0]], [1.0]), np.zeros(2),
                  what="Y of shape (2,)", mentions=["Y"])


# ------------------------------------------------------------------------------ random scenes
def random_scene(seed, n, m, d):
    """n landmarks with a correlated covariance, m observations near some of them (and one anywhere)."""
    rng = np.random.default_rng(seed)
    mu = rng.uniform(-3.0, 3.0, (n, d))
    A = 0.4 * rng.normal(size=(d * n, d * n))
    cov = A @ A.T + 0.1 * np.eye(d * n)
    near = mu[rng.integers(0, n, m)] + 0.8 * rng.normal(size=(m, d))
    Y = near.T.copy()
    if m:
        Y[:, -1] = rng.uniform(-4.0, 4.0, d)
    return mu, cov, Y


@settings(max_examples=80, deadline=None, derandomize=True, database=None, report_multiple_bugs=False)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 5), m=st.integers(0, 5), d=st.sampled_from([1, 2, 3]),
       gate=st.sampled_from([None, 0.7, 1.5, 3.0]))
def test_random_scenes_follow_the_greedy_rule(seed, n, m, d, gate):
    """On random scenes (d = 1, 2, 3) the pairs are exactly those of the greedy rule in increasing distance"""
    mu, cov, Y = random_scene(seed, n, m, d)
    dist = euclidean(mu, Y)
    allowed = np.ones_like(dist, bool) if gate is None else dist <= gate
    expected = greedy(dist, allowed)
    given = {"max_distance": gate, "distances (row k: landmark, column i: observation)": dist}
    res = nearest_neighbour(density_of(mu, cov), Y, max_distance=gate)
    check_idx(res, expected.tolist(), "the greedy one-to-one pairs", given)
    expect_true(int(res.n_pairings) == int(np.count_nonzero(expected >= 0)), "n_pairings counts the pairs",
                given=given, actual=res.n_pairings)
    expect_close(res.d2, joint_d2(mu, cov, Y, expected), "D² of the pairings (finish computes it)",
                 given={"idx": expected}, rtol=1e-8, atol=1e-10)
