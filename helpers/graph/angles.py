"""Angle wrapping shared by every module of the workbook.

wrap_angle(θ)     = θ − 2π·floor((θ + π) / 2π), element-wise, in [−π, π): the graph's edges and vertices.
wrap_angle_mod(θ) = (θ + π) mod 2π − π, the DriveBot simulator's form: the same interval, but it rounds θ + π, so
                    it can change an angle already inside [−π, π) in the last bit. The simulator keeps it so that
                    its runs stay identical.
"""
from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..validation import float_array

__all__ = ["wrap_angle", "wrap_angle_mod"]


def wrap_angle(theta: ArrayLike) -> float | np.ndarray:
    """Wrap angles (scalar or array, radians) into [−π, π). Returns a float or a new array (NaN stays NaN)."""
    arr = float_array(theta, "theta")
    out = arr - 2.0 * np.pi * np.floor((arr + np.pi) / (2.0 * np.pi))
    out = np.where(out >= np.pi, out - 2.0 * np.pi, out)       # round-off can land on +π: keep [−π, π) half-open
    return float(out) if out.ndim == 0 else out


def wrap_angle_mod(theta: ArrayLike) -> float | np.ndarray:
    """(θ + π) mod 2π − π, element-wise (the simulator's wrap); a float gives a float, anything else an array."""
    if isinstance(theta, float):
        return (theta + math.pi) % (2.0 * math.pi) - math.pi
    return (float_array(theta, "theta") + np.pi) % (2.0 * np.pi) - np.pi
