"""Victoria Park, associated online: the real dataset's tree observations with their landmark ids hidden.

    res = run_victoria_park("jcbb")
    res.association_report()   # agreement, n_landmarks, final_chi2 next to the known-id solution's

The file (``helpers.datasets.read_dataset("victoria_park")``: 6 968 ODOMETRY and 3 640 LANDMARK lines, 151
landmark ids) is processed in file order, as a robot would receive it:

- ODOMETRY i j: a new pose j, an ``EdgeSE2`` from i with the file's information; the front-end propagates its
  pose through the edge (``OnlineFrontEnd.add_pose``);
- the LANDMARK lines of one pose form a scan (1 or 2 trees): range-bearing observations with the file's noise
  (load2D's rule: σ_r = √c_xx, σ_β = √(c_xx / 10)), whose ids are set aside for the evaluation only;
- every ``optimization_period`` poses, ``OPTIMIZATION_ITERATIONS`` iterations of GTSAM's LM schedule
  (``"lm-gtsam"``, warm-started from the last estimate) and a front-end refresh: the association gates with the
  estimate and covariances of the last refresh, so the period sets how stale they are;
- at the end, a final optimisation of up to 50 iterations.

The sensor: range up to ``MAX_RANGE``, field of view ``FIELD_OF_VIEW``. The front-end (``OnlineFrontEnd``) gates
at ``n_sigma``, confirms trees by ``rules`` (default ``VICTORIA_PARK_RULES``), closes loops through single
pairings (a scan holds one or two trees) and, with ``late_association``, pairs the observations it left out after
later optimisations (``late``).

The known-id reference (``known_id_reference=True``) runs the same pipeline with the file's ids (a landmark vertex
at its first sighting, every observation an edge to it, the same noise model), optimised every
``KNOWN_ID_PERIOD`` poses: with the ids known the final estimate does not depend on the schedule (``benchmarks/
online_slam.py --sections vpschedule``), so the reference takes the cheaper one. Its final χ² is the one the
online χ² is compared with. ``batch_reference=True`` also solves the whole file at once from the
loader's initial values (odometry composition, landmarks at their first sighting).

Noise model: ``measurement_sigmas=(σ_r, σ_β)`` replaces the file's observation noise and ``odometry_scale``
multiplies the odometry covariances, in the online run *and* in the known-id reference, so that the χ² stay
comparable.
"""
from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from ...datasets import build_optimizer, read_dataset
from ...graph import EdgeRangeBearing, EdgeSE2, VertexPointXY, VertexSE2
from ...validation import boolean, integer, positive_number
from ..fast_graph import FastOptimizer
from .algorithms import check_algorithm
from .frontend import OnlineFrontEnd
from .metrics import association_scores
from .models import RangeBearingModel
from .tracks import ConfirmationRules

__all__ = ["VictoriaParkResults", "run_victoria_park", "VICTORIA_PARK_RULES", "victoria_park_scans"]

#: Confirmation rule for Victoria Park: a tree is detected in some scans only (1–2 trees per scan, many in view),
#: so a tentative landmark is confirmed at its second observation and may go unseen for 20 scans.
VICTORIA_PARK_RULES = ConfirmationRules(n_confirm=2, n_miss=20, max_age=40, exclusion_n_sigma=4.0)
#: LM iterations per periodic optimisation (warm-started: two to four suffice).
OPTIMIZATION_ITERATIONS = 10
#: The known-id reference's optimisation period (poses).
KNOWN_ID_PERIOD = 100
#: The sensor footprint: the file's ranges reach 20.7 m and its bearings lie within ±76°.
MAX_RANGE, FIELD_OF_VIEW = 25.0, math.pi
#: The loop-closure stage: a candidate whose σ relative to the vehicle exceeds 2 m goes to it, and one pairing
#: suffices to merge (a scan holds one or two trees).
_CLOSURE = {"closure_sigma": 2.0, "closure_support": 1}


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
    """graph (FastOptimizer), frontend (None for the known-id run), truth (file id of every observation, in
    file order), final_chi2, run_time (s), optimisations, and the references' χ² (NaN when not computed)."""

    data_association: str | None
    graph: FastOptimizer
    frontend: OnlineFrontEnd | None
    truth: np.ndarray
    final_chi2: float
    run_time: float
    optimisations: int
    known_id_chi2: float = float("nan")
    known_id_run_time: float = float("nan")
    batch_chi2: float = float("nan")
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

    def __init__(self, graph, model):
        self.graph, self.model, self.vertices, self.pose = graph, model, {}, None

    def process_scan(self, Z, information, ids):
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


