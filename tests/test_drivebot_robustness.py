"""Robustness of the DriveBot system and the notebook support (issue 14): bad input gets a clear ValueError naming
the argument, and a bad event batch changes nothing."""
import dataclasses
import math
import pathlib

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from hypothesis import given, settings, strategies as st  # noqa: E402

from helpers import notebook, paths, timing  # noqa: E402
from helpers.drivebot import (DriveBotSimulator, DriveBotSLAMSystem, Event, EventType, SimulatorConfiguration,  # noqa: E402
                              SLAMOptions, load_scenario, run_question)
from helpers.drivebot import analysis as an  # noqa: E402
from helpers.drivebot import marginalisation as mg  # noqa: E402
from helpers.drivebot import plotting as pl  # noqa: E402
from helpers.drivebot import pruning  # noqa: E402
from helpers.drivebot import q1_support as q1  # noqa: E402
from helpers.drivebot import q2_support as q2  # noqa: E402
from helpers.drivebot import q3_support as q3  # noqa: E402
from helpers.drivebot import runner, scenario_files, scenarios  # noqa: E402
from helpers.drivebot.config import SIGMA_BOUNDS, SIGMA_RATIO  # noqa: E402
from helpers.graph import EdgeRangeBearing  # noqa: E402
from helpers.graph import GaugeFreedomError  # noqa: E402


# ---------------------------------------------------------------------------------------------- helpers
def _system(**cfg):
    return DriveBotSLAMSystem(SimulatorConfiguration(**cfg))


def _started(**cfg):
    system = _system(**cfg)
    system.process_events([Event(0.0, EventType.VEHICLE_ODOMETRY, [1, 0, 0], np.eye(3)),
                           Event(0.0, EventType.INITIAL_CONDITION, [0, 0, 0], np.zeros((3, 3)))])
    return system


def _odo(t, u=(1.0, 0.0, 0.0)):
    return Event(t, EventType.VEHICLE_ODOMETRY, list(u), 0.01 * np.eye(3))


def _two_vertices():
    system = _started()
    system.process_events([_odo(0.1)])
    system.ensure_structure()
    return system


def _assign(obj, name, value):
    setattr(obj, name, value)


def _in_axes(fn):
    fig, ax = plt.subplots()
    try:
        return fn(ax)
    finally:
        plt.close(fig)


@pytest.fixture(scope="module")
def short_q2b():
    return run_question("q2_b", maximum_step_number=20)


def _q(**kw):
    return lambda: run_question(**kw)


