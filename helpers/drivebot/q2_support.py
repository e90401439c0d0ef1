"""Support for the Q2 notebooks (15–19): facts about a run computed from its observation events.

* ``no_observation_intervals`` — the stretches of ticks in which no landmark was observed (the "nothing in
  range" bands of the covariance and χ² plots), computed from the observation ticks, never typed in. A single
  tick without an observation is the laser's timing dither (each scan comes 0.1 s + U(0, 0.01) s after the
  previous one, so about one tick in 20 has no scan), not an empty view; ``min_ticks`` = 2 skips those.
* ``shade_intervals`` — draw such intervals as grey bands on time axes; ``mark_gaps_and_closure`` draws them
  and the loop-closure time on every axis of a figure.
* ``landmark_facts`` — per landmark: position, nearest route corner and its distance, number of observations,
  first/last observing tick and the vehicle's mean true speed while observing it.
* ``OnlineRecorder`` — a ``step_hook`` for ``run_question`` that records the *online* (filtered) marginal
  variances of the newest vehicle vertex — what the system knew at that tick — as opposed to the smoothed
  histories from the final graph, plus the size of the LDLᵀ factor after each optimisation.
* ``mean_rate`` — mean slope dy/dt over the samples selected by a mask (e.g. variance growth in the gaps).
"""
from __future__ import annotations

import numbers

import numpy as np

from ..figures import COLORS
from ..validation import int_array, integer
from .runner import Results

__all__ = ["no_observation_intervals", "interval_mask", "shade_intervals", "mark_gaps_and_closure",
           "landmark_facts", "OnlineRecorder",
           "mean_rate", "waypoint_ticks"]






def _check_results(results):
    if not isinstance(results, Results):
        raise ValueError(f"results must be a Results (from run_question), got {type(results).__name__}")


def _intervals(intervals) -> np.ndarray:
    """Inclusive tick intervals as a (K, 2) int64 array with first ≤ last (one pair [first, last] is K = 1)."""
    iv = np.asarray(intervals)
    if iv.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if iv.shape == (2,):
        iv = iv[None]
    if iv.ndim != 2 or iv.shape[1] != 2:
        raise ValueError(f"intervals must have shape (K, 2), got {iv.shape}")
    if iv.dtype == bool or not np.issubdtype(iv.dtype, np.integer):
        raise ValueError(f"intervals must hold integer ticks, got dtype {iv.dtype}")
    if np.any(iv[:, 0] > iv[:, 1]):
        raise ValueError(f"intervals must have first ≤ last in every row, got {iv.tolist()}")
    return iv.astype(np.int64)


def no_observation_intervals(tick, n_steps, min_ticks=2) -> np.ndarray:
    """Inclusive [first, last] tick ranges (K, 2) of at least ``min_ticks`` consecutive ticks without any
    landmark observation, among ticks 0 … n_steps − 1. ``tick`` (E,) is the tick of every observation."""
    tick = int_array(tick, "tick")
    n_steps = integer(n_steps, "n_steps", minimum=1)
    min_ticks = integer(min_ticks, "min_ticks", minimum=1)
    if tick.size and (tick.min() < 0 or tick.max() >= n_steps):
        raise ValueError(f"tick values must lie in [0, n_steps) = [0, {n_steps}), got [{tick.min()}, {tick.max()}]")
    empty = np.ones(n_steps, dtype=np.int8)
    empty[tick] = 0
    edges = np.diff(np.r_[0, empty, 0])
    first = np.flatnonzero(edges == 1)
    last = np.flatnonzero(edges == -1) - 1
    keep = last - first + 1 >= min_ticks
    return np.column_stack([first[keep], last[keep]]).astype(np.int64).reshape(-1, 2)


