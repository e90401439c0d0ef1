"""Bad input to the online front-end, Victoria Park and DriveBot's run_question is refused up front with a
ValueError naming the argument, and a refused or failed call leaves the state as it was: the front-end's scan
checks and undo, its argument types, algorithm options checked at construction, run_victoria_park's arguments
(and the association-only ones without data association), and run_question's options that would have no effect."""
import math

import numpy as np
import pytest

from helpers.association.common import problem_from_cov
from helpers.advanced.hidden_ids import run_hidden_ids
from helpers.drivebot import run_question, runner
from helpers.graph import EdgePositionPrior, EdgeSE2, VertexPointXY, VertexSE2
from helpers.advanced.fast_graph import FastOptimizer
from helpers.advanced.online_slam import (ALGORITHMS, ConfirmationRules, OnlineFrontEnd, RangeBearingModel,
                                          check_options, run_victoria_park)
from helpers.advanced.online_slam import victoria_park
from helpers.advanced.online_slam.victoria_park import VICTORIA_PARK_RULES

R = np.diag([0.05, 0.01]) ** 2
ODO_INFO = np.linalg.inv(np.diag([0.02, 0.02, 0.005]) ** 2)
LANDMARKS = np.array([(1.0, 2.0), (3.0, -2.5), (5.0, 1.5), (7.5, -1.0), (9.0, 2.5)])


def _frontend(algorithm="jcbb", **options):
    graph = FastOptimizer()
    first = VertexSE2(None, [0.0, 0.0, 0.0], fixed=True)
    graph.add_vertex(first)
    fe = OnlineFrontEnd(graph, RangeBearingModel(6.0, range_margin=0.5), algorithm, **options)
    fe.start(first)
    return graph, first, fe


def _move(fe, step=0.5):
    z = np.array([step, 0.0, 0.0])
    v = VertexSE2(None, fe.pose.estimate + z)
    fe.graph.add_vertex(v)
    e = EdgeSE2([fe.pose, v], measurement=z, information=ODO_INFO)
    fe.graph.add_edge(e)
    fe.add_pose(e)
    return v


def _scan_of(x):
    d = LANDMARKS - x[:2]
    r = np.hypot(d[:, 0], d[:, 1])
    seen = r <= 6.0
    return np.vstack([r[seen], np.arctan2(d[seen, 1], d[seen, 0]) - x[2]])


def _state(fe):
    """Everything a scan may change, as comparable values."""
    w = fe.window
    return {"scan_count": fe.scan_count, "log": {k: list(v) for k, v in fe.observation_log.items()},
            "tracks": [(t.key, t.status, t.hits, t.misses, list(t.observations), [p[3] for p in t.pending],
                        id(t.pending), t.vertex, t.end, t.alias_of, t.postponed_since) for t in fe.tracks],
            "window": (w.A.tolist(), w.P.tolist(), dict(w.rows), {k: v.tolist() for k, v in w.means.items()}, w.keys),
            "stats": dict(fe.stats), "orphans": len(fe.orphans), "merge_scans": dict(fe.merge_scans),
            "graph": (fe.graph.number_of_vertices(), fe.graph.number_of_edges())}


# ------------------------------------------------------------------------------------------ 1. process_scan
@pytest.mark.parametrize("information, match", [
    (-np.eye(2), "information must be positive definite"),
    (np.full((2, 2), np.nan), "information must be finite"),
    (np.array([[1.0, 0.5], [0.0, 1.0]]), "information must be symmetric"),
    (np.eye(3), r"information must be \(2, 2\) or \(1, 2, 2\)"),
    (np.array([np.eye(2), -np.eye(2)]), r"information must be \(2, 2\) or \(1, 2, 2\)"),
    ("big", "information must be an array of real numbers"),
])
def test_bad_information_is_refused_at_the_call_and_changes_nothing(information, match):
    graph, _, fe = _frontend(rules=ConfirmationRules(n_confirm=3))
    before = _state(fe)
    for _ in range(3):                  # the reported case: the third call used to fail inside add_edges
        with pytest.raises(ValueError, match=match):
            fe.process_scan(np.array([[5.0], [0.3]]), np.diag([0.1, 0.01]), information=information)
    assert _state(fe) == before


