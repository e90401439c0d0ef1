"""Victoria Park, associated online: the real dataset's tree observations with their landmark ids hidden.

    res = run_victoria_park("jcbb")
    res.association_report()   # agreement, n_landmarks, final_chi2 next to the known-id solution's

The file (``helpers.datasets.read_dataset("victoria_park")``: 6 968 ODOMETRY and 3 640 LANDMARK lines, 151
landmark ids) is processed in file order, as a robot would receive it:

- ODOMETRY i j: a new pose j, an ``EdgeSE2`` from i with the file's information; the front-end propagates its
  pose through the edge (``OnlineFrontEnd.add_pose``);
- the LANDMARK lines of one pose form a scan (1 or 2 trees): range-bearing observations with the file's noise
  (load2D's rule: σ_r = √c_xx, σ_β = √(c_xx / 10)), whose ids are set aside for the evaluation only;
- every ``optimization_period`` poses (default 10, about 6 m of driving and 5 scans), ``optimization_iterations``
  iterations of GTSAM's LM schedule (``"lm-gtsam"``, warm-started: 2–4 iterations suffice) and a front-end
  refresh. The period is chosen for the association, which gates with the estimate of the last refresh. Measured
  with the known ids (``vp_analysis.known_id_nearest_neighbour``, notebook 23): nearest-neighbour pairing from the
  pipeline's own estimate is right for 0.78 of the re-observations when optimising every 100 poses, 0.94 every
  20 and 0.95 every 10 (0.98 with hindsight). The known-id pipeline reaches the same optimum (χ² = 4 678.4) at
  every period from 10 to 100. Every 400 poses it ends in a worse local minimum (χ² = 5 740): the odometry drifts
  too far between optimisations for the linearisation to recover. Online with JCBB, a period of 10 gives
  agreement 0.33 and a final χ² 3 % above the known-id one. A period of 100 gives agreement 0.26 and 53 % above,
  in a quarter of the time.

The sensor: range up to ``max_range`` (the file's ranges reach 20.7 m), field of view ``field_of_view`` (the
bearings lie within ±76°; default 180°).

The known-id reference (``known_id_reference=True``) runs the same pipeline with the file's ids (a landmark vertex
at its first sighting, every observation an edge to it, the same optimisation schedule); its final χ² is the one
the online χ² is compared with. The batch solution of the whole file from the loader's initial values
(odometry composition, landmarks at their first sighting) stops in a far worse local minimum (χ² ≈ 2.1·10⁵ with
the exponential-map pose update, 3.4·10⁵ with the additive one, against ≈ 4.7·10³ incrementally); with
``batch_reference=True`` it is computed and reported as well.

Noise model: ``measurement_sigmas=(σ_r, σ_β)`` replaces the file's observation noise and ``odometry_scale``
multiplies the odometry covariances — in the online run *and* in the known-id reference, so that the χ² stay
comparable.

Status (measured, notebook 23, optimising every 10 poses): the online association does **not** reach the file's
landmarks — agreement 0.33 with the file's noise model (296 landmarks for 151 ids, final χ² 3 % above the known-id
one), 0.79 with (σ_r, σ_β) = (0.3 m, 0.08 rad) and the odometry covariance × 10 (155 landmarks). At a period of 100
poses the same two models give 0.26 and 0.42. Two causes, both visible with the known ids: (1) with the file's
noise (σ_β = 0.2 rad, 3 m at 15 m) a tree seen for the first time often falls inside the gate of a mapped
neighbour, and a scan of 1–2 trees gives joint compatibility no constellation to refuse it; (2) with a noise model
close to the residuals of the known-id solution (σ_r ≈ 0.14 m, σ_β ≈ 0.034 rad), the odometry drifts between
revisits by far more than its stated covariance (the known-id run's own prediction of tree 358 at scan 250 is 2.2 m
off with a relative σ of 0.23 m), so revisited trees start new landmarks, loops stay open and the drift grows. The
DriveBot runs (a consistent simulator) meet their targets.

Measured since (``vp_analysis.odometry_drift``, notebook 23): the file's odometry has a heading *bias*, not just
noise — against the known-id solution the heading error over 200 steps (≈ 116 m) has median 0.18 rad and mean
0.20 rad where the file's covariance gives σ_θ = 0.028 rad (median eᵀP⁻¹e = 56 instead of ≈ 2.4); a per-step fit
of the heading residual is 0.0005 rad + 0.001 rad/m · Δx + 1.8 % of Δθ. Correcting the odometry with that fit
(an oracle, from the known-id solution) raises the agreement only to 0.49: the bias varies along the run, and a
scan of 1–2 trees gives joint compatibility nothing to refuse a wrong pairing with. The file's ids are
themselves an association: 5 pairs of ids lie within 2 m and are never seen in one scan (2.8 % of the
observations are the smaller id of such a pair).

Late association (``late_association=True``, ``online_slam.late``): the observations the front-end leaves out are
pooled and, after each optimisation, paired with a confirmed landmark at the new estimates, or made into a landmark
when enough of them agree. On the tuned setting of notebook 23 (the wider model, ``n_confirm`` 3, a 4σ gate) it
lifts the agreement with the file's ids from 0.930 to 0.953 (precision 0.969 → 0.968, 104 landmarks), and
0.9525–0.9527 over the neighbouring settings measured (period 8, 12, 15; odometry × 8; a 3.5σ gate). Off by default,
like the tuned setting itself: with the file's noise model the map is already wrong when the pool is tested (agreement
0.326 → 0.342, precision 0.420 → 0.368, and 73 s instead of 17 s for its larger pool).
"""
from __future__ import annotations

