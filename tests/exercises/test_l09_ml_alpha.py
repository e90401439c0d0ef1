"""Lecture L09: maximum-likelihood association with the new-landmark likelihood α (public tests).

Small hand-made scenes whose answers follow from the definition: a pair (landmark k, observation i) scores
ℓ_ki = ½ d²_ki + ½ log det(2π P_kk), the negative log of N(y_i; μ_k, P_kk); with ``alpha`` given a pair is allowed
when its likelihood beats α (ℓ_ki < −log α), with ``alpha=None`` when it passes the χ² gate d²_ki ≤ χ²_d(c);
allowed pairs are taken in increasing ℓ_ki (ties → lower landmark, then lower observation) while both ends are
free. The random scenes are checked against that rule written out in this file.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_close, expect_equal, expect_raises, expect_true, fail
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2, multivariate_normal, norm

from helpers.association.common import Association
from helpers.association.maximum_likelihood import maximum_likelihood
from helpers.gaussian import Gaussian


# ------------------------------------------------------------------------------ the definition, written out
def density_of(mu, cov):
    """The predicted measurements N(mu, cov) of n landmarks: mu (n, d), cov (d·n, d·n)."""
    mu = np.asarray(mu, float)
    return Gaussian.from_cov(mu.ravel(), np.asarray(cov, float))


def isotropic(mu, variances):
    """Independent landmarks mu (n, d), landmark k with covariance variances[k]·I, and that covariance."""
    mu = np.asarray(mu, float)
    cov = np.diag(np.repeat(np.asarray(variances, float), mu.shape[1]))
    return density_of(mu, cov), cov


def gate(n_sigma, dof):
    """χ²_dof(c) with c = 2Φ(n_σ) − 1, the probability mass within n_σ of a 1-D Gaussian."""
    return float(chi2.ppf(norm.cdf(n_sigma) - norm.cdf(-n_sigma), dof))


def blocks(mu, cov):
    d = mu.shape[1]
    return [cov[d * k:d * k + d, d * k:d * k + d] for k in range(mu.shape[0])]


def individual_d2(mu, cov, Y):
    """d2[k, i] = (y_i − μ_k)ᵀ P_kk⁻¹ (y_i − μ_k), with P_kk landmark k's own block."""
    d2 = np.empty((mu.shape[0], Y.shape[1]))
    for k, block in enumerate(blocks(mu, cov)):
        for i in range(Y.shape[1]):
            nu = Y[:, i] - mu[k]
            d2[k, i] = nu @ np.linalg.solve(block, nu)
    return d2


def scores(mu, cov, Y):
    """ℓ[k, i] = −log N(y_i; μ_k, P_kk), from scipy's Gaussian density."""
    ell = np.empty((mu.shape[0], Y.shape[1]))
    for k, block in enumerate(blocks(mu, cov)):
        for i in range(Y.shape[1]):
            ell[k, i] = -multivariate_normal(mu[k], block).logpdf(Y[:, i])
    return ell


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
def test_the_log_det_term_prefers_the_certain_landmark():
    """½ log det(2π P_kk) counts: the observation has the smaller d² to the uncertain landmark but the higher
    likelihood at the certain one, and ML pairs it with the certain one"""
    mu = np.array([[0.0, 0.0], [2.0, 0.0]])
    density, cov = isotropic(mu, [0.01, 2.25])
    Y = np.array([[0.25, 0.0]]).T                  # d² 6.25 and 1.36; ℓ 0.36 and 3.33; both inside the χ² gate
    given = {"d²": individual_d2(mu, cov, Y).ravel(), "ℓ": scores(mu, cov, Y).ravel(), "gate χ²₂": gate(3.0, 2)}
    check_idx(maximum_likelihood(density, Y), [0, -1], "a certain and an uncertain landmark (alpha None)", given)
    check_idx(maximum_likelihood(density, Y, alpha=1e-6), [0, -1], "the same with alpha = 1e-6", given)


@pytest.mark.parametrize("d", [1, 2, 3])
def test_alpha_is_the_new_landmark_likelihood(d):
    """A pairing whose likelihood is just above α is made, just below α it is not (ℓ < −log α)"""
    density, cov = isotropic(np.zeros((1, d)), [0.25])
    Y = np.zeros((d, 1))
    Y[0, 0] = 1.0                                   # 2 σ along the first axis
    p = float(np.exp(-scores(np.zeros((1, d)), cov, Y)[0, 0]))
    for factor, expected in ((0.98, [0]), (1.02, [-1])):
        alpha = factor * p
        check_idx(maximum_likelihood(density, Y, alpha=alpha), expected, "p(y | landmark) = %.6g and alpha = %.6g"
                  % (p, alpha), {"ℓ": float(-np.log(p)), "−log α": float(-np.log(alpha))})


