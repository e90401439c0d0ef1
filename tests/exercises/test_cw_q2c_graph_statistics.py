"""Coursework 02, Q2c(i): the statistics of the SLAM system's graph (public tests).

The graphs are built here with the graph API: by hand, and from the recorded graph of a short run with every
DriveBot sensor (fixture ``cw_q2c_short_run``). No SLAM step runs. The expected counts come from how each graph
was built, not from the graph's own queries.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_true, fail, fixture

from helpers.drivebot.config import SimulatorConfiguration
from helpers.drivebot.edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from helpers.drivebot.slam_system import DriveBotSLAMSystem
from helpers.graph import EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2

KEYS = ("vehicle_vertices", "landmark_vertices", "edges_by_type", "landmark_edges", "observations_per_step",
        "observations_per_landmark", "measurement_dimensions", "free_state_dimensions", "dof")


def build_graph(record: dict) -> DriveBotSLAMSystem:
    """A SLAM system whose graph holds the vertices and edges of a graph record (tools/fixture_recipes_q2q3.py,
    ``graph_record``), added with the graph API; estimates and measurements default to zeros when left out."""
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_compass=True, enable_gps=True, enable_laser=True))
    graph = system.graph
    n, n_l = len(record["vehicle_id"]), len(record["landmark_id"])
    vx = record.get("vehicle_x", np.zeros((n, 3)))
    lx = record.get("landmark_x", np.zeros((n_l, 2)))
    vehicles = {}
    for k, vid in enumerate(record["vehicle_id"].tolist()):
        v = VehicleVertex(float(record["vehicle_time"][k]), id=vid, estimate=vx[k],
                          fixed=bool(record["vehicle_fixed"][k]))
        graph.add_vertex(v)
        vehicles[vid] = v
    system.vehicle_vertices = list(vehicles.values())
    system.current_vehicle_vertex = system.vehicle_vertices[-1] if n else None
    for k, lid in enumerate(record["landmark_id"].tolist()):
        v = LandmarkVertex(lid, id=lid, estimate=lx[k])
        graph.add_vertex(v)
        system.landmark_vertices[lid] = v

    def add(cls, rows, z, info, **params):
        if len(rows):
            return graph.add_edges(cls, rows, z, info, **params)
        return []

    kin = record["kin_vertices"]
    system.process_model_edges = add(
        VehicleKinematicsEdge, [(vehicles[a], vehicles[b]) for a, b in kin.tolist()],
        record.get("kin_z", np.zeros((len(kin), 3))), record["kin_info"], dt=record["kin_dt"])
    rb = record["rb_vertices"]
    add(EdgeRangeBearing, [(vehicles[a], system.landmark_vertices[b]) for a, b in rb.tolist()],
        record.get("rb_z", np.zeros((len(rb), 2))), record["rb_info"])
    cv, buggy = record["compass_vertex"], record["compass_buggy"]
    cz = record.get("compass_z", np.zeros((len(cv), 1)))
    for cls, which in ((EdgeHeadingPrior, ~buggy), (BuggyCompassEdge, buggy)):
        add(cls, [(vehicles[a],) for a in cv[which].tolist()], cz[which], record["compass_info"],
            offset=record["compass_offset"])
    gv = record["gps_vertex"]
    add(EdgePositionPrior, [(vehicles[a],) for a in gv.tolist()], record.get("gps_z", np.zeros((len(gv), 2))),
        record["gps_info"], lever_arm=record["gps_lever_arm"])
    return system


def statistics(system, given=None) -> dict:
    """graph_statistics() with its form checked: a dict with every documented key."""
    stats = system.graph_statistics()
    if not isinstance(stats, dict):
        fail("graph_statistics returns a dict", given=given, actual=type(stats).__name__)
    missing = [k for k in KEYS if k not in stats]
    if missing:
        fail("graph_statistics returns every documented key", given=given, note="missing keys: %s" % missing)
    return stats


def hand_made():
    """A graph built by hand: vehicle vertices 0 (fixed) to 4, landmarks 1 to 3, every kind of edge, and one
    vehicle vertex and one landmark that were in the graph and have been removed (the system's lists keep them)."""
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_compass=True, enable_gps=True, enable_laser=True))
    graph = system.graph
    vehicles = [VehicleVertex(0.1 * k, id=k, estimate=[k, 0.0, 0.0], fixed=(k == 0)) for k in range(6)]
    landmarks = {lid: LandmarkVertex(lid, id=lid, estimate=[lid, 5.0]) for lid in (1, 2, 3, 4)}
    for v in vehicles + list(landmarks.values()):
        graph.add_vertex(v)
    system.vehicle_vertices, system.landmark_vertices = vehicles, landmarks
    system.current_vehicle_vertex = vehicles[4]
    for a, b in zip(vehicles[:5], vehicles[1:5]):                       # 4 prediction edges
        e = VehicleKinematicsEdge([a, b], measurement=[1.0, 0.0, 0.0], dt=0.1)
        graph.add_edge(e)
        system.process_model_edges.append(e)
    observations = [(0, 1), (1, 1), (1, 2), (2, 2), (3, 3), (4, 1), (4, 3)]   # 7 landmark observations
    for k, lid in observations:
        graph.add_edge(EdgeRangeBearing([vehicles[k], landmarks[lid]], measurement=[5.0, 1.0]))
    graph.add_edge(EdgeHeadingPrior([vehicles[2]], measurement=[0.0]))
    graph.add_edge(EdgeHeadingPrior([vehicles[3]], measurement=[0.0]))
    graph.add_edge(BuggyCompassEdge([vehicles[4]], measurement=[0.0]))
    graph.add_edge(EdgePositionPrior([vehicles[4]], measurement=[4.0, 0.0]))
    graph.add_edge(EdgeSE2([vehicles[1], vehicles[4]], measurement=[3.0, 0.0, 0.0]))   # a user's loop closure
    # vehicle 5 and landmark 4 had one edge each, then lost it: the graph deletes them
    for pair in ([vehicles[4], vehicles[5]], [vehicles[2], landmarks[4]]):
        e = (VehicleKinematicsEdge if isinstance(pair[1], VehicleVertex) else EdgeRangeBearing)(pair)
        graph.add_edge(e)
        graph.remove_edge(e)
    return system


