"""Analytic Jacobians of the 2D edge set against central differences, vertex ⊞, wrap_angle."""

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from helpers.graph import (BaseEdge, EdgeHeadingPrior, EdgePointPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2,
                           EdgeSE2PointXY, EdgeSE2Prior, VertexPointXY, VertexSE2, batch_matrix, wrap_angle)


def _central_difference(cls, states, z, params, h=1e-6):
    out = []
    for k, s in enumerate(states):
        cols = []
        for a in range(s.shape[1]):
            plus = [x.copy() for x in states]
            minus = [x.copy() for x in states]
            plus[k][:, a] += h
            minus[k][:, a] -= h
            ep, _ = cls.evaluate(plus, z, params, jacobians=False)
            em, _ = cls.evaluate(minus, z, params, jacobians=False)
            cols.append(wrap_angle(ep - em) / (2 * h))
        out.append(np.stack(cols, axis=2))
    return out


def _poses(rng, n):
    return np.c_[rng.normal(size=(n, 2)) * 3, rng.uniform(-3.1, 3.1, n)]


CASES = {
    "EdgeSE2": lambda r, n: (EdgeSE2, [_poses(r, n), _poses(r, n)], _poses(r, n), {}),
    "EdgeSE2Prior": lambda r, n: (EdgeSE2Prior, [_poses(r, n)], _poses(r, n), {}),
    "EdgePositionPrior": lambda r, n: (EdgePositionPrior, [_poses(r, n)], r.normal(size=(n, 2)),
                                       {"lever_arm": r.normal(size=(n, 2)) * 10}),
    "EdgeHeadingPrior": lambda r, n: (EdgeHeadingPrior, [_poses(r, n)], r.uniform(-3, 3, (n, 1)),
                                      {"offset": r.uniform(-3, 3, n)}),
    "EdgeRangeBearing": lambda r, n: (EdgeRangeBearing, [_poses(r, n), r.normal(size=(n, 2)) * 5 + 1],
                                      np.c_[r.uniform(1, 5, n), r.uniform(-3, 3, n)], {}),
    "EdgePointPrior": lambda r, n: (EdgePointPrior, [r.normal(size=(n, 2))], r.normal(size=(n, 2)), {}),
    "EdgeSE2PointXY": lambda r, n: (EdgeSE2PointXY, [_poses(r, n), r.normal(size=(n, 2)) * 5],
                                    r.normal(size=(n, 2)), {}),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_jacobians_match_central_differences(name):
    rng = np.random.default_rng(sorted(CASES).index(name) + 11)
    cls, states, z, params = CASES[name](rng, 40)
    # keep angular errors away from the ±π cut, where the wrapped error is discontinuous
    e, jac = cls.evaluate(states, z, params)
    ok = np.ones(len(z), dtype=bool)
    ok &= np.all(np.abs(np.abs(e) - np.pi) > 1e-3, axis=1)
    num = _central_difference(cls, states, z, params)
    assert e.shape == z.shape
    for k in range(len(states)):
        assert jac[k].shape == (len(z), z.shape[1], states[k].shape[1])
        np.testing.assert_allclose(jac[k][ok], num[k][ok], atol=2e-6, rtol=1e-5)


def test_se2_between_matches_gtsam_error():
    gtsam = pytest.importorskip("gtsam", reason="gtsam is the oracle for the between-factor error")
    rng = np.random.default_rng(3)
    xi, xj, z = _poses(rng, 20), _poses(rng, 20), _poses(rng, 20)
    e, _ = EdgeSE2.evaluate([xi, xj], z, {})
    for t in range(20):
        pi, pj, pz = gtsam.Pose2(*xi[t]), gtsam.Pose2(*xj[t]), gtsam.Pose2(*z[t])
        ref = gtsam.Pose2.Logmap(pz.between(pi.between(pj)))
        np.testing.assert_allclose(e[t], ref, atol=1e-9)


def test_range_bearing_matches_gtsam():
    gtsam = pytest.importorskip("gtsam", reason="gtsam is the oracle for the bearing-range factor")
    rng = np.random.default_rng(4)
    x, m = _poses(rng, 10), rng.normal(size=(10, 2)) * 5
    z = np.c_[rng.uniform(1, 5, 10), rng.uniform(-3, 3, 10)]
    e, _ = EdgeRangeBearing.evaluate([x, m], z, {})
    noise = gtsam.noiseModel.Unit.Create(2)
    for t in range(10):
        f = gtsam.BearingRangeFactor2D(0, 1, gtsam.Rot2(z[t, 1]), z[t, 0], noise)
        vals = gtsam.Values()
        vals.insert(0, gtsam.Pose2(*x[t]))
        vals.insert(1, m[t])
        assert 2 * f.error(vals) == pytest.approx(float(e[t] @ e[t]), rel=1e-9, abs=1e-12)


def test_gps_lever_arm_and_compass_offset():
    v = VertexSE2(estimate=[1.0, 2.0, np.pi / 2])
    gps = EdgePositionPrior([v], measurement=[0.0, 0.0], lever_arm=[10.0, -20.0])
    np.testing.assert_allclose(gps.error(), [1 + 20.0, 2 + 10.0], atol=1e-12)
    assert gps.lever_arm.tolist() == [10.0, -20.0]
    compass = EdgeHeadingPrior([v], measurement=-3.0, offset=0.75 * np.pi)
    e = compass.error()[0]
    assert -np.pi <= e < np.pi
    assert e == pytest.approx(wrap_angle(np.pi / 2 + 0.75 * np.pi + 3.0))


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.floats(-50, 50, allow_nan=False))
def test_wrap_angle_range_and_equivalence(theta):
    w = wrap_angle(theta)
    assert -np.pi <= w < np.pi
    assert np.isclose(np.cos(w), np.cos(theta), atol=1e-9) and np.isclose(np.sin(w), np.sin(theta), atol=1e-9)


