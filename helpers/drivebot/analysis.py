"""Analysis of DriveBot SLAM runs for the Q2/Q3 notebooks: loop-closure detection, covariance determinants
and ellipses, position-error RMS over the vertices still in the graph, the large-map "concentric tangent"
fit and the map plot with covariance ellipses (the factor-graph drawing and the state/covariance
plots are in ``helpers.drivebot.plotting``).

Everything operates on arrays (one call for all landmarks / vertices); the graph is only read. Graph
statistics and the χ² degrees of freedom come from the DriveBot system itself
(``Results.graph_statistics()``, ``Results.chi2_bounds()``); this module does not repeat them.

Covariance ellipse of a 2×2 block P = V diag(λ₁, λ₂) Vᵀ (λ₁ ≥ λ₂) at n_σ "sigmas" of a 2-D Gaussian:
semi-axes a_i = √(λ_i · χ²₂(c)), c = 2Φ(n_σ) − 1, major axis along V[:, 0].

Concentric tangents (q2_e): if every landmark's major axis u_i is tangent to a circle about a centre o,
then u_i ⊥ (m_i − o), i.e. u_iᵀ o = u_iᵀ m_i — one linear equation per landmark, solved for o by least
squares weighted by the anisotropy w_i = 1 − λ₂/λ₁ (round ellipses carry no direction).
"""
from __future__ import annotations

import numbers

import numpy as np

from ..gaussian import chi2inv, confidence_level

__all__ = ["covariance_determinants", "determinant_table", "find_loop_closure", "position_error_rms",
           "ellipse_axes", "plot_covariance_ellipses", "tangent_misalignment", "fit_tangent_centre",
           "landmark_observations"]


