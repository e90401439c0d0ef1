"""Lecture L09: Mahalanobis nearest neighbour (individual compatibility, greedy and one-to-one; public tests).

Small hand-made scenes whose answers follow from the definition: the cost of a pair (landmark k, observation i)
is d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki with ν_ki = y_i − μ_k and P_kk landmark k's own d × d block of the covariance; a
pair is allowed when d²_ki ≤ χ²_d(c), c = 2Φ(n_σ) − 1; allowed pairs are taken in increasing d²_ki (ties →
lower landmark, then lower observation) while both ends are free. The random scenes are checked against that
rule written out in this file.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_close, expect_equal, expect_raises, expect_true, fail
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, norm

from helpers.association.common import Association
from helpers.association.nearest_neighbour import mahalanobis_nn
from helpers.gaussian import Gaussian


# ------------------------------------------------------------------------------ the definition, written out
def density_of(mu, cov):
    """The predicted measurements N(mu, cov) of n landmarks: mu (n, d), cov (d·n, d·n)."""
    mu = np.asarray(mu, float)
    return Gaussian.from_cov(mu.ravel(), np.asarray(cov, float))


def block_diagonal(blocks):
    """The covariance of independent landmarks with the given d × d blocks."""
    blocks = [np.asarray(b, float) for b in blocks]
    d = blocks[0].shape[0]
    cov = np.zeros((d * len(blocks), d * len(blocks)))
    for k, b in enumerate(blocks):
        cov[d * k:d * k + d, d * k:d * k + d] = b
    return cov


def gate(n_sigma, dof):
    """χ²_dof(c) with c = 2Φ(n_σ) − 1, the probability mass within n_σ of a 1-D Gaussian."""
    return float(chi2.ppf(norm.cdf(n_sigma) - norm.cdf(-n_sigma), dof))


def individual_d2(mu, cov, Y):
    """d2[k, i] = (y_i − μ_k)ᵀ P_kk⁻¹ (y_i − μ_k), with P_kk landmark k's own block."""
    n, d = mu.shape
    d2 = np.empty((n, Y.shape[1]))
    for k in range(n):
        block = cov[d * k:d * k + d, d * k:d * k + d]
        for i in range(Y.shape[1]):
            nu = Y[:, i] - mu[k]
            d2[k, i] = nu @ np.linalg.solve(block, nu)
    return d2


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


def check_idx(res, expected, what, given):
    """res is an Association whose idx equals expected."""
    if not isinstance(res, Association):
        fail(what, given=given, note="expected an Association (from finish), got %s" % type(res).__name__)
    expect_equal(np.asarray(res.idx).tolist(), list(expected), what + ": idx (each landmark's observation, or -1)",
                 given=given)


# ------------------------------------------------------------------------------ hand-made scenes
def test_the_uncertainty_counts():
    """The observation 1.2 m from a certain landmark (σ = 0.1 m) and 1.8 m from an uncertain one (σ = 2 m) goes
    to the uncertain one: d² = 144 is outside the certain landmark's gate, d² = 0.81 well inside the other's"""
    mu = np.array([[0.0, 0.0], [3.0, 0.0]])
    cov = block_diagonal([0.01 * np.eye(2), 4.0 * np.eye(2)])
    Y = np.array([[1.2, 0.0]]).T
    given = {"distances [m]": [1.2, 1.8], "d²": individual_d2(mu, cov, Y).ravel(), "gate χ²₂": gate(3.0, 2)}
    check_idx(mahalanobis_nn(density_of(mu, cov), Y), [-1, 0], "a certain and an uncertain landmark", given)


def test_the_cheapest_pair_first_one_to_one():
    """Both observations are individually nearest to landmark 0: the pair with the smaller d² takes it and the
    other observation takes landmark 1"""
    mu = np.array([[0.0, 0.0], [2.0, 0.0]])
    cov = block_diagonal([np.eye(2), np.eye(2)])
    Y = np.array([[0.9, 0.0], [-1.5, 0.0]]).T               # d²: (0,0) 0.81, (1,0) 1.21, (0,1) 2.25, (1,1) 12.25
    given = {"d² (row k: landmark, column i: observation)": individual_d2(mu, cov, Y)}
    check_idx(mahalanobis_nn(density_of(mu, cov), Y, n_sigma=4.0), [0, 1], "two observations wanting landmark 0 "
              "(n_sigma = 4: every pair is inside the gate)", given)


