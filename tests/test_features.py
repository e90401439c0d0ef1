"""Corner detector (helpers.features) on synthetic images with known corners."""
import cv2
import numpy as np
import pytest

from helpers.features import Features, corner_response, detect_features

CORNERS = np.array([[40, 30], [120, 30], [120, 90], [40, 90]])  # (x, y) of a filled rectangle


def rectangle_image(dtype=np.uint8):
    img = np.full((128, 160), 30, np.uint8)
    img[30:90, 40:120] = 220                          # pixel corners at (40,30), (119,30), (119,89), (40,89)
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    return img if dtype == np.uint8 else img.astype(dtype) / 255.0


@pytest.mark.parametrize("method", ["shi-tomasi", "harris"])
def test_four_strongest_features_are_the_rectangle_corners(method):
    f = detect_features(rectangle_image(), method=method, nms_radius=5, threshold=0.05)
    assert isinstance(f, Features) and len(f) >= 4
    top = np.column_stack([f.x[:4], f.y[:4]])
    # every true corner has one of the four strongest features within 3 px (and vice versa)
    d = np.linalg.norm(top[:, None, :] - CORNERS[None, :, :], axis=2)
    assert np.all(d.min(axis=0) <= 3.0) and np.all(d.min(axis=1) <= 3.0)
    # edges and flat areas are not corners: every qualifying feature is near a corner
    allf = np.column_stack([f.x, f.y])
    dall = np.linalg.norm(allf[:, None, :] - CORNERS[None, :, :], axis=2).min(axis=1)
    assert np.all(dall <= 4.0)


def test_sorted_descending_capped_and_Y_layout():
    rng = np.random.default_rng(1)
    img = (rng.random((100, 120)) * 255).astype(np.uint8)
    f = detect_features(img, max_features=50, threshold=0.0)
    assert len(f) == 50
    assert np.all(np.diff(f.score) <= 0)
    assert f.Y.shape == (2, 50) and f.Y.dtype == float
    np.testing.assert_array_equal(f.Y[0], f.x)
    np.testing.assert_array_equal(f.Y[1], f.y)
    # scores are the response at the feature pixels; the cap keeps the strongest
    R = corner_response(img, block_size=5)
    np.testing.assert_array_equal(f.score, R[f.y, f.x])
    full = detect_features(img, max_features=10**6, threshold=0.0)
    assert len(full) > 50 and f.score[-1] >= full.score[50]


def test_without_nms_a_corner_gives_a_cluster_and_with_nms_local_maxima_only():
    img = rectangle_image()
    raw = detect_features(img, threshold=0.05)
    nms = detect_features(img, threshold=0.05, nms_radius=5)
    assert len(raw) > 4 * len(nms) >= 16
    R = corner_response(img)
    for x, y in zip(nms.x, nms.y):
        assert R[y, x] == R[y - 5:y + 6, x - 5:x + 6].max()


def test_float_and_uint8_inputs_agree_and_bgr_is_accepted():
    a = detect_features(rectangle_image(), nms_radius=3)
    b = detect_features(rectangle_image(np.float32), nms_radius=3)
    c = detect_features(cv2.cvtColor(rectangle_image(), cv2.COLOR_GRAY2BGR), nms_radius=3)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.y, c.y)


def test_constant_image_gives_no_features():
    f = detect_features(np.full((50, 60), 128, np.uint8))
    assert len(f) == 0 and f.Y.shape == (2, 0)


@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"image": [[1, 2], [3, 4]]}, "image"),
        ({"image": np.zeros((5, 5, 2), np.uint8)}, "image"),
        ({"image": np.zeros((2, 2), np.uint8)}, "image"),
        ({"image": np.full((9, 9), np.nan)}, "image"),
        ({"image": np.zeros((9, 9), np.int64)}, "image"),
        ({"max_features": 0}, "max_features"),
        ({"max_features": 2.5}, "max_features"),
        ({"method": "fast"}, "method"),
        ({"threshold": 1.0}, "threshold"),
        ({"threshold": -0.1}, "threshold"),
        ({"block_size": 1}, "block_size"),
        ({"aperture_size": 4}, "aperture_size"),
        ({"harris_k": 0.5}, "harris_k"),
        ({"nms_radius": -1}, "nms_radius"),
        ({"border": 100}, "border"),
    ],
)
def test_bad_inputs_raise_named_errors(kwargs, word):
    args = {"image": rectangle_image()} | kwargs
    with pytest.raises(ValueError, match=word):
        detect_features(**args)