# ----------------------------------------------------------------------------------------------------
# validation helpers
# ----------------------------------------------------------------------------------------------------
def _cov_stack(P, name, d=2):
    P = np.asarray(P, dtype=float)
    if P.ndim == 2 and P.shape == (d, d):
        P = P[None]
    if P.ndim != 3 or P.shape[1:] != (d, d):
        raise ValueError(f"{name} must be a stack of {d}×{d} covariances with shape (L, {d}, {d}), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return P


def _points(x, name, n=None, d=2):
    x = np.asarray(x, dtype=float)
    if x.ndim == 1 and x.shape == (d,):
        x = x[None]
    if x.ndim != 2 or x.shape[1] != d or (n is not None and x.shape[0] != n):
        want = f"({n}, {d})" if n is not None else f"(L, {d})"
        raise ValueError(f"{name} must have shape {want}, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    return x


def _nonneg_int(v, name):
    if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 0:
        raise ValueError(f"{name} must be a non-negative integer, got {v!r}")
    return int(v)


# ----------------------------------------------------------------------------------------------------
# covariances
# ----------------------------------------------------------------------------------------------------
def covariance_determinants(P) -> np.ndarray:
    """det P_i for a stack (L, d, d) (vectorised)."""
    P = np.asarray(P, dtype=float)
    if P.ndim != 3 or P.shape[1] != P.shape[2] or not np.all(np.isfinite(P)):
        raise ValueError(f"P must be a finite stack of square matrices (L, d, d), got shape {P.shape}")
    return np.linalg.det(P)


def determinant_table(ids, P_before, P_after) -> dict:
    """Per-landmark det P before/after an event and the ratio after/before (< 1: uncertainty fell).

    ``ids`` (L,), ``P_before`` and ``P_after`` (L, 2, 2). Returns {"id", "det_before", "det_after",
    "ratio", "sqrt_ratio"}; √ratio is the factor by which the 1-σ ellipse *area* shrank."""
    ids = np.asarray(ids)
    Pb = _cov_stack(P_before, "P_before")
    Pa = _cov_stack(P_after, "P_after")
    if ids.ndim != 1 or ids.shape[0] != Pb.shape[0] or Pa.shape != Pb.shape:
        raise ValueError(f"ids (L,), P_before and P_after (L, 2, 2) must agree in L, got {ids.shape}, "
                         f"{Pb.shape}, {Pa.shape}")
    db, da = covariance_determinants(Pb), covariance_determinants(Pa)
    if np.any(db <= 0):
        raise ValueError("P_before must be positive definite (a determinant is ≤ 0)")
    ratio = da / db
    return {"id": ids, "det_before": db, "det_after": da, "ratio": ratio, "sqrt_ratio": np.sqrt(ratio)}


def ellipse_axes(P, n_sigma=3.0):
    """Semi-axes (a ≥ b) and orientation (rad, of the major axis) of the n_σ ellipses of (L, 2, 2) P.

    Returns (a, b, angle) arrays of shape (L,); a_i = √(λ_max · χ²₂(c)), c = 2Φ(n_σ) − 1."""
    P = _cov_stack(P, "P")
    scale = chi2inv(confidence_level(n_sigma), 2)
    size = np.maximum(np.max(np.abs(P), axis=(1, 2)), np.finfo(float).tiny)
    if np.any(np.max(np.abs(P - np.swapaxes(P, 1, 2)), axis=(1, 2)) > 1e-9 * size):
        raise ValueError("P must be symmetric covariances")
    lam, V = np.linalg.eigh(0.5 * (P + np.swapaxes(P, 1, 2)))
    if np.any(lam[:, 0] < -1e-9 * size):
        raise ValueError(f"P must be positive semi-definite covariances, got an eigenvalue {np.min(lam):.3g}")
    lam = np.clip(lam, 0.0, None)   # round-off only
    a = np.sqrt(lam[:, 1] * scale)
    b = np.sqrt(lam[:, 0] * scale)
    angle = np.arctan2(V[:, 1, 1], V[:, 0, 1])
    return a, b, angle


def plot_covariance_ellipses(ax, means, P, n_sigma=3.0, **kwargs):
    """Add the n_σ ellipses of covariances ``P`` (L, 2, 2) centred at ``means`` (L, 2) to ``ax`` as one
    EllipseCollection (no per-ellipse patches). kwargs go to the collection (``edgecolor``, ``lw``, …)."""
    from matplotlib.collections import EllipseCollection

    if not (hasattr(ax, "add_collection") and hasattr(ax, "transData")):
        raise ValueError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
    P = _cov_stack(P, "P")
    means = _points(means, "means", P.shape[0])
    a, b, angle = ellipse_axes(P, n_sigma)
    kwargs.setdefault("facecolor", "none")
    coll = EllipseCollection(2 * a, 2 * b, np.degrees(angle), units="xy", offsets=means,
                             offset_transform=ax.transData, **kwargs)
    ax.add_collection(coll)
    ax.update_datalim(np.vstack([means - a[:, None], means + a[:, None]]))
    ax.autoscale_view()
    return coll


# ----------------------------------------------------------------------------------------------------
# the loop-closure event
# ----------------------------------------------------------------------------------------------------
def find_loop_closure(step, landmark, min_gap=300):
    """The first loop-closure event in a stream of landmark observations.

    ``step`` (E,) is the tick of each observation and ``landmark`` (E,) its landmark id. A closure is a
    re-observation of a landmark after at least ``min_gap`` ticks without seeing it; the event is the
    earliest such tick. Returns (tick, landmark id) or (None, None) if the stream never closes a loop.
    Vectorised: sort by (landmark, tick), gaps between consecutive sightings of the same landmark."""
    step = np.asarray(step)
    landmark = np.asarray(landmark)
    for arr, name in ((step, "step"), (landmark, "landmark")):
        if arr.ndim != 1 or (arr.size and not np.issubdtype(arr.dtype, np.integer)):
            raise ValueError(f"{name} must be a 1-D integer array, got dtype {arr.dtype} shape {arr.shape}")
    if step.shape != landmark.shape:
        raise ValueError(f"step and landmark must have the same shape, got {step.shape} and {landmark.shape}")
    min_gap = _nonneg_int(min_gap, "min_gap")
    if min_gap == 0:
        raise ValueError("min_gap must be ≥ 1")
    if step.size < 2:
        return None, None
    order = np.lexsort((step, landmark))
    s, lm = step[order], landmark[order]
    same = lm[1:] == lm[:-1]
    gap = np.diff(s)
    hit = np.flatnonzero(same & (gap >= min_gap)) + 1
    if hit.size == 0:
        return None, None
    first = hit[np.lexsort((lm[hit], s[hit]))[0]]
    return int(s[first]), int(lm[first])


# ----------------------------------------------------------------------------------------------------
# errors and masks
# ----------------------------------------------------------------------------------------------------
def landmark_observations(system):
    """(tick, landmark id) of every landmark edge in the system's graph, in creation order.

    The tick is the vehicle vertex id (vertex k is created at tick k)."""
    from .pruning import landmark_edge_table

    table = landmark_edge_table(system)
    return table["vertex"], table["landmark"]


def position_error_rms(estimate, truth, keep=None) -> float:
    """√(mean ‖p̂_k − p_k‖²) over the vertices in ``keep`` (all if None); positions (N, 2) or (2, N)."""
    est = np.asarray(estimate, dtype=float)
    tru = np.asarray(truth, dtype=float)
    if est.shape != tru.shape or est.ndim != 2 or 2 not in est.shape:
        raise ValueError(f"estimate and truth must be matching (N, 2) or (2, N) arrays, got {est.shape}, "
                         f"{tru.shape}")
    if est.shape[0] == 2 and est.shape[1] != 2:
        est, tru = est.T, tru.T
    keep = np.ones(est.shape[0], bool) if keep is None else np.asarray(keep)
    if keep.dtype != bool or keep.shape != (est.shape[0],):
        raise ValueError(f"keep must be a boolean mask of length {est.shape[0]}, got {keep.dtype} {keep.shape}")
    if not keep.any():
        raise ValueError("keep selects no vertex")
    d = est[keep] - tru[keep]
    if not np.all(np.isfinite(d)):
        raise ValueError("estimate or truth has NaN/inf on kept vertices")
    return float(np.sqrt(np.mean(np.sum(d * d, axis=1))))


# ----------------------------------------------------------------------------------------------------
# concentric tangents (q2_e)
# ----------------------------------------------------------------------------------------------------
def tangent_misalignment(points, P, centre) -> np.ndarray:
    """|cos| of the angle between each landmark's major axis and the radial direction from ``centre``.

    0 means the ellipse is exactly tangent to the circle about ``centre`` through the landmark; 1 radial."""
    P = _cov_stack(P, "P")
    points = _points(points, "points", P.shape[0])
    centre = np.asarray(centre, dtype=float).reshape(-1)
    if centre.shape != (2,) or not np.all(np.isfinite(centre)):
        raise ValueError(f"centre must be 2 finite numbers, got {centre!r}")
    _, _, angle = ellipse_axes(P, 1.0)
    u = np.column_stack([np.cos(angle), np.sin(angle)])
    radial = points - centre
    norm = np.linalg.norm(radial, axis=1)
    if np.any(norm == 0):
        raise ValueError("centre coincides with a landmark")
    return np.abs(np.sum(u * radial, axis=1)) / norm


def fit_tangent_centre(points, P) -> np.ndarray:
    """Least-squares centre o of the circles to which the landmarks' major axes are tangent.

    Solves  w_i u_iᵀ o = w_i u_iᵀ m_i  (u_i major-axis direction, w_i = 1 − λ_min/λ_max)."""
    P = _cov_stack(P, "P")
    points = _points(points, "points", P.shape[0])
    if P.shape[0] < 2:
        raise ValueError("fit_tangent_centre needs at least 2 landmarks")
    a, b, angle = ellipse_axes(P, 1.0)
    w = 1.0 - np.divide(b ** 2, a ** 2, out=np.ones_like(a), where=a > 0)
    u = np.column_stack([np.cos(angle), np.sin(angle)])
    A = w[:, None] * u
    sv = np.linalg.svd(A, compute_uv=False)
    if sv[-1] <= 1e-12 * max(sv[0], np.finfo(float).tiny):
        raise ValueError("the landmarks' major axes do not determine a centre (the ellipses are round or their axes "
                         "all parallel): P needs anisotropic covariances in at least two directions")
    rhs = w * np.sum(u * points, axis=1)
    centre, *_ = np.linalg.lstsq(A, rhs, rcond=None)
    return centre
