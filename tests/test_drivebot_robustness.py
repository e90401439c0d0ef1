"""Robustness of the DriveBot system and the notebook support (issue 14): bad input gets a clear ValueError naming
the argument, a bad event batch changes nothing, and a run that fails part-way keeps its partial results."""
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
from helpers.drivebot import (DriveBotSimulator, DriveBotSLAMSystem, Event, EventQueue, EventType,  # noqa: E402
                              Results, SimulatorConfiguration, load_scenario, run_question)
from helpers.drivebot import analysis as an  # noqa: E402
from helpers.drivebot import marginalisation as mg  # noqa: E402
from helpers.drivebot import plotting as pl  # noqa: E402
from helpers.drivebot import pruning  # noqa: E402
from helpers.drivebot import q1_support as q1  # noqa: E402
from helpers.drivebot import q2_support as q2  # noqa: E402
from helpers.drivebot import q3_support as q3  # noqa: E402
from helpers.drivebot import runner, scenario_files, scenarios  # noqa: E402
from helpers.drivebot.config import SIGMA_BOUNDS, SIGMA_RATIO  # noqa: E402
from helpers.drivebot.edges import predict  # noqa: E402
from helpers.graph import EdgeRangeBearing  # noqa: E402
from helpers.graph import GaugeFreedomError, GraphError, VertexPointXY  # noqa: E402


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
    ("run_unknown_option", lambda: runner.run(SimulatorConfiguration(), load_scenario("q1_e"), foo=1), "foo"),
    ("run_config_text", lambda: runner.run("cfg", load_scenario("q1_e")), "config"),
    ("run_scenario_name", lambda: runner.run(SimulatorConfiguration(), "q1_e"), "scenario"),
    ("run_question_label_int", lambda: runner.run(SimulatorConfiguration(maximum_step_number=3),
                                                  load_scenario("q1_e"), question=5), "question"),
    ("variants_list", lambda: runner.run_variants("q1_e", []), "variants"),
    ("variants_empty", lambda: runner.run_variants("q1_e", {}), "variants"),
    ("variant_config_field", lambda: runner.run_variants("q1_e", {"a": {"dt": 0.2}}), "SLAM options"),
    ("variant_name_int", lambda: runner.run_variants("q1_e", {5: {}}), "variant name"),
    ("variant_rpe_odometry_only", lambda: runner.run_variants("q1_b", {"a": {"remove_prediction_edges": True}}),
     "remove_prediction_edges"),
    ("chi2_bounds_k_negative", lambda: run_question("q1_e", maximum_step_number=5).chi2_bounds(-1.0), "k must"),
    ("chi2_bounds_k_text", lambda: run_question("q1_e", maximum_step_number=40).chi2_bounds("x"), "k must"),
    # ---- configuration, events, queue
    ("config_replace_unknown", lambda: SimulatorConfiguration().replace(radar=True), "unknown"),
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
    ("queue_insert_text", lambda: EventQueue().insert("x"), "event"),
    # ---- SLAM system: event processing
    ("batch_single_event", lambda: _started().process_events(_odo(0.1)), "events must be a list"),
    ("batch_int", lambda: _started().process_events(5), "events must be a list"),
    ("batch_text", lambda: _started().process_events("events"), "events must be a list"),
    ("batch_non_event", lambda: _started().process_events([_odo(0.1), "x"]), "events must contain Event"),
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
    # ---- SLAM system: options on construction and on assignment
    ("system_config_text", lambda: DriveBotSLAMSystem(config="default"), "config"),
    ("system_dt_below_merge_time", lambda: DriveBotSLAMSystem(SimulatorConfiguration(dt=0.0015)), "dt"),
    ("system_rpe_no_sensor", lambda: DriveBotSLAMSystem(SimulatorConfiguration(), remove_prediction_edges=True),
     "remove_prediction_edges"),
    ("assign_period_zero", lambda: _assign(_started(), "optimization_period", 0), "optimization_period"),
    ("assign_compass_edge_unknown", lambda: _assign(_started(), "compass_edge", "broken"), "compass_edge"),
    ("assign_hook_int", lambda: _assign(_started(), "pre_optimization_hook", 5), "pre_optimization_hook"),
    ("assign_rpe_text", lambda: _assign(_started(enable_gps=True), "remove_prediction_edges", "yes"),
     "remove_prediction_edges"),
    ("assign_rpe_no_sensor", lambda: _assign(_started(), "remove_prediction_edges", True), "remove_prediction_edges"),
    ("assign_algorithm_unknown", lambda: _assign(_started(), "optimization_algorithm", "newton"),
     "optimization_algorithm"),
    ("assign_config", lambda: _assign(_started(), "config", SimulatorConfiguration()), "config"),
    ("platform_estimate_uninitialised", lambda: _system().platform_estimate(), "initialised"),
    ("edge_residuals_name", lambda: _started().edge_residuals("EdgeHeadingPrior"), "edge_class"),
    ("predict_dt_zero", lambda: predict([0, 0, 0], [1, 0, 0], 0.0), "dt"),
    ("predict_x_nan", lambda: predict([0, np.nan, 0], [1, 0, 0], 0.1), "x and u must be finite"),
    ("predict_u_inf", lambda: predict([0, 0, 0], [np.inf, 0, 0], 0.1), "x and u must be finite"),
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
    ("keep_k_per_group_rng", lambda: pruning.keep_k_per_group([0, 1], 1, 0), "rng"),
    ("keep_k_per_group_float_groups", lambda: pruning.keep_k_per_group([0.5, 1.0], 1, np.random.default_rng(0)),
     "group"),
    ("stride_mask_offset", lambda: pruning.stride_mask([0, 1, 2], 2, 1.5), "offset"),
    ("stride_mask_stride_zero", lambda: pruning.stride_mask([0, 1, 2], 0), "stride"),
    ("straight_window_even", lambda: pruning.straight_segment_mask(np.zeros(5), 0.1, window=4), "window"),
    ("straight_dt_negative", lambda: pruning.straight_segment_mask(np.zeros(5), -0.1), "dt"),
    ("straight_headings_nan", lambda: pruning.straight_segment_mask([0.0, np.nan], 0.1), "headings"),
    ("protect_keep_ints", lambda: pruning.protect_landmarks(np.array([1, 0]), [1, 2]), "keep"),
    ("edge_table_dt_default", lambda: pruning.landmark_edge_table(_started(), dt_default=-1.0), "dt_default"),
    ("edge_table_system_text", lambda: pruning.landmark_edge_table("graph"), "system"),
    ("keyframe_rate_nan", lambda: pruning.KeyframePruning(rate_threshold=np.nan), "rate_threshold"),
    ("alternate_stride_one", lambda: pruning.AlternateVertexPruning(1), "stride"),
    ("q3b_hook_stride_zero", lambda: pruning.q3b_hook(stride=0), "stride"),
    # ---- marginalisation
    ("schur_fractional_keep", lambda: mg.schur_complement(np.eye(3), np.zeros(3), [0.5, 1.7], [2]), "keep"),
    ("schur_duplicate_keep", lambda: mg.schur_complement(np.eye(3), np.zeros(3), [0, 0], [2]), "keep"),
    ("schur_negative_index", lambda: mg.schur_complement(np.eye(3), np.zeros(3), [-1], [2]), "keep"),
    ("schur_asymmetric", lambda: mg.schur_complement(np.array([[1.0, 0, 0.5], [0, 1, 0], [0, 0, 1]]), np.zeros(3),
                                                     [0, 1], [2]), "H must be symmetric"),
    ("schur_b_nan", lambda: mg.schur_complement(np.eye(3), [0.0, np.nan, 0.0], [0, 1], [2]), "b must be finite"),
    ("schur_singular", lambda: mg.schur_complement(np.diag([1.0, 1.0, 0.0]), np.zeros(3), [0, 1], [2]), "singular"),
    ("prior_lam_indefinite", lambda: mg.linear_prior_factor(np.diag([1.0, -1.0]), np.zeros(2)), "lam"),
    ("prior_lam_asymmetric", lambda: mg.linear_prior_factor([[2.0, 1.0], [0.0, 2.0]], np.zeros(2)), "lam"),
    ("prior_rtol_negative", lambda: mg.linear_prior_factor(np.eye(2), np.zeros(2), rtol=-1.0), "rtol"),
    ("prior_class_rank_zero", lambda: mg.linear_prior_class([VertexPointXY], 0), "rank"),
    ("local_system_text", lambda: mg.local_system("v"), "vertex"),
    ("marginalise_foreign_vertex", lambda: mg.marginalise_vertex(_started().graph, _started().vehicle_vertices[0]),
     "vertex"),
    ("hessian_blocks_twice", lambda: (lambda s: mg.hessian_blocks(s.graph, [s.vehicle_vertices[1]] * 2))(
        _two_vertices()), "distinct"),
    # ---- analysis and plotting
    ("ellipse_P_indefinite", lambda: an.ellipse_axes(np.diag([1.0, -1.0]), 1.0), "P must be positive"),
    ("ellipse_P_asymmetric", lambda: an.ellipse_axes([[1.0, 0.9], [0.0, 1.0]], 1.0), "P must be symmetric"),
    ("ellipse_n_sigma_negative", lambda: an.ellipse_axes(np.eye(2), -1.0), "n_sigma"),
    ("ellipses_ax_text", lambda: an.plot_covariance_ellipses("axes", [[0, 0]], np.eye(2)), "ax"),
    ("tangent_round_ellipses", lambda: an.fit_tangent_centre([[1.0, 2], [3, 4], [5, 1]], np.array([np.eye(2)] * 3)),
     "centre"),
    ("tangent_parallel_axes", lambda: an.fit_tangent_centre([[1.0, 2], [3, 4]], np.array([np.diag([4.0, 1.0])] * 2)),
     "centre"),
    ("loop_closure_gap_fraction", lambda: an.find_loop_closure(np.arange(3), np.arange(3), min_gap=2.5), "min_gap"),
    ("determinant_ids_length", lambda: an.determinant_table([1, 2, 3], np.eye(2)[None], np.eye(2)[None]), "ids"),
    ("landmark_observations_none", lambda: an.landmark_observations(None), "system"),
    ("wraps_period_nan", lambda: pl.break_at_wraps([0, 1], [0, 1], np.nan), "period"),
    ("wraps_2d_t", lambda: pl.break_at_wraps(np.zeros((2, 3)), np.zeros(6)), "t and angle"),
    ("wraps_text_angle", lambda: pl.break_at_wraps([0, 1], ["a", "b"]), "angle"),
    ("factor_graph_ax_none", lambda: pl.draw_factor_graph(_started(), None), "ax"),
    ("wrapped_angle_ax_text", lambda: pl.plot_wrapped_angle("ax", [0, 1], [0, 1]), "ax"),
    # ---- q1 / q2 / q3 support
    ("fraction_inside_negative_variance", lambda: q1.fraction_inside(np.zeros((1, 3)), [[1.0, -1.0, 1.0]]),
     "variance"),
    ("fraction_inside_n_sigma_nan", lambda: q1.fraction_inside(np.zeros((1, 3)), np.ones((1, 3)), n_sigma=np.nan),
     "n_sigma"),
    ("online_estimate_none", lambda: q1.OnlineEstimate()(None, 0), "system"),
    ("jacobian_eps_zero", lambda: q1.jacobian_error(_two_vertices().process_model_edges[0], 0), "eps"),
    ("interval_reversed", lambda: q2.interval_mask([1, 2, 3], [[3, 1]]), "intervals"),
    ("interval_nan", lambda: q2.interval_mask([1, 2, 3], [[np.nan, 2.0]]), "intervals"),
    ("interval_three_columns", lambda: q2.interval_mask([1, 2, 3], [[1, 2, 3]]), "intervals"),
    ("shade_three_numbers", lambda: _in_axes(lambda ax: q2.shade_intervals(ax, [1, 2, 3], 0.1)), "intervals"),
    ("shade_dt_zero", lambda: _in_axes(lambda ax: q2.shade_intervals(ax, [[1, 2]], 0.0)), "dt"),
    ("closure_text", lambda: _in_axes(lambda ax: q2.mark_gaps_and_closure([ax], np.zeros((0, 2), int), 0.1,
                                                                          closure="late")), "closure"),
    ("landmark_facts_results_text", lambda: q2.landmark_facts("res", [1], [1]), "results"),
    ("landmark_facts_negative_tick", lambda: q2.landmark_facts(run_question("q2_b", maximum_step_number=20), [-1], [1]),
     "tick"),
    ("online_recorder_none", lambda: q2.OnlineRecorder(5)(None, 0), "system"),
    ("online_recorder_every_zero", lambda: q2.OnlineRecorder(0), "every"),
    ("mean_rate_nan_time", lambda: q2.mean_rate([0.0, np.nan, 2.0], np.zeros(3), np.ones(3, bool)), "t and y"),
    ("waypoint_ticks_none", lambda: q2.waypoint_ticks(None), "results"),
    ("no_observation_tick_out_of_range", lambda: q2.no_observation_intervals([5], 3), "tick"),
    ("run_metrics_text", lambda: q3.run_metrics("res"), "results"),
    ("evaluate_keep_int", lambda: q3.evaluate_seeds("q1_e", {"a": {}}, [0], keep=5), "keep"),
    ("evaluate_keep_unknown_seed", lambda: q3.evaluate_seeds("q1_e", {"a": {}}, [0], keep=[7]), "keep"),
    ("evaluate_seeds_duplicate", lambda: q3.evaluate_seeds("q1_e", {"a": {}}, [0, 0]), "seeds"),
    ("seed_summary_unknown_metric", lambda: q3.seed_summary({"a": {0: {"x": 1.0}}}, "y"), "metric"),
    ("failures_none", lambda: q3.failures(None), "evaluation"),
    ("seed_table_empty", lambda: q3.format_seed_table({}, [("x", "x", ".1f")]), "evaluation"),
    ("seed_table_bad_columns", lambda: q3.format_seed_table({"a": {0: {"x": 1.0}}}, ["x"]), "columns"),
    ("spy_n_vehicle_fraction", lambda: _in_axes(lambda ax: q3.spy_hessian(ax, np.eye(4), [0, 2], 1.5)), "n_vehicle"),
    ("seed_bars_unknown_metric", lambda: _in_axes(lambda ax: q3.plot_seed_bars([ax], {"a": {0: {"x": 1.0}}}, ["y"])),
     "metric"),
    ("paired_unknown_variant", lambda: q3.paired({"a": {}}, "b", "a", "x"), "variant"),
    ("relative_unknown_reference", lambda: q3.format_relative({"a": {0: {"x": 1.0}}}, "b"), "reference"),
    # ---- notebook support, timing, paths
    ("claims_array_condition", lambda: notebook.Claims({"A": 1}, A=1).check(np.array([True, False]), "x"),
     "condition"),
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
    assert len(ids) == len(set(ids)) >= 70


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
    with pytest.raises(dataclasses.FrozenInstanceError, match="replace"):
        cfg.dt = -1.0
    assert cfg.dt == 0.1
    matrix = np.eye(2)
    cfg = SimulatorConfiguration(r_gps=matrix)
    matrix[0, 0] = 50.0                       # the caller's array is copied, not shared
    assert cfg.r_gps[0, 0] == 1.0 and not cfg.r_gps.flags.writeable
    assert cfg.replace(dt=0.2).dt == 0.2 and cfg.dt == 0.1


