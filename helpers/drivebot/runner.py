"""Running a question: the coursework's main loop and one entry point, ``run_question``.

Main loop, per simulator tick k (store index k, N ticks in all):

1. the SLAM system processes the tick's events (one new vehicle vertex);
2. if it recommends an optimisation, time ``optimize()`` (50 iterations at most) and record the time at
   index k, the tick time in ``chi2_time`` and χ² in ``chi2_history``; otherwise the time is NaN;
3. record the true state and its time; then the simulator steps.

The events of the final step (the one in which the controller stops) are never processed. At the end, if the last
tick did not optimise, ``optimize(20)`` runs (recorded at the last index); the vehicle histories are the smoothed
estimates from one marginal computation on the final graph.

Per-question settings: ``QUESTIONS`` (from the coursework launcher scripts; every one can be overridden by
keyword). q3_b is the coursework's student-written script for Q3b(ii): the q3_a scenario and settings, with the
graph pruned before every optimisation by a *fresh* ``pruning.q3b_hook()`` per run (hooks count their calls).
"""
from __future__ import annotations

import dataclasses
import math
import time as _time
from collections.abc import Callable

import numpy as np
from tqdm import tqdm

from ..graph import GraphError
from ..timing import timed
from ..validation import boolean, function
from . import pruning
from .config import SimulatorConfiguration
from .results import Results
from .scenarios import Scenario, load_scenario
from .simulator import DriveBotSimulator
from .slam_system import DriveBotSLAMSystem, SLAMOptions

__all__ = ["Results", "run_question", "run_variants", "QUESTIONS", "question_setup"]

#: question → (scenario, configuration fields, SLAM options); N = ticks of the run
QUESTIONS = {
    "q1_b": ("q1_b", {}, {"optimization_period": None}),                                           # N = 654
    "q1_c": ("q1_c", {"enable_compass": True, "compass_angular_offset": 0.75 * math.pi},          # N = 654
             {"optimization_period": 20, "compass_edge": "buggy"}),
    "q1_d": ("q1_d", {"enable_gps": True}, {"optimization_period": None}),                         # N = 5273
    "q1_e": ("q1_e", {"enable_gps": True}, {"optimization_period": 1}),     # N = 324; part ii: enable_compass=True
    "q2_b": ("q2_b", {"enable_laser": True}, {"optimization_period": 5}),                          # N = 1313
    "q2_c": ("q2_c", {"enable_laser": True}, {"optimization_period": None}),                       # N = 5273
    "q2_d": ("q2_d", {"enable_laser": True, "perturb_with_noise": False, "maximum_step_number": 2000},  # N = 1313
             {"optimization_period": None}),
    "q2_e": ("large_map", {"enable_laser": True}, {"optimization_period": None}),                  # N = 5667
    "q3_a": ("q3_a", {"enable_laser": True, "laser_detection_range": 30.0},                        # N = 5273
             {"optimization_period": 500, "remove_prediction_edges": False, "keep_first_prediction_edge": True}),
    # Q3b: the q3_b script — q3_a's scenario and sensors, prediction edges kept, observations pruned before
    # every optimisation by a fresh pruning.q3b_hook() (see _HOOK_FACTORIES).
    "q3_b": ("q3_a", {"enable_laser": True, "laser_detection_range": 30.0},
             {"optimization_period": 500, "remove_prediction_edges": False}),
}

#: The SLAM options (the fields of SLAMOptions).
_SLAM_OPTIONS = tuple(f.name for f in dataclasses.fields(SLAMOptions))
#: Q3b: questions whose runs get a fresh pre-optimisation hook (unless one is passed as an override).
_HOOK_FACTORIES = {"q3_b": pruning.q3b_hook}

#: Options that act only through one sensor: its flag → (sensor, the options).
_SENSOR_OPTIONS = {
    "enable_compass": ("compass", ("compass_edge", "compass_angular_offset", "compass_measurement_period",
                                   "r_compass")),
    "enable_gps": ("GPS", ("gps_measurement_period", "r_gps", "gps_position_offset")),
    "enable_laser": ("laser", ("laser_measurement_period", "laser_detection_range", "r_laser")),
}


