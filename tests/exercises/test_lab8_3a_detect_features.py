"""Lab 8, task 3a: point features (corners) of an image (public tests).

Small synthetic images whose corners are known (a bright rectangle, two equal squares, a constant image) and
properties of the result (order, cap, suppression, input types, bad arguments). The pixel-by-pixel check of the
definition on random textures is one of the instructor's hidden tests.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from feedback import expect_close, expect_equal, expect_raises, expect_true

from helpers.features import Features, detect_features

#: (x, y) of the four corners of the rectangle of rectangle_image()
CORNERS = np.array([[40, 30], [120, 30], [120, 90], [40, 90]])


def rectangle_image(dtype=np.uint8):
    """A bright 80 × 60 px rectangle on a dark 160 × 128 background, slightly blurred (like a lens)."""
    img = np.full((128, 160), 30, np.uint8)
    img[30:90, 40:120] = 220
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    return img if dtype == np.uint8 else img.astype(dtype) / 255.0


def random_image(seed, shape=(40, 50)):
    """A blurred random texture: corners everywhere, of all strengths."""
    img = (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)
    return cv2.GaussianBlur(img, (0, 0), 1.0)


def as_set(features):
    return set(zip(np.asarray(features.x).tolist(), np.asarray(features.y).tolist()))


def test_returns_features_strongest_first_ties_in_raster_order():
    """The result is a Features object, sorted by descending score; equal scores in raster order (row by row)"""
    img = np.full((60, 90), 40, np.uint8)
    img[20:40, 10:30] = 200                       # two equal squares: their corners have equal responses
    img[20:40, 50:70] = 200
    f = detect_features(img, threshold=0.1, nms_radius=3)
    expect_true(isinstance(f, Features), "the result is a helpers.features.Features", actual=type(f).__name__)
    expect_true(len(f) >= 8, "two squares give at least their 8 corners", actual=len(f))
    expect_true(np.asarray(f.x).dtype.kind == "i" and np.asarray(f.y).dtype.kind == "i",
                "x and y are integer pixel coordinates", actual=(np.asarray(f.x).dtype, np.asarray(f.y).dtype))
    for k in range(len(f) - 1):
        a, b = (float(f.score[k]), int(f.y[k]), int(f.x[k])), (float(f.score[k + 1]), int(f.y[k + 1]), int(f.x[k + 1]))
        expect_true(a[0] > b[0] or (a[0] == b[0] and a[1:] < b[1:]),
                    "feature %d comes before feature %d: a higher score, or an equal score and earlier in raster "
                    "order (y, then x)" % (k, k + 1), actual={"score, y, x of %d" % k: a, "of %d" % (k + 1): b})


@pytest.mark.parametrize("method", ["shi-tomasi", "harris"])
def test_rectangle_corners_are_the_four_strongest(method):
    """The four strongest features of a rectangle are its four corners (within 3 px), and nothing else is found"""
    f = detect_features(rectangle_image(), method=method, nms_radius=5, threshold=0.05)
    given = {"image": "rectangle_image()", "method": method, "nms_radius": 5, "threshold": 0.05}
    expect_true(len(f) >= 4, "at least four features", given=given, actual=len(f))
    top = np.column_stack([f.x[:4], f.y[:4]])
    d = np.linalg.norm(top[:, None, :] - CORNERS[None, :, :], axis=2)
    expect_true(np.all(d.min(axis=0) <= 3.0) and np.all(d.min(axis=1) <= 3.0),
                "the four strongest features sit on the four corners %s" % CORNERS.tolist(), given=given,
                actual=top)
    every = np.column_stack([f.x, f.y])
    far = np.linalg.norm(every[:, None, :] - CORNERS[None, :, :], axis=2).min(axis=1) > 4.0
    expect_true(not np.any(far), "edges and flat areas give no features (all within 4 px of a corner)",
                given=given, actual=every[far])


@pytest.mark.parametrize("image", [np.full((50, 60), 128, np.uint8), np.full((50, 60), 0.25, np.float64)],
                         ids=["uint8", "float"])
def test_constant_image_gives_no_features(image):
    """A constant image has no corner: an empty Features (len 0, Y of shape (2, 0)), not an error"""
    f = detect_features(image)
    expect_equal(len(f), 0, "the number of features of a constant image", given={"image": "constant %s" % image.dtype})
    expect_equal(f.Y.shape, (2, 0), "Y of a constant image")


def test_max_features_keeps_the_strongest():
    """max_features caps the list at the strongest features"""
    img = random_image(2, (60, 70))
    every = detect_features(img, threshold=0.0, max_features=10**6)
    capped = detect_features(img, threshold=0.0, max_features=20)
    expect_equal(len(capped), 20, "the number of features with max_features = 20", given={"threshold": 0.0})
    expect_close(np.asarray(capped.score, float), np.sort(np.asarray(every.score, float))[::-1][:20],
                 "the scores of the 20 kept features are the 20 largest", rtol=0, atol=0)


def test_suppression_turns_a_corners_cluster_into_one_feature():
    """Without suppression a corner gives a cluster of pixels; with smoothing and suppression one feature each"""
    raw = detect_features(rectangle_image(), threshold=0.05)
    one = detect_features(rectangle_image(), threshold=0.05, nms_radius=3, smoothing=1.0)
    expect_true(len(raw) > 16, "a cluster of features around each corner without suppression", actual=len(raw))
    expect_equal(len(one), 4, "the number of features with smoothing = 1 and nms_radius = 3",
                 given={"threshold": 0.05})


def test_uint8_float_and_colour_images_agree():
    """A uint8 image, the same image as floats in [0, 1] and as a BGR colour image give the same features"""
    a = detect_features(rectangle_image(), nms_radius=3)
    for other, what in ((rectangle_image(np.float32), "float32 / 255"),
                        (cv2.cvtColor(rectangle_image(), cv2.COLOR_GRAY2BGR), "BGR uint8")):
        b = detect_features(other, nms_radius=3)
        expect_equal(np.column_stack([b.x, b.y]), np.column_stack([a.x, a.y]),
                     "the features of the %s image against the uint8 gray one" % what)


@pytest.mark.parametrize("kwargs, name", [
    ({"max_features": 0}, "max_features"), ({"max_features": 2.5}, "max_features"),
    ({"threshold": 1.0}, "threshold"), ({"threshold": -0.1}, "threshold"), ({"threshold": float("nan")}, "threshold"),
    ({"nms_radius": -1}, "nms_radius"), ({"smoothing": -1.0}, "smoothing"), ({"border": 64}, "border"),
    ({"method": "fast"}, "method"), ({"image": [[1, 2], [3, 4]]}, "image")])
def test_bad_arguments_raise_a_value_error_naming_them(kwargs, name):
    """A bad argument raises ValueError naming it"""
    args = {"image": rectangle_image()} | kwargs
    shown = {k: v for k, v in kwargs.items()}
    expect_raises(ValueError, detect_features, **args, what="detect_features with %s" % shown, mentions=[name])
