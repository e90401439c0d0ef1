"""Support for the Q1 notebooks (10–14): χ² acceptance intervals and the online (filtered) vehicle estimate.

``chi2_interval(dof, probability)``: the central interval holding χ² of a consistent graph with that probability.
``OnlineEstimate`` is a ``step_hook`` for ``run_question`` recording, after every tick, the estimate of the newest
vehicle vertex as the graph held it *then*: what an online system would have reported, from the measurements so
far, while ``Results.vehicle_state_history`` holds the smoothed estimates of the final graph.
"""
from __future__ import annotations

import numpy as np

from ..gaussian import chi2_interval  # re-exported: the notebooks import it from here
from ..validation import positive_number

__all__ = ["chi2_interval", "OnlineEstimate", "fraction_inside", "jacobian_error"]


class OnlineEstimate:
    """``step_hook(system, k)`` that records, per tick, the newest vehicle vertex's time and estimate.

    After the run: ``time`` (N,) and ``state`` (3×N) — the online (filtered) estimate of the pose at each tick.
    """

    def __init__(self) -> None:
        self._t: list[float] = []
        self._x: list[np.ndarray] = []

    def __call__(self, system: object, k: int) -> None:
        vertex = system.current_vehicle_vertex
        self._t.append(float(vertex.time))
        self._x.append(np.array(vertex.estimate, dtype=float))

    @property
    def time(self) -> np.ndarray:
        """(N,) times of the recorded ticks."""
        return np.array(self._t)

    @property
    def state(self) -> np.ndarray:
        """(3, N) online estimates."""
        return np.array(self._x).reshape(-1, 3).T


def fraction_inside(err: np.ndarray, variance: np.ndarray, n_sigma: float = 2.0) -> np.ndarray:
    """Per row, the fraction of columns with |err| ≤ n_σ·σ, over the columns whose variance is positive.

    ``err`` and ``variance`` are (d, N) arrays (e.g. ``Results.state_error()`` and
    ``Results.vehicle_covariance_history``); columns with zero variance (the fixed first pose) or NaN are left out;
    a negative variance raises ValueError.
    """
    err, variance = np.asarray(err, dtype=float), np.asarray(variance, dtype=float)
    n_sigma = positive_number(n_sigma, "n_sigma")
    if np.any(variance < 0):
        raise ValueError("variance must not be negative (NaN marks a missing value)")
    use = np.isfinite(err) & np.isfinite(variance) & (variance > 0)
    if not np.all(np.any(use, axis=1)):
        raise ValueError("every row of variance needs a positive finite entry")
    inside = use & (np.abs(err) <= n_sigma * np.sqrt(np.where(use, variance, 0.0)))
    return np.sum(inside, axis=1) / np.sum(use, axis=1)


def jacobian_error(edge: object, eps: float = 1e-6) -> float:
    """max |J_analytic − J_numeric| over the edge's vertices; J_numeric by central differences of e(x ⊞ ±ε·e_d).

    Every vertex's estimate is restored afterwards. ``edge`` is any ``helpers.graph`` edge whose vertices are set.
    """
    eps = positive_number(eps, "eps")
    analytic = edge.jacobians()
    worst = 0.0
    for vertex, jac in zip(edge.vertices(), analytic):
        start = np.array(vertex.estimate, dtype=float)
        numeric = np.empty_like(jac)
        for d in range(vertex.dimension):
            step = np.zeros(vertex.dimension)
            step[d] = eps
            try:
                vertex.oplus(step)
                e_plus = edge.error()
                vertex.set_estimate(start)
                vertex.oplus(-step)
                e_minus = edge.error()
            finally:
                vertex.set_estimate(start)
            numeric[:, d] = (e_plus - e_minus) / (2 * eps)
        worst = max(worst, float(np.max(np.abs(numeric - jac))))
    return worst
