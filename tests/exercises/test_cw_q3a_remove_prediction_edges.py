"""Coursework 02, Q3a(ii): deleting the vehicle prediction edges before an optimisation (public tests).

The graphs are built by hand with the graph API, as the prediction step would build them (one vehicle vertex and
one VehicleKinematicsEdge per tick, listed in ``process_model_edges``) plus a few landmark observations; the
prediction step itself (another exercise) does not run.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal

from helpers.drivebot.config import SimulatorConfiguration
from helpers.drivebot.edges import LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from helpers.drivebot.events import Event, EventType
from helpers.drivebot.slam_system import DriveBotSLAMSystem, SLAMOptions
from helpers.graph import EdgeRangeBearing

#: vehicle vertex id -> the landmarks it observes (the others observe none)
OBSERVED = {0: [1], 2: [1, 2], 3: [2], 6: [1], 7: [2]}


def make_system(keep_first: bool, ticks: int = 8, observed=OBSERVED) -> DriveBotSLAMSystem:
    """A system asked to remove the prediction edges, with vehicle vertices 0 (fixed) .. ticks − 1 in a chain of
    prediction edges, landmarks 1 and 2, and the landmark observations of ``observed``."""
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_laser=True),
                                SLAMOptions(remove_prediction_edges=True, keep_first_prediction_edge=keep_first))
    system.process_events([Event(0.0, EventType.INITIAL_CONDITION, np.zeros(3), np.zeros((3, 3)))])
    for lid, where in ((1, [20.0, 10.0]), (2, [40.0, -10.0])):
        system.landmark_vertices[lid] = LandmarkVertex(lid, id=lid, estimate=where)
        system.graph.add_vertex(system.landmark_vertices[lid])
    observe(system, system.vehicle_vertices[0], observed)
    extend(system, range(1, ticks), observed)
    return system


def observe(system, vehicle, observed) -> None:
    for lid in observed.get(vehicle.id, []):
        system.graph.add_edge(EdgeRangeBearing([vehicle, system.landmark_vertices[lid]], measurement=[20.0, 0.5]))


def extend(system, ids, observed=OBSERVED) -> None:
    """Add the vehicle vertices ``ids`` as the prediction step does: a vertex and a prediction edge from the
    current vertex (put back into the graph first if it has been deleted), then its observations."""
    for k in ids:
        prev = system.current_vehicle_vertex
        if prev.graph is not system.graph:
            system.graph.add_vertex(prev)
        v = VehicleVertex(0.1 * k, id=k, estimate=[2.0 * k, 0.0, 0.0])
        system.graph.add_vertex(v)
        e = VehicleKinematicsEdge([prev, v], measurement=[20.0, 0.0, 0.0], dt=0.1)
        system.graph.add_edge(e)
        system.vehicle_vertices.append(v)
        system.process_model_edges.append(e)
        system.current_vehicle_vertex = v
        observe(system, v, observed)


def describe(system, note=""):
    """What the test built, for the failure message."""
    return {"vehicle vertices": "0 (fixed) to %d, one prediction edge per consecutive pair" % (
                len(system.vehicle_vertices) - 1),
            "landmark observations {vehicle id: landmarks}": OBSERVED,
            "keep_first_prediction_edge": system.options.keep_first_prediction_edge,
            **({"note": note} if note else {})}


def in_graph(system, elements):
    return [x.graph is system.graph for x in elements]


def ids_in_graph(system):
    return sorted(v.id for v in system.vehicle_vertices if v.graph is system.graph)


def test_removes_every_prediction_edge():
    """With keep_first_prediction_edge=False every prediction edge leaves the graph"""
    system = make_system(keep_first=False)
    given = describe(system)
    system._delete_prediction_edges()
    expect_equal(in_graph(system, system.process_model_edges), [False] * 7,
                 "which of the 7 prediction edges are still in the graph", given=given)
    expect_equal(sum(isinstance(e, VehicleKinematicsEdge) for e in system.graph.edges()), 0,
                 "the VehicleKinematicsEdges in the graph", given=given)
    expect_equal(ids_in_graph(system), sorted(OBSERVED),
                 "the vehicle vertices still in the graph (those left without edges are deleted by the graph)",
                 given=given)


def test_keeps_the_first_prediction_edge_when_asked():
    """With keep_first_prediction_edge=True the very first prediction edge stays and all others leave"""
    system = make_system(keep_first=True)
    given = describe(system)
    system._delete_prediction_edges()
    expect_equal(in_graph(system, system.process_model_edges), [True] + [False] * 6,
                 "which of the 7 prediction edges are still in the graph", given=given)
    expect_equal(ids_in_graph(system), sorted(set(OBSERVED) | {1}), "the vehicle vertices still in the graph",
                 given=given)


def test_leaves_the_landmark_observations_alone():
    """The landmark edges, the landmarks and every estimate are left as they were"""
    system = make_system(keep_first=False)
    given = describe(system)
    landmark_edges = [e for e in system.graph.edges() if isinstance(e, EdgeRangeBearing)]
    estimates = {v: v.estimate for v in system.graph.vertices()}
    system._delete_prediction_edges()
    expect_equal(in_graph(system, landmark_edges), [True] * len(landmark_edges),
                 "which landmark edges are still in the graph", given=given)
    expect_equal(in_graph(system, system.landmark_vertices.values()), [True, True],
                 "which landmarks are still in the graph", given=given)
    for v, x in estimates.items():
        expect_close(v.estimate, x, "the estimate of %r" % v, given=given)


def test_a_later_call_removes_only_the_edges_added_since():
    """A second call removes the prediction edges added since the first one, keeps the very first edge when asked,
    and does not try to remove an edge that is already gone"""
    for keep_first in (False, True):
        system = make_system(keep_first=keep_first)
        system._delete_prediction_edges()
        extend(system, range(8, 12))                       # four more ticks: vertices 8 .. 11
        given = describe(system, "first call after vertex 7; then vertices 8 to 11 added; then the second call")
        system._delete_prediction_edges()
        expected = [keep_first] + [False] * 10
        expect_equal(in_graph(system, system.process_model_edges), expected,
                     "which of the 11 prediction edges are still in the graph after the second call", given=given)
        expect_equal(ids_in_graph(system), sorted(set(OBSERVED) | ({1} if keep_first else set())),
                     "the vehicle vertices still in the graph after the second call", given=given)


def test_a_call_with_nothing_new_changes_nothing():
    """Called again with no new prediction edge, the method leaves the graph as it is"""
    system = make_system(keep_first=True)
    system._delete_prediction_edges()
    before = (system.graph.number_of_vertices(), system.graph.number_of_edges())
    system._delete_prediction_edges()
    expect_equal((system.graph.number_of_vertices(), system.graph.number_of_edges()), before,
                 "the graph's (vertices, edges) after a second call with nothing new", given=describe(system))


def test_the_optimiser_structure_is_rebuilt_after_the_removal():
    """The method marks the system's structure as changed, so the next build leaves out the deleted vertices"""
    system = make_system(keep_first=True)
    system.ensure_structure()
    system._delete_prediction_edges()
    system.ensure_structure()
    free = 3 * len([i for i in ids_in_graph(system) if i != 0]) + 2 * 2
    expect_equal(system.graph.dimension, free, "the free state dimension after ensure_structure() (3 per free "
                 "vehicle vertex left in the graph, 2 per landmark)", given=describe(system))