def test_wrap_angle_array_and_pi():
    out = wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi / 2, 0.0]))
    np.testing.assert_allclose(out, [-np.pi, -np.pi, -np.pi / 2, 0.0])


def test_vertex_oplus_wraps_and_point_adds():
    v = VertexSE2(estimate=[0, 0, 3.0])
    v.oplus([1.0, 2.0, 0.5])
    np.testing.assert_allclose(v.estimate, [1.0, 2.0, wrap_angle(3.5)])
    p = VertexPointXY(estimate=[1, 1])
    p.oplus([0.5, -1])
    np.testing.assert_allclose(p.estimate, [1.5, 0.0])
    np.testing.assert_allclose(VertexSE2.oplus_batch(np.array([[0, 0, 3.0]]), np.array([[0, 0, 0.5]]))[0, 2],
                               wrap_angle(3.5))


def test_per_object_error_uses_vectorised_model():
    a, b = VertexSE2(estimate=[0, 0, 0.3]), VertexSE2(estimate=[1, 0.5, -0.2])
    e = EdgeSE2([a, b], measurement=[1, 0, 0], information=np.diag([1, 2, 3]))
    ref, _ = EdgeSE2.evaluate([a.estimate[None], b.estimate[None]], np.array([[1.0, 0, 0]]), {})
    np.testing.assert_allclose(e.error(), ref[0])
    assert e.chi2() == pytest.approx(float(ref[0] @ np.diag([1, 2, 3]) @ ref[0]))


def test_information_from_covariance_is_the_validated_cached_inverse():
    from helpers.graph import information_from_covariance
    cov = np.array([[2.0, 0.5], [0.5, 1.0]])
    info = information_from_covariance(cov)
    np.testing.assert_allclose(info @ cov, np.eye(2), atol=1e-14)
    assert np.array_equal(info, info.T) and not info.flags.writeable
    assert information_from_covariance(cov.copy()) is info                  # cached by value
    for bad, msg in [(np.diag([1.0, -1.0]), "positive definite"), (np.array([[1.0, 2.0], [0.0, 1.0]]), "symmetric"),
                     (np.full((2, 2), np.nan), "finite"), (np.ones(3), "square"), ("abc", "real numbers")]:
        with pytest.raises(ValueError, match=f"cov.*{msg}|{msg}"):
            information_from_covariance(bad, "cov")


def test_an_edge_without_a_model_says_what_to_define():
    class Nothing(BaseEdge):
        vertex_types = (VertexPointXY,)
        measurement_dimension = 2

    with pytest.raises(NotImplementedError, match="evaluate"):
        Nothing.evaluate([np.zeros((1, 2))], np.zeros((1, 2)), {})


def test_batch_matrix_rows_scalars_and_bad_input():
    c, s = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    r = batch_matrix([[c, -s], [s, c]])
    assert r.shape == (2, 2, 2) and r.flags.c_contiguous
    np.testing.assert_array_equal(r[1], [[0.0, -1.0], [1.0, 0.0]])
    np.testing.assert_array_equal(batch_matrix([[c, 0], [0, 1]])[0], np.eye(2))
    for bad in ([], [[]], [[c, s], [c]]):
        with pytest.raises(ValueError, match="rows"):
            batch_matrix(bad)
