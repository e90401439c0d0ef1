"""Lab 8, task 2c: joint compatibility of an association and its total surprisal (public tests).

Hand-made bundle densities N(μ, P) of n landmarks (row pair 2k, 2k+1 = landmark k); the answers follow from the
handout's definitions: the association A is jointly compatible when (y_A − μ_A)ᵀ P_A⁻¹ (y_A − μ_A) ≤ χ²_{2|A|}(c),
c = 2Φ(n_sigma) − 1 (eq 15), and its surprisal is s = n_U s_U − log N(y_A; μ_A, P_A).
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_raises
from scipy.stats import chi2, multivariate_normal, norm

from helpers.association.compatibility import joint_compatibility
from helpers.gaussian import Gaussian

SU = float(np.log(640.0) + np.log(480.0))   # s_U = log |image| of a 640 × 480 image


def bundle(mu, cov):
    """A bundle density N(mu, cov) from its covariance (the workbook's Gaussian takes P = SᵀS's factor S)."""
    return Gaussian(np.asarray(mu, float), np.linalg.cholesky(np.asarray(cov, float)).T)


def gate(dof, n_sigma=3.0):
    return chi2.ppf(norm.cdf(n_sigma) - norm.cdf(-n_sigma), dof)


def correlated_bundle(n, seed):
    """n landmarks around (100 k, 80 + 30 k) px with a shared 2-D offset (the pose) and their own noise."""
    rng = np.random.default_rng(seed)
    shared = np.kron(np.ones((n, n)), np.diag(rng.uniform(9.0, 30.0, 2)))
    own = np.diag(rng.uniform(2.0, 10.0, 2 * n))
    mu = np.column_stack([100.0 * np.arange(1, n + 1), 80.0 + 30.0 * np.arange(n)]).ravel()
    return mu, shared + own


def surprisal_by_definition(idx, Y, mu, cov, sU=SU):
    """n_U s_U − log N(y_A; μ_A, P_A) with the rows of the associated landmarks, in landmark order."""
    k = [j for j, i in enumerate(idx) if i >= 0]
    if not k:
        return float(len(idx) * sU)
    rows = np.ravel([[2 * j, 2 * j + 1] for j in k])
    yA = np.ravel([Y[:, idx[j]] for j in k])
    return float((len(idx) - len(k)) * sU - multivariate_normal(mu[rows], cov[np.ix_(rows, rows)]).logpdf(yA))


def test_nothing_associated_is_compatible_and_costs_n_sU():
    """With every entry of idx −1 the (empty) association is compatible and the surprisal is n·s_U"""
    for n in (1, 3):
        mu, cov = correlated_bundle(n, 0)
        for Y in (np.array([[90.0, 300.0], [70.0, 20.0]]), np.zeros((2, 0))):
            idx = [-1] * n
            expect_equal(joint_compatibility(idx, SU, Y, bundle(mu, cov)), (True, n * SU),
                         "(compatible, surprisal) with nothing associated, n = %d" % n,
                         given={"idx": idx, "sU": SU, "Y": Y})


def test_one_association_costs_its_gaussian_surprisal():
    """One landmark, one associated feature: the surprisal is −log N(y_i; μ, P) (no s_U term)"""
    mu, cov = np.array([320.0, 240.0]), np.array([[36.0, 12.0], [12.0, 16.0]])
    Y = np.array([[10.0, 326.0, 600.0], [10.0, 236.0, 400.0]])
    ok, s = joint_compatibility([1], SU, Y, bundle(mu, cov))
    expect_close(s, float(-multivariate_normal(mu, cov).logpdf(Y[:, 1])), "the surprisal of idx = [1]",
                 given={"Y": Y, "mu": mu, "P": cov}, rtol=1e-10)
    expect_equal(ok, True, "idx = [1] (d² = %.2f) is compatible" % float(
        (Y[:, 1] - mu) @ np.linalg.solve(cov, Y[:, 1] - mu)), given={"Y": Y, "mu": mu, "P": cov})


def test_surprisal_of_a_partial_association_of_correlated_landmarks():
    """Unassociated landmarks add s_U each; the associated ones use the joint marginal of their rows, in landmark
    order, with the feature idx[k] of landmark k"""
    mu, cov = correlated_bundle(3, 1)
    Y = np.vstack([mu[0::2] + [3.0, -4.0, 2.0], mu[1::2] + [-2.0, 1.0, 5.0]])[:, ::-1].copy()
    Y = np.hstack([Y, [[5.0], [5.0]]])                  # feature k lies near landmark 2 − k; feature 3 is clutter
    density = bundle(mu, cov)
    for idx in ([2, -1, 0], [-1, 1, -1], [2, 1, 0], [2, 3, -1]):
        _, s = joint_compatibility(idx, SU, Y, density)
        expect_close(s, surprisal_by_definition(idx, Y, mu, cov), "the surprisal of idx = %s" % idx,
                     given={"idx": idx, "Y": Y, "mu": mu, "sU": SU}, rtol=1e-10)


def test_joint_gate_has_2A_degrees_of_freedom():
    """The gate is χ² with 2|A| degrees of freedom (|A| = number of associated landmarks), not 2 and not 2n"""
    mu, cov = correlated_bundle(3, 2)
    density = bundle(mu, cov)
    rows = [0, 1, 2, 3]                                 # landmarks 0 and 1 associated: |A| = 2, 4 degrees of freedom
    direction = np.array([1.0, -0.5, 0.3, 0.8])
    unit = direction / np.sqrt(direction @ np.linalg.solve(cov[np.ix_(rows, rows)], direction))
    cases = [(0.98 * gate(4), True), (1.02 * gate(4), False),
             (0.5 * (gate(2) + gate(4)), True),        # above χ²_2: a gate of 2 dof would reject it
             (0.5 * (gate(4) + gate(6)), False)]       # below χ²_6: a gate of 2n = 6 dof would accept it
    for d2, expected in cases:
        yA = mu[rows] + np.sqrt(d2) * unit
        Y = yA.reshape(2, 2).T
        ok, _ = joint_compatibility([0, 1, -1], SU, Y, density)
        expect_equal(ok, expected, "idx = [0, 1, -1] with d² = %.3f against χ²_4 = %.3f (χ²_2 = %.3f, χ²_6 = "
                     "%.3f)" % (d2, gate(4), gate(2), gate(6)), given={"Y": Y, "mu": mu})


def test_joint_compatibility_sees_what_individual_tests_miss():
    """Two landmarks with a shared (pose) uncertainty: features displaced the same way are jointly compatible,
    displaced in opposite ways they are not, though each pair alone is inside its gate"""
    cov = np.eye(4) + 24.0 * np.kron(np.ones((2, 2)), np.eye(2))      # each landmark σ = 5 px, correlation 0.96
    mu = np.array([100.0, 100.0, 200.0, 100.0])
    density = bundle(mu, cov)
    for shift, expected in ((+10.0, True), (-10.0, False)):
        Y = np.array([[110.0, 200.0 + shift], [100.0, 100.0]])
        d2_each = [float(d @ d) / 25.0 for d in (Y[:, 0] - mu[:2], Y[:, 1] - mu[2:])]
        d_all = Y.T.ravel() - mu
        d2_joint = float(d_all @ np.linalg.solve(cov, d_all))
        ok, _ = joint_compatibility([0, 1], SU, Y, density)
        expect_equal(ok, expected, "landmark 0's feature +10 px in x, landmark 1's %+g px: individual d² = %s "
                     "(gate %.2f), joint d² = %.2f (gate %.2f)" % (shift, d2_each, gate(2), d2_joint, gate(4)),
                     given={"Y": Y, "mu": mu, "P": cov})


def test_n_sigma_sets_the_confidence_level():
    """n_sigma sets c = 2Φ(n_sigma) − 1 of the gate: a d² between the 2σ and 3σ gates passes at 3σ only"""
    mu, cov = np.array([50.0, 60.0]), np.array([[4.0, 1.0], [1.0, 9.0]])
    d2 = 0.5 * (gate(2, 2.0) + gate(2, 3.0))
    nu = np.array([1.0, 1.0])
    Y = (mu + np.sqrt(d2 / (nu @ np.linalg.solve(cov, nu))) * nu)[:, None]
    for n_sigma, expected in ((3.0, True), (2.0, False)):
        ok, _ = joint_compatibility([0], SU, Y, bundle(mu, cov), n_sigma)
        expect_equal(ok, expected, "d² = %.3f at n_sigma = %g (gate %.3f)" % (d2, n_sigma, gate(2, n_sigma)),
                     given={"Y": Y, "mu": mu, "P": cov})


def test_returns_a_bool_and_a_float():
    """The result is a tuple (bool, float) of plain Python types"""
    mu, cov = correlated_bundle(2, 3)
    Y = np.vstack([mu[0::2], mu[1::2]])
    result = joint_compatibility([0, 1], SU, Y, bundle(mu, cov))
    expect_equal(type(result).__name__, "tuple", "the type of the result")
    expect_equal((type(result[0]).__name__, type(result[1]).__name__), ("bool", "float"),
                 "the types of (compatible, surprisal)")


def test_bad_association_raises_a_value_error_naming_idx():
    """idx of the wrong length, with a feature out of range or used twice, or an entry below −1 names idx;
    a non-finite sU names sU"""
    mu, cov = correlated_bundle(3, 4)
    density, Y = bundle(mu, cov), np.zeros((2, 4))
    for bad, what in (([0, 1], "idx of length 2 for 3 landmarks"), ([0, 1, 4], "idx = [0, 1, 4] with 4 features"),
                      ([0, -2, 1], "idx = [0, -2, 1]"), ([2, -1, 2], "idx = [2, -1, 2] (feature 2 twice)")):
        expect_raises(ValueError, joint_compatibility, bad, SU, Y, density, what=what, mentions=["idx"])
    expect_raises(ValueError, joint_compatibility, [0, 1, 2], float("nan"), Y, density, what="sU = nan",
                  mentions=["sU"])