# ---------------------------------------------------------------------------------------------- the table
#: (id, call, match): each call must raise ValueError whose message matches (and so names the argument)
BAD = [
    # ---- run_question / question_setup: degenerate or non-physical configurations (the audit's cases)
    ("rpe_odometry_only", _q(name="q1_b", remove_prediction_edges=True), "remove_prediction_edges"),
    ("rpe_keep_first_odometry_only", _q(name="q1_b", remove_prediction_edges=True, keep_first_prediction_edge=True),
     "remove_prediction_edges"),
    ("r_odometry_1e-300", _q(name="q1_e", r_odometry=1e-300 * np.eye(3)), "r_odometry"),
    ("r_gps_1e-300", _q(name="q1_e", r_gps=1e-300 * np.eye(2)), "r_gps"),
    ("r_compass_sigma_1e7", _q(name="q1_e", enable_compass=True, r_compass=[[1e14]]), "r_compass"),
    ("r_laser_sigma_1e-8", _q(name="q2_b", r_laser=np.diag([1e-16, 1e-4])), "r_laser"),
    ("r_odometry_ratio_1e12", _q(name="q1_e", r_odometry=np.diag([1e-12, 1.0, 1e12])), "r_odometry"),
    ("r_gps_negative", _q(name="q1_d", r_gps=-np.eye(2)), "r_gps"),
    ("r_gps_nan", _q(name="q1_d", r_gps=[[np.nan, 0.0], [0.0, 1.0]]), "r_gps"),
    ("r_odometry_asymmetric", _q(name="q1_b", r_odometry=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1.0]]), "r_odometry"),
    ("r_odometry_text", _q(name="q1_b", r_odometry="big"), "r_odometry"),
    ("dt_below_merge_time", _q(name="q1_b", dt=1e-4), "dt"),
    ("dt_nan", _q(name="q1_b", dt=np.nan), "dt"),
    ("dt_negative", _q(name="q1_b", dt=-0.1), "dt"),
    ("enable_odometry_false", _q(name="q1_d", enable_odometry=False), "enable_odometry"),
    ("max_delta_beyond_90deg", _q(name="q1_e", max_delta=3.0), "max_delta"),
    ("wheelbase_negative", _q(name="q1_b", wheelbase=-2.5), "wheelbase"),
    ("min_speed_above_max", _q(name="q1_b", min_speed=5.0, max_speed=2.0), "min_speed"),
    ("laser_range_zero", _q(name="q2_b", laser_detection_range=0.0), "laser_detection_range"),
    ("gps_period_inf", _q(name="q1_d", gps_measurement_period=np.inf), "gps_measurement_period"),
    ("lever_arm_inf", _q(name="q1_d", gps_position_offset=[np.inf, 0.0]), "gps_position_offset"),
    ("compass_offset_nan", _q(name="q1_c", compass_angular_offset=np.nan), "compass_angular_offset"),
    ("enable_gps_1", _q(name="q1_b", enable_gps=1), "enable_gps"),
    ("dither_negative", _q(name="q1_b", sensor_dither_time=-0.1), "sensor_dither_time"),
    # ---- run_question: names and options
    ("name_trailing_space", _q(name="q1_b "), "unknown question"),
    ("name_int", _q(name=5), "unknown question"),
    ("name_list", _q(name=["q1_b"]), "unknown question"),
    ("name_none", _q(name=None), "unknown question"),
    ("unknown_override", _q(name="q1_b", radar=True), "unknown override 'radar'"),
    ("period_zero", _q(name="q1_e", optimization_period=0), "optimization_period"),
    ("period_negative", _q(name="q1_e", optimization_period=-5), "optimization_period"),
    ("period_fraction", _q(name="q1_e", optimization_period=0.5), "optimization_period"),
    ("period_nan", _q(name="q1_e", optimization_period=np.nan), "optimization_period"),
    ("period_text", _q(name="q1_e", optimization_period="5"), "optimization_period"),
    ("period_bool", _q(name="q1_e", optimization_period=True), "optimization_period"),
    ("period_minus_inf", _q(name="q1_e", optimization_period=-np.inf), "optimization_period"),
    ("steps_zero", _q(name="q1_e", maximum_step_number=0), "maximum_step_number"),
    ("steps_negative", _q(name="q1_e", maximum_step_number=-3), "maximum_step_number"),
    ("steps_nan", _q(name="q1_e", maximum_step_number=np.nan), "maximum_step_number"),
    ("steps_fraction", _q(name="q1_e", maximum_step_number=2.5), "maximum_step_number"),
    ("steps_text", _q(name="q1_e", maximum_step_number="10"), "maximum_step_number"),
    ("seed_negative", _q(name="q1_e", seed=-1), "seed"),
    ("seed_fraction", _q(name="q1_e", seed=1.5), "seed"),
    ("seed_text", _q(name="q1_e", seed="0"), "seed"),
    ("seed_bool", _q(name="q1_e", seed=True), "seed"),
    ("progress_text", _q(name="q1_e", progress="no", maximum_step_number=3), "progress"),
    ("step_hook_int", _q(name="q1_e", step_hook=5), "step_hook"),
    ("pre_hook_text", _q(name="q3_b", pre_optimization_hook="hook"), "pre_optimization_hook"),
    ("compass_edge_unknown", _q(name="q1_c", compass_edge="broken"), "compass_edge"),
    ("algorithm_unknown", _q(name="q1_e", optimization_algorithm="newton"), "optimization_algorithm"),
    ("rpe_text", _q(name="q3_a", remove_prediction_edges="yes"), "remove_prediction_edges"),
    ("keep_first_int", _q(name="q3_a", keep_first_prediction_edge=1), "keep_first_prediction_edge"),
    # ---- run / run_variants
    ("variants_list", lambda: runner.run_variants("q1_e", []), "variants"),
    ("variants_empty", lambda: runner.run_variants("q1_e", {}), "variants"),
    ("variant_config_field", lambda: runner.run_variants("q1_e", {"a": {"dt": 0.2}}), "SLAM options"),
    ("variant_rpe_odometry_only", lambda: runner.run_variants("q1_b", {"a": {"remove_prediction_edges": True}}),
     "remove_prediction_edges"),
    ("chi2_bounds_k_negative", lambda: run_question("q1_e", maximum_step_number=5).chi2_bounds(-1.0), "k must"),
    ("chi2_bounds_k_text", lambda: run_question("q1_e", maximum_step_number=40).chi2_bounds("x"), "k must"),
    # ---- configuration, events, queue
    ("config_inplace_edit", lambda: SimulatorConfiguration().r_gps.__setitem__((0, 0), -5.0), "read-only"),
    ("config_r_laser_shape", lambda: SimulatorConfiguration(r_laser=np.zeros((2, 3))), "r_laser"),
    ("config_r_compass_zero", lambda: SimulatorConfiguration(r_compass=[[0.0]]), "r_compass"),
    ("event_time_text", lambda: Event("abc", EventType.GPS, [0, 0], np.eye(2)), "time"),
    ("event_time_none", lambda: Event(None, EventType.GPS, [0, 0], np.eye(2)), "time"),
    ("event_time_inf", lambda: Event(np.inf, EventType.GPS, [0, 0], np.eye(2)), "time"),
    ("event_duplicate_ids", lambda: Event(0.0, EventType.LANDMARK, np.ones((2, 2)), np.eye(2), landmark_ids=[3, 3]),
     "landmark_ids"),
    ("event_float_ids", lambda: Event(0.0, EventType.LANDMARK, np.ones((2, 1)), np.eye(2), landmark_ids=[1.0]),
     "landmark_ids"),
    # ---- SLAM system: event processing
    ("batch_single_event", lambda: _started().process_events(_odo(0.1)), "batch"),
    ("batch_int", lambda: _started().process_events(5), "batch"),
    ("batch_of_text", lambda: _started().process_events(["odometry"]), "Event"),
    ("event_before_current_time", lambda: _started().process_events([_odo(-0.5)]), "time order"),
    ("batch_decreasing_times", lambda: _started().process_events([_odo(0.2), _odo(0.1)]), "time order"),
    ("second_initial_condition", lambda: _started().process_events(
        [Event(0.1, EventType.INITIAL_CONDITION, [0, 0, 0], np.zeros((3, 3)))]), "INITIAL_CONDITION"),
    ("gps_disabled", lambda: _started().process_events([_odo(0.1), Event(0.1, EventType.GPS, [0, 0], np.eye(2))]),
     "enable_gps"),
    ("laser_disabled", lambda: _started().process_events(
        [Event(0.1, EventType.LANDMARK, np.ones((2, 1)), np.eye(2), landmark_ids=[1])]), "enable_laser"),
    ("compass_disabled_before_init", lambda: _system().process_events(
        [Event(0.0, EventType.COMPASS, [0.0], [[0.01]])]), "enable_compass"),
    ("odometry_covariance_not_spd", lambda: _started().process_events(
        [Event(0.1, EventType.VEHICLE_ODOMETRY, [1, 0, 0], -np.eye(3))]), "covariance"),
    ("initial_covariance_not_spd", lambda: _system().process_events(
        [_odo(0.0), Event(0.0, EventType.INITIAL_CONDITION, [0, 0, 0], np.diag([-1.0, -1.0, 1.0]))]),
     "initial covariance"),
    ("prediction_without_odometry", lambda: _system(enable_compass=True).process_events(
        [Event(0.0, EventType.INITIAL_CONDITION, [0, 0, 0], np.zeros((3, 3))),
         Event(0.1, EventType.COMPASS, [0.0], [[0.01]])]), "odometry"),
    # ---- SLAM system and its options
    ("system_config_text", lambda: DriveBotSLAMSystem(config="default"), "config"),
    ("system_dt_below_merge_time", lambda: DriveBotSLAMSystem(SimulatorConfiguration(dt=0.0015)), "dt"),
    ("system_rpe_no_sensor", lambda: DriveBotSLAMSystem(SimulatorConfiguration(),
                                                        SLAMOptions(remove_prediction_edges=True)),
     "remove_prediction_edges"),
    ("system_options_dict", lambda: DriveBotSLAMSystem(SimulatorConfiguration(), {"optimization_period": 5}),
     "options"),
    ("system_algorithm_unknown", lambda: DriveBotSLAMSystem(SimulatorConfiguration(),
                                                            SLAMOptions(optimization_algorithm="newton")),
     "optimization_algorithm"),
    ("options_period_zero", lambda: SLAMOptions(optimization_period=0), "optimization_period"),
    ("options_compass_edge_unknown", lambda: SLAMOptions(compass_edge="broken"), "compass_edge"),
    ("options_hook_int", lambda: SLAMOptions(pre_optimization_hook=5), "pre_optimization_hook"),
    ("options_rpe_text", lambda: SLAMOptions(remove_prediction_edges="yes"), "remove_prediction_edges"),
    ("platform_estimate_uninitialised", lambda: _system().platform_estimate(), "initialised"),
    ("edge_residuals_name", lambda: _started().edge_residuals("EdgeHeadingPrior"), "edge_class"),
    # ---- simulator, scenarios, scenario files
    ("simulator_seed_text", lambda: DriveBotSimulator(SimulatorConfiguration(), load_scenario("q1_e"), seed="a"),
     "seed"),
    ("load_scenario_list", lambda: load_scenario(["q1_b"]), "unknown scenario"),
    ("scenario_ids_descending", lambda: scenarios.Scenario("x", np.zeros((2, 2)), np.array([2, 1]), np.ones((2, 1))),
     "landmark_ids"),
    ("scenario_no_waypoint", lambda: scenarios.Scenario("x", np.zeros((2, 0)), np.zeros(0, int), np.zeros((2, 0))),
     "waypoints"),
    ("large_map_seed_negative", lambda: scenario_files.generate_large_map(seed=-1), "seed"),
    ("large_map_length_text", lambda: scenario_files.generate_large_map(run_length="long"), "run_length"),
    ("large_map_tries_zero", lambda: scenario_files.generate_large_map(max_tries=0), "max_tries"),
    ("write_scenarios_large_map_text", lambda: scenario_files.write_scenario_files("/nonexistent", large_map="no"),
     "large_map"),
    ("ticks_to_finish_shape", lambda: scenario_files.ticks_to_finish(np.zeros((3, 2))), "waypoints"),
    # ---- pruning
    ("keep_k_seed_text", lambda: pruning.KeepKPerVertex(2, seed="a"), "seed"),
    ("keep_k_seed_negative", lambda: pruning.KeepKPerVertex(2, seed=-1), "seed"),
    ("keep_k_zero", lambda: pruning.KeepKPerVertex(0), "k"),
    ("straight_window_even", lambda: pruning.straight_segment_mask(np.zeros(5), 0.1, window=4), "window"),
    ("keyframe_rate_nan", lambda: pruning.KeyframePruning(rate_threshold=np.nan), "rate_threshold"),
    ("alternate_stride_one", lambda: pruning.AlternateVertexPruning(1), "stride"),
    ("q3b_hook_stride_zero", lambda: pruning.q3b_hook(stride=0), "stride"),
    # ---- marginalisation
    ("schur_fractional_keep", lambda: mg.schur_complement(np.eye(3), np.zeros(3), [0.5, 1.7], [2]), "keep"),
    ("schur_duplicate_keep", lambda: mg.schur_complement(np.eye(3), np.zeros(3), [0, 0], [2]), "keep"),
    ("schur_negative_index", lambda: mg.schur_complement(np.eye(3), np.zeros(3), [-1], [2]), "keep"),
    ("schur_singular", lambda: mg.schur_complement(np.diag([1.0, 1.0, 0.0]), np.zeros(3), [0, 1], [2]), "singular"),
    ("prior_lam_indefinite", lambda: mg.linear_prior_factor(np.diag([1.0, -1.0]), np.zeros(2)), "lam"),
    ("marginalise_foreign_vertex", lambda: mg.marginalise_vertex(_started().graph, _started().vehicle_vertices[0]),
     "vertex"),
    # ---- analysis and plotting
    ("ellipse_P_indefinite", lambda: an.ellipse_axes(np.diag([1.0, -1.0]), 1.0), "P must be positive"),
    ("ellipse_P_asymmetric", lambda: an.ellipse_axes([[1.0, 0.9], [0.0, 1.0]], 1.0), "P must be symmetric"),
    ("ellipse_n_sigma_negative", lambda: an.ellipse_axes(np.eye(2), -1.0), "n_sigma"),
    ("tangent_round_ellipses", lambda: an.fit_tangent_centre([[1.0, 2], [3, 4], [5, 1]], np.array([np.eye(2)] * 3)),
     "centre"),
    ("tangent_parallel_axes", lambda: an.fit_tangent_centre([[1.0, 2], [3, 4]], np.array([np.diag([4.0, 1.0])] * 2)),
     "centre"),
    ("loop_closure_gap_fraction", lambda: an.find_loop_closure(np.arange(3), np.arange(3), min_gap=2.5), "min_gap"),
    ("determinant_ids_length", lambda: an.determinant_table([1, 2, 3], np.eye(2)[None], np.eye(2)[None]), "ids"),
    ("wraps_period_nan", lambda: _in_axes(lambda ax: pl.plot_wrapped_angle(ax, [0, 1], [0, 1], np.nan)), "period"),
    ("wraps_2d_t", lambda: _in_axes(lambda ax: pl.plot_wrapped_angle(ax, np.zeros((2, 3)), np.zeros(6))),
     "t and angle"),
    ("wraps_text_angle", lambda: _in_axes(lambda ax: pl.plot_wrapped_angle(ax, [0, 1], ["a", "b"])), "angle"),
    # ---- q1 / q2 / q3 support
    ("fraction_inside_negative_variance", lambda: q1.fraction_inside(np.zeros((1, 3)), [[1.0, -1.0, 1.0]]),
     "variance"),
    ("fraction_inside_n_sigma_nan", lambda: q1.fraction_inside(np.zeros((1, 3)), np.ones((1, 3)), n_sigma=np.nan),
     "n_sigma"),
    ("jacobian_eps_zero", lambda: q1.jacobian_error(_two_vertices().process_model_edges[0], 0), "eps"),
    ("interval_reversed", lambda: q2.interval_mask([1, 2, 3], [[3, 1]]), "intervals"),
    ("interval_nan", lambda: q2.interval_mask([1, 2, 3], [[np.nan, 2.0]]), "intervals"),
    ("interval_three_columns", lambda: q2.interval_mask([1, 2, 3], [[1, 2, 3]]), "intervals"),
    ("shade_three_numbers", lambda: _in_axes(lambda ax: q2.mark_gaps_and_closure([ax], [1, 2, 3], 0.1)), "intervals"),
    ("shade_dt_zero", lambda: _in_axes(lambda ax: q2.mark_gaps_and_closure([ax], [[1, 2]], 0.0)), "dt"),
    ("closure_text", lambda: _in_axes(lambda ax: q2.mark_gaps_and_closure([ax], np.zeros((0, 2), int), 0.1,
                                                                          closure="late")), "closure"),
    ("landmark_facts_negative_tick", lambda: q2.landmark_facts(run_question("q2_b", maximum_step_number=20), [-1], [1]),
     "tick"),
    ("online_recorder_every_zero", lambda: q2.OnlineRecorder(0), "every"),
    ("mean_rate_nan_time", lambda: q2.mean_rate([0.0, np.nan, 2.0], np.zeros(3), np.ones(3, bool)), "t and y"),
    ("no_observation_tick_out_of_range", lambda: q2.no_observation_intervals([5], 3), "tick"),
    ("evaluate_keep_unknown_seed", lambda: q3.evaluate_seeds("q1_e", {"a": {}}, [0], keep=[7]), "keep"),
    ("evaluate_seeds_duplicate", lambda: q3.evaluate_seeds("q1_e", {"a": {}}, [0, 0]), "seeds"),
    ("seed_summary_unknown_metric", lambda: q3.seed_summary({"a": {0: {"x": 1.0}}}, "y"), "metric"),
    ("seed_bars_unknown_metric", lambda: _in_axes(lambda ax: q3.plot_seed_bars([ax], {"a": {0: {"x": 1.0}}}, ["y"])),
     "metric"),
    # ---- notebook support, timing, paths
    ("claims_namespace_list", lambda: notebook.Claims([], A=1), "namespace"),
    ("claims_undefined_parameter", lambda: notebook.Claims({}, A=1), "not defined"),
    ("claims_empty_claim", lambda: notebook.Claims({"A": 1}, A=1).check(True, ""), "claim"),
    ("show_source_missing_stop", lambda: notebook.show_source(notebook.Claims.check, start="if", stop="no such line"),
     "stop"),
    ("show_source_missing_start", lambda: notebook.show_source(notebook.Claims.check, start="no such line"), "start"),
    ("show_source_start_int", lambda: notebook.show_source(notebook.Claims.check, start=5), "start"),
    ("show_source_builtin", lambda: notebook.show_source(len), "source"),
    ("timed_not_callable", lambda: timing.timed("x"), "fn"),
    ("best_of_zero", lambda: timing.best_of(0, lambda: 1), "repeats"),
    ("data_path_dotdot", lambda: paths.data_path("..", "etc"), "data_path"),
    ("data_path_absolute", lambda: paths.data_path("/etc"), "data_path"),
    ("data_path_int", lambda: paths.data_path(5), "data_path"),
]


