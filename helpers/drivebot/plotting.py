"""Figures for the DriveBot notebooks: the factor graph of a (small) run, state errors and covariances.

``draw_factor_graph(system, ax)`` lays the graph out by time: vehicle vertices (circles) on a horizontal
line at x = their index, kinematics factors (squares) between consecutive vertices, unary factors above
(compass) and below (GPS) their vertex, landmark vertices in a top row above the mean index of the poses
that observe them with a range-bearing factor on each link. Every element is read from ``system.graph``,
so the picture is the real graph, not a sketch.

``plot_wrapped_angle(ax, t, angle)`` draws a wrapped angle (heading in degrees or radians) as a line that is
broken wherever it wraps round ±180° (|Δ| > half a turn between samples), so a wrap is a gap, not a vertical
stroke across the whole axis; ``break_at_wraps`` returns the arrays with those gaps (NaN) inserted.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from ..graph import EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing
from ..validation import float_array
from .edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex

__all__ = ["draw_factor_graph", "plot_state_errors", "plot_covariances", "break_at_wraps", "plot_wrapped_angle"]

_STYLE = {
    VehicleKinematicsEdge: ("kinematics edge (odometry)", "#1f77b4", 0.0),
    EdgeHeadingPrior: ("compass edge", "#2ca02c", 1.0),
    BuggyCompassEdge: ("compass edge (buggy)", "#2ca02c", 1.0),
    EdgePositionPrior: ("GPS edge (lever arm)", "#d62728", -1.0),
    EdgeRangeBearing: ("range-bearing edge", "#9467bd", None),
}


def draw_factor_graph(system, ax, title: str | None = None) -> None:
    """Draw ``system.graph`` (a DriveBotSLAMSystem) on ``ax``; see the module docstring for the layout."""
    from .slam_system import DriveBotSLAMSystem

    if not isinstance(system, DriveBotSLAMSystem):
        raise ValueError(f"system must be a DriveBotSLAMSystem, got {type(system).__name__}")
    _check_axes(ax, None)
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


def _check_axes(axes, n):
    if n is None:
        if not hasattr(axes, "plot"):
            raise ValueError(f"ax must be a matplotlib Axes, got {type(axes).__name__}")
        return
    axes = list(np.ravel(axes))
    if len(axes) != n or not all(hasattr(a, "plot") for a in axes):
        raise ValueError(f"axes must be {n} matplotlib Axes, got {len(axes)} object(s)")


def _check_results(results):
    from .runner import Results

    if not isinstance(results, Results):
        raise ValueError(f"results must be a Results (from run_question), got {type(results).__name__}")


def plot_state_errors(results, axes, n_sigma: float = 2.0, label: str | None = None) -> None:
    """Estimate − truth for x, y, ψ (ψ wrapped) with ±n_σ bounds from the covariance history, on 3 axes."""
    _check_results(results)
    _check_axes(axes, 3)
    if isinstance(n_sigma, bool) or not isinstance(n_sigma, numbers.Real) or not 0 < n_sigma < math.inf:
        raise ValueError(f"n_sigma must be a positive number, got {n_sigma!r}")
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


def plot_covariances(results, axes, label: str | None = None) -> None:
    """The marginal variances P_xx, P_yy, P_ψψ against time, on 3 axes."""
    _check_results(results)
    _check_axes(axes, 3)
    t = results.vehicle_state_time
    names = ["P_xx (m²)", "P_yy (m²)", "P_ψψ (rad²)"]
    for i, ax in enumerate(axes):
        ax.plot(t, results.vehicle_covariance_history[i], lw=1.0, label=label)
        ax.set_ylabel(names[i])
    axes[-1].set_xlabel("time (s)")


def break_at_wraps(t, angle, period: float = 360.0):
    """(t, angle) with a NaN inserted between consecutive samples whose angles differ by more than period/2.

    ``period`` is one full turn in the angle's unit (360 for degrees, 2π for radians). A wrapped angle jumps by
    about one period where it crosses ±period/2; the NaN makes matplotlib break the line there.
    """
    t = float_array(t, "t")
    angle = float_array(angle, "angle")
    if t.ndim != 1 or t.shape != angle.shape:
        raise ValueError(f"t and angle must be 1-D arrays of the same length, got shapes {t.shape} and {angle.shape}")
    if isinstance(period, bool) or not isinstance(period, numbers.Real) or not np.isfinite(period) or period <= 0:
        raise ValueError(f"period must be a positive number (360 for degrees, 2π for radians), got {period!r}")
    jumps = np.flatnonzero(np.abs(np.diff(angle)) > 0.5 * period) + 1
    return np.insert(t, jumps, np.nan), np.insert(angle, jumps, np.nan)


def plot_wrapped_angle(ax, t, angle, period: float = 360.0, **kwargs):
    """Plot a wrapped angle against t on ``ax`` without vertical strokes at the wraps (see break_at_wraps)."""
    _check_axes(ax, None)
    tb, ab = break_at_wraps(t, angle, period)
    return ax.plot(tb, ab, **kwargs)
