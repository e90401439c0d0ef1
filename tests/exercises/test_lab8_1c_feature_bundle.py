"""Lab 8, task 1c: the predicted feature bundle h (eq 8) and its Jacobian ∂h/∂x (eq 9) (public tests).

The state is x = [ν (0..5); rBNn (6..8); Θnb (9..11); landmark j at 12 + 3j .. 14 + 3j]. The pixels come from
the camera model (Camera.body_to_pixel, the given tool): a pinhole camera without distortion gives them by hand,
and the bundle Jacobian is checked against central differences of h itself.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_close, expect_equal, expect_raises, expect_shape, expect_true, numeric_jacobian

from helpers.camera import Camera, load_lab_camera
from helpers.gaussian import Gaussian
from helpers.rotation import rpy2rot
from helpers.state_slam import StateSLAM


@pytest.fixture(scope="module")
def lab_camera():
    return load_lab_camera()


def pinhole(fx=400.0, fy=300.0, cx=320.0, cy=240.0):
    """A camera without distortion: pixel = (fx u + cx, fy v + cy) with u = x/z, v = y/z in the camera frame."""
    return Camera([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], np.zeros(12), (640, 480))


def state_from(eta, landmarks, nu=None):
    """A state with body pose eta = [rBNn; Θnb], landmarks (k, 3) and an arbitrary (small, valid) square root."""
    landmarks = np.asarray(landmarks, float)
    mu = np.concatenate([np.zeros(6) if nu is None else nu, eta, landmarks.ravel()])
    return StateSLAM(Gaussian(mu, 0.01 * np.eye(mu.size)))


def random_state(seed, n_landmarks=5):
    """Landmarks 0.6–1.8 m in front of a random body pose, within about 35° of the optical axis."""
    rng = np.random.default_rng(seed)
    eta = np.concatenate([rng.normal(scale=0.2, size=3), rng.uniform(-0.5, 0.5, 3)])
    local = np.vstack([rng.uniform(-0.3, 0.3, (2, n_landmarks)), rng.uniform(0.6, 1.8, n_landmarks)])
    landmarks = (eta[:3, None] + rpy2rot(eta[3:]) @ local).T
    return state_from(eta, landmarks, nu=rng.normal(size=6))


def landmark_columns(j):
    return [12 + 3 * j, 13 + 3 * j, 14 + 3 * j]


def test_returns_h_and_J_of_the_bundle_shapes(lab_camera):
    """h has two rows per selected landmark and J is 2k × n (eqs 8 and 9)"""
    state = random_state(0)
    for idx in ([2], [3, 0, 4], [0, 1, 2, 3, 4]):
        out = state.predict_feature_bundle(lab_camera, idx)
        expect_true(isinstance(out, tuple) and len(out) == 2, "the result is a tuple (h, J)",
                    given={"idx_landmarks": idx}, actual=type(out).__name__)
        h, J = out
        expect_shape(h, (2 * len(idx),), "h for %d selected landmarks" % len(idx), given={"idx_landmarks": idx})
        expect_shape(J, (2 * len(idx), state.size), "J for %d selected landmarks of a state of size %d"
                     % (len(idx), state.size), given={"idx_landmarks": idx})


def test_pinhole_pixels_by_hand():
    """With a pinhole camera and the body at the origin, landmark (x, y, z) is seen at (fx x/z + cx, fy y/z + cy)"""
    camera = pinhole()
    landmarks = [[0.1, 0.2, 2.0], [-0.3, 0.05, 1.0]]
    state = state_from(np.zeros(6), landmarks)
    h, _ = state.predict_feature_bundle(camera, [0, 1])
    expected = np.array([400 * 0.1 / 2 + 320, 300 * 0.2 / 2 + 240, 400 * -0.3 / 1 + 320, 300 * 0.05 / 1 + 240])
    expect_close(h, expected, "h of two landmarks seen from the origin (fx = 400, fy = 300, cx = 320, cy = 240)",
                 given={"landmarks (rows)": np.array(landmarks), "idx_landmarks": [0, 1]})


def test_pinhole_pixels_with_a_moved_and_turned_body():
    """The landmark is seen in the camera frame: rPCc = Rncᵀ (r_j − rCNn) (eq 4b), here a 90° yaw and a shift"""
    camera = pinhole()
    eta = np.array([0.1, 0.0, -1.0, 0.0, 0.0, np.pi / 2])
    # with Rnb = Rz(90°), Rᵀ [a, b, c] = [b, −a, c]: the landmark (0.3, −0.1, 1) − (0.1, 0, −1) = (0.2, −0.1, 2)
    # is (−0.1, −0.2, 2) in the camera frame
    state = state_from(eta, [[0.3, -0.1, 1.0]])
    h, _ = state.predict_feature_bundle(camera, [0])
    expect_close(h, [400 * -0.1 / 2 + 320, 300 * -0.2 / 2 + 240], "h of one landmark, body at (0.1, 0, −1) "
                 "turned by yaw 90°", given={"eta (body pose)": eta, "landmark": [0.3, -0.1, 1.0]}, atol=1e-9)


def test_rows_follow_the_selection_order(lab_camera):
    """Row pair (2k, 2k+1) belongs to the k-th selected landmark, whatever its index in the state"""
    state = random_state(1)
    mu, idx = state.density.mean, [3, 0, 4]
    h, _ = state.predict_feature_bundle(lab_camera, idx)
    for k, j in enumerate(idx):
        pixel = lab_camera.body_to_pixel(mu[landmark_columns(j)], mu[6:12])
        expect_close(h[2 * k:2 * k + 2], pixel, "rows %d and %d of h (selected landmark %d)" % (2 * k, 2 * k + 1, j),
                     given={"idx_landmarks": idx, "landmark %d" % j: mu[landmark_columns(j)]}, rtol=1e-12,
                     atol=1e-9)


def test_evaluates_at_the_given_state_x(lab_camera):
    """With x given, h and J are evaluated at x (not at the mean); without it, at the mean"""
    state = random_state(2)
    mu = state.density.mean
    x = mu.copy()
    x[6:9] += [0.02, -0.01, 0.03]                   # body moved
    x[landmark_columns(1)] += [0.05, 0.0, -0.02]    # landmark 1 moved
    h_x, _ = state.predict_feature_bundle(lab_camera, [1, 2], x)
    for k, j in enumerate([1, 2]):
        pixel = lab_camera.body_to_pixel(x[landmark_columns(j)], x[6:12])
        expect_close(h_x[2 * k:2 * k + 2], pixel, "h at x (landmark %d)" % j, given={"x - mean": x - mu},
                     rtol=1e-12, atol=1e-9)
    h_default, J_default = state.predict_feature_bundle(lab_camera, [1, 2])
    h_mean, J_mean = state.predict_feature_bundle(lab_camera, [1, 2], mu)
    expect_close(h_default, h_mean, "h without x equals h at x = mean", rtol=0, atol=0)
    expect_close(J_default, J_mean, "J without x equals J at x = mean", rtol=0, atol=0)


def expect_central_differences(state, camera, idx, given):
    """J against central differences of h, block by block (a 2 × 3 block is readable), then as a whole."""
    x0 = state.density.mean
    _, J = state.predict_feature_bundle(camera, idx)
    numeric = numeric_jacobian(lambda x: state.predict_feature_bundle(camera, idx, x)[0], x0)
    expect_shape(J, numeric.shape, "J", given=given)
    for k, j in enumerate(idx):
        rows = slice(2 * k, 2 * k + 2)
        for block, cols in (("∂h/∂rBNn (columns 6..8)", [6, 7, 8]), ("∂h/∂Θnb (columns 9..11)", [9, 10, 11]),
                            ("∂h/∂r_%d (columns %d..%d)" % (j, 12 + 3 * j, 14 + 3 * j), landmark_columns(j))):
            expect_close(J[rows][:, cols], numeric[rows][:, cols], "%s in rows %d, %d (selected landmark %d) "
                         "against central differences" % (block, 2 * k, 2 * k + 1, j), given=given, rtol=1e-5,
                         atol=1e-6)
    expect_close(J, numeric, "the whole J against central differences", given=given, rtol=1e-5, atol=1e-6)


# Central differences with a 1e-6 step (m or rad) differ from the exact J by at most 1.3e-7 px on these states
# (entries up to 1.2e3 px/m): the tolerances rtol 1e-5 and atol 1e-6 hold with margin and are far below the size
# of any wrong block.
@pytest.mark.parametrize("seed", [3, 4])
def test_jacobian_matches_central_differences(lab_camera, seed):
    """J is the derivative of h with respect to the whole state x (central differences, lab camera)"""
    state = random_state(seed)
    expect_central_differences(state, lab_camera, [3, 0, 4], given={"idx_landmarks": [3, 0, 4],
                                                                   "body pose": state.density.mean[6:12]})


def test_jacobian_with_a_camera_mounted_off_the_body(lab_camera):
    """With a camera offset rCBb and rotation Rbc on the body (eq 5), J is still the derivative of h"""
    mounted = Camera(lab_camera.K, lab_camera.dist_coeffs, lab_camera.image_size, r_cb_b=[0.02, 0.0, -0.01],
                     R_bc=rpy2rot([0.05, -0.03, 0.02]))
    state = random_state(5, n_landmarks=3)
    expect_central_differences(state, mounted, [0, 1, 2], given={"r_cb_b": mounted.r_cb_b,
                                                                "idx_landmarks": [0, 1, 2]})


def test_jacobian_has_the_block_structure_of_eq_9(lab_camera):
    """Each block row is non-zero only in the body-pose columns 6..11 and its own landmark's three columns"""
    state = random_state(6)
    idx = [4, 1, 2]
    _, J = state.predict_feature_bundle(lab_camera, idx)
    for k, j in enumerate(idx):
        nonzero = np.flatnonzero(np.any(J[2 * k:2 * k + 2] != 0, axis=0))
        expect_equal(nonzero, np.r_[6:12, landmark_columns(j)], "the non-zero columns of rows %d, %d "
                     "(selected landmark %d)" % (2 * k, 2 * k + 1, j), given={"idx_landmarks": idx})


def test_bad_arguments_raise_a_value_error_naming_them(lab_camera):
    """A landmark index out of range, repeated or missing names idx_landmarks; a wrong x names x"""
    state = random_state(7, n_landmarks=3)
    for bad, what in (([0, 3], "idx_landmarks = [0, 3] with 3 landmarks"), ([-1], "idx_landmarks = [-1]"),
                      ([], "an empty idx_landmarks"), ([1, 1], "idx_landmarks = [1, 1] (repeated)")):
        expect_raises(ValueError, state.predict_feature_bundle, lab_camera, bad, what=what,
                      mentions=["idx_landmarks"])
    expect_raises(ValueError, state.predict_feature_bundle, lab_camera, [0], np.zeros(state.size - 1),
                  what="x of the wrong length", mentions=["x"])
    expect_raises(ValueError, state.predict_feature_bundle, lab_camera, [0], np.full(state.size, np.nan),
                  what="x with NaN entries", mentions=["x"])
    expect_raises(ValueError, state.predict_feature_bundle, None, [0], what="camera = None", mentions=["camera"])
