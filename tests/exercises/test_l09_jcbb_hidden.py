"""Lecture L09: JCBB (hidden tests: the answer key's results on realistic scenes, and the node count).

The range-bearing scenes of notebooks 06–08 with a large pose error (drawn again by ``l09_scenes_hidden.py``; the
fixture holds their observations to tell a changed generator from a wrong answer) and the lab's camera scene
(recorded in full: its density comes from Lab 8 task 1c), with the number of expanded nodes; and the compiled
JCBB of the advanced part (helpers.advanced.jcbb_fast, not an exercise: one compiled loop over an explicit
stack, written apart from the course's search), which expands the same nodes. Expected values: the fixture
``l09_jcbb_hidden``, recorded from the answer key by ``tools/fixture_recipes_l09.py``.
"""
from __future__ import annotations

import inspect

import numpy as np
from l09_scenes_hidden import describe, camera_scene, recorded_scenes
from feedback import expect_close, expect_equal, fail, fixture
from hypothesis import given, settings
from hypothesis import strategies as st
from test_l09_jcbb import random_scene

import helpers.advanced.jcbb_fast as compiled
from helpers.association.jcbb import jcbb
from helpers.gaussian import Gaussian

NAME = "l09_jcbb_hidden"
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


def check_search(res, key, what, given):
    check(res, key, what, given)
    expect_equal(int(res.stats["nodes"]), int(RECORDED[key + "_nodes"]), what + ": stats['nodes'], the expanded "
                 "nodes", given=given)
    expect_equal(bool(res.budget_exhausted), bool(RECORDED[key + "_exhausted"]), what + ": budget_exhausted",
                 given=given)


def test_recorded_range_bearing_scenes():
    """The answer key's hypothesis and node count on six range-bearing scenes with a large pose error: the full
    search, a budget of 30 nodes, and n_sigma = 2"""
    for s, sc in recorded_scenes(RECORDED, NAME):
        for name, kwargs in (("full", {}), ("budget30", {"max_nodes": 30}), ("s2", {"n_sigma": 2.0})):
            check_search(jcbb(sc.density, sc.Y, **kwargs), "rb%d_%s" % (s, name),
                         "range-bearing scene %d with %s" % (s, kwargs or "n_sigma = 3"),
                         {"scene": describe(s), "options": kwargs})


def test_recorded_camera_scene():
    """The lab's camera scene (9 landmarks, 50 clutter features): every detected landmark found, no clutter
    taken, in the answer key's node count (and with a budget of 5 nodes)"""
    density, Y, truth = camera_scene(RECORDED)
    given = {"scene": "the lab camera scene", "truth": truth}
    full = jcbb(density, Y)
    expect_equal(np.asarray(full.idx).tolist(), truth.tolist(), "the camera scene: idx against the truth",
                 given=given)
    check_search(full, "cam_full", "the camera scene", given)
    check_search(jcbb(density, Y, max_nodes=5), "cam_budget5", "the camera scene with max_nodes = 5", given)


def compiled_is_independent():
    """The compiled JCBB must not run the course's search: comparing with it would check the search with itself."""
    source = inspect.getsource(compiled)
    if "_Search" in source or "association.jcbb import" in source or "association import jcbb" in source:
        fail("the compiled JCBB (helpers.advanced.jcbb_fast) is written apart from the course's search",
             note="it calls the course's jcbb: the comparison would check nothing")


@settings(max_examples=120, deadline=None, derandomize=True, database=None, report_multiple_bugs=False)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 6), m_clutter=st.integers(0, 3),
       n_sigma=st.sampled_from([1.5, 2.0, 3.0]), d=st.sampled_from([1, 2, 2, 3]),
       max_nodes=st.sampled_from([None, None, 1, 2, 4, 8]))
def test_same_nodes_as_the_compiled_jcbb(seed, n, m_clutter, n_sigma, d, max_nodes):
    """On random scenes (d = 1, 2, 3, with and without a budget) the search expands the same nodes as the compiled
    JCBB of the advanced part and returns the same hypothesis"""
    compiled_is_independent()
    mu, cov, Y = random_scene(seed, n, m_clutter, d)
    density = Gaussian.from_cov(mu.ravel(), cov)
    given = {"scene": "random_scene(seed=%d, n=%d, m_clutter=%d, d=%d) in test_l09_jcbb.py" % (seed, n, m_clutter, d),
             "n_sigma": n_sigma, "max_nodes": max_nodes}
    res = jcbb(density, Y, n_sigma=n_sigma, max_nodes=max_nodes)
    ref = compiled.jcbb(density, Y, n_sigma=n_sigma, max_nodes=max_nodes)
    expect_equal(int(res.stats["nodes"]), int(ref.stats["nodes"]), "stats['nodes'], the expanded nodes (root "
                 "included)", given=given)
    expect_equal(bool(res.budget_exhausted), bool(ref.budget_exhausted), "budget_exhausted", given=given)
    expect_equal(np.asarray(res.idx).tolist(), np.asarray(ref.idx).tolist(), "idx", given=given)
    expect_close(res.d2, ref.d2, "D² of the pairings", given=given, rtol=1e-9, atol=1e-12)
