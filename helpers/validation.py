"""Argument checks shared by every module: each names the argument and what was expected (ValueError).

The bottom layer of ``helpers`` (with ``paths``): it imports only numpy, so any module may use it.
"""
from __future__ import annotations

import numbers
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

__all__ = ["integer", "positive_number", "finite_number", "nonnegative_number", "probability", "int_array",
           "index_list", "finite_vector", "feature_columns", "float_array", "rng_seed", "boolean", "one_of", "function"]


def _real(value: Any) -> bool:
    """Whether ``value`` is a real number (not a bool)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def integer(value: Any, name: str, minimum: int | None = None, below: int | None = None,
            allow_none: bool = False) -> int | None:
    """``value`` as an int in [``minimum``, ``below``); bool and non-integers raise ValueError naming ``name``.
    With ``allow_none`` None is accepted and returned as is."""
    if value is None and allow_none:
        return None
    if type(value) is int and (minimum is None or value >= minimum) and (below is None or value < below):
        return value                                    # the common case, without the ABC checks below
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


def positive_number(value: Any, name: str) -> float:
    """``value`` as a float > 0 and finite; anything else raises ValueError naming ``name``."""
    if not _real(value) or not np.isfinite(value) or value <= 0:
        raise ValueError(f"{name} must be a positive finite number, got {value!r}")
    return float(value)


def finite_number(value: Any, name: str) -> float:
    """``value`` as a finite float; bool, non-numbers, NaN and ±inf raise ValueError naming ``name``."""
    if not _real(value) or not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return float(value)


def nonnegative_number(value: Any, name: str, what: str = "") -> float:
    """``value`` as a finite float ≥ 0 (``what`` says what the number is, in the message)."""
    if not _real(value) or not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number ≥ 0{f' ({what})' if what else ''}, got {value!r}")
    return float(value)


def probability(value: Any, name: str) -> float:
    """``value`` as a float in [0, 1]; anything else raises ValueError naming ``name``."""
    if not _real(value) or not 0.0 <= float(value) <= 1.0:
        raise ValueError(f"{name} must be a probability in [0, 1], got {value!r}")
    return float(value)


def int_array(values: Any, name: str) -> np.ndarray:
    """``values`` as a 1-D int64 array; other shapes or non-integer dtypes raise ValueError naming ``name``."""
    arr = np.asarray(values)
    if arr.ndim != 1:
        raise ValueError(f"{name} must be a 1-D integer array, got shape {arr.shape}")
    if arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must contain integers, got dtype {arr.dtype}")
    return arr.astype(np.int64)


def index_list(values: Any, n: int, name: str, kind: str = "", integral_floats: bool = False,
               distinct: bool = False) -> np.ndarray:
    """A non-empty selection of indices in [0, n) as a 1-D intp array (a scalar is a selection of one).

    ``kind`` names what is indexed in the messages (e.g. ``"landmark "``); with ``integral_floats`` whole-number
    floats are accepted; with ``distinct`` an index may appear only once."""
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
    if distinct and np.unique(arr).size != arr.size:
        raise ValueError(f"{name} must not repeat {'a' if kind else 'an'} {kind}index, got {arr.tolist()}")
    return arr.astype(np.intp)


def finite_vector(values: Any, name: str, size: int | None = None) -> np.ndarray:
    """``values`` as a finite 1-D float array (of length ``size`` if given)."""
    x = float_array(values, name)
    if x.ndim != 1:
        raise ValueError(f"{name} must be a 1-D array, got shape {x.shape}")
    if size is not None and x.shape[0] != size:
        raise ValueError(f"{name} must have shape ({size},), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return x


def feature_columns(Y: Any, name: str = "Y", allow_empty: bool = True) -> np.ndarray:
    """Measured image features as a finite 2 × m float array, one feature (x, y pixels) per column (m = 0 only
    with ``allow_empty``)."""
    Y = float_array(Y, name)
    if Y.ndim != 2 or Y.shape[0] != 2 or (Y.shape[1] == 0 and not allow_empty):
        least = 0 if allow_empty else 1
        raise ValueError(f"{name} must have shape (2, m) with m >= {least} features as columns, got {Y.shape}")
    if not np.all(np.isfinite(Y)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return Y


def float_array(values: Any, name: str) -> np.ndarray:
    """``values`` (any shape) as a float ndarray, without copying a float array. Text, None, bools, complex
    numbers and ragged or non-numeric sequences raise ValueError naming ``name``."""
    if type(values) is np.ndarray and values.dtype == np.float64:
        return values                                   # the common case: nothing to convert
    if isinstance(values, np.ndarray) and values.dtype.kind in "iuf":
        return np.asarray(values, dtype=float)
    try:
        raw = np.asarray(values)
    except (TypeError, ValueError):
        raw = None
    if raw is None or raw.dtype.kind not in "iuf":
        text = repr(values)
        text = text if len(text) <= 60 else text[:57] + "..."
        raise ValueError(f"{name} must be an array of real numbers, got {type(values).__name__} {text}")
    return raw.astype(float, copy=False)


def check_symmetric(P: np.ndarray, name: str) -> None:
    """ValueError naming ``name`` unless the square float array ``P`` is symmetric to round-off: entrywise
    |P − Pᵀ| ≤ 1e−12·max(1, max|P|) + 1e−10·|Pᵀ|."""
    if not np.all(np.abs(P - P.T) <= 1e-12 * max(1.0, float(np.max(np.abs(P), initial=0.0))) + 1e-10 * np.abs(P.T)):
        raise ValueError(f"{name} must be symmetric")


def rng_seed(seed: Any, name: str = "seed") -> Any:
    """``seed`` unchanged when ``numpy.random.default_rng`` reproduces it: a non-negative integer, a non-empty
    sequence of them, or a ``numpy.random.SeedSequence``."""
    if isinstance(seed, np.random.SeedSequence):
        return seed
    items = list(seed) if isinstance(seed, (list, tuple)) or (isinstance(seed, np.ndarray) and seed.ndim == 1) \
        else [seed]
    if not items or not all(isinstance(v, numbers.Integral) and not isinstance(v, bool) and v >= 0 for v in items):
        raise ValueError(f"{name} must be a non-negative integer or a sequence of them, got {seed!r}")
    return seed


def boolean(value: Any, name: str) -> bool:
    """``value`` as a bool: True or False (a numpy bool too); 1, "yes", None and the like raise ValueError."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {value!r}")
    return bool(value)


def one_of(value: Any, name: str, options: Iterable[str]) -> str:
    """``value`` unchanged when it is one of the strings ``options``; ValueError listing them otherwise."""
    if not isinstance(value, str) or value not in options:
        raise ValueError(f"{name} must be one of {', '.join(repr(o) for o in options)}, got {value!r}")
    return value


def function(value: Any, name: str, allow_none: bool = False) -> Callable | None:
    """``value`` unchanged when it is callable (or None with ``allow_none``); ValueError naming ``name`` otherwise."""
    if (value is None and allow_none) or callable(value):
        return value
    raise ValueError(f"{name} must be callable{' or None' if allow_none else ''}, got {value!r}")
