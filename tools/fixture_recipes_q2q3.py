"""Recipes of the grading fixtures of coursework 02, questions 2 and 3 (``tools/exercise_fixtures.py``).

Every recipe runs the answer key's simulator and SLAM system and records arrays only:

- ``cw_q2c_short_run`` (public): the graph of a short run with every DriveBot sensor (odometry, compass, GPS,
  laser), as vertex and edge tables (``graph_record``), for the Q2c tests to rebuild with the graph API.
- ``cw_q2b_range_bearing_hidden``: the landmark events of a q2_b run, the vehicle pose each was seen from, and the
  landmark vertices and range-bearing edges the answer key made of them; and the answer key's range-bearing errors
  and Jacobians over every edge of that graph.
- ``cw_q2c_graph_statistics_hidden``: the structure of the q2_c run's graph (5273 poses) and the answer key's
  ``graph_statistics`` of it.
- ``cw_q3a_remove_prediction_edges_hidden``: the structure of a q3_a run's graph with the tick each element was
  made in, and which elements the answer key's systems (all prediction edges removed / all but the first) still
  had in their graphs after each removal (events only: the removal does not depend on the estimates).
- ``cw_q3b_pruning_hidden``: the landmark-edge tables (``pruning.landmark_edge_table``) the keyframe hook of a
  q3_b run was given at its two calls, and the keep masks the answer key's ``select`` returned.

Tolerances: the structures, ids and masks are exact; the poses and measurements come from a few thousand
additions of the simulator's noise (round-off ≈ 1e-12 m); the errors and Jacobians are well conditioned (ranges
≥ 0.1 m); the q3b headings have been through one Levenberg–Marquardt optimisation (≈ 1e-9 rad across CPUs).
"""
from __future__ import annotations

import numpy as np
from exercise_fixtures import recipe

from helpers.drivebot.edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from helpers.drivebot.events import EventType
from helpers.drivebot.pruning import KeyframePruning
from helpers.drivebot.runner import question_setup, run_question
from helpers.drivebot.simulator import DriveBotSimulator
from helpers.drivebot.slam_system import DriveBotSLAMSystem, SLAMOptions
from helpers.graph import EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing


def _run_events(name: str, ticks: int, systems: list, seed: int = 0, after_tick=None, **overrides) -> None:
    """Feed ``ticks`` simulator ticks of question ``name`` to every system (no optimisation); ``after_tick(k)``."""
    scenario, config, _ = question_setup(name, **overrides)
    sim = DriveBotSimulator(config, scenario, seed=seed)
    sim.start()
    for k in range(ticks):
        if not sim.keep_running():
            break
        events = sim.events()
        for system in systems:
            system.process_events(events)
        if after_tick is not None:
            after_tick(k, events)
        sim.step()


def graph_record(graph, estimates: bool = True) -> dict:
    """The vertices and edges of a DriveBot graph as arrays (the Q2c and Q3a tests rebuild the graph from them).

    vehicle_id, vehicle_time, vehicle_fixed (N,), [vehicle_x (N, 3)]; landmark_id (L,), [landmark_x (L, 2)];
    per edge class: kin_vertices (K, 2) vehicle ids, kin_dt (K,), [kin_z (K, 3)], kin_info (3, 3);
    rb_vertices (R, 2) [vehicle id, landmark id], [rb_z (R, 2)], rb_info (2, 2); compass_vertex (C,),
    compass_buggy (C,), [compass_z (C, 1)], compass_info (1, 1), compass_offset; gps_vertex (G,), [gps_z (G, 2)],
    gps_info (2, 2), gps_lever_arm (2,). Without ``estimates`` the estimates and measurements are left out.
    """
    vehicles = [v for v in graph.vertices() if isinstance(v, VehicleVertex)]
    landmarks = [v for v in graph.vertices() if isinstance(v, LandmarkVertex)]
    edges = graph.edges()
    kin = [e for e in edges if type(e) is VehicleKinematicsEdge]
    rb = [e for e in edges if type(e) is EdgeRangeBearing]
    compass = [e for e in edges if type(e) in (EdgeHeadingPrior, BuggyCompassEdge)]
    gps = [e for e in edges if type(e) is EdgePositionPrior]
    if len(kin) + len(rb) + len(compass) + len(gps) != len(edges):
        raise ValueError("graph_record: the graph has an edge class it does not record")
    out = {
        "vehicle_id": np.array([v.id for v in vehicles], dtype=np.int64),
        "vehicle_time": np.array([v.time for v in vehicles], dtype=float),
        "vehicle_fixed": np.array([v.fixed for v in vehicles], dtype=bool),
        "landmark_id": np.array([v.landmark_id for v in landmarks], dtype=np.int64),
        "kin_vertices": np.array([[e.vertex(0).id, e.vertex(1).id] for e in kin], dtype=np.int64).reshape(-1, 2),
        "kin_dt": np.array([e.dt for e in kin], dtype=float),
        "kin_info": kin[0].information if kin else np.eye(3),
        "rb_vertices": np.array([[e.vertex(0).id, e.vertex(1).landmark_id] for e in rb], dtype=np.int64).reshape(-1, 2),
        "rb_info": rb[0].information if rb else np.eye(2),
        "compass_vertex": np.array([e.vertex(0).id for e in compass], dtype=np.int64),
        "compass_buggy": np.array([type(e) is BuggyCompassEdge for e in compass], dtype=bool),
        "compass_info": compass[0].information if compass else np.eye(1),
        "compass_offset": float(compass[0].offset) if compass else 0.0,
        "gps_vertex": np.array([e.vertex(0).id for e in gps], dtype=np.int64),
        "gps_info": gps[0].information if gps else np.eye(2),
        "gps_lever_arm": gps[0].lever_arm if gps else np.zeros(2),
    }
    if estimates:
        out.update({
            "vehicle_x": np.array([v.estimate for v in vehicles]).reshape(-1, 3),
            "landmark_x": np.array([v.estimate for v in landmarks]).reshape(-1, 2),
            "kin_z": np.array([e.measurement for e in kin]).reshape(-1, 3),
            "rb_z": np.array([e.measurement for e in rb]).reshape(-1, 2),
            "compass_z": np.array([e.measurement for e in compass]).reshape(-1, 1),
            "gps_z": np.array([e.measurement for e in gps]).reshape(-1, 2),
        })
    return out


