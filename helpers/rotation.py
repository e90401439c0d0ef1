"""Rotation matrices and roll-pitch-yaw (Euler) angles.

Conventions (course Lab 7, eq 12): right-handed, *active* rotations

    Rx(φ) = [[1, 0, 0], [0, c, −s], [0, s, c]]
    Ry(θ) = [[c, 0, s], [0, 1, 0], [−s, 0, c]]
    Rz(ψ) = [[c, −s, 0], [s, c, 0], [0, 0, 1]]

    rpy2rot([φ, θ, ψ]) = Rz(ψ) · Ry(θ) · Rx(φ)          (= e^{ψS(e3)} e^{θS(e2)} e^{φS(e1)})

and the inverse map

    rot2rpy(R) = [atan2(R21, R22), atan2(−R20, hypot(R21, R22)), atan2(R10, R00)].

Derivatives (S(·) the cross-product matrix, e1, e2, e3 the unit axes):

    ∂R/∂φ = Rz Ry Rx S(e1),   ∂R/∂θ = Rz Ry S(e2) Rx,   ∂R/∂ψ = Rz S(e3) Ry Rx.

Vectorised: an angle may be a scalar (→ 3×3) or an array of shape (...) (→ (..., 3, 3)); Euler-angle triples
are (3,) or (3, N) (→ (3, 3) or (N, 3, 3)).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .validation import float_array

__all__ = ["rotx", "roty", "rotz", "rpy2rot", "rot2rpy", "rpy2rot_derivatives"]


def _elementary(a: ArrayLike, axis: int, name: str, derivative: bool):
    a = float_array(a, name)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be finite, got {a!r}")
    c, s = np.cos(a), np.sin(a)
    R = np.zeros(a.shape + (3, 3))
    i, j = [(1, 2), (0, 2), (0, 1)][axis]
    R[..., axis, axis] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    # Ry has the sign flipped: [[c, 0, s], [0, 1, 0], [−s, 0, c]]
    sgn = -1.0 if axis == 1 else 1.0
    R[..., i, j] = -sgn * s
    R[..., j, i] = sgn * s
    if not derivative:
        return R
    dR = np.zeros_like(R)
    dR[..., i, i] = -s
    dR[..., j, j] = -s
    dR[..., i, j] = -sgn * c
    dR[..., j, i] = sgn * c
    return R, dR


def rotx(phi: ArrayLike, return_derivative: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Rx(φ); with ``return_derivative`` also dRx/dφ. Scalar → (3, 3); array (...) → (..., 3, 3)."""
    return _elementary(phi, 0, "phi", return_derivative)


def roty(theta: ArrayLike, return_derivative: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Ry(θ); with ``return_derivative`` also dRy/dθ."""
    return _elementary(theta, 1, "theta", return_derivative)


def rotz(psi: ArrayLike, return_derivative: bool = False) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Rz(ψ); with ``return_derivative`` also dRz/dψ."""
    return _elementary(psi, 2, "psi", return_derivative)


def _rpy(Theta: ArrayLike) -> np.ndarray:
    Theta = float_array(Theta, "Theta")
    if Theta.ndim not in (1, 2) or Theta.shape[0] != 3:
        raise ValueError(f"Theta must have shape (3,) or (3, N) (roll, pitch, yaw), got {Theta.shape}")
    if not np.all(np.isfinite(Theta)):
        raise ValueError("Theta must be finite")
    return Theta


def rpy2rot(Theta: ArrayLike) -> np.ndarray:
    """R = Rz(ψ) Ry(θ) Rx(φ) for Θ = [φ, θ, ψ]; Θ (3,) → (3, 3), Θ (3, N) → (N, 3, 3)."""
    Theta = _rpy(Theta)
    return rotz(Theta[2]) @ roty(Theta[1]) @ rotx(Theta[0])


def rpy2rot_derivatives(Theta: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(R, dR/dφ, dR/dθ, dR/dψ) for Θ = [φ, θ, ψ], each (3, 3) (or (N, 3, 3) for Θ of shape (3, N)).

    ∂R/∂φ = Rz Ry dRx,  ∂R/∂θ = Rz dRy Rx,  ∂R/∂ψ = dRz Ry Rx  (dRx = Rx S(e1) etc.).
    """
    Theta = _rpy(Theta)
    Rx, dRx = rotx(Theta[0], True)
    Ry, dRy = roty(Theta[1], True)
    Rz, dRz = rotz(Theta[2], True)
    RzRy = Rz @ Ry
    return RzRy @ Rx, RzRy @ dRx, Rz @ dRy @ Rx, dRz @ Ry @ Rx


def rot2rpy(R: ArrayLike) -> np.ndarray:
    """Roll-pitch-yaw angles of a rotation matrix: (3, 3) → (3,), (N, 3, 3) → (3, N).

    φ = atan2(R21, R22), θ = atan2(−R20, hypot(R21, R22)), ψ = atan2(R10, R00). The result satisfies
    rpy2rot(rot2rpy(R)) = R (it is one of the two equivalent angle sets, with θ ∈ [−π/2, π/2]).
    """
    R = float_array(R, "R")
    if R.ndim not in (2, 3) or R.shape[-2:] != (3, 3):
        raise ValueError(f"R must have shape (3, 3) or (N, 3, 3), got {R.shape}")
    if not np.all(np.isfinite(R)):
        raise ValueError("R must be finite")
    eye = np.broadcast_to(np.eye(3), R.shape)
    if not np.allclose(np.swapaxes(R, -1, -2) @ R, eye, atol=1e-6) or np.any(np.linalg.det(R) < 0):
        raise ValueError("R must be a rotation matrix (RᵀR = I, det R = +1)")
    phi = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    theta = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 2, 1], R[..., 2, 2]))
    psi = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    return np.stack([phi, theta, psi])