HAND_MADE = {"vehicle vertex ids in the graph": [0, 1, 2, 3, 4], "fixed": [0], "landmark ids in the graph": [1, 2, 3],
             "deleted by the graph (still in the system's lists)": "vehicle vertex 5, landmark 4",
             "edges": {"VehicleKinematicsEdge": 4, "EdgeRangeBearing": 7, "EdgeHeadingPrior": 2, "BuggyCompassEdge": 1,
                       "EdgePositionPrior": 1, "EdgeSE2": 1}}


def test_returns_every_documented_key_with_its_type():
    """graph_statistics returns a dict of every documented key: counts as ints, averages as floats, and the
    edge counts as a dict {class name: count}"""
    stats = statistics(hand_made(), HAND_MADE)
    for key in KEYS:
        value = stats[key]
        if key == "edges_by_type":
            ok = isinstance(value, dict) and all(isinstance(k, str) and isinstance(n, (int, np.integer))
                                                 for k, n in value.items())
        elif key.startswith("observations_per"):
            ok = isinstance(value, (float, np.floating))
        else:
            ok = isinstance(value, (int, np.integer)) and not isinstance(value, bool)
        expect_true(ok, "the type of %s" % key, given=HAND_MADE, actual=value)


def test_counts_the_vertices_in_the_graph():
    """The vehicle poses and landmarks are counted in the graph: vertices the graph has deleted do not count"""
    stats = statistics(hand_made(), HAND_MADE)
    expect_equal(stats["vehicle_vertices"], 5, "vehicle_vertices", given=HAND_MADE)
    expect_equal(stats["landmark_vertices"], 3, "landmark_vertices", given=HAND_MADE)