# ---------------------------------------------------------------------------------------------- event batches
def _state(system):
    return (len(system.vehicle_vertices), len(system.graph.edges()), system.step_number, system.current_time,
            system.initialised, None if system._u_info is None else system._u.tolist())


@pytest.mark.parametrize("batch, match", [
    ([_odo(0.1, (2.0, 0, 0)), Event(0.1, EventType.COMPASS, [0.0], [[0.01]]),
      Event(0.1, EventType.GPS, [0, 0], np.eye(2))], "enable_gps"),
    ([_odo(0.1, (2.0, 0, 0)), Event(0.1, EventType.COMPASS, [0.0], [[0.01]]), _odo(0.05)], "time order"),
    ([_odo(0.1, (2.0, 0, 0)), Event(0.1, EventType.COMPASS, [0.0], [[0.01]]), "x"], "Event"),
    ([_odo(0.1, (2.0, 0, 0)), Event(0.1, EventType.INITIAL_CONDITION, [0, 0, 0], np.zeros((3, 3)))],
     "INITIAL_CONDITION"),
    ([_odo(0.1, (2.0, 0, 0)), Event(0.1, EventType.COMPASS, [0.0], [[-1.0]])], "covariance"),
], ids=["disabled_sensor", "out_of_order", "not_an_event", "second_initial_condition", "bad_covariance"])
def test_a_bad_batch_changes_nothing(batch, match):
    system = _started(enable_compass=True)
    system.process_events([_odo(0.1), Event(0.1, EventType.COMPASS, [0.0], [[0.01]])])
    before = _state(system)
    with pytest.raises(ValueError, match=match):
        system.process_events(batch)
    assert _state(system) == before
    system.process_events([_odo(0.2)])       # and it carries on normally
    assert _state(system)[0] == before[0] + 1


