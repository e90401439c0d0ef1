"""The lens model inverted: from a distorted normalised point back to the ray (``Camera.pixel_to_vector``).

``distort(u, v, jacobian)`` is the camera's model in normalised coordinates (``Camera._distort``: (u', v'),
and with ``jacobian`` also ∂u'/∂u, ∂u'/∂v, ∂v'/∂u, ∂v'/∂v). A wide-angle rational model is invertible only
inside its fold radius r_f (:func:`fold_radius`); :func:`undistort` solves distort(u, v) = (u', v') there.
"""
from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["fold_radius", "undistort"]


def fold_radius(dist_coeffs: np.ndarray, distort: Callable) -> float:
    """Normalised radius r_f where the radial map r ↦ c(r²)·r stops increasing (∞ if it never does).

    Beyond r_f a wide-angle polynomial/rational model folds back (several radii give one pixel), so the
    model is only invertible, and only meaningful, for r < r_f (off-axis angle < atan r_f). With
    α = k1 ρ + k2 ρ² + k3 ρ³, β = k4 ρ + k5 ρ² + k6 ρ³ (ρ = r²) and c = (1 + α)/(1 + β):
    d(c r)/dr = c + 2ρ (α_ρ (1 + β) − (1 + α) β_ρ)/(1 + β)², scanned on 0 … 20 and refined by bisection."""
    k1, k2, _, _, k3, k4, k5, k6 = dist_coeffs[:8]
    r = np.linspace(0.0, 20.0, 20001)
    rho = r * r
    alpha = rho * (k1 + rho * (k2 + rho * k3))
    beta = rho * (k4 + rho * (k5 + rho * k6))
    a_r = k1 + 2 * k2 * rho + 3 * k3 * rho * rho
    b_r = k4 + 2 * k5 * rho + 3 * k6 * rho * rho
    den = 1.0 + beta
    with np.errstate(divide="ignore", invalid="ignore"):
        c = (1.0 + alpha) / den
        slope = c + 2 * rho * (a_r * den - (1.0 + alpha) * b_r) / (den * den)  # d(c r)/dr
    bad = ~(slope > 0)
    if not np.any(bad):
        return np.inf
    k = int(np.argmax(bad))
    if k == 0:
        return 0.0
    lo, hi = float(r[k - 1]), float(r[k])  # refine the sign change of the slope by bisection
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        ud, _ = distort(np.array([mid - 1e-7, mid + 1e-7]), np.zeros(2), False)
        lo, hi = (mid, hi) if ud[1] > ud[0] else (lo, mid)
    return lo


def undistort(distort: Callable, tu: np.ndarray, tv: np.ndarray, rho_max: float, tol: float,
              max_iter: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, v, squared residual) with distort(u, v) = (tu, tv) and u² + v² < rho_max: damped Newton iterations
    for all points at once (the loop runs over iterations, never over points), started at (tu, tv) pulled
    inside the fold; a point without an exact preimage stops at the least-squares one (residual > tol²)."""
    r2 = tu * tu + tv * tv
    scale = np.where(r2 > rho_max, np.sqrt(rho_max / np.maximum(r2, 1e-300)), 1.0)
    u, v = tu * scale, tv * scale

    def residual(u, v):
        ud, vd = distort(u, v, False)
        return ud - tu, vd - tv

    ru, rv = residual(u, v)
    cost = ru * ru + rv * rv
    for _ in range(max_iter):
        active = cost > tol * tol
        if not np.any(active):
            break
        _, _, a, b, c, d = distort(u, v, True)
        det = a * d - b * c
        det = np.where(det == 0, np.finfo(float).tiny, det)
        du = -(d * ru - b * rv) / det                                 # Newton step −J⁻¹ r
        dv = -(-c * ru + a * rv) / det
        step = np.ones_like(u)
        for _ in range(40):          # backtracking: halve the step wherever the cost did not drop or r ≥ r_f
            nu, nv = u + step * du, v + step * dv
            nru, nrv = residual(nu, nv)
            ncost = nru * nru + nrv * nrv
            ok = (ncost < cost) & (nu * nu + nv * nv < rho_max)
            bad = active & ~ok & (step > 1e-12)
            if not np.any(bad):
                break
            step = np.where(bad, 0.5 * step, step)
        accept = active & ok
        if not np.any(accept):
            break
        u, v = np.where(accept, nu, u), np.where(accept, nv, v)
        ru, rv = np.where(accept, nru, ru), np.where(accept, nrv, rv)
        cost = np.where(accept, ncost, cost)
    return u, v, cost
