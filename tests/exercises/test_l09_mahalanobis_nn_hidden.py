"""Lecture L09: Mahalanobis nearest neighbour (hidden tests: the answer key's results).

The range-bearing scenes of notebooks 06–08 with a large pose error (drawn again here from ``SCENES``; the
fixture holds their observations to tell a changed generator from a wrong answer) and the lab's camera scene
(recorded in full: its density comes from Lab 8 task 1c). Expected values: the fixture ``l09_mahalanobis_nn_hidden``,
recorded from the answer key by ``tools/fixture_recipes_l09.py``.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, fail, fixture

from helpers.association.nearest_neighbour import mahalanobis_nn
from helpers.association.scenarios import range_bearing_scenario
from helpers.gaussian import Gaussian

#: The same list as tools/fixture_recipes_l09.py.
SCENES = [dict(seed=(7, s), n_landmarks=100, n_visible=15, n_clutter=4, candidate_range=12.0,
               pose_sigma=(0.8, 0.8, 0.25)) for s in range(6)]
RECORDED = fixture("l09_mahalanobis_nn_hidden")


def recorded_scenes():
    """(number, scene) of the range-bearing scenes, each checked against the recorded one first."""
    for s, kwargs in enumerate(SCENES):
        sc = range_bearing_scenario(**kwargs)
        same = (sc.Y.shape == RECORDED["rb%d_Y" % s].shape
                and np.allclose(sc.Y, RECORDED["rb%d_Y" % s], rtol=1e-9, atol=1e-10)
                and np.allclose(sc.density.mean, RECORDED["rb%d_mu" % s], rtol=1e-9, atol=1e-10))
        if not same:
            fail("range-bearing scene %d of the hidden tests" % s, note="the scene generator no longer draws the "
                 "recorded scene: re-record the fixture (tools/exercise_fixtures.py record l09_mahalanobis_nn_hidden)")
        yield s, sc


def camera_scene():
    """The lab's camera scene: (density, Y, truth)."""
    return (Gaussian.from_cov(RECORDED["cam_mu"], RECORDED["cam_P"]), RECORDED["cam_Y"],
            np.asarray(RECORDED["cam_truth"]))


def describe(s):
    """The call that draws range-bearing scene s."""
    return "range_bearing_scenario(%s)" % ", ".join("%s=%s" % kv for kv in SCENES[s].items())


def check(res, key, what, given):
    """idx equals the recorded one (the landmarks that differ are shown) and D² the recorded D²."""
    expected, actual = np.asarray(RECORDED[key + "_idx"]), np.asarray(res.idx)
    if actual.shape != expected.shape:
        fail(what + ": idx", given=given, note="expected %d entries (one per landmark), got shape %s"
             % (expected.size, actual.shape))
    differ = np.flatnonzero(actual != expected)
    if differ.size:
        fail(what + ": idx at the landmarks where it differs", given={**given, "landmarks": differ},
             expected=expected[differ], actual=actual[differ],
             note="%d of %d landmarks differ (-1: unpaired)" % (differ.size, expected.size))
    expect_close(res.d2, RECORDED[key + "_d2"], what + ": D² of the pairings", given=given, rtol=1e-8,
                 atol=1e-10)


def test_recorded_range_bearing_scenes():
    """The answer key's pairs on six range-bearing scenes with a large pose error, at n_sigma = 3 and 2"""
    for s, sc in recorded_scenes():
        for name, kwargs in (("s3", {}), ("s2", {"n_sigma": 2.0})):
            check(mahalanobis_nn(sc.density, sc.Y, **kwargs), "rb%d_%s" % (s, name),
                  "range-bearing scene %d with %s" % (s, kwargs or "n_sigma = 3"),
                  {"scene": describe(s), "options": kwargs})


def test_recorded_camera_scene():
    """The answer key's pairs on the lab's camera scene (9 landmarks, 50 clutter features), at n_sigma = 3 and 2"""
    density, Y, _ = camera_scene()
    for name, kwargs in (("s3", {}), ("s2", {"n_sigma": 2.0})):
        check(mahalanobis_nn(density, Y, **kwargs), "cam_" + name, "the camera scene with %s"
              % (kwargs or "n_sigma = 3"), {"scene": "the lab camera scene", "options": kwargs})