def test_one_bad_information_matrix_of_a_stack_is_named():
    _, _, fe = _frontend()
    before = _state(fe)
    with pytest.raises(ValueError, match=r"information\[1\] must be positive definite"):
        fe.process_scan(np.array([[2.0, 3.0], [0.3, -0.2]]), R, information=np.array([np.eye(2), -np.eye(2)]))
    assert _state(fe) == before


@pytest.mark.parametrize("Z, match", [
    (np.array([[np.nan], [0.3]]), r"Z must be finite .*bad columns: \[0\]"),
    (np.array([[2.0, -5.0], [0.3, 0.1]]), r"Z\[:, 1\]: the range must be >= 0"),
    (np.zeros((3, 1)), r"Z must be a \(2, m\) array"),
    ([["a"], ["b"]], "Z must be an array of real numbers"),
])
def test_bad_observations_are_refused_and_change_nothing(Z, match):
    _, _, fe = _frontend()
    before = _state(fe)
    with pytest.raises(ValueError, match=match):
        fe.process_scan(Z, R)
    assert _state(fe) == before


def test_bad_noise_covariance_is_refused_and_changes_nothing():
    _, _, fe = _frontend()
    fe.process_scan(_scan_of(np.zeros(3)), R)
    before = _state(fe)
    for bad in (-R, np.eye(3), np.array([[1.0, 0.2], [0.0, 1.0]])):
        with pytest.raises(ValueError, match="R must be"):
            fe.process_scan(_scan_of(np.zeros(3)), bad)
    assert _state(fe) == before


class _Failure(RuntimeError):
    pass


def _run(fe, fail_at=None, fail=None):
    """Eight steps of driving and scanning (optimising every 4); at scan ``fail_at`` ``fail(fe)`` arms a failure
    and the scan must raise, leave the state as it was, and then succeed when repeated."""
    for k in range(8):
        _move(fe)
        Z = _scan_of(fe.pose.estimate)
        if k == fail_at:
            before = _state(fe)
            undo = fail(fe)
            with pytest.raises(_Failure):
                fe.process_scan(Z, R)
            undo()
            assert _state(fe) == before
        fe.process_scan(Z, R)
        if k % 4 == 3:
            fe.graph.initialize_optimization()
            fe.graph.optimize(5, algorithm="lm-gtsam")
            fe.refresh()
    return fe


def _failing_add_edges(fe):
    original = fe.graph.add_edges

    def add_edges(*args, **kwargs):
        raise _Failure("add_edges")
    fe.graph.add_edges = add_edges

    def undo():
        fe.graph.add_edges = original
    return undo


def _failing_factory(fe):
    original = fe.landmark_factory

    def factory(key, estimate):
        raise _Failure("factory")
    fe.landmark_factory = factory

    def undo():
        fe.landmark_factory = original
    return undo


@pytest.mark.parametrize("fail, fail_at", [(_failing_add_edges, 1), (_failing_factory, 1), (_failing_add_edges, 5)])
def test_a_scan_that_fails_part_way_is_undone(fail, fail_at):
    rules = ConfirmationRules(n_confirm=2, n_miss=3, max_age=None)
    clean = _run(_frontend(rules=rules)[2])
    # scan 1 confirms the first landmarks (a vertex added, tracks confirmed, edges of waiting observations);
    # scan 5 only re-observes confirmed landmarks (their observation lists grow), after an optimisation
    failed = _run(_frontend(rules=rules)[2], fail_at=fail_at, fail=fail)
    assert failed.observation_assignment().tolist() == clean.observation_assignment().tolist()
    assert failed.graph.number_of_vertices() == clean.graph.number_of_vertices()
    assert failed.graph.number_of_edges() == clean.graph.number_of_edges()
    np.testing.assert_allclose([t.vertex.estimate for t in failed.confirmed_tracks()],
                               [t.vertex.estimate for t in clean.confirmed_tracks()], atol=1e-12)


