"""Lab 8, task 2a: individual compatibility of feature i with landmark j (public tests).

Small hand-made bundles whose answers follow from the definition: the gate is d² = νᵀ P_jj⁻¹ ν ≤ χ²₂(c), with
c the probability mass within n_sigma standard deviations of a 1-D Gaussian.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_equal, expect_raises
from scipy.stats import chi2, norm

from helpers.association.compatibility import individual_compatibility
from helpers.gaussian import Gaussian


def bundle(mu, cov):
    """A bundle density N(mu, cov) from its covariance (the workbook's Gaussian takes P = SᵀS's factor S)."""
    return Gaussian(np.asarray(mu, float), np.linalg.cholesky(np.asarray(cov, float)).T)


def gate(n_sigma):
    return chi2.ppf(norm.cdf(n_sigma) - norm.cdf(-n_sigma), 2)


def test_feature_on_the_prediction_is_compatible():
    """A feature exactly at landmark j's predicted pixel is compatible with it"""
    density = bundle([10.0, 20.0, 300.0, 400.0], np.diag([4.0, 4.0, 9.0, 9.0]))
    Y = np.array([[300.0, 10.0], [400.0, 20.0]])
    for i, j in ((0, 1), (1, 0)):
        expect_equal(individual_compatibility(i, j, Y, density), True, "feature %d on landmark %d's prediction"
                     % (i, j), given={"Y": Y, "mu": density.mean, "i": i, "j": j})


def test_uses_landmark_js_own_rows_of_the_bundle():
    """Landmark j is rows 2j and 2j+1 of the bundle: a feature far from landmark 0 but on landmark 1 is
    compatible with 1 only"""
    density = bundle([0.0, 0.0, 100.0, 100.0], np.eye(4))
    Y = np.array([[100.0], [100.0]])
    given = {"Y": Y, "mu": density.mean}
    expect_equal(individual_compatibility(0, 1, Y, density), True, "feature 0 with landmark 1", given=given)
    expect_equal(individual_compatibility(0, 0, Y, density), False, "feature 0 with landmark 0", given=given)


@pytest.mark.parametrize("n_sigma", [1.0, 2.0, 3.0])
def test_gate_is_the_chi2_quantile_of_two_dof(n_sigma):
    """A feature just inside (outside) the gate's ellipse is (is not) compatible: d² against χ²₂(c)"""
    cov = np.array([[4.0, 1.5], [1.5, 9.0]])
    density = bundle([50.0, 60.0], cov)
    # a direction ν and the scale that puts d² = νᵀ P⁻¹ ν exactly on the gate: 2 % inside and outside
    v = np.array([1.0, -2.0])
    scale = np.sqrt(gate(n_sigma) / (v @ np.linalg.solve(cov, v)))
    for factor, expected in ((0.98, True), (1.02, False)):
        Y = (density.mean + factor * scale * v)[:, None]
        d2 = float((Y[:, 0] - density.mean) @ np.linalg.solve(cov, Y[:, 0] - density.mean))
        expect_equal(individual_compatibility(0, 0, Y, density, n_sigma), expected,
                     "a feature with d² = %.3f against the gate χ²₂ = %.3f at n_sigma = %g"
                     % (d2, gate(n_sigma), n_sigma), given={"Y": Y, "mu": density.mean, "P": cov})


def test_the_gate_follows_the_covariance_not_the_distance():
    """Uncertainty counts: the same 6-pixel offset is compatible along the uncertain axis, not along the certain one"""
    density = bundle([0.0, 0.0], np.diag([25.0, 1.0]))
    along_x, along_y = np.array([[6.0], [0.0]]), np.array([[0.0], [6.0]])
    expect_equal(individual_compatibility(0, 0, along_x, density), True, "6 px along x (σx = 5 px)",
                 given={"Y": along_x, "P": np.diag([25.0, 1.0])})
    expect_equal(individual_compatibility(0, 0, along_y, density), False, "6 px along y (σy = 1 px)",
                 given={"Y": along_y, "P": np.diag([25.0, 1.0])})


def test_uses_the_marginal_of_a_correlated_bundle():
    """Landmark j's 2 × 2 covariance is the marginal P_jj of the whole bundle, also when the landmarks are
    correlated (not a block of the square root S)"""
    # landmark 0 and 1 share a common offset (the pose): P = diag(1) + 24 [I I; I I]
    cov = np.eye(4) + 24.0 * np.kron(np.ones((2, 2)), np.eye(2))
    density = bundle([0.0, 0.0, 50.0, 50.0], cov)
    # P_11 = 25 I (σ = 5 px): 12 px off is within the 3σ gate (d² = 5.76); with the lower-right block of the
    # upper-triangular square root S, S_11ᵀ S_11 = P_11 − P_10 P_00⁻¹ P_01 ≈ 1.96 I, it would look 73 outside
    Y = np.array([[62.0], [50.0]])
    expect_equal(individual_compatibility(0, 1, Y, density), True, "feature 0, 12 px from landmark 1's "
                 "prediction, landmark 1's marginal σ = 5 px", given={"Y": Y, "mu": density.mean, "P": cov})


def test_returns_a_plain_bool():
    """The result is a Python bool (not a numpy array or a number)"""
    density = bundle([0.0, 0.0], np.eye(2))
    result = individual_compatibility(0, 0, np.zeros((2, 1)), density)
    expect_equal(type(result).__name__, "bool", "the type of the result")


def test_bad_indices_raise_a_value_error_naming_them():
    """i outside Y's columns or j outside the bundle's landmarks is a ValueError naming i or j"""
    density = bundle([0.0, 0.0, 1.0, 1.0], np.eye(4))
    Y = np.zeros((2, 3))
    expect_raises(ValueError, individual_compatibility, 3, 0, Y, density, what="i = 3 with 3 features",
                  mentions=["i"])
    expect_raises(ValueError, individual_compatibility, 0, 2, Y, density, what="j = 2 with 2 landmarks",
                  mentions=["j"])