def test_a_measurement_the_edge_class_rejects_fails_before_the_batch_is_applied(monkeypatch):
    from helpers.graph import EdgeRangeBearing

    def reject_far(cls, z, name):
        if np.any(z[:, 0] > 50.0):
            raise ValueError(f"{name}: range beyond the test's limit")
    monkeypatch.setattr(EdgeRangeBearing, "check_measurements", classmethod(reject_far), raising=False)
    system = _started(enable_laser=True)
    before = _state(system)
    scan = Event(0.1, EventType.LANDMARK, [[3.0, 60.0], [0.0, 1.0]], 0.01 * np.eye(2), landmark_ids=[1, 2])
    with pytest.raises(ValueError, match="LANDMARK event at t = 0.100: data: range beyond"):
        system.process_events([_odo(0.1), scan])
    assert _state(system) == before and not system.landmark_vertices


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


def test_compass_edge_assigned_after_construction_takes_effect_for_new_edges():
    system = _started(enable_compass=True)
    system.process_events([_odo(0.1), Event(0.1, EventType.COMPASS, [0.0], [[0.01]])])
    system.compass_edge = "buggy"
    system.process_events([_odo(0.2), Event(0.2, EventType.COMPASS, [0.0], [[0.01]])])
    kinds = [type(e).__name__ for e in system.graph.edges() if len(e.vertices()) == 1]
    assert kinds == ["EdgeHeadingPrior", "BuggyCompassEdge"]


