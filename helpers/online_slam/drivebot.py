"""``run_question_with_association``: a DriveBot question with the landmark ids hidden from the SLAM system.

    res = run_question_with_association("q2_b", data_association="jcbb", clutter_rate=2.0, seed=0)
    res.association_report()   # precision, recall, n_landmarks, n_true_landmarks, map error, …

The main loop is the coursework's (``helpers.drivebot.runner``: process a tick's events, optimise when
recommended, record; at the end ``optimize(20)`` if the last tick did not optimise, then the smoothed histories),
with two differences:

- between the simulator and the system, ``SensorCorruption`` drops detections (``detection_probability``), adds
  clutter (``clutter_rate`` per scan) and hides the ids; the truth of every delivered column is kept in
  ``scan_truth`` for the report;
- the system is an ``AssociatingSLAMSystem`` (front-end ``data_association`` = "nn", "mahalanobis", "ml" or
  "jcbb").

``data_association=None`` keeps the coursework: with no clutter and every detection kept the call *is*
``run_question`` (identical outputs); with ``detection_probability < 1`` the known-id system gets the thinned
scans. Clutter has no id, so it needs an association algorithm (ValueError otherwise).
"""
from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from ..drivebot.edges import LandmarkVertex
from ..drivebot.events import EventType
from ..drivebot.runner import Results, question_setup, run_question
from ..drivebot.simulator import make_rng
from ..drivebot.slam_system import DriveBotSLAMSystem
from ..timing import timed
from ..validation import integer
from .algorithms import check_algorithm
from .drivebot_system import (AssociatingSLAMSystem, ScanMarkingSimulator, SensorCorruption, check_clutter_rate,
                              check_probability)
from .metrics import association_scores, map_errors
from .tracks import DROPPED

__all__ = ["AssociationResults", "run_question_with_association", "ASSOCIATION_OPTIONS"]

#: Options of the associating system accepted by ``run_question_with_association``.
ASSOCIATION_OPTIONS = ("n_sigma", "algorithm_options", "rules", "association_period", "association_iterations",
                       "association_algorithm",
                       "range_margin", "association_space", "reject_ambiguous", "closure_sigma", "closure_support",
                       "closure_patience")

#: Seed-sequence key of the corruption's Generator (kept apart from the simulator's draws).
_CORRUPTION_STREAM = 15


@dataclass
class AssociationResults(Results):
    """``Results`` plus what association needs: ``data_association`` (None: ids given), ``clutter_rate``,
    ``detection_probability``, ``scan_truth`` (per processed scan, the true landmark id of each delivered column,
    0 for clutter)."""

    data_association: str | None = None
    clutter_rate: float = 0.0
    detection_probability: float = 1.0
    scan_truth: list = field(default_factory=list)

    def association_report(self) -> dict:
        """precision, recall (pairings vs the simulator's truth, see ``metrics``), n_landmarks (created),
        n_true_landmarks (observed at least once), n_matched, map_rmse / map_max_error (m, matched landmarks),
        n_clutter, n_clutter_paired, n_tentative_dropped, association_time (s), jcbb_nodes, final_chi2."""
        system = self.system
        frontend = getattr(system, "frontend", None)
        if frontend is None:               # ids given: every delivered detection is an edge to its landmark
            truth = np.array([e.vertex(1).landmark_id for e in system.graph.edges()
                              if isinstance(e.vertex(1), LandmarkVertex)], dtype=np.int64)
            assigned = truth.copy()
            found = {lid: v.estimate for lid, v in system.landmark_vertices.items()}
        else:
            truth = np.concatenate(self.scan_truth) if self.scan_truth else np.zeros(0, dtype=np.int64)
            assigned = frontend.observation_assignment()
            found = {t.key: t.vertex.estimate for t in frontend.confirmed_tracks()}
        if assigned.size != truth.size:
            raise ValueError(f"the run logged {assigned.size} observations but {truth.size} truths")
        scores = association_scores(assigned, truth)
        sc = self.scenario
        true_pos = {int(i): sc.landmarks[:, k] for k, i in enumerate(sc.landmark_ids)}
        errors = map_errors(scores["matching"], found, true_pos)
        report = {k: v for k, v in scores.items() if k != "matching"}
        report.update({
            "data_association": self.data_association,
            "clutter_rate": self.clutter_rate,
            "detection_probability": self.detection_probability,
            "map_rmse": float(np.sqrt(np.mean(errors ** 2))) if errors.size else float("nan"),
            "map_max_error": float(errors.max()) if errors.size else float("nan"),
            "final_chi2": self.final_chi2,
            "run_time": self.run_time,
        })
        if frontend is not None:
            report.update({
                "n_tentative_dropped": sum(t.status == DROPPED for t in frontend.tracks),
                "association_time": frontend.stats["association_time"],
                "refresh_time": frontend.stats["refresh_time"],
                "jcbb_nodes": frontend.stats["nodes"],
                "budget_exhausted": frontend.stats["budget_exhausted"],
            })
        report["matching"] = scores["matching"]
        return report


