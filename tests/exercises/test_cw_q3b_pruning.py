"""Coursework 02, Q3b(ii): the keyframe pruning rule, KeyframePruning.select (public tests).

select is given hand-made tables (the form of ``pruning.landmark_edge_table``): straight runs (a constant
heading), turns at 0.3–0.5 rad/s, far from the 0.05 rad/s threshold, and vehicle ids with gaps. Near a change
between straight and turn the smoothed turn rate lies in between, so those vertices are not checked.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_equal, expect_shape, fail

from helpers.drivebot.pruning import KeyframePruning

DT = 0.1


def table(headings, vehicle_ids=None, observations=None, dt=DT):
    """A landmark-edge table: vehicle vertices with ``headings`` (N,) and ``vehicle_ids`` (default 0..N−1);
    ``observations``: (position of the vehicle vertex in those arrays, landmark id) per edge (default: one edge
    per vertex, to landmark 1)."""
    headings = np.asarray(headings, dtype=float)
    n = headings.size
    ids = np.arange(n) if vehicle_ids is None else np.asarray(vehicle_ids, dtype=np.int64)
    obs = [(k, 1) for k in range(n)] if observations is None else observations
    pos = np.array([p for p, _ in obs], dtype=np.int64)
    return {"edges": ["edge %d" % t for t in range(len(obs))],   # stand-ins: select does not need the edge objects
            "vertex": ids[pos], "landmark": np.array([lid for _, lid in obs], dtype=np.int64),
            "vehicle_ids": ids, "headings": headings, "dt": np.full(max(n - 1, 0), dt), "vertex_pos": pos}


def select(rule, tab, given):
    """rule.select(table) with its form checked: a bool array with one entry per edge of the table."""
    keep = rule.select(tab)
    if not isinstance(keep, np.ndarray):
        fail("select returns a numpy array", given=given, actual=type(keep).__name__)
    expect_shape(keep, (len(tab["edges"]),), "the keep mask: one entry per landmark edge of the table", given=given)
    expect_equal(keep.dtype.kind, "b", "the keep mask's dtype kind (b: bool)", given=given)
    return keep


def straight(n, heading=0.3):
    return np.full(n, heading)


def turning(n, rate, start=0.0):
    return start + rate * DT * np.arange(n)


def test_returns_a_bool_mask_over_the_edges():
    """select returns a numpy bool array with one entry per landmark edge of the table"""
    select(KeyframePruning(), table(straight(12)), "12 vertices on a straight line, one edge each")


def test_on_a_straight_line_only_keyframes_keep_their_edges():
    """On a straight line only the vertices whose id is a multiple of the stride keep their landmark edges"""
    for stride in (5, 3):
        tab = table(straight(40))
        given = {"headings": "constant (a straight line)", "vehicle_ids": "0..39", "stride": stride}
        keep = select(KeyframePruning(stride=stride), tab, given)
        expect_equal(keep, tab["vertex"] % stride == 0, "the keep mask (edge t belongs to vertex t)", given=given)


def test_in_a_turn_every_vertex_keeps_its_edges():
    """In a steady turn (0.5 rad/s, well above the threshold) every vertex keeps its landmark edges"""
    tab = table(turning(40, 0.5))
    given = {"turn rate": "0.5 rad/s", "rate_threshold": 0.05, "vehicle_ids": "0..39"}
    expect_equal(select(KeyframePruning(), tab, given), np.ones(40, bool), "the keep mask", given=given)


def test_a_straight_a_turn_and_a_straight():
    """Straight, turning, straight: keyframes only on the straights, every vertex inside the turn"""
    first, turn = straight(40, 0.3), turning(40, 0.4, start=0.3)
    headings = np.r_[first, turn, straight(40, turn[-1])]
    tab = table(headings)
    keep = select(KeyframePruning(stride=5), tab, {"headings": "40 straight, 40 turning at 0.4 rad/s, 40 straight"})
    ids = tab["vehicle_ids"]
    checked = np.r_[0:33, 47:73, 87:120]                     # more than 6 vertices away from a change
    in_turn = (ids >= 40) & (ids < 80)
    expected = in_turn | (ids % 5 == 0)
    bad = [int(i) for i in checked if keep[i] != expected[i]]
    if bad:
        fail("the keep mask away from the changes (vertices 0–32, 47–72, 87–119)",
             given={"headings": "vertices 0–39 straight, 40–79 turning at 0.4 rad/s, 80–119 straight", "stride": 5},
             expected=expected[checked].astype(int), actual=keep[checked].astype(int),
             note="differs at vehicle ids %s" % bad[:12])


def test_keyframes_follow_the_vehicle_ids_not_the_table_positions():
    """Keyframes are the vertices whose vehicle id is a multiple of the stride, also when vertices are missing
    from the graph (ids with gaps), and each edge gets the decision of its own vertex (vertex_pos)"""
    ids = np.r_[0:7, 9:14, 17:30]                            # 25 vertices, ids with two gaps
    obs = [(p, 1 + p % 3) for p in range(ids.size)] + [(p, 9) for p in range(0, ids.size, 2)]
    tab = table(straight(ids.size), vehicle_ids=ids, observations=obs)
    given = {"headings": "constant (a straight line)", "vehicle_ids": ids, "vertex_pos of the edges": tab["vertex_pos"],
             "stride": 5}
    keep = select(KeyframePruning(stride=5), tab, given)
    expect_equal(keep, ids[tab["vertex_pos"]] % 5 == 0, "the keep mask", given=given)


def test_uses_the_rules_own_stride_threshold_and_window():
    """The rule uses its own stride, rate_threshold and window: a 0.1 rad/s turn is a turn for a 0.05 rad/s
    threshold and a straight for a 0.2 rad/s one"""
    tab = table(turning(30, 0.1))
    for threshold, stride, expected in ((0.05, 4, np.ones(30, bool)), (0.2, 4, np.arange(30) % 4 == 0),
                                        (0.2, 7, np.arange(30) % 7 == 0)):
        rule = KeyframePruning(stride=stride, rate_threshold=threshold, window=5)
        given = {"turn rate": "0.1 rad/s", "rate_threshold": threshold, "stride": stride, "window": 5}
        expect_equal(select(rule, tab, given), expected, "the keep mask", given=given)


def test_a_straight_line_across_the_angle_cut():
    """Heading west (ψ ≈ ±π, wrapped) is a straight line: the heading changes are wrapped before they become
    turn rates"""
    headings = np.where(np.arange(30) % 2 == 0, np.pi - 1e-4, -np.pi + 1e-4)
    tab = table(headings)
    given = {"headings": "alternating π − 1e-4 and −π + 1e-4 (a straight line due west)", "stride": 5}
    expect_equal(select(KeyframePruning(stride=5), tab, given), np.arange(30) % 5 == 0, "the keep mask", given=given)
