"""Coursework 02, Q3b(ii): value checks against the answer key on a q3_b run (instructor's tests, not shipped).

Fixture ``cw_q3b_pruning_hidden`` (tools/fixture_recipes_q2q3.py): the landmark-edge tables the q3_b hook was
given before the optimisations at ticks 500 and 1000 of a q3_b run, and the keep masks the answer key returned.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_equal, fixture
from test_cw_q3b_pruning import select

from helpers.drivebot.pruning import KeyframePruning

DATA = fixture("cw_q3b_pruning_hidden")
KEYS = ("vertex", "landmark", "vehicle_ids", "headings", "dt", "vertex_pos")


@pytest.mark.parametrize("call", [0, 1])
def test_keep_masks_of_a_q3b_run(call):
    """On the tables of a q3_b run (ticks 500 and 1000) the keyframe rule keeps the answer key's landmark edges"""
    tab = {key: DATA["call%d_%s" % (call, key)] for key in KEYS}
    tab["edges"] = ["edge %d" % t for t in range(len(tab["vertex"]))]
    rule = KeyframePruning(stride=DATA["stride"], rate_threshold=DATA["rate_threshold"], window=DATA["window"])
    given = {"table": "the q3_b hook's call %d (%d vehicle vertices, %d landmark edges)" % (
        call + 1, len(tab["vehicle_ids"]), len(tab["vertex"])), "stride": DATA["stride"],
        "rate_threshold": DATA["rate_threshold"], "window": DATA["window"]}
    keep = select(rule, tab, given)
    expected = DATA["call%d_keep" % call]
    wrong = np.flatnonzero(keep != expected)
    expect_equal({"edges kept": int(keep.sum()), "vehicle ids of the edges decided differently":
                  sorted(set(tab["vertex"][wrong].tolist()))[:20]},
                 {"edges kept": int(expected.sum()), "vehicle ids of the edges decided differently": []},
                 "the keep mask against the answer key's", given=given)