import inspect
import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from ...datasets import build_optimizer, read_dataset
from ...graph import EdgeRangeBearing, EdgeSE2, SparseOptimizer, VertexPointXY, VertexSE2
from ...validation import integer, positive_number, same_setting
from .algorithms import ALGORITHMS, check_algorithm
from .frontend import OnlineFrontEnd
from .metrics import association_scores
from .models import RangeBearingModel
from .tracks import ConfirmationRules

__all__ = ["VictoriaParkResults", "run_victoria_park", "VICTORIA_PARK_RULES", "victoria_park_scans"]

#: Confirmation rule for Victoria Park: a tree is detected in some scans only (1–2 trees per scan, many in view),
#: so a tentative landmark is confirmed at its second observation and may go unseen for 20 scans.
VICTORIA_PARK_RULES = ConfirmationRules(n_confirm=2, n_miss=20, max_age=40, exclusion_n_sigma=4.0)


def victoria_park_scans(data):
    """The file as a stream: a list of ("odometry", i, j, z, Ω) and ("scan", i, Z (2, m), Ω (m, 2, 2), ids (m,))."""
    stream, scan = [], None
    for kind, i, j, z, info in data.edges:
        if kind == "rb":
            if scan is None or scan[1] != i:
                scan = ["scan", i, [], [], []]
                stream.append(scan)
            scan[2].append(z)
            scan[3].append(info)
            scan[4].append(j)
            continue
        if kind != "se2":
            raise ValueError(f"data: unexpected record kind {kind!r} in a Victoria Park file")
        scan = None
        stream.append(("odometry", i, j, z, info))
    return [s if s[0] == "odometry" else ("scan", s[1], np.array(s[2]).T, np.array(s[3]),
                                           np.array(s[4], dtype=np.int64)) for s in stream]


