import numpy as np
import pytest
import scipy.stats

from helpers.association.common import prepare
from helpers.association.compatibility import (
    individual_compatibility,
    joint_compatibility,
    lab_test_fixture,
    uniform_surprisal,
)
from helpers.gaussian import Gaussian


@pytest.fixture(scope="module")
def fx():
    return lab_test_fixture()


def test_uniform_surprisal(fx):
    assert uniform_surprisal((1920, 1440)) == pytest.approx(14.832478857591873, rel=1e-15)
    # the fixture's number (a JSON literal) against log W + log H: equal to an ulp or two, not bit for bit by design
    assert fx["sU"] == pytest.approx(uniform_surprisal(fx["image_size"]), rel=1e-15)


# ---------------------------------------------------------------------------- individual compatibility
def test_individual_one_landmark_three_features(fx):
    Y, d = fx["Y3"], fx["density_1"]
    assert [individual_compatibility(i, 0, Y, d, fx["n_sigma"]) for i in range(3)] == [False, True, False]


def test_individual_three_landmarks_thirteen_features(fx):
    Y, d = fx["Y13"], fx["density_3"]
    expected = {(6, 0), (7, 1), (9, 1), (10, 2), (11, 2), (12, 2)}
    got = {(i, j) for i in range(13) for j in range(3) if individual_compatibility(i, j, Y, d, 3.0)}
    assert got == expected
    # the template's flat layout i*3 + j
    assert sorted(i * 3 + j for i, j in got) == [18, 22, 28, 32, 35, 38]


def test_individual_near_threshold_rejection(fx):
    d2 = prepare(fx["density_3"], fx["Y13"]).ic_d2                  # (landmark, feature)
    assert d2[0, 5] == pytest.approx(12.022, abs=5e-4)
    assert d2[0, 5] > 11.829158081900795
    assert not individual_compatibility(5, 0, fx["Y13"], fx["density_3"])
    # a looser confidence level (c = 0.998, i.e. n_sigma ≈ 3.09) would wrongly accept it
    n_sigma_loose = scipy.stats.norm.ppf((1 + 0.998) / 2)
    assert individual_compatibility(5, 0, fx["Y13"], fx["density_3"], n_sigma=n_sigma_loose)


@pytest.mark.parametrize("Yname, dname, pairs", [
    ("Y3", "density_1", {(0, 0): 26.556, (1, 0): 1.3388, (2, 0): 27.147}),
    ("Y13", "density_3", {(6, 0): 1.349, (7, 1): 2.238, (9, 1): 4.437, (10, 2): 4.435, (11, 2): 7.066,
                          (12, 2): 2.056})])
def test_individual_squared_distances(fx, Yname, dname, pairs):
    d2 = prepare(fx[dname], fx[Yname]).ic_d2                      # the distances the L09 algorithms use
    for (i, j), value in pairs.items():
        assert d2[j, i] == pytest.approx(value, abs=5e-4 if value < 10 else 5e-3)


def test_gate_follows_the_dense_formula(fx):
    Y, d = fx["Y13"], fx["density_3"]
    gate = 11.829158081900795
    P = d.cov
    for j in range(3):
        Pj = P[2 * j:2 * j + 2, 2 * j:2 * j + 2]
        D = Y - d.mean[2 * j:2 * j + 2, None]
        d2 = np.einsum("im,ij,jm->m", D, np.linalg.inv(Pj), D)
        assert np.abs(d2 - gate).min() > 1e-3 * gate                 # no pair within round-off of the gate
        assert [individual_compatibility(i, j, Y, d) for i in range(13)] == (d2 <= gate).tolist()


# ---------------------------------------------------------------------------- joint compatibility
# Published values (template). Recomputing from the printed (rounded) fixture differs by ≈ 1e-9 relative,
# so the published numbers are checked to 1e-8 and the exact recomputation to 1e-12 below.
@pytest.mark.parametrize("idx, Yname, dname, surprisal", [
    ([1], "Y3", "density_1", 10.105667572052072),
    ([-1], "Y3", "density_1", 14.832478857591873),
    ([6, 7, 10], "Y13", "density_3", 33.394861266913537)])
def test_joint_compatibility_published(fx, idx, Yname, dname, surprisal):
    ok, s = joint_compatibility(idx, fx["sU"], fx[Yname], fx[dname], fx["n_sigma"])
    assert ok is True
    assert s == pytest.approx(surprisal, rel=1e-8)


