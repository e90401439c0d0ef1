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
    for j, j_ref in zip(jac, jac_ref, strict=True):
        np.testing.assert_allclose(j, j_ref, rtol=1e-12, atol=1e-12)
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
    np.testing.assert_allclose(scalar, np.stack(se2_log_coefficients(theta), axis=1), rtol=1e-13, atol=1e-15)


def test_wrap_angle_mod_keeps_the_simulator_form_bit_for_bit():
    rng = np.random.default_rng(8)
    values = rng.uniform(-10, 10, 5000)
    assert wrap_angle_mod(values).tobytes() == ((values + np.pi) % (2.0 * np.pi) - np.pi).tobytes()
    for v in values[:200].tolist():
        out = wrap_angle_mod(v)
        assert type(out) is float and out == (v + math.pi) % (2.0 * math.pi) - math.pi
    from helpers.drivebot.simulator import wrap
    assert wrap is wrap_angle_mod
