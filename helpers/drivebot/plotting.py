"""Figures for the DriveBot notebooks: the factor graph of a (small) run, state errors and covariances.

``draw_factor_graph(system, ax)`` lays the graph out by time: vehicle vertices (circles) on a horizontal
line at x = their index, kinematics factors (squares) between consecutive vertices, unary factors above
(compass) and below (GPS) their vertex, landmark vertices in a top row above the mean index of the poses
that observe them with a range-bearing factor on each link. Every element is read from ``system.graph``,
so the picture is the real graph, not a sketch.

``plot_wrapped_angle(ax, t, angle)`` draws a wrapped angle as a line broken wherever it wraps round (a gap, not
a vertical stroke across the whole axis).
"""
from __future__ import annotations

import numpy as np

from ..graph import EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing
from ..validation import float_array, positive_number
from .edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex

__all__ = ["draw_factor_graph", "plot_state_errors", "plot_covariances", "plot_wrapped_angle"]

_STYLE = {
    VehicleKinematicsEdge: ("kinematics edge (odometry)", "#1f77b4", 0.0),
    EdgeHeadingPrior: ("compass edge", "#2ca02c", 1.0),
    BuggyCompassEdge: ("compass edge (buggy)", "#2ca02c", 1.0),
    EdgePositionPrior: ("GPS edge (lever arm)", "#d62728", -1.0),
    EdgeRangeBearing: ("range-bearing edge", "#9467bd", None),
}


def draw_factor_graph(system: object, ax: object, title: str | None = None) -> None:
    """Draw ``system.graph`` (a DriveBotSLAMSystem) on ``ax``; see the module docstring for the layout."""
    verts = system.graph.vertices()
    pos = {}
    vehicles = [v for v in verts if isinstance(v, VehicleVertex)]
    for v in vehicles:
        pos[v] = (float(v.id), 0.0)
    for v in verts:
        if isinstance(v, LandmarkVertex):
            obs = [e.vertex(0).id for e in v.edges()]
            pos[v] = (float(np.mean(obs)) if obs else 0.0, 2.5)
    seen = set()
    for e in system.graph.edges():
        label, color, dy = _STYLE.get(type(e), (type(e).__name__, "#7f7f7f", 1.5))
        lab = label if label not in seen else None
        seen.add(label)
        vs = e.vertices()
        if len(vs) == 1:
            x0, y0 = pos[vs[0]]
            fx, fy = x0, y0 + 0.8 * dy
            ax.plot([x0, fx], [y0, fy], color=color, lw=0.8, zorder=1)
        else:
            (x0, y0), (x1, y1) = pos[vs[0]], pos[vs[1]]
            fx, fy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
            ax.plot([x0, x1], [y0, y1], color=color, lw=0.8, zorder=1)
        ax.scatter([fx], [fy], marker="s", s=28, color=color, zorder=3, label=lab)
    fixed = [pos[v] for v in vehicles if v.fixed]
    free = [pos[v] for v in vehicles if not v.fixed]
    if free:
        ax.scatter(*np.array(free).T, s=70, facecolor="white", edgecolor="k", zorder=4, label="vehicle vertex")
    if fixed:
        ax.scatter(*np.array(fixed).T, s=70, facecolor="k", edgecolor="k", zorder=4, label="vehicle vertex (fixed)")
    lms = [pos[v] for v in verts if isinstance(v, LandmarkVertex)]
    if lms:
        ax.scatter(*np.array(lms).T, s=90, marker="*", color="#ff7f0e", zorder=4, label="landmark vertex")
    ax.set_xlabel("vehicle vertex index k (one per 0.1 s tick)")
    ax.set_yticks([])
    ax.grid(False)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0))
    if title:
        ax.set_title(title)


def plot_state_errors(results: object, axes: list, n_sigma: float = 2.0, label: str | None = None) -> None:
    """Estimate − truth for x, y, ψ (ψ wrapped) with ±n_σ bounds from the covariance history, on 3 axes
    (``results``: a Results from run_question)."""
    n_sigma = positive_number(n_sigma, "n_sigma")
    t = results.vehicle_state_time
    err = results.state_error()
    sig = n_sigma * np.sqrt(results.vehicle_covariance_history)
    names = ["x error (m)", "y error (m)", "ψ error (rad)"]
    for i, ax in enumerate(axes):
        ax.plot(t, err[i], lw=1.0, label=label or "estimate − truth")
        ax.plot(t, sig[i], color="#d62728", lw=0.8, ls="--", label=f"±{n_sigma:g}σ")
        ax.plot(t, -sig[i], color="#d62728", lw=0.8, ls="--")
        ax.set_ylabel(names[i])
    axes[-1].set_xlabel("time (s)")
    axes[0].legend(loc="lower left", bbox_to_anchor=(0.0, 1.0), ncol=2)  # above the data, covering none of it


def plot_covariances(results: object, axes: list, label: str | None = None) -> None:
    """The marginal variances P_xx, P_yy, P_ψψ of a Results against time, on 3 axes."""
    t = results.vehicle_state_time
    names = ["P_xx (m²)", "P_yy (m²)", "P_ψψ (rad²)"]
    for i, ax in enumerate(axes):
        ax.plot(t, results.vehicle_covariance_history[i], lw=1.0, label=label)
        ax.set_ylabel(names[i])
    axes[-1].set_xlabel("time (s)")


def plot_wrapped_angle(ax: object, t: np.ndarray, angle: np.ndarray, period: float = 360.0, **kwargs: object) -> list:
    """Plot a wrapped angle against t on ``ax``, the line broken (a NaN inserted) between consecutive samples whose
    angles differ by more than half a turn; ``period`` is one turn in the angle's unit (360 or 2π)."""
    t, angle, period = float_array(t, "t"), float_array(angle, "angle"), positive_number(period, "period")
    if t.ndim != 1 or t.shape != angle.shape:
        raise ValueError(f"t and angle must be 1-D arrays of the same length, got shapes {t.shape} and {angle.shape}")
    jumps = np.flatnonzero(np.abs(np.diff(angle)) > 0.5 * period) + 1
    return ax.plot(np.insert(t, jumps, np.nan), np.insert(angle, jumps, np.nan), **kwargs)
