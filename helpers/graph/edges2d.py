"""The standard 2D edge set, in the DriveBot conventions: e = h(x) − z, Jacobians ∂e/∂x with respect to the
additive ⊞. Pose x = [x, y, ψ], t = [x, y], R(ψ) = [[c, −s], [s, c]]. Each class docstring states its model.
"""

from __future__ import annotations

import numpy as np

from .angles import wrap_angle
from .edge import BaseEdge, batch_matrix
from .vertex import VertexPointXY, VertexSE2

__all__ = ["EdgeSE2", "EdgeSE2Prior", "EdgePositionPrior", "EdgeHeadingPrior", "EdgeRangeBearing",
           "EdgePointPrior", "EdgeSE2PointXY", "se2_log_coefficients"]


def _apply(mats: np.ndarray, vecs: np.ndarray) -> np.ndarray:
    """Matrix times vector for stacks: (E, r, c) @ (E, c) → (E, r)."""
    return np.einsum("eij,ej->ei", mats, vecs)


def se2_log_coefficients(theta: np.ndarray) -> tuple:
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


class EdgeSE2(BaseEdge):
    """Relative pose z = (t_z, θ_z) of x_j in the frame of x_i (odometry, loop closure); GTSAM's BetweenFactor.

    d = z⁻¹ (x_i⁻¹ x_j):  q = R(ψ_i)ᵀ (t_j − t_i),  t_d = R(θ_z)ᵀ (q − t_z),  θ_d = wrap(ψ_j − ψ_i − θ_z)
    e = Log(d) = [V⁻¹ t_d, θ_d],  V⁻¹ = [[α, β], [−β, α]],  α = (θ_d/2)·cot(θ_d/2),  β = θ_d/2
    J_j = [[M, D], [0, 1]],  J_i = [[−M, V⁻¹ p − D], [0, −1]]   (2×2 and 2×1 blocks), with
        M = V⁻¹ R(ψ_i + θ_z)ᵀ = ∂e_t/∂t_j,   D = (dV⁻¹/dθ) t_d = [[α', ½], [−½, α']] t_d,
        p = R(θ_z)ᵀ [q_y, −q_x]ᵀ = ∂t_d/∂ψ_i.
    χ² is 2 × GTSAM's error; for small θ_d, e equals g2o's [t_d, θ_d] to second order.
    """

    vertex_types = (VertexSE2, VertexSE2)
    measurement_dimension = 3

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        xi, xj = states
        c_i, s_i, c_z, s_z = np.cos(xi[:, 2]), np.sin(xi[:, 2]), np.cos(z[:, 2]), np.sin(z[:, 2])
        ri_t, rz_t = batch_matrix([[c_i, s_i], [-s_i, c_i]]), batch_matrix([[c_z, s_z], [-s_z, c_z]])  # Rᵀ
        q = _apply(ri_t, xj[:, :2] - xi[:, :2])
        t_d = _apply(rz_t, q - z[:, :2])
        theta = wrap_angle(xj[:, 2] - xi[:, 2] - z[:, 2])
        alpha, beta, dalpha = se2_log_coefficients(theta)
        v_inv = batch_matrix([[alpha, beta], [-beta, alpha]])
        e = np.column_stack([_apply(v_inv, t_d), theta])
        if not jacobians:
            return e, None
        m = v_inv @ rz_t @ ri_t
        d = _apply(batch_matrix([[dalpha, 0.5], [-0.5, dalpha]]), t_d)
        p = _apply(rz_t, np.column_stack([q[:, 1], -q[:, 0]]))
        ji, jj = np.zeros((len(z), 3, 3)), np.zeros((len(z), 3, 3))
        jj[:, :2, :2], jj[:, :2, 2], jj[:, 2, 2] = m, d, 1.0
        ji[:, :2, :2], ji[:, :2, 2], ji[:, 2, 2] = -m, _apply(v_inv, p) - d, -1.0
        return e, [ji, jj]


class EdgeSE2Prior(BaseEdge):
    """Pose prior: e = [x − z_x, y − z_y, wrap(ψ − z_ψ)], J = I₃."""

    vertex_types = (VertexSE2,)
    measurement_dimension = 3

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        (x,) = states
        e = x - z
        e[:, 2] = wrap_angle(e[:, 2])
        return e, ([np.broadcast_to(np.eye(3), (len(z), 3, 3))] if jacobians else None)


