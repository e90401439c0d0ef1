"""Precision and recall that stay honest when they are undefined, and their plot.

``TrialResults.summary()`` (``helpers.association.evaluation``) reports precision 1 when an algorithm made
no pairing at all. That ratio is 0/0: nothing was claimed, so nothing was claimed right *or* wrong.
:func:`rates` returns NaN there (and for recall when the trials hold no true pairing), :func:`fmt_rate`
prints it as "n/a", and :func:`plot_rates` leaves a gap with the undefined range shaded and labelled.
"""
from __future__ import annotations

import numbers

import numpy as np

from ..figures import COLORS
from ..validation import boolean, float_array

__all__ = ["rates", "fmt_rate", "plot_rates"]


def rates(results, name: str) -> dict:
    """Micro-averaged ``precision`` = TP / pairings made and ``recall`` = TP / true pairings of algorithm
    ``name`` in a ``TrialResults``; NaN when the denominator is 0. Also the summed counts ``tp``,
    ``n_pred``, ``n_true``."""
    if not isinstance(getattr(results, "counts", None), dict):
        raise ValueError(f"results must be a TrialResults (run_trials / sweep), got {type(results).__name__}")
    if name not in results.counts:
        raise ValueError(f"name {name!r} is not one of the algorithms in results: {list(results.counts)}")
    c = results.counts[name]
    tp, n_pred, n_true = (int(np.sum(c[key])) for key in ("tp", "n_pred", "n_true"))
    return {"precision": tp / n_pred if n_pred else float("nan"),
            "recall": tp / n_true if n_true else float("nan"),
            "tp": tp, "n_pred": n_pred, "n_true": n_true}


def fmt_rate(value, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals, or "n/a" (padded to the same width) when it is NaN."""
    if isinstance(digits, bool) or not isinstance(digits, int) or digits < 0:
        raise ValueError(f"digits must be a non-negative integer, got {digits!r}")
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"value must be a real number (NaN prints as n/a), got {value!r}")
    text = f"{value:.{digits}f}" if np.isfinite(value) else "n/a"
    return text.rjust(digits + 2)


def plot_rates(ax, x, precision, recall, logx: bool = True, undefined_label: str = "no pairing made: "
               "precision undefined (0/0)"):
    """Precision (circles) and recall (squares) against ``x``; where precision is NaN the line has a gap
    and the x-range is shaded grey (its legend entry says why). Returns the shaded x-range or None."""
    logx = boolean(logx, "logx")
    x, precision, recall = (float_array(a, n) for a, n in ((x, "x"), (precision, "precision"), (recall, "recall")))
    if not (x.shape == precision.shape == recall.shape) or x.ndim != 1:
        raise ValueError("x, precision and recall must be 1-D arrays of the same length")
    if not np.all(np.isfinite(x)) or (logx and np.any(x <= 0)):
        raise ValueError(f"x must be finite{' and positive (log axis)' if logx else ''}, got {x.tolist()}")
    if not hasattr(ax, "plot"):
        raise ValueError(f"ax must be a matplotlib Axes, got {type(ax).__name__}")
    plot = ax.semilogx if logx else ax.plot
    plot(x, precision, "o-", color=COLORS["estimate"], label="precision")
    plot(x, recall, "s-", color=COLORS["bound"], label="recall")
    undefined = ~np.isfinite(precision)
    span = None
    if undefined.any():
        lo, hi = x[undefined].min(), x[undefined].max()
        defined_below = x[~undefined & (x < lo)]
        left = np.sqrt(lo * defined_below.max()) if (logx and defined_below.size) else lo
        ax.axvspan(left, hi, color=COLORS["muted"], alpha=0.18, lw=0, label=undefined_label)
        span = (float(left), float(hi))
    return span
