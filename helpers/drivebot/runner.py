"""Running a question: the coursework's main loop and one entry point, ``run_question``.

Main loop, per simulator tick k (store index k, N ticks in all):

1. the SLAM system processes the tick's events (one new vehicle vertex);
2. if it recommends an optimisation, time ``optimize()`` (50 LM iterations at most) and record the time at
   index k, the tick time in ``chi2_time`` and χ² in ``chi2_history``; otherwise the time is NaN;
3. record the true state and its time; then the simulator steps.

The events of the final step (the one in which the controller stops) are never processed. At the end, if
the last tick did not optimise, ``optimize(20)`` runs and is recorded at the last index. The vehicle
histories are then the smoothed estimates from one marginal computation on the final graph.

Per-question settings (from the coursework launcher scripts; every one can be overridden by keyword):

| question | scenario  | sensors / options                                                   | period |  N   |
|----------|-----------|---------------------------------------------------------------------|--------|------|
| q1_b     | q1_b      | odometry only                                                       | None   |  654 |
| q1_c     | q1_c      | compass, offset 0.75π, compass_edge="buggy"                         | 20     |  654 |
| q1_d     | q1_d      | GPS                                                                 | None   | 5273 |
| q1_e     | q1_e      | GPS (enable_compass=True for part ii)                               | 1      |  324 |
| q2_b     | q2_b      | laser                                                               | 5      | 1313 |
| q2_c     | q2_c      | laser                                                               | None   | 5273 |
| q2_d     | q2_d      | laser, perturb_with_noise=False, maximum_step_number=2000           | None   | 1313 |
| q2_e     | large_map | laser                                                               | None   | 5667 |
| q3_a     | q3_a      | laser range 30, remove_prediction_edges=False, keep_first=True      | 500    | 5273 |
| q3_b     | q3_a      | as q3_a (prediction edges kept) + pruning.q3b_hook() before every   | 500    | 5273 |
|          |           | optimisation (keyframes on straights, stride 5)                     |        |      |

q3_b is the coursework's student-written script for Q3b(ii): the q3_a scenario and settings, with the graph
pruned before every optimisation by a *fresh* ``pruning.q3b_hook()`` per run (hooks count their calls and
edges removed). Pass ``pre_optimization_hook=`` to run another heuristic with the same settings.

A run that fails part-way keeps what it has: the exception propagates unchanged (type and message), with
``tick``, ``phase`` and the partial ``results`` attached (see ``run_question``).
"""
from __future__ import annotations

import inspect
import math
import time as _time

import numpy as np
from tqdm import tqdm

from ..graph import GraphError
from ..timing import timed
from ..validation import boolean, function, same_setting
from . import pruning
from .config import SimulatorConfiguration
from .options import check_effective
from .results import Results
from .scenarios import Scenario, load_scenario
from .simulator import DriveBotSimulator, make_rng
from .slam_system import DriveBotSLAMSystem

__all__ = ["Results", "run", "run_question", "run_variants", "QUESTIONS", "SLAM_OPTIONS", "question_setup",
           "RunError"]

#: SLAM-system options accepted by run / run_question (everything else must be a SimulatorConfiguration field).
SLAM_OPTIONS = ("optimization_period", "compass_edge", "remove_prediction_edges", "keep_first_prediction_edge",
                "pre_optimization_hook", "optimization_algorithm")

QUESTIONS = {
    "q1_b": ("q1_b", {}, {"optimization_period": None}),
    "q1_c": ("q1_c", {"enable_compass": True, "compass_angular_offset": 0.75 * math.pi},
             {"optimization_period": 20, "compass_edge": "buggy"}),
    "q1_d": ("q1_d", {"enable_gps": True}, {"optimization_period": None}),
    "q1_e": ("q1_e", {"enable_gps": True}, {"optimization_period": 1}),
    "q2_b": ("q2_b", {"enable_laser": True}, {"optimization_period": 5}),
    "q2_c": ("q2_c", {"enable_laser": True}, {"optimization_period": None}),
    "q2_d": ("q2_d", {"enable_laser": True, "perturb_with_noise": False, "maximum_step_number": 2000},
             {"optimization_period": None}),
    "q2_e": ("large_map", {"enable_laser": True}, {"optimization_period": None}),
    "q3_a": ("q3_a", {"enable_laser": True, "laser_detection_range": 30.0},
             {"optimization_period": 500, "remove_prediction_edges": False, "keep_first_prediction_edge": True}),
    # Q3b: the q3_b script — q3_a's scenario and sensors, prediction edges kept, observations pruned before
    # every optimisation by a fresh pruning.q3b_hook() (see _HOOK_FACTORIES).
    "q3_b": ("q3_a", {"enable_laser": True, "laser_detection_range": 30.0},
             {"optimization_period": 500, "remove_prediction_edges": False}),
}

