"""Tests for helpers.drivebot.analysis (χ² rule, determinants, loop closure, masks, ellipses, tangent fit)."""
import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings, strategies as st  # noqa: E402

from helpers.drivebot import analysis as an  # noqa: E402
from helpers.gaussian import chi2inv, confidence_level  # noqa: E402


def _random_spd(rng, n, d=2):
    A = rng.standard_normal((n, d, d))
    return A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(d)


# ---------------------------------------------------------------------------------------------- covariances
def test_determinant_table_ratio():
    Pb = np.array([np.diag([4.0, 1.0]), np.diag([2.0, 2.0])])
    Pa = np.array([np.diag([1.0, 1.0]), np.diag([1.0, 2.0])])
    t = an.determinant_table([1, 2], Pb, Pa)
    np.testing.assert_allclose(t["det_before"], [4, 4])
    np.testing.assert_allclose(t["ratio"], [0.25, 0.5])
    np.testing.assert_allclose(t["sqrt_ratio"], [0.5, np.sqrt(0.5)])


def test_determinant_table_bad_inputs():
    P = np.array([np.eye(2)])
    with pytest.raises(ValueError, match="must agree in L"):
        an.determinant_table([1, 2], P, P)
    with pytest.raises(ValueError, match="P_before"):
        an.determinant_table([1], np.zeros((1, 3, 3)), P)
    with pytest.raises(ValueError, match="finite"):
        an.determinant_table([1], P, np.full((1, 2, 2), np.nan))


@settings(max_examples=30, deadline=None, derandomize=True)
@given(st.integers(0, 10_000))
def test_ellipse_axes_reconstruct_covariance(seed):
    rng = np.random.default_rng(seed)
    P = _random_spd(rng, 5)
    a, b, ang = an.ellipse_axes(P, 2.0)
    s = chi2inv(confidence_level(2.0), 2)
    assert np.all(a >= b)
    c, si = np.cos(ang), np.sin(ang)
    U = np.stack([np.column_stack([c, si]), np.column_stack([-si, c])], axis=2)  # columns major, minor
    R = U @ (np.stack([a ** 2, b ** 2], 1)[:, :, None] * np.swapaxes(U, 1, 2)) / s
    np.testing.assert_allclose(R, P, rtol=1e-9, atol=1e-12)


def test_plot_covariance_ellipses_draws_the_ellipses_of_the_inputs():
    fig, ax = plt.subplots()
    means = np.array([[0.0, 0.0], [1.0, 1.0], [-2.0, 3.0]])
    P = np.array([np.eye(2), np.diag([4.0, 1.0]), [[1.0, 0.9], [0.9, 1.0]]])
    coll = an.plot_covariance_ellipses(ax, means, P, n_sigma=2.0, edgecolor="k")
    assert len(ax.collections) == 1 and coll is ax.collections[0]
    np.testing.assert_allclose(coll.get_offsets(), means)               # one ellipse at each mean
    s = np.sqrt(chi2inv(confidence_level(2.0), 2))
    # full axes 2·√(λ χ²₂): diag(4, 1) → 4s × 2s; eigenvalues of the correlated block 1.9 and 0.1 at 45°
    np.testing.assert_allclose(coll.get_widths(), 2 * s * np.sqrt([1.0, 4.0, 1.9]))
    np.testing.assert_allclose(coll.get_heights(), 2 * s * np.sqrt([1.0, 1.0, 0.1]))
    # degrees, modulo 180 (an axis has no sign); 0° sits on the cut of mod 180 (−1e-16° would read 180°), so the
    # difference is folded into [−90°, 90°) instead
    diff = np.mod(coll.get_angles()[1:] - [0.0, 45.0] + 90.0, 180.0) - 90.0
    np.testing.assert_allclose(diff, 0.0, atol=1e-9)
    plt.close(fig)