@pytest.mark.parametrize("call, match", [pytest.param(c, m, id=i) for i, c, m in BAD])
def test_bad_input_raises_a_clear_value_error(call, match):
    with pytest.raises(ValueError, match=match):
        call()
    plt.close("all")


def test_the_bad_input_table_has_unique_ids():
    ids = [i for i, _, _ in BAD]
    assert len(ids) == len(set(ids))


# ---------------------------------------------------------------------------------------------- configuration
@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.floats(-8.0, 8.0), st.floats(0.0, 7.0))
def test_covariance_bounds_accept_exactly_the_documented_range(log_sigma, log_ratio):
    sigma = np.array([10.0 ** log_sigma, 10.0 ** (log_sigma + log_ratio)])
    inside = SIGMA_BOUNDS[0] <= sigma.min() and sigma.max() <= SIGMA_BOUNDS[1] and sigma[1] / sigma[0] <= SIGMA_RATIO
    margin = min(abs(math.log10(s / b)) for s in sigma for b in SIGMA_BOUNDS)
    if margin < 1e-9 or abs(log_ratio - 6.0) < 1e-9:
        return   # exactly on a bound: round-off decides
    if inside:
        assert np.allclose(SimulatorConfiguration(r_gps=np.diag(sigma ** 2)).r_gps, np.diag(sigma ** 2))
    else:
        with pytest.raises(ValueError, match="r_gps"):
            SimulatorConfiguration(r_gps=np.diag(sigma ** 2))