# ---------------------------------------------------------------------------------------------- simulator
def test_simulator_state_before_start_and_after_the_route():
    sim = DriveBotSimulator(SimulatorConfiguration(), load_scenario("q1_e"))
    for read in (lambda: sim.time, lambda: sim.step_number, sim.step, sim.events):
        with pytest.raises(RuntimeError, match="start"):
            read()
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


# ---------------------------------------------------------------------------------------------- failures part-way
def test_step_hook_failure_keeps_the_partial_run():
    def hook(system, k):
        if k == 7:
            raise ValueError("user hook failed")
    with pytest.raises(ValueError, match="user hook failed") as info:
        run_question("q1_e", step_hook=hook, maximum_step_number=20)
    err = info.value
    assert (err.tick, err.phase) == (7, "step_hook") and isinstance(err.results, Results)
    assert any("tick 7" in note for note in err.__notes__)
    # ticks 0 … 7 processed and optimised (period 1): the same numbers as a run of 8 ticks
    ref = run_question("q1_e", maximum_step_number=8)
    np.testing.assert_array_equal(err.results.vehicle_state_history, ref.vehicle_state_history)
    np.testing.assert_array_equal(err.results.vehicle_covariance_history, ref.vehicle_covariance_history)
    np.testing.assert_array_equal(err.results.vehicle_true_state_history, ref.vehicle_true_state_history)
    np.testing.assert_array_equal(err.results.chi2_history, ref.chi2_history)


