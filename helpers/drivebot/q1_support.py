"""Support for the Q1 notebooks (10–14): χ² acceptance intervals and the online (filtered) vehicle estimate.

``chi2_interval(dof, probability)`` is the central interval that holds χ² of a consistent graph with the given
probability, from the χ² distribution's quantiles (``helpers.gaussian.chi2inv``), not from the Gaussian
approximation dof ± k√(2 dof), which goes negative for small dof and is lopsided for moderate dof.

``jacobian_error(edge)`` compares an edge's analytic Jacobians with central differences through each vertex's ⊞.

``OnlineEstimate`` is a ``step_hook`` for ``run_question``: after every tick it records the estimate of the
newest vehicle vertex as the graph held it *then* (after that tick's optimisation, if one was due). That is
the estimate an online system would have reported at that moment — it uses only the measurements received
so far — while ``Results.vehicle_state_history`` holds the smoothed estimates of the final graph, which use
every measurement of the run, including those received long after each pose.
"""
from __future__ import annotations

import numbers

import numpy as np

from ..gaussian import chi2_interval  # re-exported: the notebooks import it from here

__all__ = ["chi2_interval", "OnlineEstimate", "fraction_inside", "jacobian_error"]


class OnlineEstimate:
    """``step_hook(system, k)`` that records, per tick, the newest vehicle vertex's time and estimate.

    After the run: ``time`` (N,) and ``state`` (3×N) — the online (filtered) estimate of the pose at each tick.
    """

    def __init__(self):
        self._t: list[float] = []
        self._x: list[np.ndarray] = []

    def __call__(self, system, k) -> None:
        vertex = getattr(system, "current_vehicle_vertex", None)
        if vertex is None:
            raise ValueError("system must be a DriveBotSLAMSystem with a current vehicle vertex")
        self._t.append(float(vertex.time))
        self._x.append(np.array(vertex.estimate, dtype=float))

    @property
    def time(self) -> np.ndarray:
        return np.array(self._t)

    @property
    def state(self) -> np.ndarray:
        return np.array(self._x).reshape(-1, 3).T


def fraction_inside(err, variance, n_sigma: float = 2.0) -> np.ndarray:
    """Per row, the fraction of columns with |err| ≤ n_σ·σ, over the columns whose variance is positive.

    ``err`` and ``variance`` are (d, N) arrays (e.g. ``Results.state_error()`` and
    ``Results.vehicle_covariance_history``); columns with zero variance (the fixed first pose) or NaN are left out;
    a negative variance raises ValueError.
    """
    err = np.asarray(err, dtype=float)
    variance = np.asarray(variance, dtype=float)
    if err.ndim != 2 or err.shape != variance.shape:
        raise ValueError(f"err and variance must be (d, N) arrays of one shape, got {err.shape} and {variance.shape}")
    if isinstance(n_sigma, bool) or not isinstance(n_sigma, numbers.Real) or not n_sigma > 0:
        raise ValueError(f"n_sigma must be a positive number, got {n_sigma!r}")
    if np.any(variance < 0):
        raise ValueError("variance must not be negative (NaN marks a missing value)")
    out = np.empty(err.shape[0])
    for i in range(err.shape[0]):
        use = np.isfinite(err[i]) & np.isfinite(variance[i]) & (variance[i] > 0)
        if not np.any(use):
            raise ValueError(f"row {i} of variance has no positive finite entry")
        out[i] = np.mean(np.abs(err[i, use]) <= n_sigma * np.sqrt(variance[i, use]))
    return out


def jacobian_error(edge, eps: float = 1e-6) -> float:
    """max |J_analytic − J_numeric| over the edge's vertices; J_numeric by central differences of e(x ⊞ ±ε·e_d).

    Every vertex's estimate is restored afterwards. ``edge`` is any ``helpers.graph`` edge whose vertices are set.
    """
    if not (hasattr(edge, "jacobians") and hasattr(edge, "vertices") and hasattr(edge, "error")):
        raise ValueError(f"edge must be a helpers.graph edge, got {type(edge).__name__}")
    if isinstance(eps, bool) or not isinstance(eps, numbers.Real) or not 0 < eps < 1e-2:
        raise ValueError(f"eps must be a small positive step (0 < eps < 1e-2), got {eps!r}")
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