def test_configuration_is_read_only_after_construction():
    cfg = SimulatorConfiguration()
    with pytest.raises(dataclasses.FrozenInstanceError):
        cfg.dt = -1.0
    assert cfg.dt == 0.1
    matrix = np.eye(2)
    cfg = SimulatorConfiguration(r_gps=matrix)
    matrix[0, 0] = 50.0                       # the caller's array is copied, not shared
    assert cfg.r_gps[0, 0] == 1.0 and not cfg.r_gps.flags.writeable
    assert dataclasses.replace(cfg, dt=0.2).dt == 0.2 and cfg.dt == 0.1
    with pytest.raises(ValueError, match="dt"):
        dataclasses.replace(cfg, dt=-0.2)


def test_slam_options_are_frozen_and_checked_once():
    options = SLAMOptions(optimization_period=np.int64(5))
    assert options.optimization_period == 5 and type(options.optimization_period) is int
    assert SLAMOptions(optimization_period=np.inf).optimization_period is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        options.optimization_period = 0
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_compass=True), options)
    system.step_number = 3
    assert system.options is options and system.recommend_optimization() is False


# ---------------------------------------------------------------------------------------------- event batches
def _state(system):
    return (system.step_number, system.current_time, system.initialised, len(system.vehicle_vertices),
            system.graph.number_of_vertices(), system.graph.number_of_edges(),
            None if system._u is None else system._u.tolist())