@dataclass
class VictoriaParkResults:
    """graph (SparseOptimizer), frontend (None for the known-id run), truth (file id of every observation, in
    file order), final_chi2, run_time (s), optimisations, and the references' χ² (NaN when not computed)."""

    data_association: str | None
    graph: SparseOptimizer
    frontend: OnlineFrontEnd | None
    truth: np.ndarray
    final_chi2: float
    run_time: float
    optimisations: int
    known_id_chi2: float = float("nan")
    known_id_run_time: float = float("nan")
    batch_chi2: float = float("nan")
    settings: dict = field(default_factory=dict)
    #: known-id runs: the landmark vertex of every file id; online runs: the known-id reference run (if computed)
    landmark_vertices: dict = field(default_factory=dict)
    reference: VictoriaParkResults | None = None

    def association_report(self) -> dict:
        """agreement (observations whose landmark corresponds to the file's id under the best one-to-one
        matching), n_landmarks (found), n_reference_landmarks (ids in the file), final_chi2, known_id_chi2,
        chi2_ratio (final / known-id), batch_chi2, precision, recall, n_discarded (observations in no landmark),
        run_time."""
        if self.frontend is None:
            assigned = self.truth.copy()
        else:
            assigned = self.frontend.observation_assignment()
        s = association_scores(assigned, self.truth)
        return {
            "data_association": self.data_association,
            "agreement": s["agreement"],
            "precision": s["precision"],
            "recall": s["recall"],
            "n_landmarks": s["n_landmarks"],
            "n_reference_landmarks": s["n_true_landmarks"],
            "n_matched": s["n_matched"],
            "n_observations": s["n_observations"],
            "n_discarded": int(np.count_nonzero(assigned < 0)),
            "final_chi2": self.final_chi2,
            "known_id_chi2": self.known_id_chi2,
            "chi2_ratio": self.final_chi2 / self.known_id_chi2 if np.isfinite(self.known_id_chi2) else float("nan"),
            "batch_chi2": self.batch_chi2,
            "run_time": self.run_time,
            "known_id_run_time": self.known_id_run_time,
            "optimisations": self.optimisations,
        }


class _KnownIds:
    """The known-id 'front-end': one vertex per file id, created at its first sighting."""

    def __init__(self, graph, model, probe=None):
        self.graph, self.model, self.vertices, self.pose, self.probe = graph, model, {}, None, probe

    def process_scan(self, Z, R, information, ids):
        if self.probe is not None:
            self.probe(self.pose.estimate, Z, ids, self.vertices)
        rows = []
        for c, lid in enumerate(ids.tolist()):
            v = self.vertices.get(lid)
            if v is None:
                v = VertexPointXY(None, self.model.inverse(self.pose.estimate, Z[:, c])[0])
                self.graph.add_vertex(v)
                self.vertices[lid] = v
            rows.append((self.pose, v))
        self.graph.add_edges(EdgeRangeBearing, rows, Z.T, information)


def _optimise(graph, frontend, iterations):
    graph.initialize_optimization()
    chi2 = graph.optimize(iterations, algorithm="lm-gtsam")
    if frontend is not None:
        frontend.refresh()
    return chi2


def _with_sigmas(stream, sigmas, odometry_scale=1.0):
    """The stream with every observation's information replaced by diag(σ_r, σ_β)⁻² (None: the file's) and the
    odometry covariances multiplied by ``odometry_scale`` (both checked by ``_check_noise_model``)."""
    scale = float(odometry_scale)
    if scale != 1.0:
        stream = [(s[0], s[1], s[2], s[3], s[4] / scale) if s[0] == "odometry" else s for s in stream]
    if sigmas is None:
        return stream
    sr, sb = (float(v) for v in sigmas)
    info = np.diag([1.0 / sr ** 2, 1.0 / sb ** 2])
    return [s if s[0] == "odometry" else (s[0], s[1], s[2], np.broadcast_to(info, s[3].shape).copy(), s[4])
            for s in stream]


def _process(stream, data_association, model, period, iterations, frontend_options, progress, probe=None):
    """One pass over the stream; returns (graph, frontend or None, truth, χ², optimisations, seconds). ``probe``:
    see ``run_victoria_park``."""
    t0 = time.perf_counter()
    graph = SparseOptimizer()
    first = VertexSE2(None, np.zeros(3), fixed=True)
    graph.add_vertex(first)
    poses = {stream[0][1]: first}
    if data_association is None:
        fe = _KnownIds(graph, model, probe)
        fe.pose = first
    else:
        fe = OnlineFrontEnd(graph, model, data_association, **frontend_options)
        fe.start(first)
    truth, count, n_opt = [], 0, 0
    for item in tqdm(stream, disable=not progress, desc="victoria_park", unit="record"):
        if item[0] == "odometry":
            _, i, j, z, info = item
            prev = poses[i]
            est = _compose(prev.estimate, z)
            v = VertexSE2(None, est)
            graph.add_vertex(v)
            e = EdgeSE2([prev, v], measurement=z, information=info)
            graph.add_edge(e)
            poses[j] = v
            if data_association is None:
                fe.pose = v
            else:
                fe.add_pose(e)
            count += 1
            if count % period == 0:
                _optimise(graph, None if data_association is None else fe, iterations)
                n_opt += 1
        else:
            _, i, Z, info, ids = item
            R = np.linalg.inv(info[0])
            if data_association is None:
                fe.process_scan(Z, R, info, ids)
            else:
                fe.process_scan(Z, R, information=info)
            truth.append(ids)
    chi2 = _optimise(graph, None, max(iterations, 50))
    return (graph, fe, np.concatenate(truth), float(chi2), n_opt + 1, time.perf_counter() - t0)


