"""The coursework's exploration (notebook 18, Q2d): sensors, noise and the loop closure → the map, its covariance
ellipses and χ².

Model: the q2_d run (one loop of the 70 m square, the coursework's settings, seed ``seed``) stopped just **before**
the loop closure (the graph of ticks 0 … c − 1) or just **after** it (ticks 0 … c), c being the first tick at which
a landmark is seen again after at least ``min_gap`` ticks out of view. The knobs of :meth:`LoopClosureExplorer.draw`:

* ``sensors``: "laser" (odometry and laser: q2_d) or "odometry" (the same drive, the same odometry readings, the
  laser's events withheld from the SLAM system: nothing can tell it that it is back at the start);
* ``noise``: the σ scale s of the noise the sensors really add, the simulator's covariances being s²R (R the
  coursework's; the random draws are the same for every s, scaled by s); s = 0 is the noise-free q2_d run;
* ``assumed``: the σ scale a the SLAM system assumes, every edge's information being (a²R)⁻¹. Multiplying every
  information matrix by one factor 1/a² leaves the optimum where it is and multiplies H by 1/a², so the marginal
  covariances are a²·P₁ and χ² = χ²₁/a² (P₁, χ²₁: those at a = 1): one SLAM run per (sensors, noise) serves
  every a. Expected: χ² ≈ dof·(s/a)², inside its band when the graph's noise model is right (a = s);
* ``closed``: the graph after (True) or before (False) the closing tick.

χ²'s band is the central interval of χ²_dof holding probability 2Φ(4) − 1 (the 4σ band of notebook 16), with
dof = Σ edge dimensions − free state dimensions (notebook 09; 0 with odometry alone: nothing is redundant).
Cost: one run per (sensors, noise) at its first use (``run_question`` up to tick c), cached; a redraw
only draws. :meth:`LoopClosureExplorer.from_runs` adopts a notebook's own before/after runs as their entry.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ..figures import COLORS
from ..gaussian import chi2_interval, confidence_level
from ..validation import boolean, integer, nonnegative_number, one_of, positive_number, rng_seed
from . import analysis
from .config import SimulatorConfiguration
from .events import EventType
from .results import Results
from .runner import question_setup, run_question
from .simulator import DriveBotSimulator
from .slam_system import DriveBotSLAMSystem

__all__ = ["LoopClosureExplorer", "Snapshot", "SENSOR_SETS", "NOISE_SCALES", "ASSUMED_SCALES"]

#: label → value of the ``sensors`` knob
SENSOR_SETS = {"odometry + laser": "laser", "odometry only": "odometry"}
#: the knob positions of ``noise`` (σ scale of the real noise) and ``assumed`` (σ scale the SLAM system assumes)
NOISE_SCALES = (0.0, 0.5, 1.0, 2.0, 3.0)
ASSUMED_SCALES = (0.5, 1.0, 2.0, 3.0)
#: the map's fixed limits (m), so that the picture does not jump while a knob moves
MAP_LIMITS = (-25.0, 95.0)
_R0 = SimulatorConfiguration()          # the coursework's sensor covariances


@dataclass(frozen=True)
class Snapshot:
    """The optimised graph at its last vertex ``tick``, its edges assuming the σ scale ``scale``: ``path`` (K, 2)
    the estimated positions of vertices 0 … tick; ``vehicle_xy`` (M, 2), ``vehicle_P`` (M, 2, 2) the vertices with
    ellipses; ``current`` (3,), ``current_P`` (3, 3) the last vertex; ``landmark_xy`` (L, 2), ``landmark_P``
    (L, 2, 2), ``landmark_ids`` (L,); ``chi2`` and ``dof`` of the graph."""
    tick: int
    path: np.ndarray
    vehicle_xy: np.ndarray
    vehicle_P: np.ndarray
    current: np.ndarray
    current_P: np.ndarray
    landmark_xy: np.ndarray
    landmark_P: np.ndarray
    landmark_ids: np.ndarray
    chi2: float
    dof: int
    scale: float


class _WithoutLaser:
    """``run_question``'s ``setup`` for odometry only: the coursework's system, given every event but the laser's
    (the simulator still runs its laser, so its random draws, and the odometry noise, are those of the laser run)."""

    @staticmethod
    def system(config, options):
        return DriveBotSLAMSystem(config, options)

    @staticmethod
    def filter(events, simulator):
        return [e for e in events if e.type is not EventType.LANDMARK]


class LoopClosureExplorer:
    """Cached SLAM runs of q2_d around its loop closure, and :meth:`draw` for ``helpers.explore.explore``.

    ``runs`` counts the SLAM runs made, ``seconds`` {(sensors, noise): seconds of its first visit}. Vehicle
    ellipses every ``ellipse_every`` vertices from vertex 10 (and the last vertex), all of ``n_sigma`` σ."""

    def __init__(self, seed: int = 0, laser_range: float = 10.0, min_gap: int = 300, n_sigma: float = 3.0,
                 ellipse_every: int = 60) -> None:
        self.seed = rng_seed(seed)
        self.laser_range = positive_number(laser_range, "laser_range")
        self.min_gap = integer(min_gap, "min_gap", minimum=1)
        self.n_sigma = positive_number(n_sigma, "n_sigma")
        self.ellipse_every = integer(ellipse_every, "ellipse_every", minimum=1)
        self.scenario = question_setup("q2_d")[0]
        self.runs, self.seconds = 0, {}
        self._cache, self._closure, self._truth = {}, None, None

    @property
    def closure(self) -> int:
        """The closing tick c (the first re-observation after ``min_gap`` ticks), found once by the simulator."""
        if self._closure is None:
            config = question_setup("q2_d", **self._settings(0.0))[1]
            sim, last = DriveBotSimulator(config, self.scenario, seed=self.seed), {}
            sim.start()
            while sim.keep_running() and self._closure is None:
                for event in sim.events():
                    for lid in event.landmark_ids if event.type is EventType.LANDMARK else ():
                        if sim.step_number - last.get(lid, sim.step_number) >= self.min_gap:
                            self._closure = sim.step_number
                        last[lid] = sim.step_number
                sim.step()
            if self._closure is None:
                raise ValueError(f"no landmark is seen again after min_gap = {self.min_gap} ticks: no loop closure")
        return self._closure

    def _settings(self, noise: float) -> dict:
        """run_question's overrides for the real noise scale ``noise``."""
        if noise == 0:
            return {"laser_detection_range": self.laser_range, "perturb_with_noise": False}
        return {"laser_detection_range": self.laser_range, "perturb_with_noise": True,
                "r_odometry": noise ** 2 * _R0.r_odometry, "r_laser": noise ** 2 * _R0.r_laser}

    def _snapshot(self, system: DriveBotSLAMSystem, scale: float) -> Snapshot:
        """A Snapshot of ``system``'s graph as it is (optimised by the caller)."""
        graph, vv = system.graph, system.vehicle_vertices
        system.ensure_structure()
        verts = list(dict.fromkeys([vv[i] for i in range(10, self.closure, self.ellipse_every)] + [vv[-1]]))
        marg = graph.compute_marginals(verts)
        x_l, P_l, ids = system.landmark_estimates()
        return Snapshot(tick=len(vv) - 1, path=np.array([v.estimate[:2] for v in vv]),
                        vehicle_xy=np.array([v.estimate[:2] for v in verts[:-1]]).reshape(-1, 2),
                        vehicle_P=np.array([marg[v][:2, :2] for v in verts[:-1]]).reshape(-1, 2, 2),
                        current=vv[-1].estimate.copy(), current_P=marg[vv[-1]].copy(), landmark_xy=x_l.T,
                        landmark_P=np.moveaxis(P_l, 2, 0), landmark_ids=ids, chi2=system.chi2(),
                        dof=sum(len(e.measurement) for e in graph.edges()) - graph.dimension, scale=scale)

    def run(self, sensors: str = "laser", noise: float = 0.0) -> dict[str, Snapshot]:
        """{"before": Snapshot, "after": Snapshot} of (``sensors``, ``noise``): one SLAM run to the closing tick c
        at the first call (the "before" graph optimised in a step hook at tick c − 1, the run's own final
        optimisation giving "after"), the cache afterwards."""
        key = (one_of(sensors, "sensors", tuple(SENSOR_SETS.values())), nonnegative_number(noise, "noise"))
        noise = key[1]
        if key not in self._cache:
            t0, closure, snaps, scale = time.perf_counter(), self.closure, {}, noise if noise > 0 else 1.0

            def before(system, k):
                if k == closure - 1:
                    system.optimize()
                    snaps["before"] = self._snapshot(system, scale)
            res = run_question("q2_d", seed=self.seed, step_hook=before, maximum_step_number=closure + 1,
                               setup=None if sensors == "laser" else _WithoutLaser(), **self._settings(noise))
            self.runs += 1
            self._keep(key, snaps["before"], self._snapshot(res.system, scale), res)
            self.seconds[key] = time.perf_counter() - t0
        return self._cache[key]

    def _keep(self, key: tuple, before: Snapshot, after: Snapshot, res: Results) -> None:
        self._cache[key] = {"before": before, "after": after}
        if self._truth is None:
            self._truth = res.vehicle_true_state_history[:2].T.copy()

    @classmethod
    def from_runs(cls, before: Results, after: Results, seed: int = 0, **kwargs: object) -> LoopClosureExplorer:
        """An explorer whose entry (laser, 0 or 1) is the pair of q2_d runs ``before`` (stopped at tick c − 1) and
        ``after`` (at the closing tick c) made with ``run_question("q2_d", seed=seed, …)`` and the coursework's
        covariances; ``kwargs``: the other arguments of the class. ValueError when the runs do not fit."""
        for name, r in (("before", before), ("after", after)):
            if not isinstance(r, Results) or r.question != "q2_d" or r.setup is not None:
                raise ValueError(f"{name} must be the Results of run_question('q2_d', …), got {type(r).__name__}")
        ex = cls(seed, after.config.laser_detection_range, **kwargs)
        noise = 1.0 if after.config.perturb_with_noise else 0.0
        _, config, options = question_setup("q2_d", **ex._settings(noise))
        for name, r in (("before", before), ("after", after)):
            same = [np.array_equal(getattr(r.config, f), getattr(config, f)) for f in config.field_names()
                    if f != "maximum_step_number"]
            if not all(same) or r.system.options != options:
                raise ValueError(f"{name} must use q2_d's settings (only laser_detection_range and "
                                 "perturb_with_noise changed)")
        closure, _ = analysis.find_loop_closure(*analysis.landmark_observations(after.system), min_gap=ex.min_gap)
        if closure is None or after.n_steps != closure + 1 or before.n_steps != closure:
            raise ValueError(f"after must end at the loop-closing tick ({closure}) and before one tick earlier; got "
                             f"last ticks {before.n_steps - 1} and {after.n_steps - 1}")
        ex._closure = closure
        ex._keep(("laser", noise), ex._snapshot(before.system, 1.0), ex._snapshot(after.system, 1.0), after)
        return ex

    def draw(self, fig: Figure, sensors: str = "laser", noise: float = 0.0, assumed: float = 1.0,
             closed: bool = False) -> dict:
        """Draw the map (truth, estimated path, landmark and vehicle ellipses) and χ²/dof against its band on
        ``fig``. Returns {"tick", "chi2", "dof", "band", "sigma" (σx, σy, σψ of the last vertex)}."""
        if not isinstance(fig, Figure):
            raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
        assumed, closed = positive_number(assumed, "assumed"), boolean(closed, "closed")
        snap = self.run(sensors, noise)["after" if closed else "before"]
        k = (assumed / snap.scale) ** 2                  # covariances × k, χ² / k (module docstring)
        chi2 = snap.chi2 / k
        band = chi2_interval(snap.dof, confidence_level(4.0)) if snap.dof > 0 else (0.0, 0.0)
        ax, axc = fig.subplots(1, 2, gridspec_kw={"width_ratios": [3.0, 1.0]})
        self._draw_map(ax, snap, k)
        _draw_chi2(axc, chi2, snap.dof, band)
        sigma = np.sqrt(k * np.diag(snap.current_P))
        when = f"just {'after' if closed else 'before'} {'the loop closure at ' if sensors == 'laser' else ''}" \
               f"tick {self.closure}{'' if sensors == 'laser' else ' (where the laser closes the loop)'}"
        ax.set_title(f"{when}\ncurrent vehicle: σx {sigma[0]:.2f} m, σy {sigma[1]:.2f} m, "
                     f"σψ {np.degrees(sigma[2]):.1f}°", fontsize=9.5)
        fig.suptitle(f"q2_d, {next(n for n, v in SENSOR_SETS.items() if v == sensors)}: real noise ×{noise:g}, "
                     f"assumed ×{assumed:g}", fontsize=11)
        fig.subplots_adjust(left=0.09, right=0.97, bottom=0.2, top=0.85, wspace=0.4)
        return {"tick": snap.tick, "chi2": chi2, "dof": snap.dof, "band": band, "sigma": sigma}

    def _draw_map(self, ax, snap: Snapshot, k: float) -> None:
        """The map of ``snap`` with its covariances multiplied by ``k``."""
        c_veh, c_lm, c_now = COLORS["estimate"], COLORS["alt"], COLORS["bound"]
        truth = self._truth[: snap.tick + 1]
        ax.plot(*truth.T, color=COLORS["truth"], lw=0.8, alpha=0.5)
        ax.plot(*snap.path.T, color=c_veh, lw=1.0)
        ax.plot(*self.scenario.landmarks, "+", color=COLORS["truth"], ms=8)
        ellipses = ((snap.vehicle_xy, snap.vehicle_P, c_veh, 0.8, "vehicle"),
                    (snap.landmark_xy, snap.landmark_P, c_lm, 1.2, "landmarks"),
                    (snap.current[None, :2], snap.current_P[None, :2, :2], c_now, 1.6, "current"))
        for xy, P, colour, lw, gid in ellipses:
            if len(xy):
                analysis.plot_covariance_ellipses(ax, xy, k * P, self.n_sigma, edgecolor=colour, lw=lw, gid=gid)
        ax.plot(*snap.current[:2], "o", color=c_now, ms=4)
        ax.set(xlim=MAP_LIMITS, ylim=MAP_LIMITS, aspect="equal", xlabel="x (m)", ylabel="y (m)")
        marker = {"marker": "o", "mfc": "none", "ls": "none", "ms": 9}
        handles = [Line2D([], [], color=COLORS["truth"], lw=0.8, alpha=0.5, label="true path"),
                   Line2D([], [], color=c_veh, lw=1, label="estimated path"),
                   Line2D([], [], color=c_veh, **marker, label=f"vehicle, every {self.ellipse_every} ticks"),
                   Line2D([], [], color=c_lm, **marker, label="landmark"),
                   Line2D([], [], color=c_now, **marker, label="current vehicle"),
                   Line2D([], [], color=COLORS["truth"], marker="+", ls="none", ms=8, label="true landmark")]
        ax.figure.legend(handles=handles, loc="lower center", ncol=3, fontsize=8, frameon=False,
                         title=f"{self.n_sigma:g}σ ellipses", title_fontsize=8)