# ------------------------------------------------------------------------------------------ 2. argument types
def test_front_end_arguments_of_the_wrong_type_are_named():
    model = RangeBearingModel(20.0)
    with pytest.raises(ValueError, match="graph must be a FastOptimizer"):
        OnlineFrontEnd(None, None)
    with pytest.raises(ValueError, match="graph must be a FastOptimizer"):
        OnlineFrontEnd("g", model)
    with pytest.raises(ValueError, match="model must be a RangeBearingModel"):
        OnlineFrontEnd(FastOptimizer(), "laser")
    graph, first, fe = _frontend()
    other, point, nxt = VertexSE2(None, [1.0, 0.0, 0.0]), VertexPointXY(None, [1.0, 1.0]), VertexSE2(None, [0.5, 0, 0])
    for v in (other, point, nxt):
        graph.add_vertex(v)
    before = _state(fe)
    with pytest.raises(ValueError, match="edge must be a binary odometry edge.*got VertexSE2"):
        fe.add_pose(first)
    prior = EdgePositionPrior([first], measurement=[0.0, 0.0], information=np.eye(2))
    with pytest.raises(ValueError, match="edge must be a binary odometry edge.*EdgePositionPrior, an edge with 1"):
        fe.add_pose(prior)
    stray = EdgeSE2([other, VertexSE2(None, [2.0, 0.0, 0.0])], measurement=[1.0, 0, 0], information=ODO_INFO)
    with pytest.raises(ValueError, match="first vertex is not the current pose"):
        fe.add_pose(stray)
    to_new = EdgeSE2([first, VertexSE2(None, [2.0, 0.0, 0.0])], measurement=[1.0, 0, 0], information=ODO_INFO)
    with pytest.raises(ValueError, match=r"edge.vertex\(1\) must be a vertex of the front-end's graph"):
        fe.add_pose(to_new)
    loose = EdgeSE2([first, nxt], measurement=[0.5, 0, 0], information=ODO_INFO)       # not added to the graph
    with pytest.raises(ValueError, match="edge must be an edge of the front-end's graph"):
        fe.add_pose(loose)
    with pytest.raises(ValueError, match="pose_vertex must be a VertexSE2"):
        fe.start(None)
    with pytest.raises(ValueError, match="pose_vertex must be a VertexSE2"):
        fe.start(point)
    with pytest.raises(ValueError, match="pose_vertex must be a vertex of the front-end's graph"):
        fe.start(VertexSE2(None, [0.0, 0.0, 0.0]))
    assert _state(fe) == before and fe.pose is first
    _, _, unstarted = _frontend()
    unstarted.pose = None
    with pytest.raises(ValueError, match="call start"):
        unstarted.add_pose(prior)


# ------------------------------------------------------------------------------------------ 3. algorithm options
@pytest.mark.parametrize("algorithm, option, value", [
    ("jcbb", "max_nodes", 0), ("jcbb", "max_nodes", True), ("jcbb", "max_nodes", 2.5),
    ("nn", "max_distance", -1), ("nn", "max_distance", "5"), ("ml", "alpha", "x"), ("ml", "alpha", math.nan),
])
def test_algorithm_options_are_checked_at_construction_with_the_algorithms_message(algorithm, option, value):
    problem = problem_from_cov(np.zeros((1, 2)), np.eye(2), np.zeros((2, 1)), 3.0)
    with pytest.raises(ValueError) as own:
        ALGORITHMS[algorithm](problem, None, n_sigma=3.0, **{option: value})
    with pytest.raises(ValueError) as err:
        OnlineFrontEnd(FastOptimizer(), RangeBearingModel(20.0), algorithm, algorithm_options={option: value})
    assert str(err.value) == f"algorithm_options: {own.value}"
    with pytest.raises(ValueError, match=f"algorithm_options: {option}"):
        check_options(algorithm, {option: value})


def test_check_options_names_unknown_options_and_completes_the_defaults():
    assert check_options("jcbb", None) == {"max_nodes": 20000}
    assert check_options("nn", {"max_distance": None}) == {"max_distance": None}
    with pytest.raises(ValueError, match=r"algorithm_options: \['alpha', 1\] are not options of 'jcbb'"):
        check_options("jcbb", {"alpha": 0.1, 1: 2})
    with pytest.raises(ValueError, match="data_association must be one of"):
        check_options("icp", {})
    with pytest.raises(ValueError, match="algorithm_options must be a dict"):
        check_options("ml", [("alpha", 0.1)])


# ------------------------------------------------------------------------------------------ 4. run_victoria_park
@pytest.fixture
def no_file(monkeypatch):
    """run_victoria_park must refuse bad arguments before it reads the file: reading raises here."""
    def read(name):
        raise _Failure("the file was read")
    monkeypatch.setattr(victoria_park, "read_dataset", read)


