"""DriveBot's vertices and the two edge models that differ from ``helpers.graph``'s standard 2D set.

Reused unchanged from ``helpers.graph`` (identical models):

    EdgePositionPrior   GPS with lever arm l:  e = [x, y] + R(ψ) l − z,
                        J = [[1, 0, −s l_x − c l_y], [0, 1, c l_x − s l_y]]   (the ψ column matters: |l| = 22.4 m)
    EdgeHeadingPrior    compass (the FIXED edge):  e = wrap(ψ + Δψ_C − z),  J = [0, 0, 1]
    EdgeRangeBearing    landmark:  e = [‖m − p‖ − z_r, wrap(atan2(d_y, d_x) − ψ − z_β)]

Defined here:

``VehicleVertex``  — ``VertexSE2`` (x ⊞ δ = x + δ, then ψ wrapped) that also stores its ``time``.
``LandmarkVertex`` — ``VertexPointXY`` (additive) that also stores its 1-based ``landmark_id``.

``VehicleKinematicsEdge`` — binary, z = u = [s, 0, ψ̇] (the previous odometry), parameter ``dt``:

    x_{k+1} = x_k + ΔT M(ψ_k)(u + v)      ⇒      e = v = Mᵀ(ψ_k) Δ / ΔT − u,
    Δ = [x_{k+1} − x_k, y_{k+1} − y_k, wrap(ψ_{k+1} − ψ_k)],  c = cos ψ_k, s = sin ψ_k,
    J_k     = (1/ΔT) [[−c, −s, −Δx s + Δy c], [s, −c, −Δx c − Δy s], [0, 0, −1]],
    J_{k+1} = Mᵀ(ψ_k) / ΔT.
    (Evaluated for all edges of the class by one compiled kernel, ``_kinematics_kernel``.)
    ``initialize()`` sets x_{k+1} = x_k ⊞ ΔT M(ψ_k) z (forward prediction, ψ wrapped) — see ``predict``.

``BuggyCompassEdge`` — the coursework's provided compass edge: e = ψ + Δψ_C − z with **no wrap**,
J = [0, 0, 1]. Once ψ + Δψ_C leaves [−π, π) while the simulator's z is wrapped, every residual is off by
2π. The fix is ``EdgeHeadingPrior``, which wraps e (J unchanged).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from ..graph import (BaseEdge, EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing, VertexPointXY, VertexSE2,
                     wrap_angle)

__all__ = ["VehicleVertex", "LandmarkVertex", "VehicleKinematicsEdge", "BuggyCompassEdge", "FixedCompassEdge",
           "GPSEdge", "LandmarkRangeBearingEdge", "predict"]

#: The fixed compass edge, the GPS edge and the landmark edge are the graph package's own classes.
FixedCompassEdge = EdgeHeadingPrior
GPSEdge = EdgePositionPrior
LandmarkRangeBearingEdge = EdgeRangeBearing


class VehicleVertex(VertexSE2):
    """Vehicle pose [x, y, ψ] at ``time`` (dimension 3; ⊞ wraps ψ)."""

    def __init__(self, time, id=None, estimate=None, fixed=False):
        super().__init__(id, estimate, fixed)
        self.time = float(time)


class LandmarkVertex(VertexPointXY):
    """Landmark position [x, y] with its 1-based ``landmark_id`` (dimension 2, additive ⊞)."""

    def __init__(self, landmark_id, id=None, estimate=None, fixed=False):
        super().__init__(id, estimate, fixed)
        self.landmark_id = int(landmark_id)


def predict(x, u, dt):
    """Forward process model x' = x + ΔT M(ψ) u, ψ' wrapped; x, u (E, 3) or (3,), dt (E,) or scalar."""
    x = np.asarray(x, dtype=float)
    u = np.asarray(u, dtype=float)
    dt = np.asarray(dt, dtype=float)
    if x.shape[-1:] != (3,) or u.shape[-1:] != (3,) or x.ndim > 2 or u.ndim > 2:
        raise ValueError(f"x and u must have shape (3,) or (E, 3), got {x.shape} and {u.shape}")
    if dt.ndim > 1 or not (np.all(np.isfinite(dt)) and np.all(dt > 0)):
        raise ValueError(f"dt must be positive and finite (scalar or (E,)), got {dt!r}")
    c, s = np.cos(x[..., 2]), np.sin(x[..., 2])
    out = np.empty(np.broadcast_shapes(x.shape, u.shape))
    out[..., 0] = x[..., 0] + dt * (c * u[..., 0] - s * u[..., 1])
    out[..., 1] = x[..., 1] + dt * (s * u[..., 0] + c * u[..., 1])
    out[..., 2] = wrap_angle(x[..., 2] + dt * u[..., 2])
    return out


@njit(cache=True)
def _kinematics_kernel(xk, xn, z, dt, jacobians):
    """e = Mᵀ(ψ_k) Δ / ΔT − u and (optionally) J_k, J_{k+1} for E edges in one compiled loop."""
    n = z.shape[0]
    e = np.empty((n, 3))
    m = n if jacobians else 0
    jk = np.zeros((m, 3, 3))
    jn = np.zeros((m, 3, 3))
    two_pi = 2.0 * np.pi
    for i in range(n):
        c = np.cos(xk[i, 2])
        s = np.sin(xk[i, 2])
        inv = 1.0 / dt[i]
        dx = xn[i, 0] - xk[i, 0]
        dy = xn[i, 1] - xk[i, 1]
        dpsi = xn[i, 2] - xk[i, 2]
        dpsi -= two_pi * np.floor((dpsi + np.pi) / two_pi)
        if dpsi >= np.pi:
            dpsi -= two_pi
        e[i, 0] = (c * dx + s * dy) * inv - z[i, 0]
        e[i, 1] = (-s * dx + c * dy) * inv - z[i, 1]
        e[i, 2] = dpsi * inv - z[i, 2]
        if jacobians:
            jk[i, 0, 0] = -c * inv
            jk[i, 0, 1] = -s * inv
            jk[i, 0, 2] = (-dx * s + dy * c) * inv
            jk[i, 1, 0] = s * inv
            jk[i, 1, 1] = -c * inv
            jk[i, 1, 2] = (-dx * c - dy * s) * inv
            jk[i, 2, 2] = -inv
            jn[i, 0, 0] = c * inv
            jn[i, 0, 1] = s * inv
            jn[i, 1, 0] = -s * inv
            jn[i, 1, 1] = c * inv
            jn[i, 2, 2] = inv
    return e, jk, jn


class VehicleKinematicsEdge(BaseEdge):
    """Velocity-form process model between consecutive vehicle poses, per-edge ``dt`` (module docstring)."""

    vertex_types = (VertexSE2, VertexSE2)
    measurement_dimension = 3
    parameters = {"dt": 0.1}

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        # Q1b: the process-model edge. e = Mᵀ(ψ_k) Δ / ΔT − u, analytic J_k and J_{k+1} (module docstring),
        # for every edge of the class at once.
        xk, xn = states
        dt = np.ascontiguousarray(params["dt"], dtype=float).reshape(-1)
        e, jk, jn = _kinematics_kernel(np.ascontiguousarray(xk), np.ascontiguousarray(xn),
                                       np.ascontiguousarray(z), dt, bool(jacobians))
        return (e, [jk, jn]) if jacobians else (e, None)

    def initialize(self) -> None:
        """Set the second vertex to the forward prediction x_k + ΔT M(ψ_k) z from the first."""
        a, b = self.vertex(0), self.vertex(1)
        if a is None or b is None:
            raise ValueError("VehicleKinematicsEdge.initialize: both vertices must be set")
        b.set_estimate(predict(a.estimate, self.measurement, float(self.dt)))


class BuggyCompassEdge(EdgeHeadingPrior):
    """The coursework's provided (buggy) compass edge: e = ψ + offset − z, NOT wrapped; J = [0, 0, 1].

    It is the fixed compass edge (``helpers.graph.EdgeHeadingPrior``, e = wrap(ψ + offset − z)) with the wrap
    left out, so once ψ + offset leaves [−π, π) every residual is off by 2π."""

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        # Q1c: the bug. e is not wrapped; the fix (EdgeHeadingPrior.evaluate) returns wrap_angle(e).
        _, jac = EdgeHeadingPrior.evaluate(states, z, params, jacobians)
        e = (states[0][:, 2] + params["offset"] - z[:, 0])[:, None]
        return e, jac