#: Q3b: questions whose runs get a fresh pre-optimisation hook (unless one is passed as an override).
_HOOK_FACTORIES = {"q3_b": pruning.q3b_hook}


class RunError(RuntimeError):
    """A run failed part-way with an exception that cannot carry attributes (rare: the runner normally re-raises
    the original exception with ``tick``, ``phase`` and ``results`` attached). Raised ``from`` that exception;
    ``tick``, ``phase`` and ``results`` as described in ``run_question``."""

    def __init__(self, message, results=None, tick=None, phase=""):
        super().__init__(message)
        self.results, self.tick, self.phase = results, tick, phase


def question_setup(name: str, **overrides):
    """(scenario, SimulatorConfiguration, slam options) for a question with overrides applied."""
    if not isinstance(name, str) or name not in QUESTIONS:
        raise ValueError(f"unknown question {name!r}; known questions: {sorted(QUESTIONS)}")
    scenario_name, cfg, slam = QUESTIONS[name]
    cfg, slam = dict(cfg), dict(slam)
    fields = SimulatorConfiguration.field_names()
    for key, value in overrides.items():
        if key in SLAM_OPTIONS:
            slam[key] = value
        elif key in fields:
            cfg[key] = value
        else:
            raise ValueError(f"unknown override {key!r} for run_question; SLAM options: {list(SLAM_OPTIONS)}; "
                             f"SimulatorConfiguration fields: {list(fields)}")
    if name in _HOOK_FACTORIES and "pre_optimization_hook" not in overrides:
        slam["pre_optimization_hook"] = _HOOK_FACTORIES[name]()   # Q3b: a new hook object for every run
    return load_scenario(scenario_name), SimulatorConfiguration(**cfg), slam


def run_question(name: str, seed=0, progress: bool = False, step_hook=None, setup=None, **overrides) -> Results:
    """Run a coursework question ("q1_b" … "q3_b") with its settings (module table) and ``overrides``.

    ``setup`` (None: the coursework) changes what the loop drives: an object with ``system(config,
    **slam_options)``, which builds the SLAM system, and ``filter(events, simulator)``, which passes each tick's
    events to it (the advanced part's runs with the landmark ids hidden use this).

    Overrides are SimulatorConfiguration fields (``enable_compass=True``, ``perturb_with_noise=False``, …)
    or SLAM options (``optimization_period``, ``compass_edge``, ``remove_prediction_edges``,
    ``keep_first_prediction_edge``, ``pre_optimization_hook``, ``optimization_algorithm``). ``seed`` seeds the
    one Generator behind every random draw; ``progress`` shows a tqdm bar (off by default). ``step_hook(system, k)``,
    if given, is called after tick k has been processed (and optimised, if due) — e.g. to snapshot estimates just before
    and after a loop closure.

    Bad settings raise ValueError before anything runs (see ``SimulatorConfiguration`` for the bounds; the run
    also needs ``enable_odometry=True``, one vehicle vertex per tick, and ``remove_prediction_edges`` needs an
    observation sensor; ``algorithm_options`` are checked against the algorithm). So does an option changed from
    the question's own value that would have no effect (``options.check_effective``): one of a disabled sensor —
    ``compass_edge`` or ``compass_angular_offset`` without the compass, ``r_laser`` without the laser, … — or
    ``keep_first_prediction_edge`` without
    ``remove_prediction_edges=True``.

    **Failures part-way keep what the run has**: an exception raised by the simulator, the SLAM system or its
    optimiser (e.g. ``GaugeFreedomError``), a user hook (``step_hook``, ``pre_optimization_hook``) or a
    ``KeyboardInterrupt`` propagates *unchanged* — same type and message, so ``except GaugeFreedomError`` keeps
    working — with attributes attached:

    - ``err.tick``: the store index k of the tick being processed (the simulator step after tick k for a failing
      ``step()``; N − 1 for the final optimisation or the covariances at the end);
    - ``err.phase``: "events", "optimisation" (including the pre-optimisation hook), "step_hook",
      "simulator step", "final optimisation" or "covariances";
    - ``err.results``: a partial ``Results`` of ticks 0 … tick (the graph as it was when the error occurred; the
      covariance history is NaN when no covariance can be computed from it).

    A note in the traceback says the same. (An exception object that refuses attributes is wrapped in a
    ``RunError`` raised from it, with the same three attributes.)
    """
    scenario, config, slam = question_setup(name, **overrides)
    check_effective(_changed_options(name, overrides, config), config, slam)
    return run(config, scenario, seed=seed, progress=progress, question=name, step_hook=step_hook, setup=setup,
               **slam)


