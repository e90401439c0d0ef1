"""The standard 2D edge set, in the DriveBot conventions (e = h(x) − z, Jacobians ∂e/∂x w.r.t. the additive ⊞).

Notation: pose x = [x, y, ψ], t = [x, y], R(ψ) = [[c, −s], [s, c]], S = [[0, −1], [1, 0]] (so dR/dψ = S R).

EdgeSE2            pose–pose between (odometry / loop closure), the GTSAM/g2o relative pose measurement
                   z = (t_z, θ_z) of x_j in the frame of x_i. The error is GTSAM's BetweenFactor error
                     d = z⁻¹ (x_i⁻¹ x_j):  t_d = R(θ_z)ᵀ (R(ψ_i)ᵀ (t_j − t_i) − t_z),  θ_d = wrap(ψ_j − ψ_i − θ_z)
                     e = Log(d) = [V(θ_d)⁻¹ t_d, θ_d],  V⁻¹(θ) = [[α, β], [−β, α]], α = (θ/2)·cot(θ/2), β = θ/2
                   (so χ² equals 2 × GTSAM's error; for small θ_d it equals g2o's [t_d, θ_d] to second order).
EdgeSE2Prior       e = [t − t_z, wrap(ψ − ψ_z)], J = I₃.
EdgePositionPrior  GPS with a body-frame lever arm l: h = t + R(ψ) l, e = h − z,
                   J = [[1, 0, −s lx − c ly], [0, 1, c lx − s ly]].
EdgeHeadingPrior   compass with an offset Δψ: e = wrap(ψ + Δψ − z), J = [0, 0, 1].
EdgeRangeBearing   pose → point, z = (range, bearing); d = m − t, r = ‖d‖,
                   e = [r − z_r, wrap(atan2(dy, dx) − ψ − z_β)],
                   J_x = [[−dx/r, −dy/r, 0], [dy/r², −dx/r², −1]],  J_m = [[dx/r, dy/r], [−dy/r², dx/r²]].
EdgePointPrior     e = m − z, J = I₂.
"""

import numpy as np
from numba import njit

from .angles import wrap_angle
from .edge import BaseEdge
from .vertex import VertexPointXY, VertexSE2

__all__ = ["EdgeSE2", "EdgeSE2Prior", "EdgePositionPrior", "EdgeHeadingPrior", "EdgeRangeBearing",
           "EdgePointPrior", "se2_log_coefficients"]


def _eye_stack(n, m):
    out = np.zeros((n, m, m))
    idx = np.arange(m)
    out[:, idx, idx] = 1.0
    return out


def se2_log_coefficients(theta):
    """α(θ) = (θ/2)·cot(θ/2), β = θ/2 and their derivatives α'(θ), β' = 1/2 (series near θ = 0)."""
    theta = np.asarray(theta, dtype=float)
    half = 0.5 * theta
    small = np.abs(theta) < 1e-4
    safe = np.where(small, 1.0, theta)
    hs = 0.5 * safe
    alpha_big = hs * np.cos(hs) / np.sin(hs)
    dalpha_big = 0.5 * np.cos(hs) / np.sin(hs) - 0.25 * safe / np.sin(hs) ** 2
    t2 = theta * theta
    alpha = np.where(small, 1.0 - t2 / 12.0 - t2 * t2 / 720.0, alpha_big)
    dalpha = np.where(small, -theta / 6.0 - t2 * theta / 180.0, dalpha_big)
    return alpha, half, dalpha


@njit(cache=True)
def _se2_between(xi, xj, z, jacobians):
    """The EdgeSE2 model (one loop over edges, compiled): e = Log(z⁻¹ x_i⁻¹ x_j) and its Jacobians."""
    n = len(z)
    e = np.empty((n, 3))
    ji = np.zeros((n, 3, 3))
    jj = np.zeros((n, 3, 3))
    two_pi = 2.0 * np.pi
    for t in range(n):
        ci, si = np.cos(xi[t, 2]), np.sin(xi[t, 2])
        cz, sz = np.cos(z[t, 2]), np.sin(z[t, 2])
        dx, dy = xj[t, 0] - xi[t, 0], xj[t, 1] - xi[t, 1]
        trx, try_ = ci * dx + si * dy, -si * dx + ci * dy
        ux, uy = trx - z[t, 0], try_ - z[t, 1]
        tdx, tdy = cz * ux + sz * uy, -sz * ux + cz * uy
        th = xj[t, 2] - xi[t, 2] - z[t, 2]
        th = th - two_pi * np.floor((th + np.pi) / two_pi)
        if th >= np.pi:
            th -= two_pi
        if abs(th) < 1e-4:
            t2 = th * th
            a = 1.0 - t2 / 12.0 - t2 * t2 / 720.0
            da = -th / 6.0 - t2 * th / 180.0
        else:
            hs = 0.5 * th
            cot = np.cos(hs) / np.sin(hs)
            a = hs * cot
            da = 0.5 * cot - 0.25 * th / np.sin(hs) ** 2
        b = 0.5 * th
        e[t, 0] = a * tdx + b * tdy
        e[t, 1] = -b * tdx + a * tdy
        e[t, 2] = th
        if not jacobians:
            continue
        cg, sg = np.cos(xi[t, 2] + z[t, 2]), np.sin(xi[t, 2] + z[t, 2])
        m00, m01 = a * cg - b * sg, a * sg + b * cg
        m10, m11 = -b * cg - a * sg, -b * sg + a * cg
        dvx, dvy = da * tdx + 0.5 * tdy, -0.5 * tdx + da * tdy
        px, py = cz * try_ - sz * trx, -sz * try_ - cz * trx
        vpx, vpy = a * px + b * py, -b * px + a * py
        ji[t, 0, 0], ji[t, 0, 1], ji[t, 1, 0], ji[t, 1, 1] = -m00, -m01, -m10, -m11
        ji[t, 0, 2], ji[t, 1, 2], ji[t, 2, 2] = vpx - dvx, vpy - dvy, -1.0
        jj[t, 0, 0], jj[t, 0, 1], jj[t, 1, 0], jj[t, 1, 1] = m00, m01, m10, m11
        jj[t, 0, 2], jj[t, 1, 2], jj[t, 2, 2] = dvx, dvy, 1.0
    return e, ji, jj