class EdgePositionPrior(BaseEdge):
    """GPS (coursework appendix A.4): h = [x, y] + R(ψ) l, e = h − z, with the antenna's lever arm l = ``lever_arm``
    in the body frame (default [0, 0])."""

    vertex_types = (VertexSE2,)
    measurement_dimension = 2
    parameters = {"lever_arm": (0.0, 0.0)}

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        """Errors and Jacobians of E GPS edges at once: states = [x (E, 3)], z (E, 2), params {"lever_arm": (E, 2)}.
        Returns (e (E, 2), [J (E, 2, 3)]) with J = ∂e/∂x for the update x ⊞ δ; with jacobians False, (e, None)."""
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
    """Compass (coursework appendix A.3): h = ψ + Δψ_C with the offset Δψ_C = ``offset``, e = h − z, an angle in
    [−π, π) like every angle error of the graph."""

    vertex_types = (VertexSE2,)
    measurement_dimension = 1
    parameters = {"offset": 0.0}

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        """Errors and Jacobians of E compass edges at once: states = [x (E, 3)], z (E, 1), params {"offset": (E,)}.
        Returns (e (E, 1), [J (E, 1, 3)]) with J = ∂e/∂x for the update x ⊞ δ; with jacobians False, (e, None)."""
        (x,) = states
        e = wrap_angle(x[:, 2] + params["offset"] - z[:, 0])[:, None]
        if not jacobians:
            return e, None
        j = np.zeros((len(z), 1, 3))
        j[:, 0, 2] = 1.0
        return e, [j]


class EdgeRangeBearing(BaseEdge):
    """Range and bearing of a landmark m = [m_x, m_y] from a vehicle pose x = [x, y, ψ] (coursework appendix A.5),
    z = [z_r, z_β]:  h = [‖m − t‖, atan2(m_y − y, m_x − x) − ψ],  e = [h_r − z_r, wrap(h_β − z_β)]."""

    vertex_types = (VertexSE2, VertexPointXY)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        """Errors and Jacobians of E range-bearing edges at once (the model of the class docstring).

        ``states``: [poses (E, 3), rows [x, y, ψ]; landmarks (E, 2), rows [m_x, m_y]]; ``z`` (E, 2), rows
        [z_r, z_β]; ``params``: none ({}). Returns (e, [J_pose, J_landmark]): e (E, 2) with the bearing error
        wrapped into [−π, π), J_pose = ∂e/∂[x, y, ψ] (E, 2, 3) and J_landmark = ∂e/∂[m_x, m_y] (E, 2, 2), row /
        block t for edge t; with ``jacobians=False``, (e, None). The inputs are left unchanged.
        """
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

    @classmethod
    def check_measurements(cls, z: np.ndarray, name: str) -> None:
        """A range is a distance: z[:, 0] ≥ 0 (0 is allowed: the error r − z_r is defined there), else ValueError."""
        bad = ~(z[:, 0] >= 0.0)
        if bad.any():
            t = int(np.argmax(bad))
            row = f" (row {t})" if len(z) > 1 else ""
            raise ValueError(f"{name}: the range must be >= 0 (a distance), got {float(z[t, 0])!r}{row}")


class EdgePointPrior(BaseEdge):
    """Point prior: e = m − z, J = I₂."""

    vertex_types = (VertexPointXY,)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        (m,) = states
        return m - z, ([np.broadcast_to(np.eye(2), (len(z), 2, 2))] if jacobians else None)


class EdgeSE2PointXY(BaseEdge):
    """Point observed in the frame of a pose (g2o EDGE_SE2_XY): e = R(ψ)ᵀ(m − t) − z.

    J_x = [−R(ψ)ᵀ | [q_y, −q_x]ᵀ] with q = R(ψ)ᵀ(m − t);  J_m = R(ψ)ᵀ.
    """

    vertex_types = (VertexSE2, VertexPointXY)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        x, m = states
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        dx, dy = m[:, 0] - x[:, 0], m[:, 1] - x[:, 1]
        qx, qy = c * dx + s * dy, -s * dx + c * dy
        e = np.stack([qx - z[:, 0], qy - z[:, 1]], axis=1)
        if not jacobians:
            return e, None
        n = len(z)
        jm = np.empty((n, 2, 2))
        jm[:, 0, 0], jm[:, 0, 1], jm[:, 1, 0], jm[:, 1, 1] = c, s, -s, c
        jx = np.zeros((n, 2, 3))
        jx[:, :, :2] = -jm
        jx[:, 0, 2], jx[:, 1, 2] = qy, -qx
        return e, [jx, jm]