def _defaults(function_) -> dict:
    return {k: p.default for k, p in inspect.signature(function_).parameters.items() if p.default is not p.empty}


def _changed_options(name, given, config) -> dict:
    """The options of ``given`` whose value differs from question ``name``'s own: its settings (``QUESTIONS``),
    else the defaults of ``SimulatorConfiguration``, ``DriveBotSLAMSystem`` and ``run_question``. Configuration
    fields are compared as validated (``config`` against the question's own configuration)."""
    _, question_config, question_slam = QUESTIONS[name]
    own = SimulatorConfiguration(**question_config)
    defaults = {**_defaults(DriveBotSLAMSystem.__init__), **question_slam, **_defaults(run_question)}
    changed = {}
    for key, value in given.items():
        if key in own.field_names():
            same = np.array_equal(getattr(config, key), getattr(own, key))
        else:
            same = key in defaults and same_setting(value, defaults[key])
        if not same:
            changed[key] = value
    return changed


def run(config: SimulatorConfiguration, scenario: Scenario, seed=0, progress: bool = False, question: str = "",
        step_hook=None, setup=None, **slam_options) -> Results:
    """The main loop (module docstring) for any configuration and scenario (``step_hook``, ``setup`` and failures
    part-way: see run_question)."""
    function(step_hook, "step_hook", allow_none=True)
    if setup is not None and not (callable(getattr(setup, "system", None))
                                  and callable(getattr(setup, "filter", None))):
        raise ValueError(f"setup must have the methods system(config, **slam_options) and filter(events, "
                         f"simulator), or be None; got {type(setup).__name__}")
    _check_slam_options(slam_options, "run")
    return _main_loop(config, scenario, seed, {"": slam_options}, progress, question, step_hook, catch=False,
                      setup=setup)[""]


def _check_slam_options(options, where):
    unknown = [k for k in options if k not in SLAM_OPTIONS]
    if unknown:
        raise ValueError(f"{where}: unknown SLAM option(s) {unknown}; SLAM options: {list(SLAM_OPTIONS)}")


def run_variants(name: str, variants: dict, seed=0, progress: bool = False, **overrides) -> dict:
    """Run several SLAM-system variants of one question on **one** simulator pass: {variant: Results}.

    ``variants`` maps a name to that variant's SLAM options (e.g. ``{"full": {}, "keep first":
    {"remove_prediction_edges": True}}``); ``overrides`` (configuration fields or SLAM options) apply to all.
    Every system receives the same event batches, as in the coursework's main loop (which can drive several
    SLAM systems), so the results equal separate ``run_question`` calls with the same seed while the
    simulation runs once. A variant whose system raises a GraphError (e.g. a gauge failure) maps to that
    exception instead of a Results (with ``tick``, ``phase`` and its partial ``results`` attached, as in
    ``run_question``); the others carry on. Any other exception (a failing hook, the simulator, a
    KeyboardInterrupt) stops the pass and propagates with ``tick`` and ``phase`` and, as ``results``, the dict
    {variant: partial Results, or that variant's GraphError}. ``run_time`` of each Results is the simulator's
    time plus that system's own. As in ``run_question``, an option that would have no effect in a variant raises
    ValueError before anything runs (``options.check_effective``).
    """
    if not isinstance(variants, dict) or not variants:
        raise ValueError("variants must be a non-empty dict {name: {SLAM option: value}}")
    slams = {}
    for vname, opts in variants.items():
        if not isinstance(vname, str) or not vname:
            raise ValueError(f"variants: every variant name must be a non-empty string, got {vname!r}")
        if not isinstance(opts, dict) or any(k not in SLAM_OPTIONS for k in opts):
            raise ValueError(f"variant {vname!r}: options must be a dict of SLAM options {list(SLAM_OPTIONS)}, "
                             f"got {opts!r}")
        scenario, config, slams[vname] = question_setup(name, **overrides, **opts)
        check_effective(_changed_options(name, {**overrides, **opts}, config), config, slams[vname],
                        where=f"run_variants (variant {vname!r})")
    return _main_loop(config, scenario, seed, slams, progress, name, None, catch=True)


