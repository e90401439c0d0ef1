"""Argument checks shared by every module: each names the argument and what was expected (ValueError).

The bottom layer of ``helpers`` (with ``paths``): it imports only numpy, so any module may use it.
"""
from __future__ import annotations

import numbers

import numpy as np

__all__ = ["integer", "positive_number", "finite_number", "int_array", "index_list", "finite_vector",
           "feature_columns"]


def integer(value, name: str, minimum: int | None = None, below: int | None = None, allow_none: bool = False):
    """``value`` as an int; bool, non-integers and values outside [``minimum``, ``below``) raise ValueError naming
    ``name``. With ``allow_none`` None is accepted and returned as is."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or (minimum is not None and value < minimum) \
            or (below is not None and value >= below):
        if below is not None:
            expected = f"an integer in [{0 if minimum is None else minimum}, {below})"
        elif minimum is not None:
            expected = f"an integer ≥ {minimum}"
        else:
            expected = "an integer"
        raise ValueError(f"{name} must be {expected}{' or None' if allow_none else ''}, got {value!r}")
    return int(value)


def positive_number(value, name: str) -> float:
    """``value`` as a float > 0 and finite; anything else raises ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return float(value)


def finite_number(value, name: str) -> float:
    """``value`` as a finite float; bool, non-numbers, NaN and ±inf raise ValueError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def int_array(values, name: str) -> np.ndarray:
    """``values`` as a 1-D int64 array; other shapes or non-integer dtypes raise ValueError naming ``name``."""
    arr = np.asarray(values)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D integer array, got shape {arr.shape}")
    if arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must contain integers, got dtype {arr.dtype}")
    return arr.astype(np.int64)


def index_list(values, n: int, name: str, kind: str = "", integral_floats: bool = False) -> np.ndarray:
    """A non-empty selection of indices in [0, n) as a 1-D intp array (a scalar is a selection of one).

    ``kind`` names what is indexed in the messages (e.g. ``"landmark "``); with ``integral_floats`` floats that
    are whole numbers are accepted. Anything else raises ValueError naming ``name``."""
    arr = np.asarray(values)
    if arr.ndim == 0:
        arr = arr.reshape(1)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty 1-D list of {kind}indices, got shape {arr.shape}")
    if arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer):
        if integral_floats and np.issubdtype(arr.dtype, np.floating) and np.all(np.isfinite(arr)) \
                and np.all(arr == np.round(arr)):
            arr = arr.astype(np.intp)
        else:
            raise ValueError(f"{name} must contain integer {kind}indices, got dtype {arr.dtype}")
    if np.any(arr < 0) or np.any(arr >= n):
        raise ValueError(f"{name} has {'a' if kind else 'an'} {kind}index out of range [0, {n}): {arr.tolist()}")
    return arr.astype(np.intp)


def finite_vector(values, name: str, size: int | None = None) -> np.ndarray:
    """``values`` as a finite 1-D float array (of length ``size`` if given); anything else raises ValueError
    naming ``name``."""
    x = np.asarray(values, dtype=float)
    if x.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {x.shape}")
    if size is not None and x.shape[0] != size:
        raise ValueError(f"{name} must have shape ({size},), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return x


def feature_columns(Y, name: str = "Y", allow_empty: bool = True) -> np.ndarray:
    """Measured image features as a finite 2 × m float array, one feature (x, y pixels) per column.

    m = 0 is accepted unless ``allow_empty`` is False. Anything else raises ValueError naming ``name``."""
    Y = np.asarray(Y, dtype=float)
    if Y.ndim != 2 or Y.shape[0] != 2 or (Y.shape[1] == 0 and not allow_empty):
        least = 0 if allow_empty else 1
        raise ValueError(f"{name} must have shape (2, m) with m >= {least} features as columns, got {Y.shape}")
    if not np.all(np.isfinite(Y)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return Y