def _compose(p, z):
    c, s = math.cos(p[2]), math.sin(p[2])
    th = math.atan2(math.sin(p[2] + z[2]), math.cos(p[2] + z[2]))
    return np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], th])


#: Arguments of ``run_victoria_park`` that only the online front-end reads: with ``data_association=None`` (the
#: known-id pipeline) each must keep its default (the sensor footprint and the association's options; the
#: known-id reference is then the run itself).
_ASSOCIATION_ONLY = ("max_range", "field_of_view", "n_sigma", "algorithm_options", "rules", "association_space",
                     "closure_sigma", "closure_support", "verify_merges", "verify_n_sigma", "late_association",
                     "late_n_sigma", "known_id_reference")


def _is_default(name, value, default) -> bool:
    """Whether ``value`` is the default of ``run_victoria_park``'s argument ``name`` (a number equal to a numeric
    default counts; a bool only as a bool; ``rules`` may also be ``VICTORIA_PARK_RULES``, ``algorithm_options`` {})."""
    if value is default or (name == "algorithm_options" and isinstance(value, dict) and not value):
        return True
    if name == "rules":
        return isinstance(value, ConfirmationRules) and value == VICTORIA_PARK_RULES
    return same_setting(value, default)


def _check_noise_model(measurement_sigmas, odometry_scale) -> None:
    """ValueError unless ``measurement_sigmas`` is None or two positive finite numbers and ``odometry_scale`` a
    positive finite number (text and bools are not numbers)."""
    positive_number(odometry_scale, "odometry_scale")
    if measurement_sigmas is None:
        return
    try:
        pair = list(measurement_sigmas) if not isinstance(measurement_sigmas, (str, bytes, dict)) else None
    except TypeError:
        pair = None
    if pair is None or len(pair) != 2 or not all(
            isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) and math.isfinite(v) and v > 0
            for v in pair):
        raise ValueError(f"measurement_sigmas must be None or two positive finite numbers (σ_range [m], "
                         f"σ_bearing [rad]), got {measurement_sigmas!r}")


def _check_association_options(data_association, model, options, given) -> None:
    """Every front-end option checked before the file is read: with an algorithm, by building a front-end on an
    empty graph (the same checks and messages as the run's); without one, each association-only argument must keep
    its default (``_ASSOCIATION_ONLY``)."""
    if data_association is not None:
        OnlineFrontEnd(SparseOptimizer(), model, data_association, **options)
        return
    defaults = inspect.signature(run_victoria_park).parameters
    for name in _ASSOCIATION_ONLY:
        if not _is_default(name, given[name], defaults[name].default):
            raise ValueError(f"{name}={given[name]!r} has no effect without data association (data_association="
                             f"None runs the known-id pipeline); pass an algorithm ({', '.join(map(repr, ALGORITHMS))})"
                             f" or leave {name} at its default")