@pytest.mark.parametrize("kwargs, match", [
    (dict(measurement_sigmas=0.3), "measurement_sigmas must be None or two positive"),
    (dict(measurement_sigmas=(0.3,)), "measurement_sigmas must be None or two positive"),
    (dict(measurement_sigmas=("a", "b")), "measurement_sigmas must be None or two positive"),
    (dict(measurement_sigmas=("0.3", "0.08")), "measurement_sigmas must be None or two positive"),
    (dict(measurement_sigmas=(True, 0.08)), "measurement_sigmas must be None or two positive"),
    (dict(measurement_sigmas=(0.3, math.inf)), "measurement_sigmas must be None or two positive"),
    (dict(odometry_scale="10"), "odometry_scale must be a positive finite number"),
    (dict(odometry_scale=True), "odometry_scale must be a positive finite number"),
    (dict(odometry_scale=None), "odometry_scale must be a positive finite number"),
    (dict(late_association="yes"), "late_association"),
    (dict(rules="strict"), "rules must be a ConfirmationRules"),
    (dict(data_association=None, n_sigma=4.0), "n_sigma=4.0 has no effect without data association"),
    (dict(data_association=None, rules=ConfirmationRules()), "rules=.* has no effect"),
    (dict(data_association=None, late_association=True), "late_association=True has no effect"),
])
def test_victoria_park_arguments_are_checked_before_the_file_is_read(no_file, kwargs, match):
    with pytest.raises(ValueError, match=match):
        run_victoria_park(**kwargs)


@pytest.mark.parametrize("kwargs", [
    dict(measurement_sigmas=(0.3, 0.08), odometry_scale=10.0),
    dict(measurement_sigmas=np.array([0.3, 0.08]), odometry_scale=np.float64(2.0)),
    dict(data_association=None, n_sigma=3, rules=VICTORIA_PARK_RULES, late_association=False,
         known_id_reference=True),
])
def test_victoria_park_defaults_given_explicitly_are_accepted(no_file, kwargs):
    with pytest.raises(_Failure, match="the file was read"):
        run_victoria_park(**kwargs)


# ------------------------------------------------------------------------------------------ 5. run_question
@pytest.fixture
def no_run(monkeypatch):
    """run_question must refuse bad settings before anything runs: the main loop raises here."""
    def loop(*args, **kwargs):
        raise _Failure("the run started")
    monkeypatch.setattr(runner, "_main_loop", loop)


@pytest.mark.parametrize("name, kwargs, match", [
    ("q2_b", dict(data_association="jcbb", algorithm_options={"max_nodes": 0}), "algorithm_options: max_nodes"),
    ("q2_b", dict(data_association="nn", algorithm_options={"max_distance": -1.0}), "algorithm_options: max_dist"),
    ("q2_b", dict(data_association="ml", algorithm_options={"max_nodes": 5}), "not options of 'ml'"),
    ("q1_b", dict(compass_edge="buggy"), "compass_edge='buggy' has no effect.*enable_compass=True"),
    ("q1_b", dict(compass_angular_offset=1.0), "compass_angular_offset=1.0 has no effect.*enable_compass=True"),
    ("q1_d", dict(r_compass=[[0.01]]), "r_compass=.* has no effect: the run has no compass"),
    ("q1_b", dict(gps_measurement_period=2.0), "gps_measurement_period=2.0 has no effect.*enable_gps=True"),
    ("q1_b", dict(data_association="jcbb"), "data_association='jcbb' has no effect.*enable_laser=True"),
    ("q1_b", dict(detection_probability=0.5), "detection_probability=0.5 has no effect.*enable_laser=True"),
    ("q1_e", dict(laser_detection_range=30.0), "laser_detection_range=30.0 has no effect"),
    ("q1_b", dict(keep_first_prediction_edge=True), "keep_first_prediction_edge=True has no effect.*"
                                                    "remove_prediction_edges=True"),
    ("q3_a", dict(keep_first_prediction_edge=False), "keep_first_prediction_edge=False has no effect"),
    ("q3_b", dict(keep_first_prediction_edge=True), "keep_first_prediction_edge=True has no effect"),
    ("q1_b", dict(compass_edge="broken"), "compass_edge must be one of"),
    ("q3_a", dict(keep_first_prediction_edge=1), "keep_first_prediction_edge must be True or False"),
])
def test_run_question_refuses_bad_or_ineffective_settings_before_it_runs(no_run, name, kwargs, match):
    with pytest.raises(ValueError, match=match):
        _run_for(kwargs)(name, **kwargs)