def test_counts_the_edges_by_their_class():
    """Each edge class is counted under its own class name, subclasses included (BuggyCompassEdge is not an
    EdgeHeadingPrior here); landmark_edges counts the range-bearing edges"""
    stats = statistics(hand_made(), HAND_MADE)
    expected = {"BuggyCompassEdge": 1, "EdgeHeadingPrior": 2, "EdgePositionPrior": 1, "EdgeRangeBearing": 7,
                "EdgeSE2": 1, "VehicleKinematicsEdge": 4}
    expect_equal(dict(stats["edges_by_type"]), expected, "edges_by_type", given=HAND_MADE)
    expect_equal(stats["landmark_edges"], 7, "landmark_edges", given=HAND_MADE)


def test_observations_per_pose_and_per_landmark():
    """The averages divide the landmark observations by the vehicle poses and by the landmarks in the graph"""
    stats = statistics(hand_made(), HAND_MADE)
    expect_close(stats["observations_per_step"], 7 / 5, "observations_per_step (landmark edges per vehicle pose)",
                 given=HAND_MADE)
    expect_close(stats["observations_per_landmark"], 7 / 3, "observations_per_landmark", given=HAND_MADE)


def test_dimensions_and_degrees_of_freedom():
    """The measurement dimensions sum each edge's dimension; the free state dimensions leave out fixed vertices;
    dof is their difference"""
    stats = statistics(hand_made(), HAND_MADE)
    measurements = 4 * 3 + 7 * 2 + 2 * 1 + 1 * 1 + 1 * 2 + 1 * 3
    free = 4 * 3 + 3 * 2
    expect_equal(stats["measurement_dimensions"], measurements, "measurement_dimensions", given=HAND_MADE)
    expect_equal(stats["free_state_dimensions"], free, "free_state_dimensions", given=HAND_MADE)
    expect_equal(stats["dof"], measurements - free, "dof", given=HAND_MADE)


def test_an_empty_graph():
    """An empty graph has zero counts and zero averages (no division by zero)"""
    stats = statistics(DriveBotSLAMSystem(), "a system with an empty graph")
    for key in KEYS:
        expected = {} if key == "edges_by_type" else 0
        expect_equal(stats[key], expected, key, given="a system with an empty graph")


def test_a_short_run_with_every_sensor():
    """On the graph of a short run (odometry, compass, GPS and laser), the statistics match how it was built"""
    record = fixture("cw_q2c_short_run")
    system = build_graph(record)
    n_v, n_l = len(record["vehicle_id"]), len(record["landmark_id"])
    counts = {"VehicleKinematicsEdge": len(record["kin_vertices"]), "EdgeRangeBearing": len(record["rb_vertices"]),
              "EdgeHeadingPrior": int(np.sum(~record["compass_buggy"])), "EdgePositionPrior": len(record["gps_vertex"])}
    given = {"vehicle vertices": n_v, "fixed": int(record["vehicle_fixed"].sum()), "landmarks": n_l,
             "edges": counts}
    before = (system.graph.number_of_vertices(), system.graph.number_of_edges())
    stats = statistics(system, given)
    expect_equal((system.graph.number_of_vertices(), system.graph.number_of_edges()), before,
                 "the graph's (vertices, edges) after graph_statistics: it only reads the graph", given=given)
    expect_equal((stats["vehicle_vertices"], stats["landmark_vertices"]), (n_v, n_l),
                 "(vehicle_vertices, landmark_vertices)", given=given)
    expect_equal(dict(stats["edges_by_type"]), counts, "edges_by_type", given=given)
    expect_close(stats["observations_per_step"], counts["EdgeRangeBearing"] / n_v, "observations_per_step",
                 given=given)
    expect_close(stats["observations_per_landmark"], counts["EdgeRangeBearing"] / n_l, "observations_per_landmark",
                 given=given)
    m = 3 * counts["VehicleKinematicsEdge"] + 2 * counts["EdgeRangeBearing"] + counts["EdgeHeadingPrior"] \
        + 2 * counts["EdgePositionPrior"]
    free = 3 * int(np.sum(~record["vehicle_fixed"])) + 2 * n_l
    expect_equal((stats["measurement_dimensions"], stats["free_state_dimensions"], stats["dof"]), (m, free, m - free),
                 "(measurement_dimensions, free_state_dimensions, dof)", given=given)
