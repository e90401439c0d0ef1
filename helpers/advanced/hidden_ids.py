"""DriveBot with the landmark ids hidden: the SLAM system that associates, the harder sensor, and the report.

    res = run_hidden_ids("q2_b", data_association="jcbb", clutter_rate=2.0, seed=0)
    association_report(res)   # precision, recall, n_landmarks, n_true_landmarks, map error, …

``run_hidden_ids`` runs the coursework's main loop (``drivebot.run_question``) unchanged; with ``data_association``,
a ``clutter_rate`` or a ``detection_probability`` it hands the loop a ``HiddenIds`` set-up, which changes two things:

- between the simulator and the system, ``SensorCorruption`` drops detections (``detection_probability``), adds
  clutter (``clutter_rate`` per scan) and hides the ids; the truth of every delivered column is kept in
  ``scan_truth`` for the report, outside the system;
- the system is an ``AssociatingSLAMSystem`` (front-end ``helpers.advanced.online_slam.OnlineFrontEnd`` with the L09
  algorithm ``data_association`` = "nn", "mahalanobis", "ml" or "jcbb").

``data_association=None`` keeps the coursework (ids given): with no clutter and every detection kept, nothing of
this module is used and the outputs are the coursework's; with ``detection_probability < 1`` the known-id system
gets the thinned scans. Clutter has no id, so it needs an association algorithm (ValueError otherwise).

``AssociatingSLAMSystem`` is ``DriveBotSLAMSystem`` with one duty changed: a LANDMARK event's columns are handed to
the front-end as anonymous observations (its ``landmark_ids`` are never read), and the front-end decides which
landmark vertex each one is an edge to. Everything else — one vehicle vertex per tick, the kinematics, compass and
GPS edges, the optimisation schedule — is the base class's. Three hooks keep the front-end in step with the graph:
the initial condition starts it, every prediction propagates its pose, every optimisation refreshes its covariances.

When the question never optimises before the end (``optimization_period=None``: q2_c, q2_d, q2_e), association
still needs a graph that is optimised now and then — without it the landmarks keep their first-sighting
estimates while H claims they are known far better. Such runs therefore update the graph every
``association_period`` ticks (default 100: 10 s of driving). The update factorises H at the current estimates
once: that factorisation gives the front-end its covariances (``OnlineFrontEnd.refresh(factors=…)``) and the
first step of ``association_iterations`` iterations of ``association_algorithm`` (default: one Gauss–Newton
step with its line search; ``SparseOptimizer.optimize`` reuses a factorisation of the undamped H made at the
same estimates). The covariances are thus those of the estimates before the step; the next update is 100
ticks later, and the final optimisation of the run converges as before. On q2_e, seeds 0–2, with and without
clutter, this gives the same precision and landmark count as two iterations of GTSAM's LM followed by a
separate factorisation for the covariances, recall within 0.0004, and saves about 0.8 s of 8 (the measurements
are in ``benchmarks/RESULTS.md``).

The period is not a free knob. Between updates the front-end's window fuses no observation
(``helpers.advanced.online_slam.window``), so the landmarks' standard deviations relative to the vehicle grow with the
odometry alone; more candidates exceed ``closure_sigma`` and are handled as loop closures (a tentative landmark,
merged later or refused as ambiguous). On q2_e without clutter, periods of 120–250 ticks merge far more tentative
landmarks into old ones (81–91 merges at 200–250 ticks against 7–8 at 100); recall falls below 0.95 at 150 and
175 ticks on seed 0 and at 200 on seed 2, and the runs are at most about 1 s faster
(``benchmarks/online_slam.py --sections period``; ``benchmarks/RESULTS.md``).
"""
from __future__ import annotations

import contextlib
import math

import numpy as np

from ..drivebot.edges import LandmarkVertex
from ..drivebot.events import Event, EventType
from ..drivebot.runner import Results, question_setup, run_question
from ..drivebot.slam_system import DriveBotSLAMSystem
from ..graph import information_from_covariance
from ..validation import integer, nonnegative_number, one_of, probability
from .fast_graph import FastOptimizer
from .online_slam import (OnlineFrontEnd, RangeBearingModel, association_scores, check_algorithm, check_options,
                          map_errors)
from .online_slam.covariance import hessian_factors
from .online_slam.tracks import DROPPED

__all__ = ["AssociatingSLAMSystem", "SensorCorruption", "HiddenIds", "association_report", "ASSOCIATION_OPTIONS",
           "run_hidden_ids"]