def test_keyboard_interrupt_is_reraised_as_is_with_the_partial_run():
    def hook(system, k):
        if k == 5:
            raise KeyboardInterrupt
    with pytest.raises(KeyboardInterrupt) as info:
        run_question("q1_e", step_hook=hook, maximum_step_number=20)
    assert info.value.tick == 5 and info.value.results.n_steps == 6
    assert np.all(np.isfinite(info.value.results.vehicle_state_history))


def test_pre_optimization_hook_failure_keeps_the_partial_run():
    calls = []

    def hook(system):
        calls.append(system.step_number)
        if len(calls) == 2:
            system.graph.remove_edge(next(e for e in system.graph.edges() if type(e).__name__ == "EdgeRangeBearing"))
            raise RuntimeError("hook failed half-way")
    with pytest.raises(RuntimeError, match="half-way") as info:
        run_question("q2_b", pre_optimization_hook=hook, maximum_step_number=20)
    err = info.value
    assert (err.tick, err.phase) == (9, "optimisation") and calls == [5, 10]
    res = err.results
    assert res.n_steps == 10 == res.vehicle_true_state_time.size == res.optimization_times.size
    # the covariances are those of the graph as the hook left it (structure rebuilt, not stale)
    assert np.all(np.isfinite(res.vehicle_covariance_history[:, 1:]))


def test_gauge_failure_keeps_the_partial_run_and_its_type():
    with pytest.raises(GaugeFreedomError) as info:
        run_question("q3_a", remove_prediction_edges=True, keep_first_prediction_edge=False, maximum_step_number=520)
    err = info.value
    assert (err.tick, err.phase) == (499, "optimisation") and err.component
    res = err.results
    assert res.n_steps == 500 and np.isnan(res.vehicle_covariance_history).all()   # no covariance without a gauge
    assert np.isfinite(res.vehicle_state_history[:, res.vehicle_in_graph]).all()


