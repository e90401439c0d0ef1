import numpy as np
import pytest

from helpers.camera import Camera, load_lab_camera
from helpers.gaussian import Gaussian
from helpers.rotation import rpy2rot
from helpers.state_slam import LAB_DEMO_CAMERA_POSE, StateSLAM, lab_demo_state

# reference values at the demo pose: mean (x, y) px, σx, σy, correlation
REFERENCE = [
    ((997.66, 1185.61), 8.10, 6.81, -0.238), ((324.73, 807.68), 9.96, 8.51, 0.146),
    ((1685.50, 806.13), 7.89, 5.11, -0.081), ((1602.00, 308.80), 5.36, 4.75, -0.447),
    ((313.09, 252.71), 7.05, 6.56, 0.771), ((936.38, 661.69), 6.77, 8.85, 0.071),
    ((1058.90, 784.58), 12.57, 4.76, -0.006), ((831.19, 325.95), 5.65, 6.34, 0.503),
    ((1017.88, 166.67), 4.91, 6.10, 0.390)]


@pytest.fixture(scope="module")
def cam():
    return load_lab_camera()


@pytest.fixture(scope="module")
def demo():
    return lab_demo_state()


def random_state(rng, n_landmarks=5):
    """A state whose landmarks lie 0.5–2 m in front of a random body pose."""
    eta = np.concatenate([rng.normal(scale=0.2, size=3), rng.uniform(-0.5, 0.5, 3)])
    R = rpy2rot(eta[3:])
    local = np.vstack([rng.uniform(-0.4, 0.4, (2, n_landmarks)), rng.uniform(0.5, 2.0, n_landmarks)])
    landmarks = eta[:3, None] + R @ local
    mu = np.concatenate([rng.normal(size=6), eta, landmarks.T.ravel()])
    n = mu.size
    S = np.triu(rng.normal(scale=0.01, size=(n, n)))
    S[np.diag_indices(n)] = rng.uniform(0.005, 0.02, n)
    return StateSLAM(Gaussian(mu, S))


def test_demo_state_layout(demo, cam):
    assert demo.size == 39 and demo.number_landmarks == 9
    S = demo.density.sqrt_cov
    assert np.all(S[:6] == 0) and np.all(S[:, :6] == 0)  # ν block is all zero
    assert S[6, 11] == pytest.approx(-0.002795866555)
    assert np.count_nonzero(S[12:, 12:] - np.diag(np.diag(S[12:, 12:]))) == 0  # landmark blocks diagonal
    np.testing.assert_allclose(demo.camera_pose(cam), LAB_DEMO_CAMERA_POSE, atol=1e-12)
    np.testing.assert_allclose(demo.landmark_positions()[:, 8], [0.29029, 0.09502, -0.14843])
    np.testing.assert_array_equal(StateSLAM.landmark_indices(2), [18, 19, 20])


@pytest.mark.parametrize("j", range(9))
def test_demo_single_landmark_densities_match_reference(demo, cam, j):
    (mx, my), sx, sy, corr = REFERENCE[j]
    g = demo.predict_feature_density(cam, j)
    np.testing.assert_allclose(g.mean, [mx, my], atol=0.05)
    P = g.cov
    s = np.sqrt(np.diag(P))
    np.testing.assert_allclose(s, [sx, sy], atol=0.006)
    assert P[0, 1] / (s[0] * s[1]) == pytest.approx(corr, abs=6e-4)


def test_demo_all_landmarks_in_fov(demo, cam):
    pose = demo.camera_pose(cam)
    np.testing.assert_array_equal(cam.is_world_within_fov(demo.landmark_positions(), pose), np.ones(9, bool))


def test_bundle_rows_follow_selection_order(demo, cam):
    sel = [5, 2, 8]
    h, J = demo.predict_feature_bundle(cam, sel)
    assert h.shape == (6,) and J.shape == (6, 39)
    # one landmark vs three: the same numpy expressions, but R.T @ d is a BLAS gemv for one column and a gemm for
    # three, which may round differently. J entries are 3-term sums of terms ≤ 2.2e3 (smallest |J| 0.74):
    # 3 ε Σ|terms| is ≤ 0.025 of rtol 1e-13 + atol 1e-12 (measured), h (≥ 166 px) has ~60 ulps at rtol 1e-14
    for k, j in enumerate(sel):
        hj, Jj = demo.predict_feature(cam, j)
        np.testing.assert_allclose(h[2 * k:2 * k + 2], hj, rtol=1e-14)
        np.testing.assert_allclose(J[2 * k:2 * k + 2], Jj, rtol=1e-13, atol=1e-12)
        nz = np.flatnonzero(np.any(Jj != 0, axis=0))
        np.testing.assert_array_equal(nz, np.r_[6:12, 12 + 3 * j:15 + 3 * j])
    g = demo.predict_feature_bundle_density(cam, sel)
    for k, j in enumerate(sel):
        # κ ≤ 2.6 for these 2×2 covariances; measured relative difference ≤ 6e-16
        np.testing.assert_allclose(g.marginal([2 * k, 2 * k + 1]).cov, demo.predict_feature_density(cam, j).cov,
                                   rtol=1e-10)


