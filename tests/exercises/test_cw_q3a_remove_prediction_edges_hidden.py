"""Coursework 02, Q3a(ii): value checks against the answer key on a q3_a run (instructor's tests, not shipped).

Fixture ``cw_q3a_remove_prediction_edges_hidden`` (tools/fixture_recipes_q2q3.py): the structure of the first 1100
ticks of a q3_a run with the tick each element was made in, and what the answer key's graphs held right after the
removals at ticks 499 and 999 (where the system optimises), with all prediction edges removed and with all but
the first. The test rebuilds the graph tick by tick, as the prediction and landmark steps would, and removes.
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_equal, fixture

from helpers.drivebot.config import SimulatorConfiguration
from helpers.drivebot.edges import LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from helpers.drivebot.events import Event, EventType
from helpers.drivebot.slam_system import DriveBotSLAMSystem, SLAMOptions
from helpers.graph import EdgeRangeBearing

DATA = fixture("cw_q3a_remove_prediction_edges_hidden")


def differences(actual, expected, label):
    """The ``label``s where the masks differ, as {"in the graph, should not be": [...], "deleted, ...": [...]}."""
    actual, expected = np.asarray(actual, bool), np.asarray(expected, bool)
    return {"in the graph, should not be": np.asarray(label)[actual & ~expected].tolist()[:20],
            "deleted, should not be": np.asarray(label)[~actual & expected].tolist()[:20]}


@pytest.mark.parametrize("variant", ["all", "first"])
def test_removals_in_a_q3a_run(variant):
    """Replaying 1100 ticks of q3_a with removals at ticks 499 and 999 leaves the answer key's vertices and
    prediction edges in the graph"""
    keep_first = variant == "first"
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_laser=True, laser_detection_range=30.0),
                                SLAMOptions(remove_prediction_edges=True, keep_first_prediction_edge=keep_first))
    system.process_events([Event(0.0, EventType.INITIAL_CONDITION, np.zeros(3), np.zeros((3, 3)))])
    graph, vehicles, landmarks = system.graph, {0: system.vehicle_vertices[0]}, {}
    kin, rb, ids = DATA["kin_vertices"], DATA["rb_vertices"], DATA["landmark_id"]
    calls = DATA["call_ticks"].tolist()
    for tick in range(calls[-1] + 1):
        for i in np.flatnonzero(DATA["kin_tick"] == tick).tolist():        # the prediction step
            prev = vehicles[int(kin[i, 0])]
            if prev.graph is not graph:
                graph.add_vertex(prev)
            v = VehicleVertex(0.1 * tick, id=int(kin[i, 1]))
            graph.add_vertex(v)
            e = VehicleKinematicsEdge([prev, v], measurement=np.zeros(3), dt=float(DATA["kin_dt"][i]))
            graph.add_edge(e)
            vehicles[v.id] = v
            system.vehicle_vertices.append(v)
            system.process_model_edges.append(e)
            system.current_vehicle_vertex = v
        for j in np.flatnonzero(DATA["landmark_tick"] == tick).tolist():    # the landmark step
            lid = int(ids[j])
            landmarks[lid] = system.landmark_vertices[lid] = LandmarkVertex(lid, id=lid)
            graph.add_vertex(landmarks[lid])
        for j in np.flatnonzero(DATA["rb_tick"] == tick).tolist():
            graph.add_edge(EdgeRangeBearing([vehicles[int(rb[j, 0])], landmarks[int(rb[j, 1])]],
                                            measurement=[1.0, 0.0]))
        if tick in calls:
            c = calls.index(tick)
            system._delete_prediction_edges()
            given = {"removal": "after tick %d (call %d)" % (tick, c + 1), "keep_first_prediction_edge": keep_first,
                     "vehicle vertices so far": len(system.vehicle_vertices)}
            key = "%s_call%d_" % (variant, c)
            none = {"in the graph, should not be": [], "deleted, should not be": []}
            expect_equal(differences([e.graph is graph for e in system.process_model_edges], DATA[key + "kin"],
                                     np.arange(len(system.process_model_edges))), none,
                         "the prediction edges (index in process_model_edges) in the graph", given=given)
            expect_equal(differences([v.graph is graph for v in system.vehicle_vertices], DATA[key + "vehicle"],
                                     [v.id for v in system.vehicle_vertices]), none,
                         "the vehicle vertices (ids) in the graph", given=given)
            expect_equal(differences([lid in landmarks and landmarks[lid].graph is graph for lid in ids.tolist()],
                                     DATA[key + "landmark"], ids), none, "the landmarks (ids) in the graph",
                         given=given)
