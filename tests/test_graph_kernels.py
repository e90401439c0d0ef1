"""Compiled fast paths (helpers.graph.kernels) against their numpy references, and the shared angle wraps."""
import math

import numpy as np
import pytest

import helpers.graph as hg
from helpers.graph import EdgeSE2, kernels, wrap_angle, wrap_angle_mod
from helpers.graph.edges2d import se2_log_coefficients


def _poses(rng, n, scale=30.0):
    return np.c_[rng.normal(size=(n, 2)) * scale, rng.uniform(-3.2, 3.2, n)]


def _se2_case(seed, n=3000):
    """Random between-edges; a third with |θ_d| < 1e-4 (series branch), some with θ_d at the ±π cut."""
    rng = np.random.default_rng(seed)
    xi, xj, z = _poses(rng, n), _poses(rng, n), _poses(rng, n)
    k = n // 3
    z[:k, 2] = wrap_angle(xj[:k, 2] - xi[:k, 2] + rng.normal(size=k) * 1e-5)
    z[k:k + 10, 2] = xj[k:k + 10, 2] - xi[k:k + 10, 2] + np.pi
    return [xi, xj], z


def _dalpha_term_size(theta):
    """½|cot(θ/2)| + |θ|/(4 sin²(θ/2)): α′ = ½cot(θ/2) − θ/(4 sin²(θ/2)) cancels two terms of this size (≈ 2/|θ|
    for small θ) to one of size ≈ |θ|/6, so an ulp of sin or cos (numpy's or the kernel's libm) moves α′ by about
    ε times this. 1 on the series branch (|θ| < 1e−4), which has no cancellation."""
    small = np.abs(theta) < 1e-4
    half = 0.5 * np.where(small, 1.0, theta)
    size = 0.5 * np.abs(np.cos(half) / np.sin(half)) + 0.5 * np.abs(half) / np.sin(half) ** 2
    return np.where(small, 1.0, size)


def _edge_classes_with_reference():
    import helpers.drivebot.edges as drivebot_edges

    classes = [c for module in (hg, drivebot_edges) for c in vars(module).values()
               if isinstance(c, type) and issubclass(c, hg.BaseEdge)]
    return sorted({c for c in classes if c.evaluate_reference is not None}, key=lambda c: c.__name__)


def test_every_kernel_backed_edge_is_listed():
    """The kernel-backed classes; each has its equality test (here and in test_drivebot_edges.py)."""
    assert [c.__name__ for c in _edge_classes_with_reference()] == ["EdgeSE2", "VehicleKinematicsEdge"]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_se2_kernel_equals_numpy_reference(seed):
    states, z = _se2_case(seed)
    e, jac = EdgeSE2.evaluate(states, z, {})
    e_ref, jac_ref = EdgeSE2.evaluate_reference(states, z, {})
    np.testing.assert_allclose(e, e_ref, rtol=1e-12, atol=1e-12)
    # D = (dV⁻¹/dθ)·t_d in the Jacobians carries α′(θ_d)·t_d, whose round-off is ε·|t_d|·_dalpha_term_size(θ_d)
    # (|t_d| ≤ |e_t|): at the smallest |θ_d| here (9e−4, |t_d| ≈ 50) one ulp of sin or cos is 2e−11, as large as a
    # flat 1e−12 + 1e−12·|J| tolerance. So the tolerance is 1e−12 of that size per edge.
    scale = 1.0 + np.linalg.norm(e_ref[:, :2], axis=1) * _dalpha_term_size(e_ref[:, 2])
    for j, j_ref in zip(jac, jac_ref, strict=True):
        assert np.all(np.abs(j - j_ref) <= 1e-12 * (np.abs(j_ref) + scale[:, None, None])), \
            np.max(np.abs(j - j_ref) / (np.abs(j_ref) + scale[:, None, None]))
    e_only, none = EdgeSE2.evaluate(states, z, {}, jacobians=False)
    assert none is None and EdgeSE2.evaluate_reference(states, z, {}, jacobians=False)[1] is None
    np.testing.assert_array_equal(e_only, e)


def test_se2_kernel_on_one_edge_and_no_edges():
    states, z = _se2_case(4, n=1)
    np.testing.assert_allclose(EdgeSE2.evaluate(states, z, {})[0], EdgeSE2.evaluate_reference(states, z, {})[0],
                               rtol=1e-12, atol=1e-12)
    e, (ji, jj) = EdgeSE2.evaluate([np.zeros((0, 3)), np.zeros((0, 3))], np.zeros((0, 3)), {})
    assert e.shape == (0, 3) and ji.shape == jj.shape == (0, 3, 3)


def test_wrap_angle_scalar_is_bit_identical_to_wrap_angle():
    rng = np.random.default_rng(7)
    values = np.r_[rng.uniform(-20, 20, 2000), [np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 0.0, np.nextafter(np.pi, 0)]]
    compiled = np.array([kernels.wrap_angle_scalar(v) for v in values])
    assert compiled.tobytes() == wrap_angle(values).tobytes()


def test_log_coefficients_scalar_match_the_array_version():
    theta = np.r_[np.linspace(-np.pi, np.pi, 401), [0.0, 5e-5, -9e-5, 1e-4, 2e-4]]
    scalar = np.array([kernels.se2_log_coefficients_scalar(t) for t in theta])
    ref = np.stack(se2_log_coefficients(theta), axis=1)
    np.testing.assert_allclose(scalar[:, :2], ref[:, :2], rtol=1e-13, atol=1e-15)       # α, β: well conditioned
    # α′ cancels terms of _dalpha_term_size(θ) (1800× its value at θ = 2e−4): one ulp of sin or cos, where numpy's
    # and the kernel's libm differ, moves it by ≈ ε times that size, so the tolerance is 50 ε times it
    assert np.all(np.abs(scalar[:, 2] - ref[:, 2]) <= 1e-14 * _dalpha_term_size(theta))


def test_wrap_angle_mod_keeps_the_simulator_form_bit_for_bit():
    rng = np.random.default_rng(8)
    values = rng.uniform(-10, 10, 5000)
    assert wrap_angle_mod(values).tobytes() == ((values + np.pi) % (2.0 * np.pi) - np.pi).tobytes()
    for v in values[:200].tolist():
        out = wrap_angle_mod(v)
        assert type(out) is float and out == (v + math.pi) % (2.0 * math.pi) - math.pi
    from helpers.drivebot.simulator import wrap
    assert wrap is wrap_angle_mod
