"""Wall-clock timing shared by the benchmarks in the notebooks (``time.perf_counter``, in seconds).

Bottom layer (imports only the standard library): ``timed`` times one call, ``best_of`` keeps the fastest
of several calls (best-of-k timing is the least sensitive to other processes and to cold caches).
"""
from __future__ import annotations

import time

from .validation import integer

__all__ = ["timed", "best_of"]


def timed(fn, *args, **kwargs):
    """(result, seconds) of one call ``fn(*args, **kwargs)``; ``fn``'s own exceptions propagate unchanged."""
    if not callable(fn):
        raise ValueError(f"fn must be callable, got {type(fn).__name__}")
    t0 = time.perf_counter()
    result = fn(*args, **kwargs)
    return result, time.perf_counter() - t0


def best_of(repeats: int, fn, *args, **kwargs):
    """(result of the last call, fastest wall time in seconds) of ``repeats`` calls ``fn(*args, **kwargs)``."""
    repeats = integer(repeats, "repeats", minimum=1)
    if not callable(fn):
        raise ValueError(f"fn must be callable, got {type(fn).__name__}")
    best = float("inf")
    for _ in range(repeats):
        result, seconds = timed(fn, *args, **kwargs)
        best = min(best, seconds)
    return result, best