# ---------------------------------------------------------------------------------------------- loop closure
def test_find_loop_closure_first_regap():
    # landmark 1 seen at 1..50 then again at 1207; landmark 2 at 3..40 and at 1211; landmark 3 contiguous
    step = np.r_[np.arange(1, 51), np.arange(3, 41), np.arange(100, 200), 1207, 1208, 1211]
    lm = np.r_[np.ones(50, int), np.full(38, 2), np.full(100, 3), 1, 1, 2]
    assert an.find_loop_closure(step, lm, min_gap=300) == (1207, 1)
    assert an.find_loop_closure(step[:188], lm[:188]) == (None, None)
    # order of the stream does not matter
    p = np.random.default_rng(1).permutation(step.size)
    assert an.find_loop_closure(step[p], lm[p]) == (1207, 1)


def test_find_loop_closure_bad_inputs():
    with pytest.raises(ValueError, match="min_gap"):
        an.find_loop_closure(np.arange(3), np.arange(3), min_gap=0)


# ---------------------------------------------------------------------------------------------- masks / RMS
def test_rms():
    keep = np.array([True, False, True])
    est = np.array([[0.0, 0.0], [100.0, 0.0], [3.0, 4.0]]).T
    assert an.position_error_rms(est, np.zeros((2, 3)), keep) == pytest.approx(np.sqrt(12.5))


def test_rms_bad_inputs():
    with pytest.raises(ValueError, match="estimate and truth"):
        an.position_error_rms(np.zeros((2, 3)), np.zeros((2, 3)), np.zeros(3, bool))
    with pytest.raises(ValueError, match="finite"):
        an.position_error_rms(np.full((2, 3), np.nan), np.zeros((2, 3)))


# ---------------------------------------------------------------------------------------------- tangents
def test_fit_tangent_centre_recovers_centre():
    rng = np.random.default_rng(3)
    centre = np.array([12.0, -4.0])
    pts = rng.uniform(-50, 50, (40, 2))
    radial = pts - centre
    t = np.column_stack([-radial[:, 1], radial[:, 0]]) / np.linalg.norm(radial, axis=1)[:, None]
    n = radial / np.linalg.norm(radial, axis=1)[:, None]
    P = 4.0 * t[:, :, None] * t[:, None, :] + 0.5 * n[:, :, None] * n[:, None, :]
    np.testing.assert_allclose(an.fit_tangent_centre(pts, P), centre, atol=1e-8)
    assert np.max(an.tangent_misalignment(pts, P, centre)) < 1e-8


@pytest.mark.parametrize("centre, expected", [
    ([0.0, 0.0], 0.6),     # radial (3, 4)/5, major axis along x: |cos| = 3/5
    ([3.0, 0.0], 0.0),     # radial along y: the axis is tangent
    ([0.0, 4.0], 1.0),     # radial along x: the axis points at the centre
    ([7.0, 1.0], 0.8),     # radial (−4, 3)/5: |cos| = 4/5
])
def test_tangent_misalignment_known_geometry(centre, expected):
    P = np.diag([4.0, 1.0])[None]            # major axis along x
    assert an.tangent_misalignment([[3.0, 4.0]], P, centre) == pytest.approx([expected], abs=1e-12)


def test_tangent_bad_inputs():
    P = np.array([np.eye(2), np.eye(2)])
    with pytest.raises(ValueError, match="do not determine a centre"):
        an.fit_tangent_centre(np.zeros((1, 2)), P[:1])


def test_landmark_observations_of_a_short_run():
    from helpers.drivebot import run_question

    res = run_question("q2_b", maximum_step_number=40)
    tick, lm = an.landmark_observations(res.system)
    stats = res.graph_statistics()
    assert tick.size == lm.size == stats["landmark_edges"] > 0
    assert set(lm.tolist()) == {1, 2}                 # only landmarks 1 and 2 are in range at the start
    assert tick.min() >= 1 and tick.max() < res.n_steps  # no scan at tick 0
