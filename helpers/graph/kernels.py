"""Compiled fast paths (numba): one loop over the edges of a class, for the models where that clearly pays off.

Each kernel computes the numbers of a readable numpy reference that lives next to the model's equations (the
edge class's ``evaluate_reference``); the class's ``evaluate`` calls the kernel, and the tests check both against
each other on random states. Keep a kernel only while it is clearly faster than its reference on large batches
(W10000-sized: 64k edges); measured there, both kernels below take a third to a half of the reference's time.

wrap_angle_scalar(θ)                          numba twin of ``angles.wrap_angle`` for one float (same bits)
se2_log_coefficients_scalar(θ)                α, β, α' of ``edges2d.se2_log_coefficients`` for one float
se2_between(xi, xj, z, jacobians)             ``EdgeSE2``: e (E, 3), J_i, J_j (E, 3, 3)
vehicle_kinematics(xk, xn, z, dt, jacobians)  DriveBot's ``VehicleKinematicsEdge``: e (E, 3), J_k, J_{k+1}
                                              (E, 3, 3), or (0, 3, 3) arrays when ``jacobians`` is false

The two batch kernels are called through thin Python wrappers that check the array shapes first (compiled code
does not bounds-check: a short array would be read past its end); the compiled loops are ``_se2_between`` and
``_vehicle_kinematics``.
"""

import numpy as np
from numba import njit

__all__ = ["wrap_angle_scalar", "se2_log_coefficients_scalar", "se2_between", "vehicle_kinematics"]

_TWO_PI = 2.0 * np.pi


@njit(cache=True)
def wrap_angle_scalar(theta):
    """θ − 2π·floor((θ + π) / 2π), folded into [−π, π): ``angles.wrap_angle`` for one float, compiled."""
    out = theta - _TWO_PI * np.floor((theta + np.pi) / _TWO_PI)
    if out >= np.pi:
        out -= _TWO_PI
    return out


@njit(cache=True)
def se2_log_coefficients_scalar(theta):
    """(α, β, α') with α = (θ/2)·cot(θ/2), β = θ/2, α' = dα/dθ (series for |θ| < 1e-4)."""
    if abs(theta) < 1e-4:
        t2 = theta * theta
        return 1.0 - t2 / 12.0 - t2 * t2 / 720.0, 0.5 * theta, -theta / 6.0 - t2 * theta / 180.0
    half = 0.5 * theta
    cot = np.cos(half) / np.sin(half)
    return half * cot, 0.5 * theta, 0.5 * cot - 0.25 * theta / np.sin(half) ** 2


def _check_rows(name, arrays, width):
    """Every array in ``arrays`` (name -> array) must be 2-D (E, width) with the same E; ValueError otherwise."""
    count = None
    for key, arr in arrays.items():
        shape = np.shape(arr)
        if len(shape) != 2 or shape[1] != width or (count is not None and shape[0] != count):
            raise ValueError(f"{name}: {key} must have shape (E, {width}) with the same E for every array, "
                             f"got {shape}")
        count = shape[0]
    return count


def se2_between(xi, xj, z, jacobians):
    """EdgeSE2 for E edges in one compiled loop: (e (E, 3), J_i, J_j (E, 3, 3)); xi, xj, z are (E, 3)."""
    _check_rows("se2_between", {"xi": xi, "xj": xj, "z": z}, 3)
    return _se2_between(xi, xj, z, jacobians)


def vehicle_kinematics(xk, xn, z, dt, jacobians):
    """DriveBot's kinematics edge for E edges in one compiled loop; xk, xn, z (E, 3), dt (E,)."""
    count = _check_rows("vehicle_kinematics", {"xk": xk, "xn": xn, "z": z}, 3)
    if np.shape(dt) != (count,):
        raise ValueError(f"vehicle_kinematics: dt must have shape ({count},), got {np.shape(dt)}")
    return _vehicle_kinematics(xk, xn, z, dt, jacobians)


