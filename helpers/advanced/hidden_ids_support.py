"""Support for notebook 22 (DriveBot with the landmark ids hidden): runs, what happened at the loop closure, the
results table and the figures.

* ``Runs`` — runs ``run_hidden_ids(question, data_association=..., clutter_rate=...)`` once per setting and keeps a
  ``Case``: the association report, the graph's χ² degrees of freedom, and — for the questions named in
  ``keep`` — the ``Results`` and an ``AssociationRecorder`` (the large map keeps only the numbers).
* ``AssociationRecorder`` — a ``step_hook`` that records what the front-end knew *online*: the tick of every scan,
  the vehicle's online pose, every new (tentative) landmark placed by the pose estimate of the moment together
  with the map as it was then, and every merge of a tentative landmark into an old one (a loop-closure pairing).
* ``true_sources`` — the true landmark behind each front-end landmark (the source of its first observation; the
  front-end never sees it); ``observation_ticks`` — the tick of every observation.
* ``revisits`` — new landmarks started for a true landmark that is already in the map: at a loop closure the
  drifted pose places a re-observed landmark metres from its map estimate. Their innovations ν = (where the current
  pose puts it) − (where the map has it) are what the association algorithms are asked to explain.
* ``closure_pairings`` — each merge, with the true landmarks on both sides: right or wrong; ``closure_outcome``
  sums it up ("right", "wrong" or "none"); ``run_summary`` counts merges and clutter landmarks of any run.
* ``association_table`` — the results as text, every number rounded to what holds across machines (ratios of
  counts to 3 decimals, χ² to 3 significant figures, map error in cm to 2).
* ``plot_final_map``, ``plot_closure`` — the figures.
* ``nn_gate`` — the Euclidean gate of the front-end's NN at a range r: n_σ·√(σ_r² + r²σ_β²), the sensor noise alone
  (the pose and map uncertainty ignored), in the Cartesian association space of ``helpers.advanced.online_slam.models``.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from ..drivebot.runner import Results
from ..figures import COLORS
from ..validation import integer, nonnegative_number, positive_number
from .hidden_ids import association_report, run_hidden_ids
from .online_slam import check_algorithm

__all__ = ["ALGORITHM_LABELS", "Case", "Runs", "AssociationRecorder", "true_sources", "run_summary",
           "observation_ticks", "revisits", "closure_pairings", "closure_outcome", "nn_gate", "sig",
           "association_table", "plot_final_map", "plot_closure"]

#: How the notebook names the four algorithms.
ALGORITHM_LABELS = {"nn": "NN (Euclidean)", "mahalanobis": "Mahalanobis NN", "ml": "ML", "jcbb": "JCBB"}


# ------------------------------------------------------------------------------------------------ recording
class AssociationRecorder:
    """``step_hook`` for ``run_hidden_ids(..., data_association=...)``: what the front-end knew online.

    After every tick k it stores

    - ``scan_tick``: the tick of every scan the front-end has processed (scan index → tick);
    - ``poses`` (N, 3): the vehicle's online pose estimate (after that tick's optimisation, if one ran);
    - ``born`` {key: (tick, position (2,), map)}: each new landmark of the tick, placed by the inverse observation
      of its first sighting from the pose estimate of that tick, and ``map`` {key: estimate (2,)} of the confirmed
      landmarks as they were at the end of the previous tick;
    - ``merges`` [(tick, key, old key, map)]: each tentative landmark merged into an old one in this tick, with the
      map of the end of the previous tick (before the merge and the optimisation that follows it).
    """

    def __init__(self):
        self.scan_tick: list[int] = []
        self._poses: list[np.ndarray] = []
        self.born: dict = {}
        self.merges: list = []
        self._merged: set = set()
        self._map: dict = {}

    def __call__(self, system, k):
        frontend = getattr(system, "frontend", None)
        if frontend is None:
            raise ValueError("AssociationRecorder needs a run with the ids hidden (run_hidden_ids(..., "
                             "data_association=...)): this system has no front-end")
        k = integer(k, "k", minimum=0)
        self.scan_tick.extend([k] * (frontend.scan_count - len(self.scan_tick)))
        for t in frontend.tracks[len(self.born):]:
            position = frontend.model.inverse(t.parent.estimate, t.z0)[0]
            self.born[t.key] = (k, position, self._map)
        for t in frontend.tracks:
            if t.alias_of >= 0 and t.key not in self._merged:
                self._merged.add(t.key)
                self.merges.append((k, t.key, t.alias_of, self._map))
        self._map = {t.key: np.array(t.vertex.estimate, dtype=float) for t in frontend.confirmed_tracks()}
        self._poses.append(np.array(system.current_vehicle_vertex.estimate, dtype=float))

    @property
    def poses(self) -> np.ndarray:
        """(N, 3) online pose estimate after each tick."""
        return np.array(self._poses, dtype=float).reshape(-1, 3)


@dataclass
class Case:
    """One run: its setting, the association report, the graph's χ² degrees of freedom, and (if kept) the
    ``Results`` and the ``AssociationRecorder``; ``extra``: ``run_summary`` of the run."""

    question: str
    algorithm: str
    clutter_rate: float
    seed: int
    report: dict
    dof: int
    results: Results | None = None
    recorder: AssociationRecorder | None = None
    extra: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        return ALGORITHM_LABELS[self.algorithm]

    @property
    def chi2_per_dof(self) -> float:
        return self.report["final_chi2"] / self.dof if self.dof > 0 else float("nan")


class Runs:
    """Runs of ``run_hidden_ids`` with the ids hidden, each setting run once (``case``).

    ``seed``: the default seed; ``keep``: questions whose runs keep their ``Results`` and record an
    ``AssociationRecorder`` (q2_b: small; the large map keeps only its numbers); ``overrides``: passed to every
    run (e.g. ``n_sigma``).
    """

    def __init__(self, seed=0, keep=("q2_b",), **overrides):
        self.seed = integer(seed, "seed", minimum=0)
        if isinstance(keep, str) or not all(isinstance(q, str) for q in keep):
            raise ValueError(f"keep must be a sequence of question names, got {keep!r}")
        self.keep = tuple(keep)
        self.overrides = dict(overrides)
        self._cases: dict = {}

    def case(self, question: str, algorithm: str, clutter_rate: float = 0.0, seed=None) -> Case:
        """The run of ``question`` with ``algorithm`` and ``clutter_rate`` spurious detections per scan (cached)."""
        check_algorithm(algorithm, "algorithm")
        clutter_rate = nonnegative_number(clutter_rate, "clutter_rate", "spurious detections per scan")
        seed = self.seed if seed is None else integer(seed, "seed", minimum=0)
        key = (question, algorithm, clutter_rate, seed)
        if key not in self._cases:
            keep = question in self.keep
            recorder = AssociationRecorder() if keep else None
            res = run_hidden_ids(question, seed=seed, data_association=algorithm, clutter_rate=clutter_rate,
                               step_hook=recorder, **self.overrides)
            dof = int(res.graph_statistics()["dof"])
            self._cases[key] = Case(question, algorithm, clutter_rate, seed, association_report(res), dof,
                                    res if keep else None, recorder, run_summary(res))
        return self._cases[key]


# ------------------------------------------------------------------------------------------------ analysis
def _kept(case, what):
    if not isinstance(case, Case):
        raise ValueError(f"{what} needs a Case (from Runs.case), got {type(case).__name__}")
    if case.results is None or case.recorder is None:
        raise ValueError(f"{what} needs a run that kept its Results and recorder (Runs(keep=(...{case.question!r})))")
    return case.results, case.recorder


def true_sources(results) -> dict:
    """{front-end key: true landmark id of its first observation} (0: started by clutter)."""
    if not isinstance(results, Results) or getattr(results.system, "frontend", None) is None:
        raise ValueError("true_sources needs the Results of a run with data_association")
    scans = results.setup.scan_truth
    truth = np.concatenate(scans) if scans else np.zeros(0, dtype=np.int64)
    return {t.key: int(truth[t.observations[0]]) for t in results.system.frontend.tracks}


def run_summary(results) -> dict:
    """Counts of a run with the ids hidden that need the truth: {scans (processed by the front-end), merges
    (tentative landmarks merged into old ones), wrong_merges (into an old landmark of another source),
    clutter_landmarks (confirmed landmarks started by a clutter detection), clutter_tracks (tentative landmarks
    started by clutter), clutter_paired_again (those paired with a later observation at least once)}."""
    src = true_sources(results)
    frontend = results.system.frontend
    merged = [t for t in frontend.tracks if t.alias_of >= 0]
    clutter = [t for t in frontend.tracks if src[t.key] == 0]
    return {"scans": int(frontend.scan_count), "merges": len(merged),
            "wrong_merges": sum(src[t.key] != src[t.alias_of] or src[t.key] == 0 for t in merged),
            "clutter_landmarks": sum(src[t.key] == 0 for t in frontend.confirmed_tracks()),
            "clutter_tracks": len(clutter), "clutter_paired_again": sum(t.hits >= 2 for t in clutter)}


def observation_ticks(case) -> tuple:
    """(tick (E,), true source (E,)) of every observation the front-end processed (source 0: clutter)."""
    res, rec = _kept(case, "observation_ticks")
    scans = np.asarray(res.system.frontend.observation_log["scan"], dtype=np.int64)
    ticks = np.asarray(rec.scan_tick, dtype=np.int64)
    parts = res.setup.scan_truth
    truth = np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)
    return (ticks[scans] if scans.size else np.zeros(0, dtype=np.int64)), truth


def revisits(case, min_innovation: float = 0.0) -> list:
    """New landmarks started for a true landmark the map already had (``AssociationRecorder``), in order of
    birth, with ‖ν‖ ≥ ``min_innovation`` (m). Each: {key, source, tick, position, mapped_key (the map's landmark of
    the same source; the oldest if several), mapped (its estimate then), innovation ν = position − mapped (2,),
    distances {map key: distance from position} to every landmark of that map, fate (the track's status,
    "merged" if it was merged)}."""
    res, rec = _kept(case, "revisits")
    min_innovation = nonnegative_number(min_innovation, "min_innovation", "metres")
    src = true_sources(res)
    tracks = res.system.frontend.tracks
    out = []
    for key, (tick, position, mapped) in rec.born.items():
        s = src[key]
        same = [m for m in mapped if src[m] == s]
        if s == 0 or not same:
            continue
        nu = position - mapped[same[0]]
        if np.hypot(*nu) < min_innovation:
            continue
        t = tracks[key]
        out.append({"key": key, "source": s, "tick": tick, "position": position, "mapped_key": same[0],
                    "mapped": mapped[same[0]], "innovation": nu,
                    "distances": {m: float(np.hypot(*(position - p))) for m, p in mapped.items()},
                    "fate": "merged" if t.alias_of >= 0 else t.status})
    return out


def closure_pairings(case) -> list:
    """Every merge of a tentative landmark into an old one: {tick, key, source, old_key, old_source, right,
    position (the tentative landmark where it was placed), old (the old landmark's estimate just before)}."""
    res, rec = _kept(case, "closure_pairings")
    src = true_sources(res)
    out = []
    for tick, key, old, mapped in rec.merges:
        out.append({"tick": tick, "key": key, "source": src[key], "old_key": old, "old_source": src[old],
                    "right": src[key] == src[old] and src[key] != 0, "position": rec.born[key][1],
                    "old": mapped.get(old, np.full(2, np.nan))})
    return out


def closure_outcome(case) -> str:
    """"right", "wrong" (at least one wrong merge) or "none" (no merge: the loop never closed)."""
    pairs = closure_pairings(case)
    if not pairs:
        return "none"
    return "right" if all(p["right"] for p in pairs) else "wrong"


def nn_gate(config, n_sigma: float = 3.0, r=None) -> float:
    """The front-end's default Euclidean NN gate (m) for a landmark at range ``r`` (default: the laser's
    maximum range): n_σ·√trace(G R Gᵀ) = n_σ·√(σ_r² + r²σ_β²)."""
    n_sigma = positive_number(n_sigma, "n_sigma")
    r = config.laser_detection_range if r is None else nonnegative_number(r, "r", "metres")
    R = np.asarray(config.r_laser, dtype=float)
    return float(n_sigma * math.sqrt(R[0, 0] + r * r * R[1, 1]))


# ------------------------------------------------------------------------------------------------ tables
def sig(x, n: int = 3) -> str:
    """``x`` to ``n`` significant figures, without an exponent (e.g. 1654.4 → "1650", 0.0897 → "0.0897")."""
    n = integer(n, "n", minimum=1)
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise ValueError(f"x must be a real number, got {x!r}")
    x = float(x)
    if not math.isfinite(x):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf")
    if x == 0:
        return "0"
    digits = n - 1 - math.floor(math.log10(abs(x)))
    rounded = round(x, digits)
    if rounded != 0 and math.floor(math.log10(abs(rounded))) != math.floor(math.log10(abs(x))):
        digits -= 1                                      # 9.96 → 10.0 at 3 figures gains a digit: "10.0" → "10"
        rounded = round(x, digits)
    return f"{rounded:.{max(digits, 0)}f}"


def _ratio(x) -> str:
    return "—" if not math.isfinite(x) else f"{x:.3f}"


def _rows(header, rows) -> str:
    widths = [max(len(str(c)) for c in col) for col in zip(header, *rows)]

    def line(cells):
        return "  ".join(str(c).rjust(w) for c, w in zip(cells, widths))

    return "\n".join([line(header), line(["-" * w for w in widths])] + [line(r) for r in rows])


def association_table(cases) -> str:
    """One line per run: question, clutter per scan, algorithm, precision, recall (3 decimals), landmarks created
    (true), map RMSE (cm, 2 significant figures), final χ² (3 significant figures), χ²/dof (2 decimals)."""
    header = ["question", "clutter/scan", "algorithm", "precision", "recall", "landmarks (true)", "map RMSE [cm]",
              "final χ²", "χ²/dof"]
    rows = []
    for c in cases:
        r = c.report
        rows.append([c.question, f"{c.clutter_rate:g}", c.label, _ratio(r["precision"]), _ratio(r["recall"]),
                     f"{r['n_landmarks']} ({r['n_true_landmarks']})", sig(100 * r["map_rmse"], 2),
                     sig(r["final_chi2"], 3), f"{c.chi2_per_dof:.2f}"])
    return _rows(header, rows)


# ------------------------------------------------------------------------------------------------ figures
def _axes(ax):
    if not hasattr(ax, "plot"):
        raise ValueError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
    return ax


def _metric_axes(ax):
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")


def _sources_at(mapped, src, sources):
    return [(k, p) for k, p in mapped.items() if src.get(k) in sources]


def plot_final_map(ax, case):
    """The final graph of a kept run: true and estimated paths, true landmarks (+, with their ids), estimated
    landmarks (o) labelled with the true landmark each was started for, dotted to it."""
    _axes(ax)
    res = _kept(case, "plot_final_map")[0]
    sc = res.scenario
    src = true_sources(res)
    ax.plot(*res.vehicle_true_state_history[:2], color=COLORS["muted"], lw=0.8, label="true path")
    ax.plot(*res.vehicle_state_history[:2], color=COLORS["estimate"], lw=1.0, label="estimated path (final graph)")
    ax.plot(*sc.landmarks, "+", color=COLORS["truth"], ms=9, mew=1.5, label="true landmark (id)")
    true_pos = {int(i): sc.landmarks[:, k] for k, i in enumerate(sc.landmark_ids)}
    for i, p in true_pos.items():
        ax.annotate(str(i), p, xytext=(-9, -11), textcoords="offset points", fontsize=8, color=COLORS["truth"])
    first = True
    for t in res.system.frontend.confirmed_tracks():
        p, s = np.asarray(t.vertex.estimate, dtype=float), src[t.key]
        ax.plot(*p, "o", mfc="none", color=COLORS["bound"], ms=7, mew=1.2,
                label="estimated landmark (the id it was started for)" if first else None)
        ax.annotate(str(s) if s else "clutter", p, xytext=(5, 4), textcoords="offset points", fontsize=8,
                    color=COLORS["bound"])
        if s in true_pos:
            ax.plot(*np.c_[p, true_pos[s]], ":", color=COLORS["bound"], lw=0.8)
        first = False
    _metric_axes(ax)


def plot_closure(ax, case, margin: float = 1.5):
    """The loop closure as the front-end saw it: the map's landmarks just before (open squares, labelled with
    their true ids), the re-observed landmarks placed by the drifted pose estimate (x), the pairings made (arrows:
    right in green, wrong in red), the true landmarks (+) and the vehicle (online estimate vs truth). Zoomed on
    the landmarks involved. Returns the revisits drawn: the first return of each of the first two landmarks that
    came back further than the NN gate (``revisits``)."""
    _axes(ax)
    margin = nonnegative_number(margin, "margin", "metres")
    res, rec = _kept(case, "plot_closure")
    src = true_sources(res)
    gate = nn_gate(res.config, res.system.frontend.n_sigma)
    seen = revisits(case, min_innovation=gate)
    pairs = closure_pairings(case)
    if not seen:
        ax.text(0.5, 0.5, "no landmark came back\nfurther than the NN gate", ha="center", va="center",
                transform=ax.transAxes)
        return seen
    first = seen[0]
    mapped = rec.born[first["key"]][2]
    sources = {v["source"] for v in seen[:2]}
    seen = [v for i, v in enumerate(seen) if v["source"] in sources
            and all(w["source"] != v["source"] for w in seen[:i])]            # the first return of each
    sc = res.scenario
    true_pos = {int(i): sc.landmarks[:, k] for k, i in enumerate(sc.landmark_ids)}
    pts = []
    for i, (k, p) in enumerate(_sources_at(mapped, src, sources)):
        ax.plot(*p, "s", mfc="none", color=COLORS["estimate"], ms=9, mew=1.3,
                label="map landmark just before (its id)" if i == 0 else None)
        ax.annotate(str(src[k]), p, xytext=(6, -12), textcoords="offset points", color=COLORS["estimate"])
        pts.append(p)
    for i, s in enumerate(sorted(sources)):
        ax.plot(*true_pos[s], "+", color=COLORS["truth"], ms=10, mew=1.5,
                label="true landmark (id)" if i == 0 else None)
        pts.append(true_pos[s])
    for i, v in enumerate(seen):
        ax.plot(*v["position"], "x", color=COLORS["muted"], ms=8, mew=1.5,
                label="re-observed, placed by the pose estimate (its id)" if i == 0 else None)
        ax.annotate(str(v["source"]), v["position"], xytext=(6, 4), textcoords="offset points", color=COLORS["muted"])
        pts.append(v["position"])
    done = {"right": False, "wrong": False}
    for p in pairs:
        if p["source"] not in sources:
            continue
        kind = "right" if p["right"] else "wrong"
        ax.annotate("", p["old"], p["position"], arrowprops={"arrowstyle": "->", "lw": 1.6,
                                                              "color": COLORS["alt" if p["right"] else "bound"]})
        if not done[kind]:
            ax.plot([], [], color=COLORS["alt" if p["right"] else "bound"], lw=1.6, label=f"pairing made: {kind}")
            done[kind] = True
    k = first["tick"]
    ax.plot(*rec.poses[k, :2], "^", color=COLORS["estimate"], ms=8, label="vehicle, online estimate then")
    ax.plot(*res.vehicle_true_state_history[:2, k], "^", color=COLORS["truth"], mfc="none", ms=8,
            label="vehicle, true position then")
    pts = np.array(pts + [rec.poses[k, :2], res.vehicle_true_state_history[:2, k]])
    lo, hi = pts.min(axis=0) - margin, pts.max(axis=0) + margin
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    _metric_axes(ax)
    return seen
