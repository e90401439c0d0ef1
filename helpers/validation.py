"""Argument checks shared by every module: each names the argument and what was expected (ValueError)."""
from __future__ import annotations

import numbers

import numpy as np

__all__ = ["integer", "positive_number", "int_array"]


def integer(value, name: str, minimum: int | None = None) -> int:
    """``value`` as an int; bool, non-integers and values below ``minimum`` raise ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or (minimum is not None and value < minimum):
        expected = "an integer" if minimum is None else f"an integer ≥ {minimum}"
        raise ValueError(f"{name} must be {expected}, got {value!r}")
    return int(value)


def positive_number(value, name: str) -> float:
    """``value`` as a float > 0 and finite; anything else raises ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return float(value)


def int_array(values, name: str) -> np.ndarray:
    """``values`` as a 1-D int64 array; other shapes or non-integer dtypes raise ValueError naming ``name``."""
    arr = np.asarray(values)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D integer array, got shape {arr.shape}")
    if arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must contain integers, got dtype {arr.dtype}")
    return arr.astype(np.int64)