def test_alpha_decides_alone_without_the_chi2_gate():
    """With alpha given the χ² gate plays no part: a pair 4 σ away (outside the 3σ gate) is made when its
    likelihood beats a small α, and a pair on the prediction is refused when α is larger than its likelihood"""
    density, cov = isotropic(np.zeros((1, 2)), [1.0])
    far = np.array([[4.0], [0.0]])                  # d² = 16 > χ²₂(3σ) = 11.8; ℓ = 8 + log 2π = 9.84
    given = {"d²": 16.0, "ℓ": float(scores(np.zeros((1, 2)), cov, far)[0, 0]), "gate χ²₂": gate(3.0, 2)}
    check_idx(maximum_likelihood(density, far), [-1], "4 σ away with alpha None (the χ² gate)", given)
    check_idx(maximum_likelihood(density, far, alpha=1e-6), [0], "4 σ away with alpha = 1e-6 (−log α = 13.8)",
              given)
    on = np.zeros((2, 1))                           # ℓ = log 2π = 1.84, p = 0.159
    check_idx(maximum_likelihood(density, on, alpha=0.2), [-1], "on the prediction with alpha = 0.2 > p = 0.159",
              {"ℓ": float(scores(np.zeros((1, 2)), cov, on)[0, 0]), "−log α": float(-np.log(0.2))})


@pytest.mark.parametrize("n_sigma", [1.0, 2.0, 3.0])
def test_without_alpha_the_chi2_gate_decides(n_sigma):
    """With alpha None a pair is allowed when d² ≤ χ²_d(c): just inside the gate it is made, just outside not"""
    block = np.array([[2.0, 0.6], [0.6, 1.0]])
    density = density_of([[1.0, -1.0]], block)
    v = np.array([1.0, 2.0])
    scale = np.sqrt(gate(n_sigma, 2) / (v @ np.linalg.solve(block, v)))       # puts d² exactly on the gate
    for factor, expected in ((0.98, [0]), (1.02, [-1])):
        Y = (np.array([1.0, -1.0]) + factor * scale * v)[:, None]
        d2 = individual_d2(np.array([[1.0, -1.0]]), block, Y)[0, 0]
        check_idx(maximum_likelihood(density, Y, n_sigma=n_sigma), expected, "d² = %.4f against χ²₂ = %.4f at "
                  "n_sigma = %g" % (d2, gate(n_sigma, 2), n_sigma), {"P": block, "y − μ": Y[:, 0] - [1.0, -1.0]})


def test_a_pair_outside_the_gate_does_not_block_its_observation():
    """With alpha None the order is by ℓ but the gate is on d²: the most likely pair fails the gate and takes
    nothing, so its observation is paired with the next landmark that passes"""
    mu = np.array([[0.0, 0.0], [0.0, 0.0]])
    density, cov = isotropic(mu, [1e-4, 1.0])
    Y = np.array([[0.04, 0.0]]).T
    # landmark 0 (σ = 0.01): d² = 16, outside the 3σ gate χ²₂ = 11.8, but ℓ = 0.63 is the lowest;
    # landmark 1 (σ = 1): d² = 0.0016, ℓ = 1.84
    given = {"ℓ (landmark 0, landmark 1)": scores(mu, cov, Y).ravel(), "d²": individual_d2(mu, cov, Y).ravel(),
             "gate χ²₂": gate(3.0, 2)}
    check_idx(maximum_likelihood(density, Y), [-1, 0], "the most likely pair is outside the gate", given)


def test_the_cheapest_pair_first_one_to_one():
    """Both observations are most likely at landmark 0: the pair with the lower ℓ takes it, the other observation
    takes landmark 1"""
    mu = np.array([[0.0, 0.0], [2.0, 0.0]])
    density, cov = isotropic(mu, [1.0, 1.0])
    Y = np.array([[0.9, 0.0], [-1.5, 0.0]]).T
    given = {"ℓ (row k: landmark, column i: observation)": scores(mu, cov, Y)}
    check_idx(maximum_likelihood(density, Y, alpha=1e-6), [0, 1], "two observations wanting landmark 0", given)


def test_ties_go_to_the_lower_landmark_then_the_lower_observation():
    """Equal ℓ: the lower landmark index wins, then the lower observation index"""
    density, cov = isotropic([[-1.0, 0.0], [1.0, 0.0]], [1.0, 1.0])
    Y = np.array([[0.0, 0.0]]).T
    check_idx(maximum_likelihood(density, Y), [0, -1], "one observation halfway between two equal landmarks",
              {"ℓ": scores(np.array([[-1.0, 0.0], [1.0, 0.0]]), cov, Y).ravel()})
    density, cov = isotropic([[0.0, 0.0]], [1.0])
    Y = np.array([[1.0, 0.0], [0.0, 1.0]]).T
    check_idx(maximum_likelihood(density, Y), [0], "two observations at the same ℓ",
              {"ℓ": scores(np.zeros((1, 2)), cov, Y).ravel()})


def test_no_observations_leave_every_landmark_unpaired():
    """With no observations (Y of shape (d, 0)) every landmark is unpaired and D² is 0"""
    density, _ = isotropic([[0.0, 0.0], [1.0, 1.0]], [1.0, 1.0])
    res = maximum_likelihood(density, np.zeros((2, 0)), alpha=1e-3)
    check_idx(res, [-1, -1], "Y of shape (2, 0)", {"Y shape": (2, 0)})
    expect_equal(float(res.d2), 0.0, "D² with nothing paired")


