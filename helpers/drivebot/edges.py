"""DriveBot's vertices and the two edge models that differ from ``helpers.graph``'s standard 2D set (the GPS,
the fixed compass and the landmark edges are the graph package's ``EdgePositionPrior``, ``EdgeHeadingPrior`` and
``EdgeRangeBearing``).

``VehicleVertex``  — ``VertexSE2`` (x ⊞ δ = x + δ, then ψ wrapped) that also stores its ``time``.
``LandmarkVertex`` — ``VertexPointXY`` (additive) that also stores its 1-based ``landmark_id``.

``VehicleKinematicsEdge`` — binary (x_k, x_{k+1}), measurement z = u_k = [s, 0, ψ̇] (the odometry stored before
the tick), parameter ``dt`` = ΔT_k, information R_odometry⁻¹. Its model is the coursework's process model
(handout, appendix A.2):

    x_{k+1} = x_k + ΔT_k M(ψ_k) (u_k + v_k),    M(ψ) = [[cos ψ, −sin ψ, 0], [sin ψ, cos ψ, 0], [0, 0, 1]].

The information is the inverse covariance of the process noise v_k, so the edge's error is v_k: the noise that
makes the model hold for the two poses (the graph's convention e = h(x) − z, with z = u_k). Headings ψ and
ψ + 2π are the same heading. ``evaluate`` computes e and its Jacobians for all edges of the class at once;
``initialize()`` sets x_{k+1} = x_k ⊞ ΔT M(ψ_k) z (forward prediction, ψ wrapped) — see ``predict``.

``BuggyCompassEdge`` — the compass edge the coursework provides for appendix A.3's model z = ψ + Δψ_C + w; it
has the bug that coursework Q1c asks you to find. ``EdgeHeadingPrior`` is the corrected edge.
"""
from __future__ import annotations

import numpy as np

from ..graph import BaseEdge, EdgeHeadingPrior, VertexPointXY, VertexSE2, batch_matrix, wrap_angle

__all__ = ["VehicleVertex", "LandmarkVertex", "VehicleKinematicsEdge", "BuggyCompassEdge", "predict"]


class VehicleVertex(VertexSE2):
    """Vehicle pose [x, y, ψ] at ``time`` (dimension 3; ⊞ wraps ψ)."""

    def __init__(self, time: float, id: int | None = None, estimate: np.ndarray | None = None, fixed: bool = False):
        super().__init__(id, estimate, fixed)
        self.time = float(time)


class LandmarkVertex(VertexPointXY):
    """Landmark position [x, y] with its 1-based ``landmark_id`` (dimension 2, additive ⊞)."""

    def __init__(self, landmark_id: int, id: int | None = None, estimate: np.ndarray | None = None,
                 fixed: bool = False):
        super().__init__(id, estimate, fixed)
        self.landmark_id = int(landmark_id)


def predict(x: np.ndarray, u: np.ndarray, dt: float | np.ndarray) -> np.ndarray:
    """Forward process model x' = x + ΔT M(ψ) u, ψ' wrapped; x, u (E, 3) or (3,), dt (E,) or scalar."""
    x, u, dt = np.asarray(x, dtype=float), np.asarray(u, dtype=float), np.asarray(dt, dtype=float)
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    out = np.empty(np.broadcast_shapes(x.shape, u.shape))
    out[..., 0] = x[..., 0] + dt * (c * u[..., 0] - s * u[..., 1])
    out[..., 1] = x[..., 1] + dt * (s * u[..., 0] + c * u[..., 1])
    out[..., 2] = wrap_angle(x[..., 2] + dt * u[..., 2])
    return out


class VehicleKinematicsEdge(BaseEdge):
    """Velocity-form process model between consecutive vehicle poses, per-edge ``dt`` (module docstring)."""

    vertex_types = (VertexSE2, VertexSE2)
    measurement_dimension = 3
    parameters = {"dt": 0.1}

    @staticmethod
    def evaluate(states: list[np.ndarray], z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        """Errors and Jacobians of E kinematics edges at once (the model and what e is: module docstring).

        states = [x_k, x_{k+1}], each (E, 3) poses [x, y, ψ]; z (E, 3), each edge's odometry u_k; params
        {"dt": (E,)}, each edge's ΔT_k > 0. Returns (e, [J_k, J_{k+1}]): e (E, 3); J_k = ∂e/∂x_k and
        J_{k+1} = ∂e/∂x_{k+1}, (E, 3, 3) each, for the vertices' update x ⊞ δ. With jacobians False: (e, None).
        """
        # Q1b: the process-model edge, e = v = Mᵀ(ψ_k) Δ / ΔT − u with Δ = [x_{k+1} − x_k, y_{k+1} − y_k,
        # wrap(ψ_{k+1} − ψ_k)], and its analytic Jacobians (c = cos ψ_k, s = sin ψ_k), for all edges at once:
        #   J_k = (1/ΔT) [[−c, −s, −Δx s + Δy c], [s, −c, −Δx c − Δy s], [0, 0, −1]],  J_{k+1} = Mᵀ(ψ_k) / ΔT.
        xk, xn = states
        inv_dt = 1.0 / params["dt"]
        c, s = np.cos(xk[:, 2]), np.sin(xk[:, 2])
        dx, dy = xn[:, 0] - xk[:, 0], xn[:, 1] - xk[:, 1]
        dpsi = wrap_angle(xn[:, 2] - xk[:, 2])
        e = np.stack([c * dx + s * dy, -s * dx + c * dy, dpsi], axis=1) * inv_dt[:, None] - z
        if not jacobians:
            return e, None
        jk = batch_matrix([[-c, -s, -dx * s + dy * c],
                           [s, -c, -dx * c - dy * s],
                           [0, 0, -1]])
        jn = batch_matrix([[c, s, 0],
                           [-s, c, 0],
                           [0, 0, 1]])
        return e, [jk * inv_dt[:, None, None], jn * inv_dt[:, None, None]]

    def initialize(self) -> None:
        """Set the second vertex to the forward prediction x_k + ΔT M(ψ_k) z from the first."""
        a, b = self.vertex(0), self.vertex(1)
        b.set_estimate(predict(a.estimate, self.measurement, float(self.dt)))


class BuggyCompassEdge(EdgeHeadingPrior):
    """The compass edge the coursework provides (appendix A.3), with the bug of coursework Q1c (module docstring)."""

    @staticmethod
    def evaluate(states: list[np.ndarray], z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        # Q1c: the bug. e is not wrapped; the fix (EdgeHeadingPrior.evaluate) returns wrap_angle(e).
        _, jac = EdgeHeadingPrior.evaluate(states, z, params, jacobians)
        e = (states[0][:, 2] + params["offset"] - z[:, 0])[:, None]
        return e, jac
