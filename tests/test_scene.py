"""Rendered lab scene (helpers.scene): determinism, geometry against world_to_pixel, lab pose recovery."""
import numpy as np
import pytest

from helpers.association.lab_demo import DEMO_DETECTOR
from helpers.camera import Camera, load_lab_camera
from helpers.features import detect_features
from helpers.scene import (LAB_LANDMARKS, REFERENCE_POSE, ChessboardNotFoundError, board_points,
                           find_board_corners, recover_pose, render_lab_scene)


@pytest.fixture(scope="module")
def camera():
    return load_lab_camera()


@pytest.fixture(scope="module")
def small_camera(camera):
    """The lab lens at a quarter of the resolution (cheap renders for determinism tests)."""
    K = camera.K.copy()
    K[:2] /= 4.0
    K[:2, 2] = (camera.K[:2, 2] + 0.5) / 4.0 - 0.5
    return Camera(K, camera.dist_coeffs, (480, 360))


@pytest.fixture(scope="module")
def scene(camera):
    return render_lab_scene(camera)


def test_full_resolution_image_and_true_pose(scene, camera):
    assert scene.image.shape == (1440, 1920) and scene.image.dtype == np.uint8
    np.testing.assert_array_equal(scene.pose, REFERENCE_POSE)
    assert 40 < scene.image.mean() < 200 and scene.image.std() > 30      # textured, not blank


def test_rendered_board_corners_land_where_world_to_pixel_says(scene, camera):
    corners = find_board_corners(scene.image)
    expected = camera.world_to_pixel(board_points(), scene.pose)
    err = np.hypot(*(corners - expected))
    assert corners.shape == (2, 70)
    assert err.max() < 0.5, f"max corner error {err.max():.3f} px"
    assert err.mean() < 0.25


def test_lab_pose_recovery_reproduces_the_true_pose(scene, camera):
    pose, corners = recover_pose(scene.image, camera)
    assert np.linalg.norm(pose[:3] - scene.pose[:3]) < 1e-3               # < 1 mm
    assert np.max(np.abs(pose[3:] - scene.pose[3:])) < 1.5e-3             # < 1.5 mrad per angle


def test_every_landmark_has_a_detected_corner_at_its_true_projection(scene, camera):
    f = detect_features(scene.image, **DEMO_DETECTOR)
    truth = camera.world_to_pixel(LAB_LANDMARKS.T, scene.pose)
    d = np.hypot(f.Y[0][:, None] - truth[0], f.Y[1][:, None] - truth[1])   # (m, 9)
    assert np.all(d.min(axis=0) < 1.0)
    # the next feature is well separated, so "the feature at the true projection" is well defined
    assert np.all(np.sort(d, axis=0)[1] > 5.0)


def test_same_seed_same_bytes_other_seed_other_texture(small_camera):
    a = render_lab_scene(small_camera, seed=3)
    b = render_lab_scene(small_camera, seed=3)
    c = render_lab_scene(small_camera, seed=4)
    assert a.image.tobytes() == b.image.tobytes()
    assert a.image.tobytes() != c.image.tobytes()


def test_occluder_blanks_a_landmark_and_card_follows_landmark_8(small_camera):
    j = 7
    plain = render_lab_scene(small_camera, noise_sigma=0.0)
    hidden = render_lab_scene(small_camera, noise_sigma=0.0, occluders=LAB_LANDMARKS[j, :2, None], occluder_half=0.03)
    x, y = np.round(small_camera.world_to_pixel(LAB_LANDMARKS[j], REFERENCE_POSE)).astype(int)
    win = np.s_[y - 3:y + 4, x - 3:x + 4]
    assert plain.image[win].std() > 30                     # checker at the landmark
    assert hidden.image[win].std() < 2                     # uniform grey patch
    no_card = render_lab_scene(small_camera, noise_sigma=0.0, card=False)
    x8, y8 = np.round(small_camera.world_to_pixel(LAB_LANDMARKS[8], REFERENCE_POSE)).astype(int)
    assert plain.image[y8 - 3:y8 + 4, x8 - 3:x8 + 4].std() > 30
    assert np.any(no_card.image[y8 - 6:y8 + 7, x8 - 6:x8 + 7] != plain.image[y8 - 6:y8 + 7, x8 - 6:x8 + 7])


def test_blank_image_has_no_chessboard(camera):
    with pytest.raises(ChessboardNotFoundError):
        recover_pose(np.full((1440, 1920), 128, np.uint8), camera)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"camera": "camera.xml"}, "camera"),
        ({"pose": np.zeros(5)}, "pose"),
        ({"pose": np.full(6, np.nan)}, "pose"),
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"markers": np.zeros((2, 3))}, "markers"),
        ({"markers": np.array([[0.0], [0.0], [0.1]])}, "markers"),
        ({"occluders": np.zeros((3, 1))}, "occluders"),
        ({"occluder_half": 0.0}, "occluder_half"),
        ({"supersample": 0}, "supersample"),
        ({"blur_sigma": -1.0}, "blur_sigma"),
        ({"noise_sigma": np.nan}, "noise_sigma"),
    ],
)
def test_render_bad_inputs(small_camera, kwargs, word):
    args = {"camera": small_camera} | kwargs
    with pytest.raises(ValueError, match=word):
        render_lab_scene(**args)


def test_pose_recovery_bad_inputs(camera):
    with pytest.raises(ValueError, match="image"):
        find_board_corners(np.zeros((10, 10), np.float64))
    with pytest.raises(ValueError, match="camera"):
        recover_pose(np.zeros((10, 10), np.uint8), "camera")
