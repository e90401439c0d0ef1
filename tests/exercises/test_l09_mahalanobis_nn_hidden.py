"""Lecture L09: Mahalanobis nearest neighbour (hidden tests: the answer key's results).

The range-bearing scenes of notebooks 06–08 with a large pose error (drawn again by ``l09_scenes_hidden.py``; the
fixture holds their observations to tell a changed generator from a wrong answer) and the lab's camera scene
(recorded in full: its density comes from Lab 8 task 1c). Expected values: the fixture ``l09_mahalanobis_nn_hidden``,
recorded from the answer key by ``tools/fixture_recipes_l09.py``.
"""
from __future__ import annotations

import numpy as np
from l09_scenes_hidden import describe, camera_scene, recorded_scenes
from feedback import expect_close, fail, fixture

from helpers.association.nearest_neighbour import mahalanobis_nn

NAME = "l09_mahalanobis_nn_hidden"
RECORDED = fixture(NAME)


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
    for s, sc in recorded_scenes(RECORDED, NAME):
        for name, kwargs in (("s3", {}), ("s2", {"n_sigma": 2.0})):
            check(mahalanobis_nn(sc.density, sc.Y, **kwargs), "rb%d_%s" % (s, name),
                  "range-bearing scene %d with %s" % (s, kwargs or "n_sigma = 3"),
                  {"scene": describe(s), "options": kwargs})


def test_recorded_camera_scene():
    """The answer key's pairs on the lab's camera scene (9 landmarks, 50 clutter features), at n_sigma = 3 and 2"""
    density, Y, _ = camera_scene(RECORDED)
    for name, kwargs in (("s3", {}), ("s2", {"n_sigma": 2.0})):
        check(mahalanobis_nn(density, Y, **kwargs), "cam_" + name, "the camera scene with %s"
              % (kwargs or "n_sigma = 3"), {"scene": "the lab camera scene", "options": kwargs})
