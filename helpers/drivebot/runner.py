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
"""
from __future__ import annotations

import math
import time as _time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from .config import SimulatorConfiguration
from .scenarios import Scenario, load_scenario
from .simulator import DriveBotSimulator, make_rng
from .slam_system import DriveBotSLAMSystem

__all__ = ["Results", "run", "run_question", "QUESTIONS", "SLAM_OPTIONS", "question_setup"]

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
}


@dataclass
class Results:
    """What a run produced (N = number of processed ticks = number of vehicle vertices).

    optimization_times (N,)          wall time of each optimisation at its tick, NaN where none ran
    optimization_iterations (N,)     LM iterations of that optimisation (0 where none ran)
    chi2_time, chi2_history (K,)     tick time and χ² after each optimisation (including the final one)
    vehicle_true_state_time (N,), vehicle_true_state_history (3×N)
    vehicle_state_time (N,), vehicle_state_history (3×N)      smoothed estimates from the final graph
    vehicle_covariance_history (3×N) covariance diagonals (0 for the fixed first vertex)
    vehicle_in_graph (N,) bool       False for vertices deleted from the graph (Q3a/Q3b); their state and
                                     covariance columns are NaN so that plots show gaps, not spikes
    system                           the final DriveBotSLAMSystem (``system.graph`` is the optimiser)
    """

    question: str
    config: SimulatorConfiguration
    scenario: Scenario
    optimization_times: np.ndarray
    chi2_time: np.ndarray
    chi2_history: np.ndarray
    vehicle_true_state_time: np.ndarray
    vehicle_true_state_history: np.ndarray
    vehicle_state_time: np.ndarray
    vehicle_state_history: np.ndarray
    vehicle_covariance_history: np.ndarray
    vehicle_in_graph: np.ndarray
    system: DriveBotSLAMSystem
    optimization_iterations: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    run_time: float = field(default=float("nan"))

    @property
    def n_steps(self) -> int:
        """N, the number of processed ticks (= vehicle vertices created)."""
        return int(self.vehicle_state_time.size)

    @property
    def final_chi2(self) -> float:
        return float(self.chi2_history[-1])

    def state_error(self) -> np.ndarray:
        """Estimate − truth (3×N), heading wrapped into [−π, π)."""
        err = self.vehicle_state_history - self.vehicle_true_state_history
        err[2] = (err[2] + np.pi) % (2 * np.pi) - np.pi
        return err

    def graph_statistics(self) -> dict:
        """Counts by vertex and edge type and the χ² degrees of freedom (see DriveBotSLAMSystem)."""
        return self.system.graph_statistics()

    def landmark_estimates(self):
        """(x 2×L, P 2×2×L, ids) from the final graph."""
        return self.system.landmark_estimates()

    def chi2_bounds(self, k: float = 4.0) -> tuple[float, float]:
        """dof ± k·√(2·dof) with dof = measurement dimensions − free state dimensions."""
        dof = self.graph_statistics()["dof"]
        half = k * math.sqrt(2.0 * max(dof, 0))
        return dof - half, dof + half


def question_setup(name: str, **overrides):
    """(scenario, SimulatorConfiguration, slam options) for a question with overrides applied."""
    if name not in QUESTIONS:
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
    return load_scenario(scenario_name), SimulatorConfiguration(**cfg), slam


def run_question(name: str, seed=0, progress: bool = False, step_hook=None, **overrides) -> Results:
    """Run a coursework question ("q1_b" … "q3_a") with its settings (module table) and ``overrides``.

    Overrides are SimulatorConfiguration fields (``enable_compass=True``, ``perturb_with_noise=False``, …)
    or SLAM options (``optimization_period``, ``compass_edge``, ``remove_prediction_edges``,
    ``keep_first_prediction_edge``, ``pre_optimization_hook``, ``optimization_algorithm``). ``seed`` seeds the
    one Generator behind every random draw; ``progress`` shows a tqdm bar (off by default). ``step_hook(system, k)``, if given, is
    called after tick k has been processed (and optimised, if due) — e.g. to snapshot estimates just before
    and after a loop closure.
    """
    scenario, config, slam = question_setup(name, **overrides)
    return run(config, scenario, seed=seed, progress=progress, question=name, step_hook=step_hook, **slam)


def run(config: SimulatorConfiguration, scenario: Scenario, seed=0, progress: bool = False, question: str = "",
        step_hook=None, **slam_options) -> Results:
    """The main loop (module docstring) for any configuration and scenario (``step_hook``: see run_question)."""
    if step_hook is not None and not callable(step_hook):
        raise ValueError(f"step_hook must be callable(system, k) or None, got {step_hook!r}")
    rng = make_rng(seed)
    sim = DriveBotSimulator(config, scenario, seed=rng)
    system = DriveBotSLAMSystem(config, **slam_options)
    t_start = _time.perf_counter()
    opt_times, opt_iters, true_t, true_x = [], [], [], []
    chi2_t, chi2_h = [], []
    sim.start()
    total = None if math.isinf(config.maximum_step_number) else int(config.maximum_step_number)
    last_optimised = False
    with tqdm(total=total, disable=not progress, desc=question or "drivebot", unit="step") as bar:
        while sim.keep_running():
            system.process_events(sim.events())
            last_optimised = system.recommend_optimization()
            if last_optimised:
                t0 = _time.perf_counter()
                chi2 = system.optimize()
                opt_times.append(_time.perf_counter() - t0)
                opt_iters.append(system.graph.iterations)
                chi2_t.append(sim.time)
                chi2_h.append(chi2)
            else:
                opt_times.append(np.nan)
                opt_iters.append(0)
            true_t.append(sim.time)
            true_x.append(sim.ground_truth())
            if step_hook is not None:
                step_hook(system, len(true_t) - 1)
            sim.step()
            bar.update(1)
    if not last_optimised:
        t0 = _time.perf_counter()
        chi2 = system.optimize(20)
        opt_times[-1] = _time.perf_counter() - t0
        opt_iters[-1] = system.graph.iterations
        chi2_t.append(true_t[-1])
        chi2_h.append(chi2)
    T, X, P, in_graph = system.platform_estimate_history()
    return Results(question=question, config=config, scenario=scenario,
                   optimization_times=np.array(opt_times), chi2_time=np.array(chi2_t),
                   chi2_history=np.array(chi2_h), vehicle_true_state_time=np.array(true_t),
                   vehicle_true_state_history=np.array(true_x).T, vehicle_state_time=T,
                   vehicle_state_history=X, vehicle_covariance_history=P, vehicle_in_graph=in_graph,
                   system=system, optimization_iterations=np.array(opt_iters, dtype=np.int64), run_time=_time.perf_counter() - t_start)
