"""Lab 8, task 3a: the detector on the rendered lab scene (hidden tests).

Three 120 × 120 crops of the rendered lab scene (helpers.scene.render_lab_scene, the lab camera at the demo pose)
around landmark 5 (a chessboard corner), landmark 7 (a sticker on the texture) and landmark 8 (the floating card),
recorded with the answer key's features for three detector settings in the fixture
``lab8_3a_detect_features_hidden`` (tools/fixture_recipes_lab8.py).
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest
from feedback import expect_close, expect_equal, expect_true, fixture

from helpers.features import corner_response, detect_features

LANDMARKS = (5, 7, 8)
DETECTORS = {
    "demo": dict(max_features=10000, method="shi-tomasi", threshold=0.01, block_size=5, nms_radius=3, smoothing=1.0),
    "plain": dict(threshold=0.2),
    "harris": dict(method="harris", nms_radius=3, max_features=25),
}


@pytest.fixture(scope="module")
def ref():
    return fixture("lab8_3a_detect_features_hidden")


@pytest.mark.parametrize("crop", range(3), ids=["landmark5", "landmark7", "landmark8"])
@pytest.mark.parametrize("setting", sorted(DETECTORS))
def test_scene_crop_features_equal_the_answer_key(ref, setting, crop):
    """On a crop of the rendered lab scene the features and scores equal the answer key's"""
    f = detect_features(ref["images"][crop], **DETECTORS[setting])
    given = {"image": "120 × 120 crop around landmark %d" % LANDMARKS[crop], "settings": DETECTORS[setting]}
    expected_xy, expected_score = ref["%s_%d_xy" % (setting, crop)], ref["%s_%d_score" % (setting, crop)]
    order = np.lexsort((np.asarray(f.x), np.asarray(f.y)))          # raster order, as recorded
    xy = np.vstack([np.asarray(f.x)[order], np.asarray(f.y)[order]])
    expect_equal(len(f), expected_xy.shape[1], "the number of features", given=given)
    expect_equal(xy, expected_xy, "the feature pixels (x; y) in raster order", given=given)
    expect_close(np.asarray(f.score, float)[order], expected_score, "the scores in raster order", given=given,
                 rtol=1e-5, atol=1e-9)
    expect_true(np.all(np.diff(np.asarray(f.score, float)) <= 0), "the features are sorted strongest first",
                given=given)


@pytest.mark.parametrize("crop", range(3), ids=["landmark5", "landmark7", "landmark8"])
def test_the_landmark_corner_is_detected_at_its_true_pixel(ref, crop):
    """With the workbook demo's settings one feature lies within 1 px of the landmark's true projection and the
    next is more than 5 px away"""
    f = detect_features(ref["images"][crop], **DETECTORS["demo"])
    truth = ref["truth"][:, crop]
    d = np.sort(np.hypot(np.asarray(f.x) - truth[0], np.asarray(f.y) - truth[1]))
    given = {"image": "crop around landmark %d" % LANDMARKS[crop], "true pixel in the crop": truth}
    expect_true(d.size >= 2 and d[0] < 1.0 and d[1] > 5.0, "the nearest feature is within 1 px of the landmark, "
                "the second nearest more than 5 px away", given=given, actual=d[:2])


def random_image(seed, shape=(40, 50)):
    """A blurred random texture: corners everywhere, of all strengths."""
    img = (np.random.default_rng(seed).random(shape) * 255).astype(np.uint8)
    return cv2.GaussianBlur(img, (0, 0), 1.0)


def as_set(features):
    return set(zip(np.asarray(features.x).tolist(), np.asarray(features.y).tolist()))


def qualifying(R, threshold, border, nms_radius=0):
    """The pixels (x, y) the definition keeps, as a set."""
    h, w = R.shape
    inner = np.zeros(R.shape, bool)
    inner[border:h - border, border:w - border] = True
    keep = inner & (R > threshold * R[inner].max()) & (R > 0)
    if nms_radius:
        r = nms_radius
        local_max = np.array([[R[y, x] >= R[max(y - r, 0):y + r + 1, max(x - r, 0):x + r + 1].max()
                               for x in range(w)] for y in range(h)])
        keep &= local_max
    ys, xs = np.nonzero(keep)
    return set(zip(xs.tolist(), ys.tolist()))