# Recomputed from the printed fixture the surprisals are 10.1056675834 and 33.3948613328; the issue
# asks for agreement to 1e-9 relative, which holds against these (the published ones differ by fixture rounding).
@pytest.mark.parametrize("idx, Yname, dname, surprisal", [
    ([1], "Y3", "density_1", 10.1056675834),
    ([-1], "Y3", "density_1", 14.832478857591873),
    ([6, 7, 10], "Y13", "density_3", 33.3948613328)])
def test_joint_compatibility_fixture_recomputed(fx, idx, Yname, dname, surprisal):
    ok, s = joint_compatibility(idx, fx["sU"], fx[Yname], fx[dname], fx["n_sigma"])
    assert ok is True
    assert s == pytest.approx(surprisal, rel=1e-9)


def test_joint_compatibility_matches_dense_density(fx):
    Y, d, sU = fx["Y13"], fx["density_3"], fx["sU"]
    idx = [6, -1, 10]
    ok, s = joint_compatibility(idx, sU, Y, d)
    rows = [0, 1, 4, 5]
    yA = np.concatenate([Y[:, 6], Y[:, 10]])
    P = d.cov[np.ix_(rows, rows)]
    expected = sU - scipy.stats.multivariate_normal(d.mean[rows], P).logpdf(yA)
    assert s == pytest.approx(expected, rel=1e-12)
    dA = yA - d.mean[rows]
    assert ok == (dA @ np.linalg.solve(P, dA) <= 16.251340813956187)


def test_joint_compatibility_third_case_distance(fx):
    d = fx["density_3"]
    yA = fx["Y13"][:, [6, 7, 10]].T.ravel()
    assert d.sq_mahalanobis(yA) == pytest.approx(12.744, abs=5e-4)


def test_joint_incompatible_association(fx):
    ok, s = joint_compatibility([0], fx["sU"], fx["Y3"], fx["density_1"])  # wᵀw = 26.6 > 11.83
    assert ok is False
    assert np.isfinite(s)


# ---------------------------------------------------------------------------- bad inputs
def test_bad_inputs(fx):
    Y, d, sU = fx["Y13"], fx["density_3"], fx["sU"]
    with pytest.raises(ValueError, match="Y must have shape"):
        individual_compatibility(0, 0, Y.T, d)
    with pytest.raises(ValueError, match="Y must have shape"):
        individual_compatibility(0, 0, np.zeros((2, 0)), d)
    with pytest.raises(ValueError, match="Y must be finite"):
        individual_compatibility(0, 0, np.full((2, 3), np.nan), d)
    with pytest.raises(ValueError, match="i must be an integer"):
        individual_compatibility(13, 0, Y, d)
    with pytest.raises(ValueError, match="j must be an integer"):
        individual_compatibility(0, 3, Y, d)
    with pytest.raises(ValueError, match="density must be a Gaussian"):
        individual_compatibility(0, 0, Y, np.eye(2))
    with pytest.raises(ValueError, match="density must have even size"):
        individual_compatibility(0, 0, Y, Gaussian(np.zeros(3), np.eye(3)))
    with pytest.raises(ValueError, match="n_sigma"):
        individual_compatibility(0, 0, Y, d, n_sigma=0.0)
    with pytest.raises(ValueError, match="n_sigma"):
        individual_compatibility(0, 0, Y, d, n_sigma=np.nan)
    with pytest.raises(ValueError, match="idx must have one entry per landmark"):
        joint_compatibility([6, 7], sU, Y, d)
    with pytest.raises(ValueError, match="idx entries must be -1"):
        joint_compatibility([6, 7, 13], sU, Y, d)
    with pytest.raises(ValueError, match="idx entries must be -1"):
        joint_compatibility([6, -2, 1], sU, Y, d)
    with pytest.raises(ValueError, match="idx must contain integers"):
        joint_compatibility([6.0, 7.0, 1.0], sU, Y, d)
    with pytest.raises(ValueError, match="sU must be a finite"):
        joint_compatibility([6, 7, 10], np.nan, Y, d)
    with pytest.raises(ValueError, match="n_sigma"):
        joint_compatibility([-1, -1, -1], sU, Y, d, n_sigma=-3.0)
    for bad in [(0, 1440), (1920,), (-1, 5), (np.nan, 2)]:
        with pytest.raises(ValueError, match="image_size"):
            uniform_surprisal(bad)