@njit(cache=True)
def _se2_between(xi, xj, z, jacobians):
    """EdgeSE2 for E edges in one loop; the names follow the equations in ``edges2d.EdgeSE2``'s docstring."""
    n = len(z)
    e = np.empty((n, 3))
    m = n if jacobians else 0                  # no Jacobian arrays when only the errors are asked for
    ji = np.empty((m, 3, 3))                   # every entry is written below
    jj = np.empty((m, 3, 3))
    for t in range(n):
        c_i, s_i = np.cos(xi[t, 2]), np.sin(xi[t, 2])
        c_z, s_z = np.cos(z[t, 2]), np.sin(z[t, 2])
        dx, dy = xj[t, 0] - xi[t, 0], xj[t, 1] - xi[t, 1]
        q_x, q_y = c_i * dx + s_i * dy, -s_i * dx + c_i * dy          # q = R(ψ_i)ᵀ (t_j − t_i)
        u_x, u_y = q_x - z[t, 0], q_y - z[t, 1]
        td_x, td_y = c_z * u_x + s_z * u_y, -s_z * u_x + c_z * u_y    # t_d = R(θ_z)ᵀ (q − t_z)
        theta = wrap_angle_scalar(xj[t, 2] - xi[t, 2] - z[t, 2])       # θ_d
        alpha, beta, dalpha = se2_log_coefficients_scalar(theta)
        e[t, 0] = alpha * td_x + beta * td_y                              # e = [V⁻¹(θ_d) t_d, θ_d]
        e[t, 1] = -beta * td_x + alpha * td_y
        e[t, 2] = theta
        if not jacobians:
            continue
        c_iz, s_iz = np.cos(xi[t, 2] + z[t, 2]), np.sin(xi[t, 2] + z[t, 2])
        jj[t, 0, 0], jj[t, 0, 1] = alpha * c_iz - beta * s_iz, alpha * s_iz + beta * c_iz  # M = V⁻¹ R(ψ_i + θ_z)ᵀ
        jj[t, 1, 0], jj[t, 1, 1] = -beta * c_iz - alpha * s_iz, -beta * s_iz + alpha * c_iz
        d_x, d_y = dalpha * td_x + 0.5 * td_y, -0.5 * td_x + dalpha * td_y      # D = (dV⁻¹/dθ) t_d
        p_x, p_y = c_z * q_y - s_z * q_x, -s_z * q_y - c_z * q_x              # p = R(θ_z)ᵀ [q_y, −q_x]
        jj[t, 0, 2], jj[t, 1, 2], jj[t, 2, 2] = d_x, d_y, 1.0
        ji[t, 0, 0], ji[t, 0, 1] = -jj[t, 0, 0], -jj[t, 0, 1]
        ji[t, 1, 0], ji[t, 1, 1] = -jj[t, 1, 0], -jj[t, 1, 1]
        ji[t, 0, 2] = (alpha * p_x + beta * p_y) - d_x                      # V⁻¹ p − D
        ji[t, 1, 2] = (-beta * p_x + alpha * p_y) - d_y
        ji[t, 2, 2] = -1.0
        ji[t, 2, 0] = ji[t, 2, 1] = jj[t, 2, 0] = jj[t, 2, 1] = 0.0
    return e, ji, jj


@njit(cache=True)
def _vehicle_kinematics(xk, xn, z, dt, jacobians):
    """e = Mᵀ(ψ_k) Δ / ΔT − u and J_k, J_{k+1} (``helpers.drivebot.edges``' docstring) for E edges in one loop."""
    n = z.shape[0]
    e = np.empty((n, 3))
    m = n if jacobians else 0
    jk = np.empty((m, 3, 3))                   # every entry is written below
    jn = np.empty((m, 3, 3))
    for t in range(n):
        c, s = np.cos(xk[t, 2]), np.sin(xk[t, 2])
        inv_dt = 1.0 / dt[t]
        dx, dy = xn[t, 0] - xk[t, 0], xn[t, 1] - xk[t, 1]
        dpsi = wrap_angle_scalar(xn[t, 2] - xk[t, 2])
        e[t, 0] = (c * dx + s * dy) * inv_dt - z[t, 0]
        e[t, 1] = (-s * dx + c * dy) * inv_dt - z[t, 1]
        e[t, 2] = dpsi * inv_dt - z[t, 2]
        if jacobians:
            jk[t, 0, 0], jk[t, 0, 1], jk[t, 0, 2] = -c * inv_dt, -s * inv_dt, (-dx * s + dy * c) * inv_dt
            jk[t, 1, 0], jk[t, 1, 1], jk[t, 1, 2] = s * inv_dt, -c * inv_dt, (-dx * c - dy * s) * inv_dt
            jk[t, 2, 2] = -inv_dt
            jn[t, 0, 0], jn[t, 0, 1] = c * inv_dt, s * inv_dt
            jn[t, 1, 0], jn[t, 1, 1] = -s * inv_dt, c * inv_dt
            jn[t, 2, 2] = inv_dt
            jk[t, 2, 0] = jk[t, 2, 1] = 0.0
            jn[t, 0, 2] = jn[t, 1, 2] = jn[t, 2, 0] = jn[t, 2, 1] = 0.0
    return e, jk, jn