def test_simulator_failure_keeps_the_partial_run(monkeypatch):
    step = DriveBotSimulator.step

    def failing(self):
        if self.step_number == 4:
            raise OSError("sensor bus down")
        step(self)
    monkeypatch.setattr(DriveBotSimulator, "step", failing)
    with pytest.raises(OSError, match="sensor bus down") as info:
        run_question("q1_e", maximum_step_number=20)
    assert (info.value.tick, info.value.phase) == (4, "simulator step")
    assert info.value.results.n_steps == 5


def test_partial_results_before_any_optimisation():
    def hook(system, k):
        if k == 3:
            raise ValueError("early")
    with pytest.raises(ValueError, match="early") as info:
        run_question("q1_e", step_hook=hook, optimization_period=None, maximum_step_number=10)
    res = info.value.results
    assert res.n_steps == 4 and res.chi2_history.size == 0 and np.isnan(res.optimization_times).all()
    with pytest.raises(ValueError, match="no optimisation has run"):
        _ = res.final_chi2


def test_final_covariance_failure_keeps_the_estimates(monkeypatch):
    def no_covariance(self):
        raise GraphError("compute_marginals: H is not positive definite")
    monkeypatch.setattr(DriveBotSLAMSystem, "platform_estimate_history", no_covariance)
    with pytest.raises(GraphError, match="positive definite") as info:
        run_question("q1_e", maximum_step_number=15, optimization_period=None)
    err = info.value
    assert (err.tick, err.phase) == (14, "covariances")
    res = err.results
    assert res.n_steps == 15 and res.chi2_history.size == 1 and np.isfinite(res.final_chi2)
    assert np.isnan(res.vehicle_covariance_history).all() and np.isfinite(res.vehicle_state_history).all()


def test_an_exception_that_refuses_attributes_becomes_a_run_error():
    class Sealed(Exception):
        def __setattr__(self, name, value):
            raise AttributeError(name)

    def hook(system, k):
        if k == 3:
            raise Sealed("sealed")
    with pytest.raises(runner.RunError, match="tick 3") as info:
        run_question("q1_e", step_hook=hook, maximum_step_number=10)
    assert isinstance(info.value.__cause__, Sealed) and info.value.results.n_steps == 4


def test_run_variants_failures_carry_partial_results():
    out = runner.run_variants("q3_a", {"full": {}, "all": {"remove_prediction_edges": True,
                                                           "keep_first_prediction_edge": False}},
                              seed=3, maximum_step_number=520)
    assert isinstance(out["full"], Results) and isinstance(out["all"], GaugeFreedomError)
    assert out["all"].tick == 499 and out["all"].results.n_steps == 500

    def hook(system):
        raise RuntimeError("variant hook")
    with pytest.raises(RuntimeError, match="variant hook") as info:
        runner.run_variants("q2_b", {"a": {}, "b": {"pre_optimization_hook": hook}}, maximum_step_number=20)
    assert info.value.tick == 4 and set(info.value.results) == {"a", "b"}
    assert info.value.results["a"].n_steps == 5


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


def test_optimize_checks_max_iterations_before_the_hook_runs():
    calls = []
    res = run_question("q3_b", maximum_step_number=30, optimization_period=None,
                       pre_optimization_hook=lambda system: calls.append(1))
    n = len(calls)
    for bad in (-1, 1.5, "10"):
        with pytest.raises(ValueError, match="max_iterations"):
            res.system.optimize(bad)
    assert len(calls) == n                       # the hook never ran for a rejected call


def test_a_hook_that_edits_then_raises_leaves_a_usable_system():
    res = run_question("q2_b", maximum_step_number=40, optimization_period=None)
    system = res.system

    def prune_then_fail(s):
        edge = next(e for e in s.graph.edges() if isinstance(e, EdgeRangeBearing))
        s.graph.remove_edge(edge)
        raise RuntimeError("hook failed after editing the graph")

    system.pre_optimization_hook = prune_then_fail
    with pytest.raises(RuntimeError, match="hook failed"):
        system.optimize()
    system.pre_optimization_hook = None
    x, P = system.platform_estimate()            # the structure is rebuilt for the edited graph
    assert np.all(np.isfinite(x)) and np.all(np.isfinite(P))
    assert np.isfinite(system.optimize())
