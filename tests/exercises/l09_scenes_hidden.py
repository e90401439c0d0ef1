"""The recorded scenes the hidden tests of the four L09 exercises grade on (answer key only, like those tests).

The range-bearing scenes of notebooks 06–08 with a large pose error are drawn again from ``SCENES`` and checked
against the observations and means recorded in the exercise's hidden fixture (to tell a changed generator from a
wrong answer); the lab's camera scene is recorded in full (its density comes from Lab 8 task 1c).
"""
from __future__ import annotations

import numpy as np
from feedback import fail

from helpers.association.scenarios import range_bearing_scenario
from helpers.gaussian import Gaussian

#: The same list as tools/fixture_recipes_l09.py.
SCENES = [dict(seed=(7, s), n_landmarks=100, n_visible=15, n_clutter=4, candidate_range=12.0,
               pose_sigma=(0.8, 0.8, 0.25)) for s in range(6)]


def describe(s):
    """The call that draws range-bearing scene s."""
    return "range_bearing_scenario(%s)" % ", ".join("%s=%s" % kv for kv in SCENES[s].items())


def recorded_scenes(recorded, name: str):
    """(number, scene) of the range-bearing scenes, each checked against the one recorded in the fixture
    ``name`` (loaded as ``recorded``) first."""
    for s, kwargs in enumerate(SCENES):
        sc = range_bearing_scenario(**kwargs)
        same = (sc.Y.shape == recorded["rb%d_Y" % s].shape
                and np.allclose(sc.Y, recorded["rb%d_Y" % s], rtol=1e-9, atol=1e-10)
                and np.allclose(sc.density.mean, recorded["rb%d_mu" % s], rtol=1e-9, atol=1e-10))
        if not same:
            fail("range-bearing scene %d of the hidden tests" % s, note="the scene generator no longer draws the "
                 "recorded scene: re-record the fixture (tools/exercise_fixtures.py record %s)" % name)
        yield s, sc


def camera_scene(recorded):
    """The lab's camera scene from the fixture: (density, Y, truth)."""
    return (Gaussian.from_cov(recorded["cam_mu"], recorded["cam_P"]), recorded["cam_Y"],
            np.asarray(recorded["cam_truth"]))