# ------------------------------------------------------------------------------------------------ Q2c (public)
@recipe("cw_q2c_short_run", rtol=1e-9, atol=1e-9)
def q2c_short_run() -> dict:
    """60 ticks of the q2_b scenario with the compass, the GPS and the laser: every DriveBot edge class."""
    _, config, _ = question_setup("q2_b", enable_compass=True, enable_gps=True)
    system = DriveBotSLAMSystem(config, SLAMOptions())
    _run_events("q2_b", 60, [system], enable_compass=True, enable_gps=True)
    return graph_record(system.graph)


# ------------------------------------------------------------------------------------------------ Q2b (hidden)
@recipe("cw_q2b_range_bearing_hidden", rtol=1e-9, atol=1e-9)
def q2b_hidden() -> dict:
    """Landmark events of the first 400 ticks of q2_b (no optimisation), the pose each was seen from, and what
    the answer key made of them; the answer key's errors and Jacobians of every range-bearing edge at the end."""
    _, config, _ = question_setup("q2_b")
    system = DriveBotSLAMSystem(config, SLAMOptions())
    seen = {"tick": [], "vehicle": [], "pose": [], "ids": [], "z": []}

    def after(k, events):
        for event in events:
            if event.type is EventType.LANDMARK:
                n = event.data.shape[1]
                seen["tick"] += [k] * n
                seen["vehicle"] += [system.current_vehicle_vertex.id] * n
                seen["pose"] += [system.current_vehicle_vertex.estimate] * n
                seen["ids"] += event.landmark_ids.tolist()
                seen["z"] += event.data.T.tolist()

    _run_events("q2_b", 400, [system], after_tick=after)
    rb = [e for e in system.graph.edges() if type(e) is EdgeRangeBearing]
    ids = sorted(system.landmark_vertices)
    states = [np.array([e.vertex(0).estimate for e in rb]), np.array([e.vertex(1).estimate for e in rb])]
    z = np.array([e.measurement for e in rb])
    err, (jx, jm) = EdgeRangeBearing.evaluate(states, z, {}, True)
    return {
        "obs_tick": np.array(seen["tick"], dtype=np.int64),
        "obs_vehicle": np.array(seen["vehicle"], dtype=np.int64),
        "obs_pose": np.array(seen["pose"]),
        "obs_landmark": np.array(seen["ids"], dtype=np.int64),
        "obs_z": np.array(seen["z"]),
        "r_laser": np.array(config.r_laser),
        "landmark_id": np.array(ids, dtype=np.int64),
        "landmark_x": np.array([system.landmark_vertices[i].estimate for i in ids]),
        "edge_vehicle": np.array([e.vertex(0).id for e in rb], dtype=np.int64),
        "edge_landmark": np.array([e.vertex(1).landmark_id for e in rb], dtype=np.int64),
        "edge_z": z,
        "pose": states[0],
        "landmark": states[1],
        "error": err,
        "jacobian_pose": jx,
        "jacobian_landmark": jm,
    }