def _check_arguments(data_association, clutter_rate, detection_probability, seed):
    if data_association is not None:
        check_algorithm(data_association, "data_association")
    clutter_rate = check_clutter_rate(clutter_rate)
    detection_probability = check_probability(detection_probability, "detection_probability")
    if data_association is None and clutter_rate > 0:
        raise ValueError("clutter_rate > 0 needs a data_association algorithm: a spurious detection has no id")
    return clutter_rate, detection_probability, integer(seed, "seed", minimum=0)


def run_question_with_association(name: str, data_association: str | None = "jcbb", clutter_rate: float = 0.0,
                                  detection_probability: float = 1.0, seed: int = 0, progress: bool = False,
                                  **options) -> AssociationResults:
    """Run question ``name`` with the ids hidden and ``data_association`` (module docstring).

    ``options``: the associating system's options (``ASSOCIATION_OPTIONS``: n_sigma, algorithm_options, rules,
    association_period, association_iterations, association_algorithm, range_margin, association_space,
    reject_ambiguous, closure_sigma, closure_support, closure_patience; see ``AssociatingSLAMSystem`` and
    ``OnlineFrontEnd``) and everything ``run_question`` accepts (SimulatorConfiguration fields, SLAM options).
    """
    clutter_rate, detection_probability, seed = _check_arguments(data_association, clutter_rate,
                                                                 detection_probability, seed)
    assoc = {k: options.pop(k) for k in list(options) if k in ASSOCIATION_OPTIONS}
    if data_association is None and assoc:
        raise ValueError(f"{sorted(assoc)} are options of the association; data_association is None")
    if data_association is None and detection_probability == 1.0:
        res = run_question(name, seed=seed, progress=progress, **options)
        out = AssociationResults(**{f.name: getattr(res, f.name) for f in dataclasses.fields(Results)})
        return out
    scenario, config, slam = question_setup(name, **options)
    if data_association is None:
        system = DriveBotSLAMSystem(config, **slam)
    else:
        system = AssociatingSLAMSystem(config, data_association, **assoc, **slam)
    corruption = SensorCorruption(clutter_rate, detection_probability, config.laser_detection_range,
                                  config.r_laser, np.random.default_rng([seed, _CORRUPTION_STREAM]))
    res = _run(system, config, scenario, make_rng(seed), corruption, data_association is not None, progress, name)
    res.data_association, res.clutter_rate, res.detection_probability = (data_association, clutter_rate,
                                                                          detection_probability)
    return res


def _deliver(events, sim, corruption, hide_ids, truth_log):
    """The tick's events with the LANDMARK event corrupted (or added: clutter on a scan that saw nothing)."""
    if not getattr(sim, "laser_fired", False):
        return events
    pos = next((i for i, e in enumerate(events) if e.type is EventType.LANDMARK), None)
    original = None if pos is None else events[pos]
    new, truth = corruption.scan(sim.time, original, hide_ids=hide_ids)
    out = [e for e in events if e.type is not EventType.LANDMARK]
    if new is None:
        return out
    if pos is None:
        pos = next((i for i, e in enumerate(out) if e.type is EventType.GPS), len(out))
    out.insert(pos, new)
    truth_log.append(truth)
    return out


def _run(system, config, scenario, rng, corruption, hide_ids, progress, question):
    """The coursework main loop (module docstring) with the corruption between simulator and system."""
    sim = ScanMarkingSimulator(config, scenario, seed=rng)
    rec = {"times": [], "iters": [], "chi2_t": [], "chi2_h": []}
    truth_log, true_t, true_x = [], [], []
    last = False
    t0 = _time.perf_counter()
    sim.start()
    total = None if np.isinf(config.maximum_step_number) else int(config.maximum_step_number)
    with tqdm(total=total, disable=not progress, desc=question, unit="step") as bar:
        while sim.keep_running():
            system.process_events(_deliver(sim.events(), sim, corruption, hide_ids, truth_log))
            last = system.recommend_optimization()
            if last:
                chi2, seconds = timed(system.optimize)
                rec["times"].append(seconds)
                rec["iters"].append(system.graph.iterations)
                rec["chi2_t"].append(sim.time)
                rec["chi2_h"].append(chi2)
            else:
                rec["times"].append(np.nan)
                rec["iters"].append(0)
            true_t.append(sim.time)
            true_x.append(sim.ground_truth())
            sim.step()
            bar.update(1)
    if not last:
        chi2, rec["times"][-1] = timed(system.optimize, 20)
        rec["iters"][-1] = system.graph.iterations
        rec["chi2_t"].append(true_t[-1])
        rec["chi2_h"].append(chi2)
    T, X, P, in_graph = system.platform_estimate_history()
    res = AssociationResults(
        question=question, config=config, scenario=scenario, optimization_times=np.array(rec["times"]),
        chi2_time=np.array(rec["chi2_t"]), chi2_history=np.array(rec["chi2_h"]),
        vehicle_true_state_time=np.array(true_t), vehicle_true_state_history=np.array(true_x).T,
        vehicle_state_time=T, vehicle_state_history=X, vehicle_covariance_history=P, vehicle_in_graph=in_graph,
        system=system, optimization_iterations=np.array(rec["iters"], dtype=np.int64),
        run_time=_time.perf_counter() - t0, scan_truth=truth_log)
    return res