def _draw_chi2(ax, chi2: float, dof: int, band: tuple[float, float]) -> None:
    """χ²/dof (a dot; a triangle at the bottom edge when below it) against the 4σ band, on a log scale (drawn as
    log₁₀ on a linear axis with plain tick labels: a log axis's labels cost a third of a redraw)."""
    lo, hi = -2.0, 2.0
    ax.set(ylim=(lo, hi), xlim=(-1, 1), xticks=[], yticks=np.arange(lo, hi + 1), ylabel="χ² / dof (log scale)",
           yticklabels=["0.01", "0.1", "1", "10", "100"])
    ax.set_title("χ² of the graph", fontsize=9.5)
    if dof <= 0:
        ax.text(0, 0, "dof = 0:\nnothing is\nredundant,\nχ² = 0", ha="center", va="center", fontsize=8.5)
        return
    ax.axhspan(*np.log10(np.divide(band, dof)), color="0.85", lw=0)
    ax.axhline(0.0, color=COLORS["muted"], lw=0.8, ls=":")
    y = np.log10(chi2 / dof) if chi2 > 0 else -np.inf
    ax.plot(0, min(max(y, lo + 0.06), hi - 0.06), "v" if y < lo else "o", color=COLORS["bound"], ms=8)
    inside = band[0] <= chi2 <= band[1]
    value = f"χ² = {chi2:.4g}" if chi2 > 1e-6 * dof else "χ² ≈ 0"
    ax.text(0, -1.5 if y > -0.3 else 1.5, f"{value}\ndof = {dof}\n{'in' if inside else 'outside'} the\n"
            "4σ band (grey)", ha="center", va="center", fontsize=8.5)
