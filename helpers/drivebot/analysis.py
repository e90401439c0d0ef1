"""Analysis of DriveBot runs for the Q2/Q3 notebooks: loop closure, covariance determinants and ellipses,
position-error RMS and the large-map "concentric tangent" fit, on arrays (one call for all landmarks / vertices)."""
from __future__ import annotations

import numpy as np

from ..gaussian import chi2inv, confidence_level
from ..validation import check_symmetric, float_array, integer, positive_number

__all__ = ["determinant_table", "find_loop_closure", "position_error_rms",
           "ellipse_axes", "plot_covariance_ellipses", "tangent_misalignment", "fit_tangent_centre",
           "landmark_observations"]


def _cov_stack(P, name="P") -> np.ndarray:
    """A finite (L, 2, 2) stack of covariances (one 2×2 matrix is L = 1)."""
    P = float_array(P, name)
    P = P[None] if P.shape == (2, 2) else P
    if P.ndim != 3 or P.shape[1:] != (2, 2) or not np.all(np.isfinite(P)):
        raise ValueError(f"{name} must be a finite stack of 2×2 covariances with shape (L, 2, 2), got {P.shape}")
    return P


def determinant_table(ids: np.ndarray, P_before: np.ndarray, P_after: np.ndarray) -> dict:
    """Per-landmark det P before/after an event and the ratio after/before (< 1: uncertainty fell).

    ``ids`` (L,), ``P_before`` and ``P_after`` (L, 2, 2). Returns {"id", "det_before", "det_after",
    "ratio", "sqrt_ratio"}; √ratio is the factor by which the 1-σ ellipse *area* shrank."""
    ids, Pb, Pa = np.asarray(ids), _cov_stack(P_before, "P_before"), _cov_stack(P_after, "P_after")
    if ids.shape != (Pb.shape[0],) or Pa.shape != Pb.shape:
        raise ValueError(f"ids (L,), P_before and P_after (L, 2, 2) must agree in L, got {ids.shape}, "
                         f"{Pb.shape}, {Pa.shape}")
    db, da = np.linalg.det(Pb), np.linalg.det(Pa)
    return {"id": ids, "det_before": db, "det_after": da, "ratio": da / db, "sqrt_ratio": np.sqrt(da / db)}