@pytest.mark.parametrize("batch", [
    [_odo(0.1), _odo(0.2), _odo(0.15)],                                            # time order, third event
    [_odo(0.1), Event(0.1, EventType.GPS, [0, 0], np.eye(2))],                     # a disabled sensor, second
    [_odo(0.1), Event(0.2, EventType.INITIAL_CONDITION, [0, 0, 0], np.zeros((3, 3)))],
    [_odo(0.1), Event(0.2, EventType.VEHICLE_ODOMETRY, [1, 0, 0], -np.eye(3))],   # covariance, after a prediction
], ids=["time_order", "disabled_sensor", "second_initial_condition", "odometry_covariance"])
def test_a_bad_batch_changes_nothing(batch):
    system = _started()
    system.process_events([_odo(0.05, u=(2.0, 0.0, 0.1))])
    before = _state(system)
    with pytest.raises(ValueError):
        system.process_events(batch)
    assert _state(system) == before
    system.process_events([_odo(0.3)])                      # and the system goes on
    assert len(system.vehicle_vertices) == before[3] + 1


def test_a_bad_first_batch_changes_nothing():
    system = _system()
    before = _state(system)
    with pytest.raises(ValueError, match="initial covariance"):
        system.process_events([_odo(0.0), Event(0.0, EventType.INITIAL_CONDITION, [0, 0, 0],
                                                np.diag([-1.0, -1.0, 1.0]))])
    assert _state(system) == before


