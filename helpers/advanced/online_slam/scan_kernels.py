"""Compiled fast paths of the two per-scan computations of ``RangeBearingModel`` that run on every scan.

The front-end runs these on every laser scan (5 365 times in a q2_e run), on a few to a few hundred landmarks.
At that size numpy's cost is its per-call overhead, not the arithmetic: the readable paths below make 20–30 array
calls per scan. Each kernel does the same arithmetic in one compiled loop. The readable numpy paths stay the
reference (``RangeBearingModel.footprint_reference`` and ``scan_density_reference``), and the tests compare each
kernel with its reference on random inputs. ``benchmarks/online_slam.py --sections timing`` measures the gain.

``in_footprint(x, points, max_range, half_fov, dr, db)``
    Whether each landmark (k, 2) is predicted inside the sensor footprint seen from pose x, widened by (dr, db).
    The prediction is ``EdgeRangeBearing``'s, z = [‖m − p‖, wrap(atan2(m_y − y, m_x − x) − ψ)]. The test is
    z_r ≤ r_max + dr and, for a sensor narrower than a full turn (half_fov < π), |z_β| ≤ half_fov + db.

``block_largest_sd(C, Rk)``
    For each 2 × 2 diagonal block of C, the square root of the largest eigenvalue of C_kk − R_k (in the Cartesian
    space, the covariance of the landmark in the vehicle frame): ``decisions.largest_sd`` on the blocks.

``cartesian_density(x, means, sig_v, R)``
    The candidates' predicted observations in the Cartesian association space, and their joint covariance:
        ŷ_i = q_i = R(ψ)ᵀ(m_i − p)                             (``EdgeSE2PointXY`` at z = 0)
        H_x,i = [−R(ψ)ᵀ | [q_y, −q_x]ᵀ],   H_m,i = R(ψ)ᵀ         (its Jacobians)
        R_i = G_i R G_iᵀ,   G_i = ∂(r [cos β, sin β])/∂(r, β) at (r, β) = (‖q_i‖, atan2(q_y, q_x))
        C = J Σ_v Jᵀ + blockdiag(R_1 … R_k),   J = [H_x | blockdiag(H_m,1 … H_m,k)]
    Σ_v is the joint covariance of [x; m_1 … m_k]. The zeros of J are never formed. The first product is
    T = J Σ_v, whose rows for landmark i are H_x,i Σ_v[x, :] + H_m,i Σ_v[m_i, :]. Then C = T Jᵀ.
"""
from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["in_footprint", "cartesian_density", "block_largest_sd"]

_TWO_PI = 2.0 * np.pi


@njit(cache=True)
def wrap_angle_scalar(theta):
    """θ − 2π·floor((θ + π) / 2π), folded into [−π, π): ``angles.wrap_angle`` for one float, compiled."""
    out = theta - _TWO_PI * np.floor((theta + np.pi) / _TWO_PI)
    if out >= np.pi:
        out -= _TWO_PI
    return out


@njit(cache=True)
def in_footprint(x, points, max_range, half_fov, dr, db):
    """Boolean (k,): landmark ``points`` (k, 2) predicted inside the footprint from pose x (module docstring)."""
    k = points.shape[0]
    out = np.empty(k, dtype=np.bool_)
    limited = half_fov < np.pi
    for i in range(k):
        dx, dy = points[i, 0] - x[0], points[i, 1] - x[1]
        ok = np.sqrt(dx * dx + dy * dy) <= max_range + dr
        if ok and limited:
            ok = abs(wrap_angle_scalar(np.arctan2(dy, dx) - x[2])) <= half_fov + db
        out[i] = ok
    return out


@njit(cache=True)
def cartesian_density(x, means, sig_v, R):
    """(ŷ (k, 2), C (2k, 2k), R_k (k, 2, 2)) in the Cartesian association space (module docstring)."""
    k = means.shape[0]
    n = sig_v.shape[0]
    yhat = np.empty((k, 2))
    hx = np.zeros((k, 2, 3))
    hm = np.empty((k, 2, 2))
    Rk = np.empty((k, 2, 2))
    c, s = np.cos(x[2]), np.sin(x[2])
    for i in range(k):
        dx, dy = means[i, 0] - x[0], means[i, 1] - x[1]
        qx, qy = c * dx + s * dy, -s * dx + c * dy
        yhat[i, 0], yhat[i, 1] = qx, qy
        hm[i, 0, 0], hm[i, 0, 1], hm[i, 1, 0], hm[i, 1, 1] = c, s, -s, c
        hx[i, 0, 0], hx[i, 0, 1], hx[i, 0, 2] = -c, -s, qy
        hx[i, 1, 0], hx[i, 1, 1], hx[i, 1, 2] = s, -c, -qx
        r, b = np.hypot(qx, qy), np.arctan2(qy, qx)
        cb, sb = np.cos(b), np.sin(b)
        g00, g01, g10, g11 = cb, -r * sb, sb, r * cb
        a00 = g00 * R[0, 0] + g01 * R[1, 0]                   # G R, then (G R) Gᵀ
        a01 = g00 * R[0, 1] + g01 * R[1, 1]
        a10 = g10 * R[0, 0] + g11 * R[1, 0]
        a11 = g10 * R[0, 1] + g11 * R[1, 1]
        Rk[i, 0, 0], Rk[i, 0, 1] = a00 * g00 + a01 * g01, a00 * g10 + a01 * g11
        Rk[i, 1, 0], Rk[i, 1, 1] = a10 * g00 + a11 * g01, a10 * g10 + a11 * g11
    T = np.zeros((2 * k, n))                                  # T = J Σ_v
    for i in range(k):
        for a in range(2):
            row = 2 * i + a
            for col in range(n):
                acc = 0.0
                for b in range(3):
                    acc += hx[i, a, b] * sig_v[b, col]
                for b in range(2):
                    acc += hm[i, a, b] * sig_v[3 + 2 * i + b, col]
                T[row, col] = acc
    C = np.empty((2 * k, 2 * k))                              # C = T Jᵀ + blockdiag(R_k)
    for row in range(2 * k):
        for j in range(k):
            for e in range(2):
                acc = 0.0
                for b in range(3):
                    acc += T[row, b] * hx[j, e, b]
                for b in range(2):
                    acc += T[row, 3 + 2 * j + b] * hm[j, e, b]
                C[row, 2 * j + e] = acc
    for i in range(k):
        for a in range(2):
            for e in range(2):
                C[2 * i + a, 2 * i + e] += Rk[i, a, e]
    for row in range(2 * k):                                  # ½(C + Cᵀ)
        for col in range(row + 1, 2 * k):
            v = 0.5 * (C[row, col] + C[col, row])
            C[row, col] = v
            C[col, row] = v
    return yhat, C, Rk


@njit(cache=True)
def block_largest_sd(C, Rk):
    """(k,) largest standard deviations of the 2 × 2 matrices C_kk − R_k (``decisions.largest_sd``'s formula)."""
    k = Rk.shape[0]
    out = np.empty(k)
    for i in range(k):
        a = C[2 * i, 2 * i] - Rk[i, 0, 0]
        b = C[2 * i, 2 * i + 1] - Rk[i, 0, 1]
        c = C[2 * i + 1, 2 * i] - Rk[i, 1, 0]
        e = C[2 * i + 1, 2 * i + 1] - Rk[i, 1, 1]
        half = 0.5 * (a + e)
        det = a * e - b * c
        out[i] = np.sqrt(max(half + np.sqrt(max(half * half - det, 0.0)), 0.0))
    return out