def test_the_whole_block_counts_not_only_its_diagonal():
    """A correlated block P_kk makes an offset along its long axis cheap and across it expensive: the full
    2 x 2 block decides, not its diagonal"""
    mu = np.array([[0.0, 0.0], [0.0, 0.0]])
    cov = block_diagonal([[[1.0, 0.9], [0.9, 1.0]], 1.5 * np.eye(2)])
    Y = np.array([[1.0, 1.0], [1.0, -1.0]]).T
    # d²: landmark 0 (correlated) 2/1.9 = 1.05 along (1, 1), 2/0.1 = 20 across; landmark 1 2/1.5 = 1.33 for both
    given = {"P_00": cov[:2, :2], "Y": Y, "d² (row k: landmark, column i: observation)": individual_d2(mu, cov, Y)}
    check_idx(mahalanobis_nn(density_of(mu, cov), Y), [0, 1], "two landmarks at the origin", given)


def test_cross_covariances_do_not_change_the_pairs():
    """The pairing uses each landmark's own block P_kk only: correlations between landmarks change the reported
    joint D², not which pairs are made"""
    mu = np.array([[0.0, 0.0], [1.5, 0.0]])
    independent = block_diagonal([np.eye(2), np.eye(2)])
    correlated = independent + np.kron(np.array([[0.0, 0.8], [0.8, 0.0]]), np.eye(2))
    Y = np.array([[1.0, 0.0], [2.0, 0.5]]).T
    for cov in (independent, correlated):
        d2 = individual_d2(mu, cov, Y)
        expected = greedy(d2, d2 <= gate(3.0, 2))
        given = {"d² (row k: landmark, column i: observation)": d2}
        res = mahalanobis_nn(density_of(mu, cov), Y)
        check_idx(res, expected.tolist(), "two landmarks %s" % ("correlated" if cov is correlated else
                                                                "independent"), given)
        expect_close(res.d2, joint_d2(mu, cov, Y, expected), "Association.d2, the joint D² with the "
                     "cross-covariance", given={"P": cov}, rtol=1e-9)


@pytest.mark.parametrize("n_sigma", [1.0, 2.0, 3.0])
@pytest.mark.parametrize("d", [1, 2, 3])
def test_the_gate_is_the_chi2_quantile_of_d_dof(n_sigma, d):
    """An observation just inside (outside) the gate's ellipsoid is (is not) paired: d² ≤ χ²_d(c)"""
    rng = np.random.default_rng(10 * d + int(n_sigma))
    A = rng.normal(size=(d, d))
    block = A @ A.T + 0.5 * np.eye(d)
    mu = rng.normal(size=(1, d))
    v = rng.normal(size=d)
    scale = np.sqrt(gate(n_sigma, d) / (v @ np.linalg.solve(block, v)))      # puts d² exactly on the gate
    for factor, expected in ((0.98, [0]), (1.02, [-1])):
        Y = (mu[0] + factor * scale * v)[:, None]
        d2 = individual_d2(mu, block, Y)
        check_idx(mahalanobis_nn(density_of(mu, block), Y, n_sigma=n_sigma), expected,
                  "d² = %.4f against the gate χ²_%d = %.4f at n_sigma = %g" % (d2[0, 0], d, gate(n_sigma, d), n_sigma),
                  {"P": block, "y − μ": Y[:, 0] - mu[0]})


def test_ties_go_to_the_lower_landmark_then_the_lower_observation():
    """Equal d²: the lower landmark index wins, then the lower observation index"""
    mu = np.array([[-1.0, 0.0], [1.0, 0.0]])
    cov = block_diagonal([np.eye(2), np.eye(2)])
    Y = np.array([[0.0, 0.0]]).T                              # d² = 1 to both
    check_idx(mahalanobis_nn(density_of(mu, cov), Y), [0, -1], "one observation halfway between two landmarks",
              {"d²": individual_d2(mu, cov, Y).ravel()})
    mu = np.array([[0.0, 0.0]])
    Y = np.array([[1.0, 0.0], [0.0, 1.0]]).T                 # d² = 1 for both
    check_idx(mahalanobis_nn(density_of(mu, np.eye(2)), Y), [0], "two observations at the same d²",
              {"d²": individual_d2(mu, np.eye(2), Y).ravel()})


def test_no_observations_leave_every_landmark_unpaired():
    """With no observations (Y of shape (d, 0)) every landmark is unpaired and D² is 0"""
    res = mahalanobis_nn(density_of([[0.0, 0.0], [1.0, 1.0]], np.eye(4)), np.zeros((2, 0)))
    check_idx(res, [-1, -1], "Y of shape (2, 0)", {"Y shape": (2, 0)})
    expect_equal(float(res.d2), 0.0, "D² with nothing paired")