@pytest.mark.parametrize("name, kwargs", [
    ("q1_b", dict(compass_edge="fixed", compass_angular_offset=0, keep_first_prediction_edge=False,
                  data_association=None, clutter_rate=0, detection_probability=1, r_gps=np.eye(2))),
    ("q1_c", dict(compass_edge="fixed", compass_angular_offset=0.75 * math.pi)),
    ("q1_e", dict(enable_compass=True, compass_edge="buggy", compass_angular_offset=0.1)),
    ("q1_e", dict(enable_laser=True, data_association="jcbb", detection_probability=0.9)),
    ("q2_b", dict(data_association=None, detection_probability=0.5)),
    ("q3_a", dict(keep_first_prediction_edge=True, remove_prediction_edges=False)),
    ("q3_a", dict(remove_prediction_edges=True, keep_first_prediction_edge=False)),
    ("q3_b", dict(remove_prediction_edges=True, keep_first_prediction_edge=True)),
])
def test_run_question_accepts_defaults_and_options_that_act(no_run, name, kwargs):
    with pytest.raises(_Failure, match="the run started"):
        _run_for(kwargs)(name, **kwargs)


def _run_for(kwargs):
    """run_hidden_ids for the settings of the runs with the ids hidden, run_question for the coursework's."""
    hidden = {"data_association", "clutter_rate", "detection_probability", "algorithm_options"}
    return run_hidden_ids if hidden & set(kwargs) else run_question


@pytest.mark.parametrize("name, variants, overrides, match", [
    ("q2_b", {"a": {}, "b": {"keep_first_prediction_edge": True}}, {},
     r"run_variants \(variant 'b'\): keep_first_prediction_edge=True has no effect"),
    ("q1_b", {"a": {}}, dict(compass_edge="buggy"), r"variant 'a'\): compass_edge='buggy' has no effect"),
])
def test_run_variants_refuses_options_without_effect_before_it_runs(no_run, name, variants, overrides, match):
    with pytest.raises(ValueError, match=match):
        runner.run_variants(name, variants, **overrides)


def test_run_variants_accepts_the_options_that_act(no_run):
    variants = {"full": {}, "keep first": {"remove_prediction_edges": True, "keep_first_prediction_edge": True},
                "remove all": {"remove_prediction_edges": True, "keep_first_prediction_edge": False}}
    with pytest.raises(_Failure, match="the run started"):
        runner.run_variants("q3_a", variants)


def test_a_failed_drivebot_scan_leaves_no_landmark_outside_the_graph():
    """A scan that fails inside the front-end is undone there; the vertices the system registered for it go too."""
    armed = {}

    def hook(system, k):
        armed.setdefault("system", system)
        if k != 25 or "registered" in armed or "armed" in armed:
            return
        armed["armed"] = True
        fe, graph = system.frontend, system.graph
        factory = fe.landmark_factory

        def landmark(key, estimate):
            armed["registered"] = True
            return factory(key, estimate)

        def add_edges(*args, **kwargs):
            if armed.get("registered"):
                raise _Failure("add_edges")
            return type(graph).add_edges(graph, *args, **kwargs)
        fe.landmark_factory, graph.add_edges = landmark, add_edges

    with pytest.raises(_Failure):
        run_hidden_ids("q2_b", data_association="jcbb", maximum_step_number=120, step_hook=hook)
    system = armed["system"]
    assert armed.get("registered")
    assert all(v.graph is system.graph for v in system.landmark_vertices.values())
    assert all(v.number_of_edges() > 0 for v in system.landmark_vertices.values())   # none added without edges
    confirmed = [t for t in system.frontend.tracks if t.vertex is not None]
    assert all(t.vertex.graph is system.graph for t in confirmed)
    assert {t.key + 1 for t in system.frontend.confirmed_tracks()} == set(system.landmark_vertices)