#: Options of the associating system that ``run_hidden_ids`` accepts next to ``data_association``.
ASSOCIATION_OPTIONS = ("n_sigma", "algorithm_options", "rules", "association_period", "association_iterations",
                       "association_algorithm", "range_margin", "association_space", "reject_ambiguous",
                       "closure_sigma", "closure_support", "closure_patience", "verify_merges", "verify_n_sigma")

#: Seed-sequence key of the corruption's Generator (kept apart from the simulator's draws).
_CORRUPTION_STREAM = 15


class SensorCorruption:
    """Missed detections and clutter on LANDMARK events (module docstring)."""

    def __init__(self, clutter_rate: float, detection_probability: float, max_range: float, covariance, rng):
        self.clutter_rate = nonnegative_number(clutter_rate, "clutter_rate", "spurious detections per scan")
        self.detection_probability = probability(detection_probability, "detection_probability")
        self.max_range = float(max_range)
        self.covariance = np.asarray(covariance, dtype=float)
        if self.covariance.shape != (2, 2) or not np.isfinite(self.covariance).all():
            raise ValueError(f"covariance must be the laser's finite (2, 2) noise covariance, got shape "
                             f"{self.covariance.shape}")
        self.rng = rng

    def scan(self, time, event, hide_ids: bool = True):
        """(event for the system or None, truth ids (n,) with 0 for clutter) for one laser scan; ``event`` is
        the simulator's LANDMARK event of the scan, or None when it saw no landmark. With ``hide_ids`` False
        (known-id runs; then ``clutter_rate`` must be 0) the event keeps its true ids."""
        rng = self.rng
        if event is not None:
            z, ids = event.data, event.landmark_ids
            keep = rng.random(ids.size) < self.detection_probability
            z, ids = z[:, keep], ids[keep]
            cov = event.covariance
        else:
            z, ids, cov = np.zeros((2, 0)), np.zeros(0, dtype=np.int64), self.covariance
        k = int(rng.poisson(self.clutter_rate)) if self.clutter_rate > 0 else 0
        if k:
            r = self.max_range * np.sqrt(rng.random(k))
            b = rng.uniform(-math.pi, math.pi, k)
            z = np.hstack([z, np.vstack([r, b])])
            ids = np.concatenate([ids, np.zeros(k, dtype=np.int64)])
        if ids.size == 0:
            return None, ids
        order = rng.permutation(ids.size)
        z, ids = z[:, order], ids[order]
        shown = np.arange(1, ids.size + 1, dtype=np.int64) if hide_ids else ids
        # the columns of a checked event, permuted or thinned, and finite clutter columns: valid by construction,
        # so the event is built without the constructor's checks
        event = object.__new__(Event)
        for name, value in (("time", float(time)), ("type", EventType.LANDMARK), ("data", z), ("covariance", cov),
                            ("landmark_ids", shown)):
            object.__setattr__(event, name, value)
        return event, ids