def interval_mask(ticks, intervals) -> np.ndarray:
    """Boolean mask: which of ``ticks`` lie inside one of the inclusive ``intervals`` (K, 2)."""
    ticks = int_array(ticks, "ticks")
    iv = _intervals(intervals)
    if iv.size == 0:
        return np.zeros(ticks.shape, bool)
    return np.any((ticks[:, None] >= iv[None, :, 0]) & (ticks[:, None] <= iv[None, :, 1]), axis=1)


def shade_intervals(ax, intervals, dt, label=None, color="0.85"):
    """Grey bands on a time axis for tick intervals (K, 2): from t = dt·first to t = dt·(last + 1), so that
    a band covers its ticks. ``label`` names the first band only (for a legend)."""
    if not hasattr(ax, "axvspan"):
        raise ValueError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
    if isinstance(dt, bool) or not isinstance(dt, numbers.Real) or not dt > 0:
        raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
    iv = _intervals(intervals)
    for i, (a, b) in enumerate(iv):
        ax.axvspan(dt * a, dt * (b + 1), color=color, lw=0, zorder=0, label=label if i == 0 else None)


def mark_gaps_and_closure(axes, intervals, dt, closure=None, color=None):
    """On each axis of ``axes``: the no-observation ``intervals`` as grey bands (labelled "no landmark in
    range") and, if ``closure`` (a tick) is not None, a dotted vertical line at its time ("loop closure")."""
    color = COLORS["muted"] if color is None else color
    if closure is not None:
        closure = integer(closure, "closure (a tick)", minimum=0)
    for ax in np.ravel(axes):
        shade_intervals(ax, intervals, dt, label="no landmark in range")
        if closure is not None:
            ax.axvline(dt * closure, color=color, ls=":", lw=1.2, label="loop closure")


def landmark_facts(results, tick, landmark) -> dict:
    """Facts about every observed landmark of a run, in ascending id order.

    Returns arrays {"id", "xy" (L, 2), "corner" (L, 2) nearest route corner (start or waypoint),
    "corner_distance", "n_obs", "first_tick", "last_tick", "mean_speed"} — mean_speed is the vehicle's mean
    true speed (m/s) over the ticks at which it observed the landmark."""
    _check_results(results)
    tick = int_array(tick, "tick")
    landmark = int_array(landmark, "landmark")
    if tick.shape != landmark.shape:
        raise ValueError(f"tick and landmark must have the same shape, got {tick.shape} and {landmark.shape}")
    sc = results.scenario
    truth = np.asarray(results.vehicle_true_state_history, dtype=float)[:2]
    if tick.size and (tick.min() < 0 or tick.max() >= truth.shape[1]):
        raise ValueError(f"tick values must lie in [0, {truth.shape[1]}) (the run's ticks), got "
                         f"[{tick.min()}, {tick.max()}]")
    dt = float(results.config.dt)
    speed = np.r_[0.0, np.linalg.norm(np.diff(truth, axis=1), axis=0) / dt]
    corners = np.vstack([[0.0, 0.0], np.asarray(sc.waypoints, dtype=float).T])
    corners = np.unique(corners, axis=0)
    ids = np.unique(landmark)
    col = {int(i): k for k, i in enumerate(np.asarray(sc.landmark_ids).tolist())}
    missing = [int(i) for i in ids if int(i) not in col]
    if missing:
        raise ValueError(f"landmark ids {missing} are not in the scenario")
    xy = np.array([sc.landmarks[:, col[int(i)]] for i in ids], dtype=float).reshape(-1, 2)
    d = np.linalg.norm(xy[:, None, :] - corners[None], axis=2)
    nearest = np.argmin(d, axis=1) if ids.size else np.zeros(0, int)
    out = {"id": ids, "xy": xy, "corner": corners[nearest], "corner_distance": d[np.arange(ids.size), nearest],
           "n_obs": np.array([np.sum(landmark == i) for i in ids], dtype=np.int64),
           "first_tick": np.array([tick[landmark == i].min() for i in ids], dtype=np.int64),
           "last_tick": np.array([tick[landmark == i].max() for i in ids], dtype=np.int64),
           "mean_speed": np.array([speed[tick[landmark == i]].mean() for i in ids])}
    return out