def test_events_from_a_generator_and_within_the_merge_time():
    system = _started()
    system.process_events(e for e in [_odo(0.1), _odo(0.1 - 5e-4)])   # 0.5 ms earlier: the same vertex
    assert len(system.vehicle_vertices) == 2 and system.step_number == 2


def test_events_before_the_initial_condition_are_ignored_as_documented():
    system = _system(enable_compass=True)
    system.process_events([Event(0.0, EventType.COMPASS, [0.3], [[0.01]]), _odo(0.0)])
    assert not system.initialised and system.step_number == 1 and not system.graph.edges()
    system.process_events([Event(0.0, EventType.INITIAL_CONDITION, [0, 0, 0], np.zeros((3, 3)))])
    system.process_events([_odo(0.1)])                    # the odometry stored before initialisation is used
    np.testing.assert_allclose(system.vehicle_vertices[1].estimate, [0.1, 0.0, 0.0])


# ---------------------------------------------------------------------------------------------- simulator
def test_simulator_after_the_route():
    sim = DriveBotSimulator(SimulatorConfiguration(), load_scenario("q1_e"))
    sim.start()
    while sim.keep_running():
        sim.step()
    with pytest.raises(RuntimeError, match="route is finished"):
        sim.step()


# ---------------------------------------------------------------------------------------------- scenario files
@pytest.mark.parametrize("landmarks, waypoints, match", [
    (b"", b"x,y\n70,0\n", "header"),
    (b"\x89PNG\r\n\x1a\n\x00binary", b"x,y\n70,0\n", "cannot read"),
    (b"id,x,y\n1.5,2,2\n", b"x,y\n70,0\n", "integers"),
    (b"id,x,y\n1,2,2\n2,nan,3\n", b"x,y\n70,0\n", "finite"),
    (b"id,x,y\n1,2,2\n", b"x,y\n", "waypoints"),
    (b"id,x,y\n1,2,2\n", b"x,y\n70,0\n80\n", "malformed"),
    (b"id,x,y\n1,2\n", b"x,y\n70,0\n", "columns"),
    (b"id,x,y\n1,2,2\n", b"", "header"),
], ids=["empty", "binary", "fractional_id", "nan", "no_waypoint", "truncated_row", "missing_column",
        "empty_waypoints"])