# ------------------------------------------------------------------------------------------------ Q2c (hidden)
@recipe("cw_q2c_graph_statistics_hidden", rtol=1e-12, atol=0.0)
def q2c_hidden() -> dict:
    """The q2_c run's graph (its structure: the statistics do not depend on the estimates) and its statistics."""
    res = run_question("q2_c")
    stats = res.graph_statistics()
    out = graph_record(res.system.graph, estimates=False)
    out.update({"stat_" + k: v for k, v in stats.items() if k != "edges_by_type"})
    out["stat_edge_classes"] = np.array(sorted(stats["edges_by_type"]))
    out["stat_edge_counts"] = np.array([stats["edges_by_type"][k] for k in sorted(stats["edges_by_type"])])
    return out


# ------------------------------------------------------------------------------------------------ Q3a (hidden)
@recipe("cw_q3a_remove_prediction_edges_hidden", rtol=0.0, atol=0.0)
def q3a_hidden() -> dict:
    """1100 ticks of q3_a, with the removals after the 500th and the 1000th tick (where the system optimises).

    One system keeps every element: its graph, with each element's creation tick, is what the test replays. Two
    systems remove the prediction edges (all / all but the first) where ``optimize`` would; what their graphs
    hold right after each removal is the expected value: ``<all|first>_call<i>_vehicle`` (vehicle vertices made so
    far, in the graph?), ``..._kin`` (prediction edges made so far), ``..._landmark`` (per landmark_id). Events
    only: the removal is structural."""
    _, config, _ = question_setup("q3_a")
    keep_all = DriveBotSLAMSystem(config, SLAMOptions())
    variants = {name: DriveBotSLAMSystem(config, SLAMOptions(remove_prediction_edges=True,
                                                             keep_first_prediction_edge=first))
                for name, first in (("all", False), ("first", True))}
    created, calls, masks = {}, [], {name: [] for name in variants}

    def after(k, events):
        for e in keep_all.graph.edges():
            created.setdefault(e, k)
        for v in keep_all.landmark_vertices.values():
            created.setdefault(v, k)
        if keep_all.step_number % 500 == 0:
            calls.append(k)
            for name, system in variants.items():
                system._delete_prediction_edges()
                masks[name].append({
                    "vehicle": np.array([v.graph is system.graph for v in system.vehicle_vertices]),
                    "kin": np.array([e.graph is system.graph for e in system.process_model_edges]),
                    "landmark": {i: v.graph is system.graph for i, v in system.landmark_vertices.items()},
                })

    _run_events("q3_a", 1100, [keep_all, *variants.values()], after_tick=after)
    out = graph_record(keep_all.graph, estimates=False)
    edges = keep_all.graph.edges()
    kin = [e for e in edges if type(e) is VehicleKinematicsEdge]
    rb = [e for e in edges if type(e) is EdgeRangeBearing]
    ids = out["landmark_id"].tolist()
    out["kin_tick"] = np.array([created[e] for e in kin], dtype=np.int64)
    out["rb_tick"] = np.array([created[e] for e in rb], dtype=np.int64)
    out["landmark_tick"] = np.array([created[keep_all.landmark_vertices[i]] for i in ids], dtype=np.int64)
    out["call_ticks"] = np.array(calls, dtype=np.int64)
    for name, per_call in masks.items():
        for c, mask in enumerate(per_call):
            out["%s_call%d_vehicle" % (name, c)] = mask["vehicle"]
            out["%s_call%d_kin" % (name, c)] = mask["kin"]
            out["%s_call%d_landmark" % (name, c)] = np.array([mask["landmark"].get(i, False) for i in ids])
    return out


# ------------------------------------------------------------------------------------------------ Q3b (hidden)
class _RecordingKeyframes(KeyframePruning):
    """The q3_b hook (the answer key's KeyframePruning) that also keeps every table and keep mask it produced."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.seen = []

    def select(self, table: dict) -> np.ndarray:
        keep = super().select(table)
        self.seen.append(({k: v for k, v in table.items() if k != "edges"}, keep))
        return keep


@recipe("cw_q3b_pruning_hidden", rtol=1e-6, atol=1e-8)
def q3b_hidden() -> dict:
    """The tables the q3_b hook (stride 5, 0.05 rad/s, window 11) was given before the optimisations at ticks 500
    and 1000 of a q3_b run, and the answer key's keep masks: ``call<i>_<table key>``, ``call<i>_keep``."""
    hook = _RecordingKeyframes(stride=5, rate_threshold=0.05, window=11)
    run_question("q3_b", maximum_step_number=1000, pre_optimization_hook=hook)
    out = {"stride": 5, "rate_threshold": 0.05, "window": 11}
    for c, (table, keep) in enumerate(hook.seen[:2]):
        for key, value in table.items():
            out["call%d_%s" % (c, key)] = value
        out["call%d_keep" % c] = keep
    return out
