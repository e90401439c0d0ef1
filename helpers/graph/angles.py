"""Angle wrapping shared by every module of the workbook.

wrap_angle(θ)     = θ − 2π·floor((θ + π) / 2π), element-wise, result in [−π, π). Used by the graph's edges and
                    vertices. (The coursework's ``normalize_theta`` adds or subtracts 2π once; this robust form
                    agrees with it except exactly at +π, which maps to −π, and for |θ| > 3π.)
wrap_angle_mod(θ) = (θ + π) mod 2π − π, the DriveBot simulator's form. Same interval, but it rounds θ + π, so for
                    about 2 % of angles already inside [−π, π) it differs from θ in the last bit, where
                    ``wrap_angle`` returns θ unchanged. The simulator keeps it so that its runs stay identical.
"""

import math

import numpy as np

__all__ = ["wrap_angle", "wrap_angle_mod"]

_TWO_PI = 2.0 * np.pi


def _angles(theta):
    try:
        return np.asarray(theta, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"theta must be a number or an array of numbers (radians), got {theta!r}") from None


def wrap_angle(theta):
    """Wrap angles (scalar or array, radians) into [−π, π). Returns a float or a new array (NaN stays NaN)."""
    arr = _angles(theta)
    out = arr - _TWO_PI * np.floor((arr + np.pi) / _TWO_PI)
    # floating round-off can land exactly on +π; fold it to −π so the interval stays half-open
    out = np.where(out >= np.pi, out - _TWO_PI, out)
    if out.ndim == 0:
        return float(out)
    return out


def wrap_angle_mod(theta):
    """(θ + π) mod 2π − π, element-wise (the simulator's wrap). A float gives a float (plain Python arithmetic),
    anything else an array."""
    if isinstance(theta, float):
        return (theta + math.pi) % _TWO_PI - math.pi
    return (_angles(theta) + np.pi) % _TWO_PI - np.pi