def _main_loop(config, scenario, seed, slams, progress, question, step_hook, catch, setup=None):
    """The loop of the module docstring for one simulator and the SLAM systems ``slams`` {name: options}
    (``setup``: builds the systems and filters the events they receive; see run_question)."""
    boolean(progress, "progress")
    if not isinstance(question, str):
        raise ValueError(f"question must be a string (the label of the run), got {question!r}")
    rng = make_rng(seed)
    sim = DriveBotSimulator(config, scenario, seed=rng)
    if not config.enable_odometry:
        raise ValueError("enable_odometry must be True for a run: the SLAM system creates one vehicle vertex per "
                         "odometry tick (use DriveBotSimulator directly to study other event streams)")
    factory = DriveBotSLAMSystem if setup is None else setup.system
    systems = {n: factory(config, **opts) for n, opts in slams.items()}
    state = _Run(sim, systems, question, config, scenario)
    state.setup = setup
    try:
        _loop(state, progress, step_hook, catch)
        return _finish_all(state, catch)
    except BaseException as err:
        results = _partial(state, "") if not catch else \
            {n: state.failed[n] if n in state.failed else _partial(state, n) for n in systems}
        wrapped = _attach(err, results, state.tick, state.phase, question)
        if wrapped is err:
            raise
        raise wrapped from err


class _Run:
    """The state of one pass of the main loop (what a partial result is built from)."""

    def __init__(self, sim, systems, question, config, scenario):
        self.sim, self.systems, self.question, self.config, self.scenario = sim, systems, question, config, scenario
        self.rec = {n: {"times": [], "iters": [], "chi2_t": [], "chi2_h": [], "last": False, "wall": 0.0}
                    for n in systems}
        self.failed = {}
        self.true_t, self.true_x = [], []
        self.t_start = _time.perf_counter()
        self.tick, self.phase = 0, "start"
        self.setup = None


def _loop(state, progress, step_hook, catch):
    """Ticks until the simulator stops (module docstring, steps 1–3)."""
    sim, systems, rec = state.sim, state.systems, state.rec
    sim.start()
    total = None if math.isinf(state.config.maximum_step_number) else int(state.config.maximum_step_number)
    with tqdm(total=total, disable=not progress, desc=state.question or "drivebot", unit="step") as bar:
        while sim.keep_running():
            state.tick = len(state.true_t)
            events = sim.events()
            if state.setup is not None:
                events = state.setup.filter(events, sim)
            for n, system in systems.items():
                if n in state.failed:
                    continue
                t_sys = _time.perf_counter()
                try:
                    _tick(system, events, rec[n], sim.time, state)
                except GraphError as err:
                    if not catch:
                        raise
                    state.failed[n] = _attach(err, _partial(state, n), state.tick, state.phase, state.question)
                rec[n]["wall"] += _time.perf_counter() - t_sys
            state.true_t.append(sim.time)
            state.true_x.append(sim.ground_truth())
            if step_hook is not None:
                state.phase = "step_hook"
                step_hook(systems[""], state.tick)
            state.phase = "simulator step"
            sim.step()
            bar.update(1)


def _finish_all(state, catch):
    """The end of the run for every system that has not failed: final optimisation and histories."""
    rec = state.rec
    shared = _time.perf_counter() - state.t_start - sum(r["wall"] for r in rec.values())
    out = dict(state.failed)
    for n, system in state.systems.items():
        if n in state.failed:
            continue
        t_sys = _time.perf_counter()
        try:
            out[n] = _finish(system, rec[n], state.true_t, state.true_x, state.question, state.config,
                             state.scenario, state)
        except GraphError as err:
            if not catch:
                raise
            out[n] = _attach(err, _partial(state, n), state.tick, state.phase, state.question)
            continue
        out[n].run_time = shared + rec[n]["wall"] + _time.perf_counter() - t_sys
        out[n].dropped_laser_readings = state.sim.dropped_laser_readings
        out[n].setup = state.setup
    return {n: out[n] for n in state.systems}


