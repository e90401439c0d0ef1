"""DriveBot's vertices and the two edge models that differ from ``helpers.graph``'s standard 2D set (the GPS,
the fixed compass and the landmark edges are the graph package's ``EdgePositionPrior``, ``EdgeHeadingPrior`` and
``EdgeRangeBearing``).

``VehicleVertex``  — ``VertexSE2`` (x ⊞ δ = x + δ, then ψ wrapped) that also stores its ``time``.
``LandmarkVertex`` — ``VertexPointXY`` (additive) that also stores its 1-based ``landmark_id``.

``VehicleKinematicsEdge`` — binary, z = u = [s, 0, ψ̇] (the previous odometry), parameter ``dt``:

    x_{k+1} = x_k + ΔT M(ψ_k)(u + v)      ⇒      e = v = Mᵀ(ψ_k) Δ / ΔT − u,
    Δ = [x_{k+1} − x_k, y_{k+1} − y_k, wrap(ψ_{k+1} − ψ_k)],  c = cos ψ_k, s = sin ψ_k,
    J_k     = (1/ΔT) [[−c, −s, −Δx s + Δy c], [s, −c, −Δx c − Δy s], [0, 0, −1]],
    J_{k+1} = Mᵀ(ψ_k) / ΔT = (1/ΔT) [[c, s, 0], [−s, c, 0], [0, 0, 1]].
    ``evaluate`` is these equations in numpy, for all edges of the class at once; ``initialize()`` sets
    x_{k+1} = x_k ⊞ ΔT M(ψ_k) z (forward prediction, ψ wrapped) — see ``predict``.

``BuggyCompassEdge`` — the coursework's provided compass edge: e = ψ + Δψ_C − z with **no wrap**,
J = [0, 0, 1]. Once ψ + Δψ_C leaves [−π, π) while the simulator's z is wrapped, every residual is off by
2π. The fix is ``EdgeHeadingPrior``, which wraps e (J unchanged).
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
        # Q1b: the process-model edge, e = Mᵀ(ψ_k) Δ / ΔT − u, and its analytic Jacobians J_k, J_{k+1}
        # (module docstring), for every edge of the class at once.
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
    """The coursework's provided (buggy) compass edge: e = ψ + offset − z, NOT wrapped; J = [0, 0, 1]
    (module docstring)."""

    @staticmethod
    def evaluate(states: list[np.ndarray], z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        # Q1c: the bug. e is not wrapped; the fix (EdgeHeadingPrior.evaluate) returns wrap_angle(e).
        _, jac = EdgeHeadingPrior.evaluate(states, z, params, jacobians)
        e = (states[0][:, 2] + params["offset"] - z[:, 0])[:, None]
        return e, jac
