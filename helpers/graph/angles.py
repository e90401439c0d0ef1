"""Angle wrapping shared by every module of the workbook.

wrap_angle(θ) = θ − 2π·floor((θ + π) / 2π), element-wise, result in [−π, π).
(The coursework's ``normalize_theta`` adds or subtracts 2π once; this robust form agrees with it
except exactly at +π, which maps to −π, and for |θ| > 3π.)
"""

import numpy as np

__all__ = ["wrap_angle"]

_TWO_PI = 2.0 * np.pi


def wrap_angle(theta):
    """Wrap angles (scalar or array, radians) into [−π, π). Returns a float or a new array."""
    arr = np.asarray(theta, dtype=float)
    out = arr - _TWO_PI * np.floor((arr + np.pi) / _TWO_PI)
    # floating round-off can land exactly on +π; fold it to −π so the interval stays half-open
    out = np.where(out >= np.pi, out - _TWO_PI, out)
    if out.ndim == 0:
        return float(out)
    return out