def _tick(system, events, rec, time, state):
    """One tick of one SLAM system: process the batch; optimise (timed) when recommended."""
    state.phase = "events"
    system.process_events(events)
    rec["last"] = system.recommend_optimization()
    if rec["last"]:
        state.phase = "optimisation"
        chi2, seconds = timed(system.optimize)
        rec["times"].append(seconds)
        rec["iters"].append(system.graph.iterations)
        rec["chi2_t"].append(time)
        rec["chi2_h"].append(chi2)
    else:
        rec["times"].append(np.nan)
        rec["iters"].append(0)


def _finish(system, rec, true_t, true_x, question, config, scenario, state) -> Results:
    """End of run: the final optimisation if the last tick did not optimise, then the smoothed histories."""
    if not rec["last"]:
        state.phase = "final optimisation"
        chi2, rec["times"][-1] = timed(system.optimize, 20)
        rec["iters"][-1] = system.graph.iterations
        rec["chi2_t"].append(true_t[-1])
        rec["chi2_h"].append(chi2)
    state.phase = "covariances"
    T, X, P, in_graph = system.platform_estimate_history()
    return _results(system, rec, true_t, true_x, question, config, scenario, (T, X, P, in_graph))


def _results(system, rec, true_t, true_x, question, config, scenario, history) -> Results:
    T, X, P, in_graph = history
    return Results(question=question, config=config, scenario=scenario,
                   optimization_times=np.array(rec["times"]), chi2_time=np.array(rec["chi2_t"]),
                   chi2_history=np.array(rec["chi2_h"]), vehicle_true_state_time=np.array(true_t),
                   vehicle_true_state_history=np.array(true_x).T, vehicle_state_time=T,
                   vehicle_state_history=X, vehicle_covariance_history=P, vehicle_in_graph=in_graph,
                   system=system, optimization_iterations=np.array(rec["iters"], dtype=np.int64))


# ----------------------------------------------------------------------------------------------------
# failures part-way: partial results
# ----------------------------------------------------------------------------------------------------
def _partial(state, name):
    """The Results of system ``name`` as far as the run got (ticks 0 … state.tick); None if even that fails."""
    try:
        system, rec = state.systems[name], dict(state.rec[name])
        true_t, true_x = list(state.true_t), list(state.true_x)
        if len(true_t) == state.tick and state.phase in ("events", "optimisation"):   # the tick being processed
            true_t.append(state.sim.time)
            true_x.append(state.sim.ground_truth())
        n = min(len(true_t), len(system.vehicle_vertices))
        rec["times"] = (list(rec["times"]) + [np.nan] * n)[:n]
        rec["iters"] = (list(rec["iters"]) + [0] * n)[:n]
        system._built = False     # a failing hook may have edited the graph after the last structure build
        try:
            history = system.platform_estimate_history()
        except Exception:         # noqa: BLE001 - no covariance from this graph: estimates only
            history = _estimates_only(system)
        res = _results(system, rec, true_t[:n], true_x[:n] or np.zeros((0, 3)), state.question, state.config,
                       state.scenario, history)
        res.run_time = _time.perf_counter() - state.t_start
        res.setup = state.setup
        return res
    except Exception:             # noqa: BLE001 - the original error matters more than its partial results
        return None


def _estimates_only(system):
    """(T, X, P, in_graph) like platform_estimate_history, with NaN covariances."""
    vv = system.vehicle_vertices
    in_graph = np.array([v.graph is system.graph for v in vv], dtype=bool)
    X = np.full((3, len(vv)), np.nan)
    X[:, in_graph] = np.array([v.estimate for v, g in zip(vv, in_graph) if g], dtype=float).reshape(-1, 3).T
    return np.array([v.time for v in vv], dtype=float), X, np.full((3, len(vv)), np.nan), in_graph


def _attach(err, results, tick, phase, question):
    """``err`` with ``results``, ``tick`` and ``phase`` attached and a note added; a RunError from it when the
    exception object refuses attributes."""
    where = f"{question or 'run'}: {type(err).__name__} at tick {tick} ({phase})"
    try:
        err.results, err.tick, err.phase = results, tick, phase
    except (AttributeError, TypeError):
        return RunError(f"{where}: {err}", results, tick, phase)
    err.add_note(f"{where}; the partial results of ticks 0 … {tick} are in err.results")
    return err