@pytest.mark.parametrize("method", ["shi-tomasi", "harris"])
@pytest.mark.parametrize("threshold, border", [(0.3, 4), (0.1, 7)])
def test_features_are_the_pixels_above_the_threshold(method, threshold, border):
    """Without suppression the features are exactly the pixels at least `border` from the edge with
    R > threshold · max(R), each with its response as score"""
    img = random_image(1)
    R = corner_response(img, method)
    f = detect_features(img, method=method, threshold=threshold, border=border)
    given = {"image": "random 40 × 50", "method": method, "threshold": threshold, "border": border}
    expected = qualifying(R, threshold, border)
    got = as_set(f)
    expect_true(len(f) == len(got) == len(expected) and got == expected, "the features are the qualifying pixels",
                given=given, note="expected %d features, got %d; (x, y) missing: %s; not qualifying: %s" % (
                    len(expected), len(f), sorted(expected - got)[:5], sorted(got - expected)[:5]))
    expect_close(np.asarray(f.score, float), R[f.y, f.x].astype(float), "the scores are R at the features",
                 given=given, rtol=1e-6, atol=0)


def test_threshold_is_relative_to_the_strongest_response_inside_the_border():
    """max(R) is taken over the pixels the detector may return: a strong corner in the border strip does not
    raise the threshold"""
    img = np.full((64, 80), 100, np.uint8)
    img[:3, :3] = 255                              # a high-contrast corner at (3, 3): inside the 4-px border strip
    img[20:44, 25:55] = 130                        # a faint rectangle inside
    img = cv2.GaussianBlur(img, (0, 0), 0.8)
    R = corner_response(img)
    f = detect_features(img, threshold=0.5, border=6)
    expected = qualifying(R, 0.5, 6)
    expect_true(as_set(f) == expected and len(expected) > 0, "the faint rectangle's corners are found against "
                "the strongest response inside the border (%.3g), not the image's (%.3g)" % (
                    R[6:-6, 6:-6].max(), R.max()), given={"threshold": 0.5, "border": 6},
                actual=sorted(as_set(f)), note="expected %s" % sorted(expected))


@pytest.mark.parametrize("nms_radius", [1, 3])
def test_non_maximum_suppression_keeps_the_local_maxima(nms_radius):
    """With nms_radius = r a feature must also be the maximum of R in its (2r + 1) × (2r + 1) neighbourhood
    (clipped at the image edge; equal neighbours both stay)"""
    img = random_image(3)
    R = corner_response(img)
    f = detect_features(img, threshold=0.05, nms_radius=nms_radius)
    given = {"image": "random 40 × 50", "threshold": 0.05, "nms_radius": nms_radius}
    expected = qualifying(R, 0.05, 4, nms_radius)
    got = as_set(f)
    expect_true(len(f) == len(got) == len(expected) and got == expected, "the features are the qualifying local "
                "maxima", given=given, note="expected %d features, got %d; (x, y) missing: %s; not local maxima: %s"
                % (len(expected), len(f), sorted(expected - got)[:5], sorted(got - expected)[:5]))


def test_smoothing_blurs_the_response_first():
    """With smoothing σ the detector works on R blurred by a Gaussian of σ px (cv2.GaussianBlur(R, (0, 0), σ))"""
    img = random_image(4)
    Rs = cv2.GaussianBlur(corner_response(img), (0, 0), 1.5)
    f = detect_features(img, threshold=0.1, smoothing=1.5, nms_radius=2)
    expected = qualifying(Rs, 0.1, 4, 2)
    given = {"threshold": 0.1, "smoothing": 1.5, "nms_radius": 2}
    got = as_set(f)
    expect_true(len(f) == len(got) == len(expected) and got == expected, "the features of the smoothed response",
                given=given, note="expected %d features, got %d; (x, y) missing: %s; not expected: %s" % (
                    len(expected), len(f), sorted(expected - got)[:5], sorted(got - expected)[:5]))
    expect_close(np.asarray(f.score, float), Rs[f.y, f.x].astype(float), "the scores are the smoothed R",
                 given=given, rtol=1e-6, atol=0)