def question_setup(name: str, **overrides: object) -> tuple[Scenario, SimulatorConfiguration, SLAMOptions]:
    """(scenario, configuration, SLAM options) of a question with ``overrides`` (configuration fields or SLAM
    options) applied; the configuration and the options check their values when they are built."""
    if not isinstance(name, str) or name not in QUESTIONS:
        raise ValueError(f"unknown question {name!r}; known questions: {sorted(QUESTIONS)}")
    scenario_name, cfg, slam = QUESTIONS[name]
    cfg, slam = dict(cfg), dict(slam)
    for key, value in overrides.items():
        if key in _SLAM_OPTIONS:
            slam[key] = value
        elif key in SimulatorConfiguration.field_names():
            cfg[key] = value
        else:
            raise ValueError(f"unknown override {key!r}; SLAM options: {list(_SLAM_OPTIONS)}; "
                             f"SimulatorConfiguration fields: {list(SimulatorConfiguration.field_names())}")
    if name in _HOOK_FACTORIES and "pre_optimization_hook" not in overrides:
        slam["pre_optimization_hook"] = _HOOK_FACTORIES[name]()   # Q3b: a new hook object for every run
    return load_scenario(scenario_name), SimulatorConfiguration(**cfg), SLAMOptions(**slam)


def _check_effective(name, given, config, options, where="run_question") -> None:
    """ValueError for the first option of ``given`` changed from question ``name``'s own value that would have no
    effect on the run: one acting through a disabled sensor, or keep_first_prediction_edge while the prediction
    edges are kept (values are compared as validated)."""
    _, own_config, own_options = QUESTIONS[name]
    own = {"config": SimulatorConfiguration(**own_config), "options": SLAMOptions(**own_options)}
    changed = {}
    for key, value in given.items():
        part = "options" if key in _SLAM_OPTIONS else "config"
        if not np.array_equal(getattr(config if part == "config" else options, key), getattr(own[part], key)):
            changed[key] = f"{key}={value.tolist() if isinstance(value, np.ndarray) else value!r}"
    for flag, (sensor, names) in _SENSOR_OPTIONS.items():
        hit = [n for n in names if n in changed]
        if hit and not getattr(config, flag):
            raise ValueError(f"{where}: {changed[hit[0]]} has no effect: the run has no {sensor} ({flag}=False); "
                             f"pass {flag}=True to use it, or leave {hit[0]} as the question sets it")
    if "keep_first_prediction_edge" in changed and not options.remove_prediction_edges:
        raise ValueError(f"{where}: {changed['keep_first_prediction_edge']} has no effect while the prediction edges "
                         "are kept: it chooses which of them remove_prediction_edges=True removes; pass that too, "
                         "or leave keep_first_prediction_edge as the question sets it")


def run_question(name: str, seed: int | np.random.Generator = 0, progress: bool = False,
                 step_hook: Callable[[DriveBotSLAMSystem, int], object] | None = None, setup: object = None,
                 **overrides: object) -> Results:
    """Run a coursework question ("q1_b" … "q3_b") with its settings (``QUESTIONS``) and ``overrides``:
    SimulatorConfiguration fields (``enable_compass=True``, …) or SLAMOptions fields (``optimization_period``, …).

    ``seed`` seeds the one Generator behind every random draw; ``progress`` shows a tqdm bar;
    ``step_hook(system, k)`` is called after tick k has been processed (and optimised, if due). ``setup`` (None:
    the coursework) has ``system(config, options)``, which builds the SLAM system, and ``filter(events,
    simulator)``, which passes each tick's events to it (the advanced part hides the landmark ids with it).

    Bad settings raise ValueError before anything runs, and so does an option changed from the question's own value
    that would have no effect: one of a disabled sensor (``r_laser`` without the laser, …) or
    ``keep_first_prediction_edge`` without ``remove_prediction_edges=True``. An error during the run (e.g.
    ``GaugeFreedomError``) propagates unchanged.
    """
    scenario, config, options = question_setup(name, **overrides)
    _check_effective(name, overrides, config, options)
    function(step_hook, "step_hook", allow_none=True)
    if setup is not None and not all(callable(getattr(setup, m, None)) for m in ("system", "filter")):
        raise ValueError(f"setup must have the methods system(config, options) and filter(events, simulator), or be "
                         f"None; got {type(setup).__name__}")
    return _main_loop(config, scenario, seed, {"": options}, progress, name, step_hook, setup)[""]