def test_malformed_scenario_files(tmp_path, monkeypatch, landmarks, waypoints, match):
    (tmp_path / "q1_b").mkdir()
    (tmp_path / "q1_b" / "landmarks.csv").write_bytes(landmarks)
    (tmp_path / "q1_b" / "waypoints.csv").write_bytes(waypoints)
    monkeypatch.setattr(scenarios, "data_dir", lambda: tmp_path)
    with pytest.raises(ValueError, match=match):
        load_scenario("q1_b")


def test_scenario_with_a_header_only_landmark_file(tmp_path, monkeypatch):
    (tmp_path / "q1_b").mkdir()
    (tmp_path / "q1_b" / "landmarks.csv").write_text("id,x,y\n")
    (tmp_path / "q1_b" / "waypoints.csv").write_text("x,y\n70,0\n")
    monkeypatch.setattr(scenarios, "data_dir", lambda: tmp_path)
    sc = load_scenario("q1_b")
    assert sc.landmarks.shape == (2, 0) and sc.waypoints.tolist() == [[70.0], [0.0]]


def test_write_scenario_files_root_and_atomic_writes(tmp_path):
    afile = tmp_path / "file"
    afile.write_text("x")
    with pytest.raises(ValueError, match="root"):
        scenario_files.write_scenario_files(afile, large_map=False)
    scenario_files.write_scenario_files(tmp_path / "out", large_map=False)
    written = sorted(p.relative_to(tmp_path / "out").as_posix() for p in (tmp_path / "out").rglob("*"))
    assert "q1_b/landmarks.csv" in written and not [p for p in written if p.split("/")[-1].startswith(".")]
    assert load_scenario("q1_b").landmarks.tolist() == np.loadtxt(
        tmp_path / "out" / "q1_b" / "landmarks.csv", delimiter=",", skiprows=1)[:, 1:].T.tolist()


