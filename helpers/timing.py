"""Wall-clock timing shared by the benchmarks in the notebooks (``time.perf_counter``, in seconds).

``best_of`` keeps the fastest of several calls: best-of-k timing is the least sensitive to other processes.
"""
from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from .validation import function, integer

__all__ = ["timed", "best_of"]


def timed(fn: Callable, *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """(result, seconds) of one call ``fn(*args, **kwargs)``; ``fn``'s own exceptions propagate unchanged."""
    function(fn, "fn")
    t0 = time.perf_counter()
    result = fn(*args, **kwargs)
    return result, time.perf_counter() - t0


def best_of(repeats: int, fn: Callable, *args: Any, **kwargs: Any) -> tuple[Any, float]:
    """(result of the last call, fastest wall time in seconds) of ``repeats`` calls ``fn(*args, **kwargs)``."""
    repeats = integer(repeats, "repeats", minimum=1)
    best = float("inf")
    for _ in range(repeats):
        result, seconds = timed(fn, *args, **kwargs)
        best = min(best, seconds)
    return result, best
