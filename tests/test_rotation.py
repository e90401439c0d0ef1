import numpy as np
import pytest

from helpers.rotation import rot2rpy, rotx, roty, rotz, rpy2rot, rpy2rot_derivatives


def skew(v):
    """Cross-product matrix S(v): S(v) w = v × w."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])

R123 = np.array([
    [0.411982245666, -0.833737651774, -0.367630462925],
    [-0.0587266449276, -0.426917621276, 0.902381585483],
    [-0.909297426826, -0.350175488374, -0.224845095366],
])


def test_rpy2rot_published_value():
    np.testing.assert_allclose(rpy2rot([1.0, 2.0, 3.0]), R123, atol=1e-11)


def test_rpy2rot_is_rz_ry_rx():
    phi, theta, psi = 0.3, -0.7, 2.1
    np.testing.assert_allclose(rpy2rot([phi, theta, psi]), rotz(psi) @ roty(theta) @ rotx(phi), atol=1e-15)


def test_rot2rpy_round_trip_of_published_matrix():
    Theta = rot2rpy(R123)
    np.testing.assert_allclose(Theta, [-2.14159265359, 1.14159265359, -0.14159265359], atol=1e-9)
    np.testing.assert_allclose(rpy2rot(Theta), R123, atol=1e-11)


def test_rot2rpy_round_trip_random_vectorised():
    rng = np.random.default_rng(1)
    Theta = rng.uniform([-np.pi, -np.pi / 2 + 0.01, -np.pi], [np.pi, np.pi / 2 - 0.01, np.pi], size=(50, 3)).T
    R = rpy2rot(Theta)
    assert R.shape == (50, 3, 3)
    np.testing.assert_allclose(rot2rpy(R), Theta, atol=1e-12)
    np.testing.assert_allclose(R[7], rpy2rot(Theta[:, 7]), atol=1e-15)


@pytest.mark.parametrize("angle", [0.0, 0.1, 5 * np.pi / 3])
@pytest.mark.parametrize("fn, axis", [(rotx, 0), (roty, 1), (rotz, 2)])
def test_elementary_rotations_and_derivatives(fn, axis, angle):
    R, dR = fn(angle, return_derivative=True)
    e = np.eye(3)[axis]
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(R @ e, e, atol=1e-15)  # the axis is fixed
    np.testing.assert_allclose(dR, R @ skew(e), atol=1e-15)  # dR/dangle = R S(e)
    h = 1e-6
    np.testing.assert_allclose(dR, (fn(angle + h) - fn(angle - h)) / (2 * h), atol=1e-9)


def test_rotx_sign_convention():
    np.testing.assert_allclose(rotx(np.pi / 2) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(roty(np.pi / 2) @ [0, 0, 1], [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(rotz(np.pi / 2) @ [1, 0, 0], [0, 1, 0], atol=1e-15)


def test_rpy2rot_derivatives_central_differences():
    rng = np.random.default_rng(2)
    h = 1e-6
    for _ in range(10):
        Theta = rng.uniform(-np.pi, np.pi, 3)
        R, *dR = rpy2rot_derivatives(Theta)
        np.testing.assert_allclose(R, rpy2rot(Theta), atol=1e-15)
        for k in range(3):
            e = np.eye(3)[k] * h
            fd = (rpy2rot(Theta + e) - rpy2rot(Theta - e)) / (2 * h)
            np.testing.assert_allclose(dR[k], fd, atol=1e-9)


def test_rpy2rot_derivatives_closed_forms():
    Theta = np.array([0.4, -0.2, 1.3])
    R, dphi, dtheta, dpsi = rpy2rot_derivatives(Theta)
    Rx, Ry, Rz = rotx(Theta[0]), roty(Theta[1]), rotz(Theta[2])
    e1, e2, e3 = np.eye(3)
    np.testing.assert_allclose(dphi, Rz @ Ry @ Rx @ skew(e1), atol=1e-15)
    np.testing.assert_allclose(dtheta, Rz @ Ry @ skew(e2) @ Rx, atol=1e-15)
    np.testing.assert_allclose(dpsi, Rz @ skew(e3) @ Ry @ Rx, atol=1e-15)


def test_rpy2rot_derivatives_vectorised():
    Theta = np.random.default_rng(3).normal(size=(3, 4))
    out = rpy2rot_derivatives(Theta)
    for k in range(4):
        single = rpy2rot_derivatives(Theta[:, k])
        for a, b in zip(out, single):
            np.testing.assert_allclose(a[k], b, atol=1e-15)


@pytest.mark.parametrize("bad", [[1.0, 2.0], np.zeros((2, 2)), [np.nan, 0.0, 0.0]])
def test_rpy2rot_bad_input(bad):
    with pytest.raises(ValueError, match="Theta"):
        rpy2rot(bad)
    with pytest.raises(ValueError, match="Theta"):
        rpy2rot_derivatives(bad)


@pytest.mark.parametrize("bad", [np.eye(2), np.full((3, 3), np.nan), 2 * np.eye(3), np.diag([1.0, 1.0, -1.0])])
def test_rot2rpy_bad_input(bad):
    with pytest.raises(ValueError, match="R must"):
        rot2rpy(bad)


@pytest.mark.parametrize("fn, name", [(rotx, "phi"), (roty, "theta"), (rotz, "psi")])
def test_elementary_bad_input(fn, name):
    with pytest.raises(ValueError, match=name):
        fn(np.nan)
