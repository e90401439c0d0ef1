"""Support for the Q2 notebooks (15–19): facts about a run computed from its observation events.

``no_observation_intervals`` finds the stretches of ticks without a landmark observation (a single empty tick is
the laser's timing dither, so ``min_ticks`` = 2 skips those) and ``mark_gaps_and_closure`` draws them;
``OnlineRecorder`` records the *online* (filtered) variances of the newest vehicle vertex during a run.
"""
from __future__ import annotations

import numpy as np

from ..figures import COLORS
from ..validation import int_array, integer, positive_number
from .results import Results

__all__ = ["no_observation_intervals", "interval_mask", "mark_gaps_and_closure",
           "landmark_facts", "OnlineRecorder", "mean_rate", "waypoint_ticks"]


def _intervals(intervals) -> np.ndarray:
    """Inclusive tick intervals [first, last] as a (K, 2) int64 array with first ≤ last."""
    iv = int_array(np.ravel(intervals), "intervals")
    if iv.size % 2 or np.ndim(intervals) > 2 or np.any(iv[0::2] > iv[1::2]):
        raise ValueError(f"intervals must be (K, 2) integer ticks [first, last] with first ≤ last, got {intervals!r}")
    return iv.reshape(-1, 2)


def no_observation_intervals(tick: np.ndarray, n_steps: int, min_ticks: int = 2) -> np.ndarray:
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


def interval_mask(ticks: np.ndarray, intervals: np.ndarray) -> np.ndarray:
    """Boolean mask: which of ``ticks`` lie inside one of the inclusive ``intervals`` (K, 2)."""
    ticks, iv = int_array(ticks, "ticks"), _intervals(intervals)
    return np.any((ticks[:, None] >= iv[None, :, 0]) & (ticks[:, None] <= iv[None, :, 1]), axis=1)


def mark_gaps_and_closure(axes: object, intervals: np.ndarray, dt: float, closure: int | None = None,
                          color: str | None = None) -> None:
    """On each axis of ``axes``: the no-observation tick ``intervals`` (K, 2) as grey bands from t = dt·first to
    dt·(last + 1) (the first labelled "no landmark in range") and, if ``closure`` (a tick) is not None, a dotted
    vertical line at its time ("loop closure")."""
    color = COLORS["muted"] if color is None else color
    dt, intervals = positive_number(dt, "dt"), _intervals(intervals)
    if closure is not None:
        closure = integer(closure, "closure (a tick)", minimum=0)
    for ax in np.ravel(axes):
        for i, (a, b) in enumerate(intervals):
            label = "no landmark in range" if i == 0 else None
            ax.axvspan(dt * a, dt * (b + 1), color="0.85", lw=0, zorder=0, label=label)
        if closure is not None:
            ax.axvline(dt * closure, color=color, ls=":", lw=1.2, label="loop closure")


def landmark_facts(results: Results, tick: np.ndarray, landmark: np.ndarray) -> dict:
    """Facts about every observed landmark of a run, in ascending id order.

    Returns arrays {"id", "xy" (L, 2), "corner" (L, 2) nearest route corner (start or waypoint),
    "corner_distance", "n_obs", "first_tick", "last_tick", "mean_speed"} — mean_speed is the vehicle's mean
    true speed (m/s) over the ticks at which it observed the landmark."""
    tick, landmark = int_array(tick, "tick"), int_array(landmark, "landmark")
    sc = results.scenario
    truth = results.vehicle_true_state_history[:2]
    if tick.shape != landmark.shape or (tick.size and (tick.min() < 0 or tick.max() >= truth.shape[1])):
        raise ValueError(f"tick and landmark must have one shape and tick lie in [0, {truth.shape[1]}) (the run's "
                         f"ticks), got shapes {tick.shape} and {landmark.shape}")
    speed = np.r_[0.0, np.linalg.norm(np.diff(truth, axis=1), axis=0) / results.config.dt]
    corners = np.unique(np.vstack([[0.0, 0.0], sc.waypoints.T]), axis=0)
    ids = np.unique(landmark)
    xy = sc.landmarks[:, np.searchsorted(sc.landmark_ids, ids)].T.reshape(-1, 2)
    d = np.linalg.norm(xy[:, None, :] - corners[None], axis=2)
    nearest = np.argmin(d, axis=1) if ids.size else np.zeros(0, int)
    return {"id": ids, "xy": xy, "corner": corners[nearest], "corner_distance": d[np.arange(ids.size), nearest],
            "n_obs": np.array([np.sum(landmark == i) for i in ids], dtype=np.int64),
            "first_tick": np.array([tick[landmark == i].min() for i in ids], dtype=np.int64),
            "last_tick": np.array([tick[landmark == i].max() for i in ids], dtype=np.int64),
            "mean_speed": np.array([speed[tick[landmark == i]].mean() for i in ids])}


class OnlineRecorder:
    """``step_hook`` for run_question: the online marginal variances of the newest vehicle vertex.

    When ``system.step_number`` is a multiple of ``every`` (the rule of the optimisation period) it stores the
    diagonal of the current vertex's marginal covariance given the graph *as it is at that tick*: the filtered
    estimate. After every optimisation it stores the non-zeros of the LDLᵀ factor of H (``factor_nnz``: {tick: nnz}).
    """

    def __init__(self, every: int = 10):
        self.every = integer(every, "every", minimum=1)
        self._ticks, self._var = [], []
        self.factor_nnz = {}

    def __call__(self, system: object, k: int) -> None:
        if system.recommend_optimization() and system.graph.factor is not None:   # the last optimisation's LDLᵀ
            self.factor_nnz[int(k)] = int(system.graph.factor.factors()[0].nnz)
        if system.step_number % self.every == 0:
            _, P = system.platform_estimate()
            self._ticks.append(int(k))
            self._var.append(np.diag(P).copy())

    @property
    def ticks(self) -> np.ndarray:
        """(K,) the recorded ticks."""
        return np.array(self._ticks, dtype=np.int64)

    @property
    def variances(self) -> np.ndarray:
        """(3, K) online variances P_xx, P_yy, P_ψψ at ``ticks``."""
        return np.array(self._var, dtype=float).reshape(-1, 3).T


def mean_rate(t: np.ndarray, y: np.ndarray, mask: np.ndarray) -> float:
    """Mean of Δy/Δt over consecutive samples that are both selected by ``mask`` (NaN if there is none)."""
    t, y, mask = np.asarray(t, dtype=float), np.asarray(y, dtype=float), np.asarray(mask, dtype=bool)
    pair = mask[1:] & mask[:-1]
    dt = np.diff(t)[pair]
    if dt.size == 0:
        return float("nan")
    if not (np.all(dt > 0) and np.all(np.isfinite(y[1:][pair])) and np.all(np.isfinite(y[:-1][pair]))):
        raise ValueError("t and y must be finite where mask selects them, and t strictly increasing")
    return float(np.mean(np.diff(y)[pair] / dt))


def waypoint_ticks(results: Results, radius: float = 1.0) -> np.ndarray:
    """The first tick at which the true vehicle comes within ``radius`` m of each waypoint in turn (the
    controller switches to the next waypoint there); waypoints not reached in the run are left out."""
    radius = positive_number(radius, "radius")
    p = results.vehicle_true_state_history[:2].T
    out, start = [], 0
    for w in results.scenario.waypoints.T:
        near = np.flatnonzero(np.linalg.norm(p[start:] - w, axis=1) < radius)
        if near.size == 0:
            break
        start += int(near[0])
        out.append(start)
    return np.array(out, dtype=np.int64)