def test_bundle_jacobian_central_differences(cam):
    rng = np.random.default_rng(0)
    for _ in range(3):
        st = random_state(rng)
        sel = [3, 0, 4]
        x0 = st.density.mean
        _, J = st.predict_feature_bundle(cam, sel)
        h = 1e-6
        fd = np.empty_like(J)
        for k in range(x0.size):
            e = np.zeros_like(x0)
            e[k] = h
            plus, minus = st.predict_feature_bundle(cam, sel, x0 + e)[0], st.predict_feature_bundle(cam, sel, x0 - e)[0]
            fd[:, k] = (plus - minus) / (2 * h)
        np.testing.assert_allclose(J, fd, rtol=1e-6, atol=2e-3)


def test_bundle_jacobian_with_camera_mounting(cam):
    mounted = Camera(cam.K, cam.dist_coeffs, cam.image_size, r_cb_b=[0.02, 0.0, -0.01],
                     R_bc=rpy2rot([0.05, -0.03, 0.02]))
    st = random_state(np.random.default_rng(1), 3)
    x0 = st.density.mean
    _, J = st.predict_feature_bundle(mounted, [0, 1, 2])
    h = 1e-6
    for k in range(6, x0.size):
        e = np.zeros_like(x0)
        e[k] = h
        fd = (st.predict_feature_bundle(mounted, [0, 1, 2], x0 + e)[0]
              - st.predict_feature_bundle(mounted, [0, 1, 2], x0 - e)[0]) / (2 * h)
        np.testing.assert_allclose(J[:, k], fd, rtol=1e-6, atol=2e-3)


def test_bundle_density_dense_formula_and_noise(demo, cam):
    sel = [0, 4, 7]
    h, J = demo.predict_feature_bundle(cam, sel)
    g = demo.predict_feature_bundle_density(cam, sel)
    np.testing.assert_allclose(g.mean, h)
    np.testing.assert_allclose(g.cov, J @ demo.density.cov @ J.T, rtol=1e-9, atol=1e-9)
    noise = Gaussian.from_sqrt_cov(np.eye(2))
    gn = demo.predict_feature_bundle_density(cam, sel, noise=noise)
    np.testing.assert_allclose(gn.cov, g.cov + np.eye(6), rtol=1e-9, atol=1e-9)
    g1 = demo.predict_feature_density(cam, 4, noise=noise)
    np.testing.assert_allclose(g1.cov, gn.marginal([2, 3]).cov, rtol=1e-9)


def test_bad_inputs(demo, cam):
    with pytest.raises(ValueError, match="density must be a Gaussian"):
        StateSLAM(np.eye(3))
    with pytest.raises(ValueError, match="density must have size 12"):
        StateSLAM(Gaussian(np.zeros(13), np.eye(13)))
    with pytest.raises(ValueError, match="idx_landmarks has a landmark index out of range"):
        demo.predict_feature_bundle(cam, [0, 9])
    with pytest.raises(ValueError, match="idx_landmarks has a landmark index out of range"):
        demo.predict_feature_bundle_density(cam, [-1])
    with pytest.raises(ValueError, match="idx_landmarks must be a non-empty"):
        demo.predict_feature_bundle(cam, [])
    with pytest.raises(ValueError, match="idx_landmarks must contain integer"):
        demo.predict_feature_bundle(cam, [0.5])
    with pytest.raises(ValueError, match="j has a landmark index out of range"):
        demo.predict_feature(cam, 9)
    with pytest.raises(ValueError, match="j must be an integer"):
        demo.predict_feature_density(cam, 1.0)
    with pytest.raises(ValueError, match="camera must be"):
        demo.predict_feature(None, 0)
    with pytest.raises(ValueError, match="x must be a finite state"):
        demo.predict_feature(cam, 0, x=np.zeros(38))
    with pytest.raises(ValueError, match="x must be a finite state"):
        demo.predict_feature(cam, 0, x=np.full(39, np.nan))
    with pytest.raises(ValueError, match="noise must have size"):
        demo.predict_feature_bundle_density(cam, [0, 1], noise=Gaussian.from_sqrt_cov(np.eye(3)))
    with pytest.raises(ValueError, match="noise must have zero mean"):
        demo.predict_feature_bundle_density(cam, [0, 1], noise=Gaussian(np.ones(2), np.eye(2)))
    with pytest.raises(ValueError, match="noise must be a Gaussian"):
        demo.predict_feature_density(cam, 0, noise=np.eye(2))
    with pytest.raises(ValueError, match="camera_pose"):
        lab_demo_state(np.zeros(5))