class OnlineRecorder:
    """``step_hook`` for run_question: the online marginal variances of the newest vehicle vertex.

    Every ``every`` ticks (after tick k whose batch count ``system.step_number`` = k + 1 is a multiple of
    ``every`` — the same rule as the optimisation period, so with ``every`` a multiple of the period the
    records fall on optimised ticks and need no extra structure build) it stores the diagonal of the current vertex's
    marginal covariance given the graph *as it is at that tick* (after that tick's optimisation, if one
    ran) — the filtered estimate, which uses no later measurement. After every optimisation it also stores
    the number of non-zeros of the LDLᵀ factor of H (``factor_nnz``: {tick: nnz}), which shows fill-in.
    """

    def __init__(self, every=10):
        self.every = integer(every, "every", minimum=1)
        self._ticks, self._var = [], []
        self.factor_nnz = {}

    def __call__(self, system, k):
        if not all(hasattr(system, a) for a in ("recommend_optimization", "graph", "platform_estimate")):
            raise ValueError(f"system must be a DriveBotSLAMSystem, got {type(system).__name__}")
        k = integer(k, "k", minimum=0)
        optimised = system.recommend_optimization()
        if optimised:
            if system.graph.factor is not None:          # the LDLᵀ factor of the last optimisation
                self.factor_nnz[int(k)] = int(system.graph.factor.factors()[0].nnz)
        if system.step_number % self.every == 0:
            _, P = system.platform_estimate()
            self._ticks.append(int(k))
            self._var.append(np.diag(P).copy())

    @property
    def ticks(self) -> np.ndarray:
        return np.array(self._ticks, dtype=np.int64)

    @property
    def variances(self) -> np.ndarray:
        """(3, K) online variances P_xx, P_yy, P_ψψ at ``ticks``."""
        return np.array(self._var, dtype=float).reshape(-1, 3).T


def mean_rate(t, y, mask) -> float:
    """Mean of Δy/Δt over consecutive samples that are both selected by ``mask`` (NaN if there is none)."""
    t = np.asarray(t, dtype=float)
    y = np.asarray(y, dtype=float)
    mask = np.asarray(mask)
    if t.ndim != 1 or y.shape != t.shape or mask.shape != t.shape or mask.dtype != bool:
        raise ValueError(f"t, y and mask must be 1-D of equal length (mask boolean), got {t.shape}, {y.shape}, "
                         f"{mask.shape} {mask.dtype}")
    if not (np.all(np.isfinite(t[mask])) and np.all(np.isfinite(y[mask]))):
        raise ValueError("t and y must be finite where mask selects them")
    pair = mask[1:] & mask[:-1]
    dt = np.diff(t)[pair]
    if dt.size == 0:
        return float("nan")
    if np.any(dt <= 0):
        raise ValueError("t must be strictly increasing")
    return float(np.mean(np.diff(y)[pair] / dt))


def waypoint_ticks(results, radius=1.0) -> np.ndarray:
    """The first tick at which the true vehicle comes within ``radius`` m of each waypoint in turn (the
    controller switches to the next waypoint there); waypoints not reached in the run are left out."""
    if isinstance(radius, bool) or not isinstance(radius, numbers.Real) or not radius > 0:
        raise ValueError(f"radius must be a positive number of metres, got {radius!r}")
    _check_results(results)
    p = np.asarray(results.vehicle_true_state_history, dtype=float)[:2].T
    out, start = [], 0
    for w in np.asarray(results.scenario.waypoints, dtype=float).T:
        near = np.flatnonzero(np.linalg.norm(p[start:] - w, axis=1) < radius)
        if near.size == 0:
            break
        start += int(near[0])
        out.append(start)
    return np.array(out, dtype=np.int64)