class AssociatingSLAMSystem(DriveBotSLAMSystem):
    """``DriveBotSLAMSystem`` whose landmark observations are associated online (module docstring).

    Extra parameters: ``data_association`` ("nn", "mahalanobis", "ml", "jcbb"), ``n_sigma``,
    ``algorithm_options``, ``rules`` (``ConfirmationRules``), ``association_period`` and
    ``association_iterations`` (used only when ``optimization_period`` is None), ``association_algorithm``,
    ``range_margin``, ``association_space``, ``reject_ambiguous``, ``closure_sigma``, ``closure_support``,
    ``closure_patience``, ``verify_merges``, ``verify_n_sigma`` (see ``OnlineFrontEnd``). The front-end is
    ``self.frontend``; confirmed landmarks appear in ``landmark_vertices`` under key + 1. Its graph is a
    ``FastOptimizer`` (the front-end reads the LDLᵀ factor of H from it).
    """

    graph_class = FastOptimizer

    def __init__(self, config=None, options=None, data_association: str = "jcbb", n_sigma: float = 3.0,
                 algorithm_options=None, rules=None, association_period: int = 100, association_iterations: int = 1,
                 association_algorithm: str = "gn",
                 range_margin: float = 1.0, association_space: str = "cartesian", reject_ambiguous: bool = True,
                 closure_sigma: float = 0.5, closure_support: int = 2, closure_patience: int = 50,
                 verify_merges: bool = False, verify_n_sigma: float = 3.0):
        super().__init__(config, options)
        self.association_period = integer(association_period, "association_period", minimum=1)
        self.association_iterations = integer(association_iterations, "association_iterations", minimum=1)
        self.association_algorithm = one_of(association_algorithm, "association_algorithm", ("lm", "gn", "lm-gtsam"))
        model = RangeBearingModel(self.config.laser_detection_range, range_margin=range_margin,
                                  association_space=association_space)
        self.frontend = OnlineFrontEnd(self.graph, model, data_association, n_sigma=n_sigma,
                                       algorithm_options=algorithm_options, rules=rules,
                                       landmark_factory=self._new_landmark, reject_ambiguous=reject_ambiguous,
                                       closure_sigma=closure_sigma, closure_support=closure_support,
                                       closure_patience=closure_patience, verify_merges=verify_merges,
                                       verify_n_sigma=verify_n_sigma)

    def _new_landmark(self, key, estimate):
        v = LandmarkVertex(key + 1, id=key + 1, estimate=estimate)
        self.landmark_vertices[key + 1] = v
        return v

    @staticmethod
    def _information(cov):
        """Ω = cov⁻¹ of an event's covariance (validated, cached by value)."""
        return information_from_covariance(cov, "laser covariance")

    def _handle_initial_condition(self, event):
        super()._handle_initial_condition(event)
        self.frontend.start(self.current_vehicle_vertex)

    def _predict_to_time(self, time, dt):
        super()._predict_to_time(time, dt)
        self.frontend.add_pose(self.process_model_edges[-1])

    def _handle_landmarks(self, event):
        # The ids of the event are not read: the front-end associates the columns.
        with self._registrations_kept_only_on_success():
            self.frontend.process_scan(event.data, event.covariance, information=self._information(event.covariance))
        self._built = False

    @contextlib.contextmanager
    def _registrations_kept_only_on_success(self):
        """A scan that fails is undone by the front-end (its new landmark vertices leave the graph), so the
        vertices registered here for it are forgotten too."""
        registered = len(self.landmark_vertices)
        try:
            yield
        except BaseException:
            for key in list(self.landmark_vertices)[registered:]:
                del self.landmark_vertices[key]
            raise


    def _association_only(self) -> bool:
        return self.options.optimization_period is None and self.step_number % self.association_period == 0

    def recommend_optimization(self) -> bool:
        return super().recommend_optimization() or self._association_only()

    def optimize(self, max_iterations: int = 50) -> float:
        """The base optimisation, then a front-end refresh at the optimised estimates. An optimisation run only for
        association factorises H at the current estimates first — the front-end's covariances — and then runs at
        most ``association_iterations`` iterations of ``association_algorithm``, whose first Gauss–Newton step
        reuses that factorisation (module docstring)."""
        if not self._association_only():
            chi2 = super().optimize(max_iterations)
            self.frontend.refresh()
            return chi2
        max_iterations = integer(max_iterations, "max_iterations", minimum=0)
        super().optimize(0)                     # the hook, the edge removal and the structure; linearises H once
        factors = hessian_factors(self.graph)
        chi2 = float(self.graph.optimize(min(max_iterations, self.association_iterations),
                                         algorithm=self.association_algorithm))
        self.frontend.refresh(factors=factors)
        return chi2


class HiddenIds:
    """The set-up of a run with the ids hidden or the sensor corrupted (module docstring): it builds the system
    (``system``), corrupts each tick's events (``filter``) and logs the truth of every delivered column
    (``scan_truth``: per scan, the true landmark id of each column, 0 for clutter)."""

    def __init__(self, data_association, clutter_rate, detection_probability, seed, options):
        if data_association is not None:
            check_algorithm(data_association, "data_association")
        self.data_association = data_association
        self.clutter_rate = nonnegative_number(clutter_rate, "clutter_rate", "spurious detections per scan")
        self.detection_probability = probability(detection_probability, "detection_probability")
        if data_association is None and self.clutter_rate > 0:
            raise ValueError("clutter_rate > 0 needs a data_association algorithm: a spurious detection has no id")
        if data_association is None and options:
            raise ValueError(f"{sorted(options)} are options of the association; data_association is None")
        if data_association is not None:            # refused now, not at the first scan that runs the algorithm
            check_options(data_association, options.get("algorithm_options"))
        self.options = dict(options)
        self.rng = np.random.default_rng([integer(seed, "seed", minimum=0), _CORRUPTION_STREAM])
        self.scan_truth = []
        self.corruption = None

    def system(self, config, options):
        """The SLAM system of the run (``options``: its SLAMOptions)."""
        self.corruption = SensorCorruption(self.clutter_rate, self.detection_probability,
                                           config.laser_detection_range, config.r_laser, self.rng)
        if self.data_association is None:
            return DriveBotSLAMSystem(config, options)
        return AssociatingSLAMSystem(config, options, self.data_association, **self.options)

    def filter(self, events, sim):
        """The tick's events with the LANDMARK event corrupted (or added: clutter on a scan that saw nothing)."""
        if not sim.laser_fired:
            return events
        pos = next((i for i, e in enumerate(events) if e.type is EventType.LANDMARK), None)
        original = None if pos is None else events[pos]
        new, truth = self.corruption.scan(sim.time, original, hide_ids=self.data_association is not None)
        out = [e for e in events if e.type is not EventType.LANDMARK]
        if new is None:
            return out
        if pos is None:
            pos = next((i for i, e in enumerate(out) if e.type is EventType.GPS), len(out))
        out.insert(pos, new)
        self.scan_truth.append(truth)
        return out