class EdgeSE2(BaseEdge):
    """Relative pose between two SE2 vertices (see the module docstring for e and the Jacobians).

    The model is one compiled kernel (``_se2_between``) over all edges of the class.
    """

    vertex_types = (VertexSE2, VertexSE2)
    measurement_dimension = 3

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        xi, xj = states
        e, ji, jj = _se2_between(np.ascontiguousarray(xi, dtype=float), np.ascontiguousarray(xj, dtype=float),
                                 np.ascontiguousarray(z, dtype=float), bool(jacobians))
        return e, ([ji, jj] if jacobians else None)


class EdgeSE2Prior(BaseEdge):
    """Pose prior: e = [x − z_x, y − z_y, wrap(ψ − z_ψ)], J = I₃."""

    vertex_types = (VertexSE2,)
    measurement_dimension = 3

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        (x,) = states
        e = x - z
        e[:, 2] = wrap_angle(e[:, 2])
        return e, ([_eye_stack(len(z), 3)] if jacobians else None)


class EdgePositionPrior(BaseEdge):
    """GPS: h = [x, y] + R(ψ)·lever_arm, e = h − z (lever arm in the body frame, default [0, 0])."""

    vertex_types = (VertexSE2,)
    measurement_dimension = 2
    parameters = {"lever_arm": (0.0, 0.0)}

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        # Q1d: the antenna sits at the lever arm l in the body frame, so h = [x, y] + R(ψ) l and the ψ column of J
        # is ∂(R(ψ) l)/∂ψ = [−(R l)_y, (R l)_x]; with |l| = 22.4 m it couples heading and position.
        (x,) = states
        lev = params["lever_arm"]
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        rx = c * lev[:, 0] - s * lev[:, 1]
        ry = s * lev[:, 0] + c * lev[:, 1]
        e = np.empty_like(z)
        e[:, 0] = x[:, 0] + rx - z[:, 0]
        e[:, 1] = x[:, 1] + ry - z[:, 1]
        if not jacobians:
            return e, None
        j = np.zeros((len(z), 2, 3))
        j[:, 0, 0] = 1.0
        j[:, 1, 1] = 1.0
        j[:, 0, 2] = -ry
        j[:, 1, 2] = rx
        return e, [j]


class EdgeHeadingPrior(BaseEdge):
    """Compass: e = wrap(ψ + offset − z), J = [0, 0, 1]."""

    vertex_types = (VertexSE2,)
    measurement_dimension = 1
    parameters = {"offset": 0.0}

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        (x,) = states
        e = wrap_angle(x[:, 2] + params["offset"] - z[:, 0])[:, None]
        if not jacobians:
            return e, None
        j = np.zeros((len(z), 1, 3))
        j[:, 0, 2] = 1.0
        return e, [j]


class EdgeRangeBearing(BaseEdge):
    """Range-bearing from a pose to a point, z = (range, bearing) (see the module docstring)."""

    vertex_types = (VertexSE2, VertexPointXY)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        # Q2b: the landmark observation model, range and bearing from the vehicle to the landmark, the bearing
        # relative to the heading and wrapped; J_m = [[d_x/r, d_y/r], [−d_y/r², d_x/r²]], J_x = [−J_m | [0, −1]ᵀ].
        x, m = states
        dx, dy = m[:, 0] - x[:, 0], m[:, 1] - x[:, 1]
        r2 = dx * dx + dy * dy
        r = np.sqrt(r2)
        e = np.empty_like(z)
        e[:, 0] = r - z[:, 0]
        e[:, 1] = wrap_angle(np.arctan2(dy, dx) - x[:, 2] - z[:, 1])
        if not jacobians:
            return e, None
        n = len(z)
        jm = np.empty((n, 2, 2))
        jm[:, 0, 0], jm[:, 0, 1] = dx / r, dy / r
        jm[:, 1, 0], jm[:, 1, 1] = -dy / r2, dx / r2
        jx = np.zeros((n, 2, 3))
        jx[:, :, :2] = -jm
        jx[:, 1, 2] = -1.0
        return e, [jx, jm]


class EdgePointPrior(BaseEdge):
    """Point prior: e = m − z, J = I₂."""

    vertex_types = (VertexPointXY,)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        (m,) = states
        return m - z, ([_eye_stack(len(z), 2)] if jacobians else None)