def ellipse_axes(P: np.ndarray, n_sigma: float = 3.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Semi-axes (a ≥ b) and orientation (rad, of the major axis) of the n_σ ellipses of (L, 2, 2) P.

    Returns (a, b, angle) arrays of shape (L,); a_i = √(λ_max · χ²₂(c)), c = 2Φ(n_σ) − 1."""
    P = _cov_stack(P)
    scale = chi2inv(confidence_level(positive_number(n_sigma, "n_sigma")), 2)
    for Pi in P:
        check_symmetric(Pi, "P")
    lam, V = np.linalg.eigh(0.5 * (P + np.swapaxes(P, 1, 2)))
    if np.any(lam[:, 0] < -1e-9 * np.maximum(lam[:, 1], np.finfo(float).tiny)):
        raise ValueError(f"P must be positive semi-definite covariances, got an eigenvalue {np.min(lam):.3g}")
    lam = np.clip(lam, 0.0, None)   # round-off only
    return np.sqrt(lam[:, 1] * scale), np.sqrt(lam[:, 0] * scale), np.arctan2(V[:, 1, 1], V[:, 0, 1])


def plot_covariance_ellipses(ax: object, means: np.ndarray, P: np.ndarray, n_sigma: float = 3.0,
                             **kwargs: object) -> object:
    """Add the n_σ ellipses of covariances ``P`` (L, 2, 2) centred at ``means`` (L, 2) to ``ax`` as one
    EllipseCollection (returned). kwargs go to the collection (``edgecolor``, ``lw``, …)."""
    from matplotlib.collections import EllipseCollection

    a, b, angle = ellipse_axes(P, n_sigma)
    means = float_array(means, "means").reshape(-1, 2)
    kwargs.setdefault("facecolor", "none")
    coll = EllipseCollection(2 * a, 2 * b, np.degrees(angle), units="xy", offsets=means,
                             offset_transform=ax.transData, **kwargs)
    ax.add_collection(coll)
    ax.update_datalim(np.vstack([means - a[:, None], means + a[:, None]]))
    ax.autoscale_view()
    return coll


def find_loop_closure(step: np.ndarray, landmark: np.ndarray, min_gap: int = 300) -> tuple[int | None, int | None]:
    """The first loop-closure event in a stream of landmark observations.

    ``step`` (E,) is the tick of each observation and ``landmark`` (E,) its landmark id. A closure is a
    re-observation of a landmark after at least ``min_gap`` ticks without seeing it; the event is the
    earliest such tick. Returns (tick, landmark id) or (None, None) if the stream never closes a loop.
    Vectorised: sort by (landmark, tick), gaps between consecutive sightings of the same landmark."""
    step, landmark = np.asarray(step), np.asarray(landmark)
    min_gap = integer(min_gap, "min_gap", minimum=1)
    order = np.lexsort((step, landmark))
    s, lm = step[order], landmark[order]
    hit = np.flatnonzero((lm[1:] == lm[:-1]) & (np.diff(s) >= min_gap)) + 1
    if hit.size == 0:
        return None, None
    first = hit[np.lexsort((lm[hit], s[hit]))[0]]
    return int(s[first]), int(lm[first])


def landmark_observations(system: object) -> tuple[np.ndarray, np.ndarray]:
    """(tick, landmark id) of every landmark edge in the system's graph, in creation order.

    The tick is the vehicle vertex id (vertex k is created at tick k)."""
    from .pruning import landmark_edge_table

    table = landmark_edge_table(system)
    return table["vertex"], table["landmark"]


def position_error_rms(estimate: np.ndarray, truth: np.ndarray, keep: np.ndarray | None = None) -> float:
    """√(mean ‖p̂_k − p_k‖²) over the vertices in ``keep`` (a boolean mask; all if None); positions (2, N)."""
    d = float_array(estimate, "estimate") - float_array(truth, "truth")
    d = d if keep is None else d[:, keep]
    if d.shape[0] != 2 or d.shape[1] == 0 or not np.all(np.isfinite(d)):
        raise ValueError(f"estimate and truth must be finite (2, N) positions on the kept vertices, got {d.shape}")
    return float(np.sqrt(np.mean(np.sum(d * d, axis=0))))


def tangent_misalignment(points: np.ndarray, P: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """|cos| of the angle between each landmark's major axis and the radial direction from ``centre``.

    0 means the ellipse is exactly tangent to the circle about ``centre`` through the landmark; 1 radial.
    ``points`` (L, 2), ``P`` (L, 2, 2)."""
    _, _, angle = ellipse_axes(P, 1.0)
    u = np.column_stack([np.cos(angle), np.sin(angle)])
    radial = float_array(points, "points") - float_array(centre, "centre")
    return np.abs(np.sum(u * radial, axis=1)) / np.linalg.norm(radial, axis=1)


def fit_tangent_centre(points: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Least-squares centre o of the circles to which the landmarks' major axes are tangent (q2_e).

    A major axis u_i tangent to the circle about o through m_i is ⊥ (m_i − o): u_iᵀ o = u_iᵀ m_i, one equation
    per landmark, weighted by the anisotropy w_i = 1 − λ_min/λ_max (round ellipses carry no direction)."""
    a, b, angle = ellipse_axes(P, 1.0)
    w = 1.0 - np.divide(b ** 2, a ** 2, out=np.ones_like(a), where=a > 0)
    u = np.column_stack([np.cos(angle), np.sin(angle)])
    A = w[:, None] * u
    sv = np.linalg.svd(A, compute_uv=False)
    if sv.size < 2 or sv[-1] <= 1e-12 * max(sv[0], np.finfo(float).tiny):
        raise ValueError("the landmarks' major axes do not determine a centre (the ellipses are round or their axes "
                         "all parallel): P needs anisotropic covariances in at least two directions")
    centre, *_ = np.linalg.lstsq(A, w * np.sum(u * float_array(points, "points"), axis=1), rcond=None)
    return centre
