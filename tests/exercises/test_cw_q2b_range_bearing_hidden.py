"""Coursework 02, Q2b: value checks against the answer key on a q2_b run (instructor's tests, not shipped).

Fixture ``cw_q2b_range_bearing_hidden`` (tools/fixture_recipes_q2q3.py): the landmark events of the first 400
ticks of a q2_b run with the pose each was seen from, the landmark vertices and edges the answer key made of them,
and the answer key's errors and Jacobians of every range-bearing edge of that graph.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, fixture
from test_cw_q2b_range_bearing import evaluate, initialised_system, landmark_event, range_bearing_edges

from helpers.drivebot.edges import VehicleVertex

DATA = fixture("cw_q2b_range_bearing_hidden")


def test_landmarks_and_edges_of_a_q2b_run():
    """Replaying the landmark events of a q2_b run gives the answer key's landmark vertices and edges"""
    ticks, vehicles, poses = DATA["obs_tick"], DATA["obs_vehicle"], DATA["obs_pose"]
    first = np.flatnonzero(vehicles == 0)
    system = initialised_system(poses[first[0]] if first.size else np.zeros(3))
    for tick in np.unique(ticks).tolist():
        rows = np.flatnonzero(ticks == tick)
        vid = int(vehicles[rows[0]])
        if vid != 0:
            vehicle = VehicleVertex(0.1 * tick, id=vid, estimate=poses[rows[0]])
            system.graph.add_vertex(vehicle)
            system.vehicle_vertices.append(vehicle)
            system.current_vehicle_vertex = vehicle
        system._handle_landmarks(landmark_event(0.1 * tick, DATA["obs_z"][rows].T, DATA["obs_landmark"][rows],
                                                DATA["r_laser"]))
    ids = sorted(system.landmark_vertices)
    expect_equal(ids, DATA["landmark_id"].tolist(), "the landmark ids seen in 400 ticks of q2_b")
    expect_close(np.array([system.landmark_vertices[i].estimate for i in ids]), DATA["landmark_x"],
                 "the landmarks' initial positions (rows: landmark ids %s)" % ids, rtol=1e-9, atol=1e-9)
    edges = range_bearing_edges(system)
    expect_equal(len(edges), len(DATA["edge_z"]), "the number of range-bearing edges")
    expect_equal(np.array([[e.vertex(0).id, e.vertex(1).landmark_id] for e in edges]),
                 np.column_stack([DATA["edge_vehicle"], DATA["edge_landmark"]]),
                 "each edge's (vehicle vertex id, landmark id), in the order the edges were added")
    expect_close(np.array([e.measurement for e in edges]), DATA["edge_z"], "each edge's measurement")


def test_errors_and_jacobians_of_a_q2b_run():
    """The errors and Jacobians of all 391 range-bearing edges of a q2_b run equal the answer key's"""
    e, (j_pose, j_landmark) = evaluate(DATA["pose"], DATA["landmark"], DATA["edge_z"])
    for what, actual, expected in (("the error", e, DATA["error"]), ("J_pose", j_pose, DATA["jacobian_pose"]),
                                   ("J_landmark", j_landmark, DATA["jacobian_landmark"])):
        bad = ~np.isclose(actual, expected, rtol=1e-9, atol=1e-9).reshape(len(e), -1).all(axis=1)
        if bad.any():                                  # show the first edge that differs, with its inputs
            t = int(np.argmax(bad))
            expect_close(actual[t], expected[t], "%s of edge %d (%d of %d edges differ)" % (
                what, t, int(bad.sum()), len(e)), given={"pose": DATA["pose"][t], "landmark": DATA["landmark"][t],
                                                         "z": DATA["edge_z"][t]}, rtol=1e-9, atol=1e-9)