def _process(stream, data_association, model, period, frontend_options):
    """One pass over the stream; returns (graph, frontend or None, truth, χ², optimisations, seconds)."""
    t0 = time.perf_counter()
    graph = FastOptimizer()
    first = VertexSE2(None, np.zeros(3), fixed=True)
    graph.add_vertex(first)
    poses = {stream[0][1]: first}
    if data_association is None:
        fe = _KnownIds(graph, model)
        fe.pose = first
    else:
        fe = OnlineFrontEnd(graph, model, data_association, **frontend_options)
        fe.start(first)
    truth, count, n_opt = [], 0, 0
    for item in stream:
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
                _optimise(graph, None if data_association is None else fe, OPTIMIZATION_ITERATIONS)
                n_opt += 1
        else:
            _, i, Z, info, ids = item
            if data_association is None:
                fe.process_scan(Z, info, ids)
            else:
                fe.process_scan(Z, np.linalg.inv(info[0]), information=info)
            truth.append(ids)
    chi2 = _optimise(graph, None, 50)
    return (graph, fe, np.concatenate(truth), float(chi2), n_opt + 1, time.perf_counter() - t0)


def _compose(p, z):
    c, s = math.cos(p[2]), math.sin(p[2])
    th = math.atan2(math.sin(p[2] + z[2]), math.cos(p[2] + z[2]))
    return np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], th])


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


def _same_setting(value: object, default: object) -> bool:
    """Whether an option's ``value`` is its ``default``: the same object, or equal and of the same kind (a bool only
    as a bool, a number as a number, text as text)."""
    if value is default:
        return True
    if isinstance(default, bool) or isinstance(value, (bool, np.bool_)):
        return isinstance(value, (bool, np.bool_)) and isinstance(default, bool) and bool(value) == default
    if isinstance(default, numbers.Real) and isinstance(value, numbers.Real):
        return value == default
    return isinstance(default, str) and isinstance(value, str) and value == default


def run_victoria_park(data_association: str | None = "jcbb", optimization_period: int = 10, n_sigma: float = 3.0,
                      rules: ConfirmationRules | None = None, measurement_sigmas=None, odometry_scale: float = 1.0,
                      late_association: bool = False, known_id_reference: bool = True,
                      batch_reference: bool = False) -> VictoriaParkResults:
    """Process Victoria Park online with the ids hidden (module docstring); ``data_association=None`` runs the
    known-id pipeline itself. ``n_sigma``, ``rules`` and ``late_association`` are the front-end's
    (``OnlineFrontEnd``). Every argument is checked before the file is read (ValueError naming it); with
    ``data_association=None`` the front-end's arguments must keep their defaults (they would have no effect)."""
    period = integer(optimization_period, "optimization_period", minimum=1)
    for name, flag in (("known_id_reference", known_id_reference), ("batch_reference", batch_reference)):
        boolean(flag, name)
    _check_noise_model(measurement_sigmas, odometry_scale)
    model = RangeBearingModel(MAX_RANGE, field_of_view=FIELD_OF_VIEW, range_margin=2.0, bearing_margin=0.1)
    options = {"n_sigma": n_sigma, "rules": VICTORIA_PARK_RULES if rules is None else rules,
               "late_association": late_association, **_CLOSURE}
    if data_association is not None:
        check_algorithm(data_association, "data_association")
        OnlineFrontEnd(FastOptimizer(), model, data_association, **options)      # checks every option
    else:
        for name, value, default in (("n_sigma", n_sigma, 3.0), ("rules", options["rules"], VICTORIA_PARK_RULES),
                                     ("late_association", late_association, False)):
            if not (_same_setting(value, default) or isinstance(value, ConfirmationRules) and value == default):
                raise ValueError(f"{name}={value!r} has no effect without data association (data_association=None "
                                 f"runs the known-id pipeline); pass an algorithm or leave {name} at its default")
    stream = _with_sigmas(victoria_park_scans(read_dataset("victoria_park")), measurement_sigmas, odometry_scale)
    graph, fe, truth, chi2, n_opt, seconds = _process(stream, data_association, model, period, options)
    known = data_association is None
    res = VictoriaParkResults(data_association=data_association, graph=graph, frontend=None if known else fe,
                              truth=truth, final_chi2=chi2, run_time=seconds, optimisations=n_opt,
                              landmark_vertices=dict(fe.vertices) if known else {})
    if known:
        res.known_id_chi2, res.known_id_run_time = chi2, seconds
    elif known_id_reference:
        ref = _process(stream, None, model, KNOWN_ID_PERIOD, options)
        res.known_id_chi2, res.known_id_run_time = ref[3], ref[5]
        res.reference = VictoriaParkResults(data_association=None, graph=ref[0], frontend=None, truth=ref[2],
                                            final_chi2=ref[3], run_time=ref[5], optimisations=ref[4],
                                            known_id_chi2=ref[3], known_id_run_time=ref[5],
                                            landmark_vertices=dict(ref[1].vertices))
    if batch_reference:
        batch = build_optimizer(read_dataset("victoria_park"), optimizer_class=FastOptimizer)
        batch.initialize_optimization()
        res.batch_chi2 = float(batch.optimize(100, algorithm="lm-gtsam"))
    return res