# ---------------------------------------------------------------------------------------------- failures
def test_a_failure_during_a_run_propagates_unchanged():
    with pytest.raises(GaugeFreedomError) as info:
        run_question("q3_a", remove_prediction_edges=True, keep_first_prediction_edge=False, maximum_step_number=520)
    assert info.value.component

    def hook(system, k):
        if k == 5:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt):
        run_question("q1_e", step_hook=hook, maximum_step_number=20)


# ---------------------------------------------------------------------------------------------- support
def test_plot_state_errors_accepts_any_real_n_sigma(short_q2b):
    fig, axes = plt.subplots(3)
    pl.plot_state_errors(short_q2b, axes, n_sigma=np.float32(2.0))
    bound = axes[0].lines[1].get_ydata()
    plt.close(fig)
    np.testing.assert_allclose(bound, 2.0 * np.sqrt(short_q2b.vehicle_covariance_history[0]), rtol=1e-6)


def test_timed_propagates_the_functions_own_error():
    with pytest.raises(ZeroDivisionError):
        timing.timed(lambda: 1 / 0)


def test_data_path_inside_data():
    assert paths.data_path("drivebot", "q1_b") == paths.data_dir() / "drivebot" / "q1_b"
    assert isinstance(paths.data_path("drivebot"), pathlib.Path)


def test_show_source_to_the_end_without_stop(capsys):
    text = notebook.source_lines(notebook.Claims.check)
    assert text.splitlines()[-1].strip() == "return ok"


def test_a_hook_that_edits_then_raises_leaves_a_usable_system():
    res = run_question("q2_b", maximum_step_number=40, optimization_period=None)
    system = res.system

    def prune_then_fail(s):
        edge = next(e for e in s.graph.edges() if isinstance(e, EdgeRangeBearing))
        s.graph.remove_edge(edge)
        raise RuntimeError("hook failed after editing the graph")

    system.options = SLAMOptions(pre_optimization_hook=prune_then_fail)
    with pytest.raises(RuntimeError, match="hook failed"):
        system.optimize()
    system.options = SLAMOptions()
    x, P = system.platform_estimate()            # the structure is rebuilt for the edited graph
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(P))
    assert np.isfinite(system.optimize())