def association_report(results) -> dict:
    """The association of a finished run (``Results.association_report``): precision, recall (pairings vs the
    simulator's truth, see ``helpers.advanced.online_slam.metrics``), n_landmarks (created), n_true_landmarks
    (observed at
    least once), n_matched, map_rmse / map_max_error (m, matched landmarks), n_clutter, n_clutter_paired,
    data_association, clutter_rate, detection_probability, final_chi2, run_time; with a front-end also
    n_tentative_dropped, association_time and refresh_time (s), jcbb_nodes, budget_exhausted; and ``matching``."""
    system, hidden = results.system, results.setup if isinstance(results.setup, HiddenIds) else None
    frontend = getattr(system, "frontend", None)
    if frontend is None:                   # ids given: every delivered detection is an edge to its landmark
        truth = np.array([e.vertex(1).landmark_id for e in system.graph.edges()
                          if isinstance(e.vertex(1), LandmarkVertex)], dtype=np.int64)
        assigned = truth.copy()
        found = {lid: v.estimate for lid, v in system.landmark_vertices.items()}
    else:
        truth = np.concatenate(hidden.scan_truth) if hidden.scan_truth else np.zeros(0, dtype=np.int64)
        assigned = frontend.observation_assignment()
        found = {t.key: t.vertex.estimate for t in frontend.confirmed_tracks()}
    if assigned.size != truth.size:
        raise ValueError(f"the run logged {assigned.size} observations but {truth.size} truths")
    scores = association_scores(assigned, truth)
    sc = results.scenario
    true_pos = {int(i): sc.landmarks[:, k] for k, i in enumerate(sc.landmark_ids)}
    errors = map_errors(scores["matching"], found, true_pos)
    report = {k: v for k, v in scores.items() if k != "matching"}
    report.update({
        "data_association": None if hidden is None else hidden.data_association,
        "clutter_rate": 0.0 if hidden is None else hidden.clutter_rate,
        "detection_probability": 1.0 if hidden is None else hidden.detection_probability,
        "map_rmse": float(np.sqrt(np.mean(errors ** 2))) if errors.size else float("nan"),
        "map_max_error": float(errors.max()) if errors.size else float("nan"),
        "final_chi2": results.final_chi2,
        "run_time": results.run_time,
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


def run_hidden_ids(name: str, data_association: str | None = None, clutter_rate: float = 0.0,
                   detection_probability: float = 1.0, seed=0, progress: bool = False, step_hook=None,
                   **overrides) -> Results:
    """``drivebot.run_question`` with the landmark ids hidden (module docstring).

    ``data_association``: None keeps the ids (the coursework), or "nn", "mahalanobis", "ml" or "jcbb", the L09
    algorithm the system associates every scan with; ``clutter_rate``: spurious detections per scan (Poisson,
    uniform in the sensor footprint; needs an algorithm); ``detection_probability``: each true detection is kept
    with this probability. ``overrides``: those of ``run_question`` and the association's options
    (``ASSOCIATION_OPTIONS``, only with an algorithm). These act through the laser: a question without it raises
    ValueError, as does any bad value, before anything runs."""
    overrides = dict(overrides)
    options = {k: overrides.pop(k) for k in list(overrides) if k in ASSOCIATION_OPTIONS}
    setup = HiddenIds(data_association, clutter_rate, detection_probability, seed, options)
    corrupted = data_association is not None or setup.detection_probability < 1.0
    if corrupted and not question_setup(name, **overrides)[1].enable_laser:
        given = next(f"{k}={v!r}" for k, v in [("data_association", data_association),
                                                ("detection_probability", detection_probability)]
                     if v not in (None, 1.0))
        raise ValueError(f"{given} has no effect on {name!r}: it acts through the laser; enable it with "
                         f"enable_laser=True")
    return run_question(name, seed=seed, progress=progress, step_hook=step_hook,
                        setup=setup if corrupted else None, **overrides)