def run_victoria_park(data_association: str | None = "jcbb", optimization_period: int = 10,
                      optimization_iterations: int = 10, max_range: float = 25.0,
                      field_of_view: float = math.pi, n_sigma: float = 3.0, algorithm_options=None,
                      rules: ConfirmationRules | None = None, association_space: str = "cartesian",
                      closure_sigma: float = 2.0, closure_support: int = 1, measurement_sigmas=None,
                      odometry_scale: float = 1.0, verify_merges: bool = False, verify_n_sigma: float = 3.0,
                      late_association: bool = False, late_n_sigma: float = 2.0, known_id_reference: bool = True,
                      batch_reference: bool = False, progress: bool = False,
                      scan_probe=None) -> VictoriaParkResults:
    """Process Victoria Park online with the ids hidden (module docstring). ``data_association=None`` runs the
    known-id pipeline itself; there ``scan_probe(pose estimate, Z, ids, {file id: landmark vertex})``, if given,
    is called before each scan is added (what the pipeline knows at that moment: ``vp_analysis``). Front-end
    options as in ``OnlineFrontEnd`` (``rules`` default ``VICTORIA_PARK_RULES``; ``verify_merges`` and
    ``verify_n_sigma``: merge verification with undo, ``verification``). Every argument is checked before the file
    is read; with ``data_association=None`` the arguments only the front-end reads (``_ASSOCIATION_ONLY``) must
    keep their defaults (ValueError otherwise: they would have no effect)."""
    if scan_probe is not None and (data_association is not None or not callable(scan_probe)):
        raise ValueError("scan_probe must be a callable, and applies to the known-id run (data_association=None) "
                         f"only; got scan_probe={scan_probe!r} with data_association={data_association!r}")
    if data_association is not None:
        check_algorithm(data_association, "data_association")
    period = integer(optimization_period, "optimization_period", minimum=1)
    iterations = integer(optimization_iterations, "optimization_iterations", minimum=1)
    for name, flag in (("known_id_reference", known_id_reference), ("batch_reference", batch_reference),
                       ("progress", progress)):
        if not isinstance(flag, (bool, np.bool_)):
            raise ValueError(f"{name} must be True or False, got {flag!r}")
    model = RangeBearingModel(max_range, field_of_view=field_of_view, range_margin=2.0, bearing_margin=0.1,
                              association_space=association_space)
    options = {"n_sigma": n_sigma, "algorithm_options": algorithm_options,
               "rules": VICTORIA_PARK_RULES if rules is None else rules, "closure_sigma": closure_sigma,
               "closure_support": closure_support, "verify_merges": verify_merges, "verify_n_sigma": verify_n_sigma,
               "late_association": late_association, "late_n_sigma": late_n_sigma}
    _check_noise_model(measurement_sigmas, odometry_scale)
    _check_association_options(data_association, model, options, {
        "max_range": max_range, "field_of_view": field_of_view, "association_space": association_space,
        "known_id_reference": known_id_reference, **options, "rules": rules})
    stream = victoria_park_scans(read_dataset("victoria_park"))
    stream = _with_sigmas(stream, measurement_sigmas, odometry_scale)
    graph, fe, truth, chi2, n_opt, seconds = _process(stream, data_association, model, period, iterations,
                                                      options, progress, scan_probe)
    known = data_association is None
    res = VictoriaParkResults(data_association=data_association, graph=graph, frontend=None if known else fe,
                              truth=truth, final_chi2=chi2, run_time=seconds, optimisations=n_opt,
                              landmark_vertices=dict(fe.vertices) if known else {},
                              settings={"optimization_period": period, "optimization_iterations": iterations,
                                        "model": repr(model), **{k: v for k, v in options.items() if k != "rules"},
                                        "rules": options["rules"]})
    if known_id_reference and data_association is not None:
        ref = _process(stream, None, model, period, iterations, options, False)
        res.known_id_chi2, res.known_id_run_time = ref[3], ref[5]
        res.reference = VictoriaParkResults(data_association=None, graph=ref[0], frontend=None, truth=ref[2],
                                            final_chi2=ref[3], run_time=ref[5], optimisations=ref[4],
                                            known_id_chi2=ref[3], known_id_run_time=ref[5],
                                            settings=res.settings, landmark_vertices=dict(ref[1].vertices))
    elif data_association is None:
        res.known_id_chi2, res.known_id_run_time = chi2, seconds
    if batch_reference:
        batch = build_optimizer(read_dataset("victoria_park"))
        batch.initialize_optimization()
        res.batch_chi2 = float(batch.optimize(100, algorithm="lm-gtsam"))
    return res
