"""Ground-truth helpers of the rendered scene (helpers.scene_truth)."""
import numpy as np
import pytest

from helpers.camera import Camera, load_lab_camera
from helpers.scene import CARD_HALF, LAB_LANDMARKS, REFERENCE_POSE, STICKER_HALF
from helpers.scene_truth import fiducial_half_size, pixel_to_plane, ray_interpolation_error


@pytest.fixture(scope="module")
def camera():
    return load_lab_camera()


def test_pixel_to_plane_inverts_world_to_pixel(camera):
    for j in range(9):
        L = LAB_LANDMARKS[j]
        pixel = camera.world_to_pixel(L, REFERENCE_POSE)
        np.testing.assert_allclose(pixel_to_plane(camera, REFERENCE_POSE, pixel, L[2]), L, atol=1e-9)
    pixels = camera.world_to_pixel(LAB_LANDMARKS[:8].T, REFERENCE_POSE)      # landmarks 0-7 lie on z = 0
    np.testing.assert_allclose(pixel_to_plane(camera, REFERENCE_POSE, pixels), LAB_LANDMARKS[:8].T, atol=1e-9)


def test_pixel_to_plane_behind_the_camera_is_nan(camera):
    # the plane z = -1 lies behind the camera (which sits at z = -0.446 and looks towards +z)
    assert np.all(np.isnan(pixel_to_plane(camera, REFERENCE_POSE, camera.K[:2, 2], -1.0)))


def test_fiducial_half_size():
    assert fiducial_half_size(LAB_LANDMARKS[0]) == STICKER_HALF
    assert fiducial_half_size(LAB_LANDMARKS[8]) == CARD_HALF
    with pytest.raises(ValueError, match="marker"):
        fiducial_half_size([0.0, 0.0])


def test_ray_interpolation_error_is_tiny_inside_the_fold(camera):
    assert ray_interpolation_error(camera, 300) < 0.01
    # a lens without distortion is interpolated exactly (the ray map is affine)
    pinhole = Camera(camera.K, np.zeros(12), camera.image_size)
    assert ray_interpolation_error(pinhole, 300) < 1e-8


@pytest.mark.parametrize("kwargs, word", [({"n_samples": 0}, "n_samples"), ({"inside": 0.0}, "inside"),
                                          ({"inside": 1.5}, "inside")])
def test_bad_inputs(camera, kwargs, word):
    with pytest.raises(ValueError, match=word):
        ray_interpolation_error(camera, **kwargs)
    with pytest.raises(ValueError, match="z0"):
        pixel_to_plane(camera, REFERENCE_POSE, [0.0, 0.0], np.inf)
    with pytest.raises(ValueError, match="pose"):
        pixel_to_plane(camera, np.zeros(5), [0.0, 0.0])