def run_variants(name: str, variants: dict, seed: int = 0, progress: bool = False, **overrides: object) -> dict:
    """Run several SLAM-system variants of one question on **one** simulator pass: {variant: Results}.

    ``variants`` maps a name to that variant's SLAM options (e.g. ``{"full": {}, "keep first":
    {"remove_prediction_edges": True}}``); ``overrides`` apply to all. Every system receives the same events, so
    the results equal separate ``run_question`` calls with the same seed. A variant whose system raises a
    GraphError (e.g. a gauge failure) maps to that exception; the others carry on. ``run_time`` is the simulator's
    time plus that system's own.
    """
    if not isinstance(variants, dict) or not variants:
        raise ValueError("variants must be a non-empty dict {name: {SLAM option: value}}")
    options = {}
    for vname, opts in variants.items():
        if not isinstance(opts, dict) or any(k not in _SLAM_OPTIONS for k in opts):
            raise ValueError(f"variant {vname!r}: options must be a dict of SLAM options "
                             f"{list(_SLAM_OPTIONS)}, got {opts!r}")
        scenario, config, options[vname] = question_setup(name, **overrides, **opts)
        _check_effective(name, {**overrides, **opts}, config, options[vname], f"run_variants (variant {vname!r})")
    return _main_loop(config, scenario, seed, options, progress, name, catch=True)


def _main_loop(config, scenario, seed, options, progress, question, step_hook=None, setup=None, catch=False):
    """The loop of the module docstring for one simulator and one SLAM system per entry of ``options``
    {name: SLAMOptions}; with ``catch``, a system that raises a GraphError is left out from then on and its
    entry of the result is that error."""
    boolean(progress, "progress")
    if not config.enable_odometry:
        raise ValueError("enable_odometry must be True for a run: the SLAM system creates one vehicle vertex per "
                         "odometry tick (use DriveBotSimulator directly to study other event streams)")
    sim = DriveBotSimulator(config, scenario, seed=seed)
    build = DriveBotSLAMSystem if setup is None else setup.system
    systems = {n: build(config, opts) for n, opts in options.items()}
    rec = {n: {"times": [], "iters": [], "chi2_t": [], "chi2_h": [], "last": False, "wall": 0.0} for n in systems}
    failed, true_t, true_x = {}, [], []
    t_start = _time.perf_counter()

    def each_system(step, *args):
        for n, system in systems.items():
            if n in failed:
                continue
            t0 = _time.perf_counter()
            try:
                step(system, rec[n], *args)
            except GraphError as err:
                if not catch:
                    raise
                failed[n] = err
            rec[n]["wall"] += _time.perf_counter() - t0

    sim.start()
    total = None if math.isinf(config.maximum_step_number) else int(config.maximum_step_number)
    with tqdm(total=total, disable=not progress, desc=question, unit="step") as bar:
        while sim.keep_running():
            events = sim.events() if setup is None else setup.filter(sim.events(), sim)
            each_system(_tick, events, sim.time)
            true_t.append(sim.time)
            true_x.append(sim.ground_truth())
            if step_hook is not None:
                step_hook(systems[""], len(true_t) - 1)
            sim.step()
            bar.update(1)
    each_system(_finish, true_t[-1])
    shared = _time.perf_counter() - t_start - sum(r["wall"] for r in rec.values())
    return {n: failed[n] if n in failed else _results(systems[n], rec[n], true_t, true_x, question, config, scenario,
                                                      shared, sim, setup) for n in systems}


def _tick(system, rec, events, time):
    """One tick of one SLAM system: process the batch; optimise (timed) when recommended."""
    system.process_events(events)
    rec["last"] = system.recommend_optimization()
    if rec["last"]:
        chi2, seconds = timed(system.optimize)
        rec["times"].append(seconds)
        rec["iters"].append(system.graph.iterations)
        rec["chi2_t"].append(time)
        rec["chi2_h"].append(chi2)
    else:
        rec["times"].append(np.nan)
        rec["iters"].append(0)


def _finish(system, rec, last_time):
    """End of run: the final optimisation if the last tick did not optimise, then the smoothed histories."""
    if not rec["last"]:
        chi2, rec["times"][-1] = timed(system.optimize, 20)
        rec["iters"][-1] = system.graph.iterations
        rec["chi2_t"].append(last_time)
        rec["chi2_h"].append(chi2)
    rec["history"] = system.platform_estimate_history()


def _results(system, rec, true_t, true_x, question, config, scenario, shared, sim, setup) -> Results:
    T, X, P, in_graph = rec["history"]
    return Results(question=question, config=config, scenario=scenario,
                   optimization_times=np.array(rec["times"]), chi2_time=np.array(rec["chi2_t"]),
                   chi2_history=np.array(rec["chi2_h"]), vehicle_true_state_time=np.array(true_t),
                   vehicle_true_state_history=np.array(true_x).T, vehicle_state_time=T,
                   vehicle_state_history=X, vehicle_covariance_history=P, vehicle_in_graph=in_graph,
                   system=system, optimization_iterations=np.array(rec["iters"], dtype=np.int64),
                   run_time=shared + rec["wall"], dropped_laser_readings=sim.dropped_laser_readings, setup=setup)