def test_the_result_is_the_common_association():
    """The result is the Association of finish: named "maximum_likelihood", with stats {"alpha": alpha,
    "neg_log_alpha": −log α, or None when alpha is None} and the joint D² of its pairings"""
    mu = np.array([[0.0, 0.0], [4.0, 0.0]])
    cov = np.array([[1.0, 0.2, 0.5, 0.1], [0.2, 1.0, 0.0, 0.4], [0.5, 0.0, 2.0, 0.3], [0.1, 0.4, 0.3, 1.5]])
    Y = np.array([[0.5, -0.2], [3.1, 0.7]]).T
    given = {"ℓ (row k: landmark, column i: observation)": scores(mu, cov, Y)}
    for alpha in (1e-3, None):
        res = maximum_likelihood(density_of(mu, cov), Y, alpha=alpha)
        check_idx(res, [0, 1], "two landmarks, two observations, alpha = %s" % alpha, given)
        expect_equal(res.algorithm, "maximum_likelihood", "Association.algorithm", given=given)
        expect_equal(sorted(res.stats), ["alpha", "neg_log_alpha"], "the keys of Association.stats", given=given)
        expect_equal(res.stats["alpha"], alpha, "stats['alpha']", given=given)
        if alpha is None:
            expect_equal(res.stats["neg_log_alpha"], None, "stats['neg_log_alpha'] with alpha None", given=given)
        else:
            expect_close(res.stats["neg_log_alpha"], -np.log(alpha), "stats['neg_log_alpha'] = −log α",
                         given=given, rtol=1e-12)
        expect_close(res.d2, joint_d2(mu, cov, Y, np.array([0, 1])), "Association.d2, the joint D² with the "
                     "cross-covariance", given={"P": cov}, rtol=1e-9)


@pytest.mark.parametrize("bad", [0.0, -1e-3, float("nan"), float("inf")])
def test_bad_alpha_is_a_value_error_naming_it(bad):
    """alpha that is not a positive finite number (or None) is a ValueError naming alpha"""
    density, _ = isotropic([[0.0, 0.0]], [1.0])
    expect_raises(ValueError, maximum_likelihood, density, np.zeros((2, 1)), alpha=bad, what="alpha = %r" % bad,
                  mentions=["alpha"])


def test_bad_observations_are_a_value_error_naming_Y():
    """Y that is not a 2-D (d, m) array is a ValueError naming Y (prepare checks it)"""
    density, _ = isotropic([[0.0, 0.0]], [1.0])
    expect_raises(ValueError, maximum_likelihood, density, np.zeros(2), what="Y of shape (2,)", mentions=["Y"])


# ------------------------------------------------------------------------------ random scenes
def random_scene(seed, n, m, d):
    """n landmarks of very different sizes with a correlated covariance, m observations near some of them."""
    rng = np.random.default_rng(seed)
    mu = rng.uniform(-3.0, 3.0, (n, d))
    A = rng.normal(size=(d * n, d * n)) * np.repeat(rng.uniform(0.1, 1.5, n), d)[:, None]
    cov = A @ A.T / (d * n) + 0.02 * np.eye(d * n)
    near = mu[rng.integers(0, n, m)] + 0.6 * rng.normal(size=(m, d))
    Y = near.T.copy()
    if m:
        Y[:, -1] = rng.uniform(-4.0, 4.0, d)
    return mu, cov, Y


@settings(max_examples=80, deadline=None, derandomize=True, database=None, report_multiple_bugs=False)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 5), m=st.integers(0, 5), d=st.sampled_from([1, 2, 3]),
       neg_log_alpha=st.one_of(st.none(), st.sampled_from([-1.0, 1.0, 3.0, 6.0, 12.0])))
def test_random_scenes_follow_the_greedy_rule(seed, n, m, d, neg_log_alpha):
    """On random correlated scenes (d = 1, 2, 3; alpha None or given) the pairs are exactly those of the greedy
    rule in increasing ℓ"""
    mu, cov, Y = random_scene(seed, n, m, d)
    ell, d2 = scores(mu, cov, Y), individual_d2(mu, cov, Y)
    alpha = None if neg_log_alpha is None else float(np.exp(-neg_log_alpha))
    allowed = d2 <= gate(3.0, d) if alpha is None else ell < -np.log(alpha)
    expected = greedy(ell, allowed)
    given = {"alpha": alpha, "rule": "χ² gate on d²" if alpha is None else "ℓ < −log α = %.6g" % -np.log(alpha),
             "ℓ of the allowed pairs (nan: not allowed)": np.where(allowed, ell, np.nan)}
    res = maximum_likelihood(density_of(mu, cov), Y, alpha=alpha)
    check_idx(res, expected.tolist(), "the greedy one-to-one pairs in increasing ℓ", given)
    expect_true(int(res.n_pairings) == int(np.count_nonzero(expected >= 0)), "n_pairings counts the pairs",
                given=given, actual=res.n_pairings)
    expect_close(res.d2, joint_d2(mu, cov, Y, expected), "D² of the pairings (finish computes it)",
                 given={"idx": expected}, rtol=1e-8, atol=1e-10)