def test_the_result_is_the_common_association():
    """The result is the Association of finish: named "mahalanobis_nn", with stats {"ic_threshold": χ²_d(c),
    "ic_pairs": the number of individually compatible pairs}"""
    mu = np.array([[0.0, 0.0], [4.0, 0.0]])
    cov = np.array([[1.0, 0.2, 0.5, 0.1], [0.2, 1.0, 0.0, 0.4], [0.5, 0.0, 2.0, 0.3], [0.1, 0.4, 0.3, 1.5]])
    Y = np.array([[0.5, -0.2], [3.1, 0.7], [2.0, 0.0]]).T
    d2 = individual_d2(mu, cov, Y)
    given = {"d² (row k: landmark, column i: observation)": d2, "gate χ²₂ (n_sigma = 2)": gate(2.0, 2)}
    res = mahalanobis_nn(density_of(mu, cov), Y, n_sigma=2.0)
    if not isinstance(res, Association):
        fail("the result", given=given, note="expected an Association (from finish), got %s" % type(res).__name__)
    expect_equal(res.algorithm, "mahalanobis_nn", "Association.algorithm", given=given)
    expect_equal(sorted(res.stats), ["ic_pairs", "ic_threshold"], "the keys of Association.stats", given=given)
    expect_close(res.stats["ic_threshold"], gate(2.0, 2), "stats['ic_threshold'] at n_sigma = 2", given=given,
                 rtol=1e-9)
    expect_equal(int(res.stats["ic_pairs"]), int(np.count_nonzero(d2 <= gate(2.0, 2))), "stats['ic_pairs']",
                 given=given)
    expect_equal(bool(res.jointly_compatible), bool(res.d2 <= gate(2.0, 2 * res.n_pairings)),
                 "jointly_compatible at n_sigma = 2 (D² ≤ χ²_{2a})", given=given)


def test_bad_input_is_a_value_error_naming_the_argument():
    """Bad density, Y or n_sigma is a ValueError naming it (prepare checks them)"""
    density = density_of([[0.0, 0.0]], np.eye(2))
    expect_raises(ValueError, mahalanobis_nn, np.eye(2), np.zeros((2, 1)), what="density a plain array",
                  mentions=["density"])
    expect_raises(ValueError, mahalanobis_nn, density, np.zeros(2), what="Y of shape (2,)", mentions=["Y"])
    expect_raises(ValueError, mahalanobis_nn, density, np.zeros((2, 1)), n_sigma=0.0, what="n_sigma = 0",
                  mentions=["n_sigma"])


# ------------------------------------------------------------------------------ random scenes
def random_scene(seed, n, m, d):
    """n landmarks with a correlated covariance, m observations near some of them (and one anywhere)."""
    rng = np.random.default_rng(seed)
    mu = rng.uniform(-3.0, 3.0, (n, d))
    A = 0.5 * rng.normal(size=(d * n, d * n))
    cov = A @ A.T + 0.05 * np.eye(d * n)
    near = mu[rng.integers(0, n, m)] + 0.8 * rng.normal(size=(m, d))
    Y = near.T.copy()
    if m:
        Y[:, -1] = rng.uniform(-4.0, 4.0, d)
    return mu, cov, Y


@settings(max_examples=80, deadline=None, derandomize=True, database=None, report_multiple_bugs=False)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 5), m=st.integers(0, 5), d=st.sampled_from([1, 2, 3]),
       n_sigma=st.sampled_from([1.0, 2.0, 3.0]))
def test_random_scenes_follow_the_greedy_rule(seed, n, m, d, n_sigma):
    """On random correlated scenes (d = 1, 2, 3) the pairs are exactly those of the greedy rule in increasing d²
    within the gate"""
    mu, cov, Y = random_scene(seed, n, m, d)
    d2 = individual_d2(mu, cov, Y)
    expected = greedy(d2, d2 <= gate(n_sigma, d))
    given = {"gate χ²_d": gate(n_sigma, d), "d² (row k: landmark, column i: observation)": d2}
    res = mahalanobis_nn(density_of(mu, cov), Y, n_sigma=n_sigma)
    check_idx(res, expected.tolist(), "the greedy one-to-one pairs within the gate", given)
    expect_true(int(res.n_pairings) == int(np.count_nonzero(expected >= 0)), "n_pairings counts the pairs",
                given=given, actual=res.n_pairings)
    expect_close(res.d2, joint_d2(mu, cov, Y, expected), "D² of the pairings (finish computes it)",
                 given={"idx": expected}, rtol=1e-8, atol=1e-10)
