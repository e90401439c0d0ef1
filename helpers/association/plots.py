"""Figures for the association notebooks: gates, pairings, the JCBB interpretation tree, and the ground-truth
evaluation (rates with Wilson intervals against one factor, JCBB's cost against m)."""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import matplotlib.ticker as mticker
import numpy as np
from matplotlib.axes import Axes
from numpy.typing import ArrayLike

from ..figures import COLORS
from ..gaussian import Gaussian
from ..validation import boolean, feature_columns, float_array, index_list, one_of
from .common import check_hypothesis
from .compatibility import check_bundle_density
from .evaluation import RATES, check_results
from .jcbb import TRACE_BEST, TRACE_BOUND, TRACE_EXPANDED, TRACE_JC_FAIL, JCBBTrace

__all__ = ["draw_gates", "draw_association", "draw_interpretation_tree", "ALGORITHM_STYLE", "plot_rate_sweep",
           "draw_node_counts", "draw_times", "plot_rates"]

#: One colour (from the workbook's palette) and marker per association algorithm (others: muted, 'x').
ALGORITHM_STYLE = {
    "NN": dict(color=COLORS["muted"], marker="o"),
    "ICNN": dict(color=COLORS["estimate"], marker="s"),
    "ML": dict(color=COLORS["truth"], marker="^"),
    "SNN": dict(color=COLORS["bound"], marker="v"),
    "JCBB": dict(color=COLORS["alt"], marker="D"),
}


def _style(name: str) -> dict:
    return dict(ALGORITHM_STYLE.get(name, dict(color=COLORS["muted"], marker="x")))


def draw_gates(ax: Axes, density: Gaussian, n_sigma: float = 3.0, landmarks: ArrayLike | None = None,
               color: str | None = None, label_landmarks: bool = True) -> None:
    """Each landmark's predicted mean ('+') and its n_σ gate (the marginal confidence ellipse); ``landmarks``
    selects which (default all)."""
    n = check_bundle_density(density, allow_empty=False)
    if landmarks is None:
        landmarks = range(n)
    elif np.size(landmarks):
        landmarks = index_list(landmarks, n, "landmarks", kind="landmark ")
    color = COLORS["estimate"] if color is None else color
    mu = density.mean.reshape(n, 2)
    for k in landmarks:
        E = density.marginal([2 * k, 2 * k + 1]).confidence_ellipse(n_sigma)
        ax.plot(E[0], E[1], color=color, lw=0.9, alpha=0.8)
        ax.plot(*mu[k], "+", color=color, ms=8, mew=1.5)
        if label_landmarks:
            ax.annotate(str(k), mu[k], textcoords="offset points", xytext=(4, 4), color=color, fontsize=8)


def draw_association(ax: Axes, density: Gaussian, Y: ArrayLike, idx: ArrayLike, truth: ArrayLike | None = None,
                     title: str | None = None, n_sigma: float = 3.0, landmarks: ArrayLike | None = None,
                     label_landmarks: bool = True) -> None:
    """Gates, observations (black dots) and the pairings of ``idx`` (one entry per landmark): a line from the
    predicted mean to the paired observation, green when it matches ``truth``, red when not (blue without
    truth)."""
    n = check_bundle_density(density, allow_empty=False)
    Y = feature_columns(Y)
    idx = check_hypothesis(idx, n, Y.shape[1], "idx")
    truth = None if truth is None else check_hypothesis(truth, n, Y.shape[1], "truth")
    draw_gates(ax, density, n_sigma, landmarks=landmarks, label_landmarks=label_landmarks)
    mu = density.mean.reshape(-1, 2)
    ax.plot(Y[0], Y[1], "o", color=COLORS["truth"], ms=4, label="observations")
    for k in np.flatnonzero(idx >= 0):
        col = COLORS["estimate"] if truth is None else (COLORS["alt"] if truth[k] == idx[k] else COLORS["bound"])
        ax.plot([mu[k, 0], Y[0, idx[k]]], [mu[k, 1], Y[1, idx[k]]], "-", color=col, lw=2.0)
    if truth is not None:
        ax.plot([], [], "-", color=COLORS["alt"], lw=2, label="correct pairing")
        ax.plot([], [], "-", color=COLORS["bound"], lw=2, label="wrong pairing")
    ax.set_aspect("equal")
    if title:
        ax.set_title(title)


def _tree_layout(trace: JCBBTrace) -> tuple[np.ndarray, np.ndarray]:
    """(x, y) of every trace node: leaves at consecutive x in visiting order, parents centred over their
    children, y = −depth."""
    n = trace.parent.size
    children = [[] for _ in range(n)]
    for i in range(1, n):
        children[trace.parent[i]].append(i)
    x = np.zeros(n)
    counter = [0.0]

    def place(i):                          # recursion depth ≤ tree depth (small trees only)
        if not children[i]:
            x[i] = counter[0]
            counter[0] += 1.0
            return
        for c in children[i]:
            place(c)
        x[i] = 0.5 * (x[children[i][0]] + x[children[i][-1]])

    place(0)
    return x, -(trace.level + 1).astype(float)


def draw_interpretation_tree(ax: Axes, trace: JCBBTrace, best_idx: ArrayLike | None = None) -> None:
    """Draw the searched interpretation tree (``jcbb(..., trace=True).stats["trace"]``). Edges are labelled with
    the observation taken (∗ = star). Expanded nodes: dots; new incumbents (Best): green; joint-gate rejections:
    red ×; bound cuts: grey squares. With ``best_idx`` the path of the final hypothesis is drawn thick."""
    if not isinstance(trace, JCBBTrace):
        raise ValueError(f"trace must be a JCBBTrace (jcbb(..., trace=True).stats['trace']), got {trace!r}")
    x, y = _tree_layout(trace)
    n = trace.parent.size
    on_best = np.zeros(n, dtype=bool)
    best_nodes = np.flatnonzero(trace.status == TRACE_BEST)
    i = int(best_nodes[-1]) if best_idx is not None and best_nodes.size else -1
    while i >= 0:                                        # the final hypothesis: the last Best, up to the root
        on_best[i] = True
        i = int(trace.parent[i])
    style = {TRACE_EXPANDED: dict(color=COLORS["truth"], ls="-"), TRACE_BEST: dict(color=COLORS["alt"], ls="-"),
             TRACE_JC_FAIL: dict(color=COLORS["bound"], ls=":"), TRACE_BOUND: dict(color=COLORS["muted"], ls="--")}
    for i in range(1, n):
        p = trace.parent[i]
        st = style[int(trace.status[i])]
        ax.plot([x[p], x[i]], [y[p], y[i]], color=st["color"], ls=st["ls"], lw=2.6 if on_best[i] else 0.9, zorder=1)
        lab = "∗" if trace.obs[i] < 0 else str(int(trace.obs[i]))
        ax.text(0.5 * (x[p] + x[i]), 0.5 * (y[p] + y[i]), lab, fontsize=7, ha="center", va="center",
                color=st["color"], bbox=dict(boxstyle="round,pad=0.1", fc="white", ec="none", alpha=0.8), zorder=3)
    for status, marker, col, lab in ((TRACE_EXPANDED, "o", COLORS["truth"], "expanded"),
                                     (TRACE_BEST, "o", COLORS["alt"], "new incumbent (Best)"),
                                     (TRACE_JC_FAIL, "x", COLORS["bound"], "rejected by the joint χ² gate"),
                                     (TRACE_BOUND, "s", COLORS["muted"], "cut by the bound")):
        sel = trace.status == status
        ax.scatter(x[sel], y[sel], marker=marker, color=col, s=22, zorder=2, label=lab)
    levels = int(trace.level.max()) + 1 if n > 1 else 0
    ax.set_yticks(-np.arange(levels + 1))
    ax.set_yticklabels(["root"] + [f"landmark {int(trace.landmark[np.flatnonzero(trace.level == t)[0]])}"
                                   if np.any(trace.level == t) else f"level {t}" for t in range(levels)])
    ax.set_xticks([])
    ax.grid(False)
    ax.legend(loc="lower left", fontsize=8)


def plot_rate_sweep(ax: Axes, results: Mapping, key: str, confidence: float = 0.95,
                    names: Sequence[str] | None = None, jitter: float = 0.0) -> None:
    """One line per algorithm: the rate ``key`` (precision / recall / accuracy) of ``results`` ({factor value:
    TrialResults}) against the factor value, with Wilson ``confidence`` intervals as error bars. ``jitter``
    shifts the algorithms' x positions apart (in data units) so the bars do not overlap."""
    known = check_results(results, names)
    names = list(known if names is None else names)
    key = one_of(key, "key", list(RATES))
    xs = np.asarray(list(results), dtype=float)
    for j, name in enumerate(names):
        rate = np.array([results[v].summary()[name][key] for v in results])
        ci = np.array([results[v].interval(name, key, confidence) for v in results])
        yerr = np.clip(np.vstack([rate - ci[:, 0], ci[:, 1] - rate]), 0.0, None)
        ax.errorbar(xs + jitter * (j - 0.5 * (len(names) - 1)), rate, yerr=yerr, capsize=2.5, ms=5, label=name,
                    **_style(name))


def _log_count_axis(ax: Axes) -> None:
    """A log y axis with plain labels at the powers of ten (1, 10, 100, 1 000, …) and unlabelled minor ticks;
    the lower limit moves down to a power of ten, so at least one labelled tick is visible."""
    ax.set_yscale("log")
    lo, hi = ax.get_ylim()
    if lo > 0 and hi > 0 and np.isfinite(ax.dataLim.y0) and ax.dataLim.y0 > 0:
        ax.set_ylim(min(lo, 10.0 ** np.floor(np.log10(ax.dataLim.y0))), hi)     # the decade below the data
    ax.yaxis.set_major_locator(mticker.LogLocator(base=10.0, numticks=12))
    ax.yaxis.set_major_formatter(mticker.FuncFormatter(lambda v, _: f"{v:,.0f}".replace(",", " ") if v >= 1
                                                       else f"{v:g}"))
    ax.yaxis.set_minor_locator(mticker.LogLocator(base=10.0, subs=np.arange(2, 10), numticks=12))
    ax.yaxis.set_minor_formatter(mticker.NullFormatter())


def draw_node_counts(ax: Axes, cost: Mapping, max_nodes: int | None = None, name: str = "JCBB") -> None:
    """Median and maximum expanded nodes of algorithm ``name`` against m (``cost``: {m: TrialResults}), with the
    node budget ``max_nodes`` as a labelled horizontal line and the number of searches it cut."""
    check_results(cost, [name])
    ms = list(cost)
    nodes = [cost[m].counts[name]["nodes"] for m in ms]
    col = _style(name)["color"]
    ax.plot(ms, [np.median(v) for v in nodes], "o-", color=col, label="median")
    ax.plot(ms, [np.max(v) for v in nodes], "o--", color=col, alpha=0.6, label="maximum")
    if max_nodes is not None:
        n_cut = sum(int(cost[m].counts[name]["exhausted"].sum()) for m in ms)
        n_all = sum(cost[m].n_trials for m in ms)
        ax.axhline(max_nodes, color=COLORS["bound"], ls=":", lw=1.2,
                   label=f"node budget {max_nodes:,}".replace(",", " ") + f" (cut {n_cut} of {n_all} searches)")
    ax.set_xticks(ms)
    _log_count_axis(ax)
    ax.set_xlabel("observed landmarks m (+ clutter)")
    ax.set_ylabel(f"{name} expanded nodes per scene")
    ax.legend(loc="upper left")


def draw_times(ax: Axes, cost: Mapping, names: Sequence[str]) -> None:
    """Median (solid) and maximum (dashed) time per call of each algorithm in ``names`` against m, in ms
    (``cost``: {m: TrialResults})."""
    check_results(cost, names)
    ms = list(cost)
    for name in names:
        times = [1e3 * cost[m].counts[name]["time"] for m in ms]
        ax.plot(ms, [np.median(t) for t in times], "-", label=f"{name} median", **_style(name))
        ax.plot(ms, [np.max(t) for t in times], "--", alpha=0.6, label=f"{name} max", **_style(name))
    ax.set_xticks(ms)
    _log_count_axis(ax)
    ax.set_xlabel("observed landmarks m (+ clutter)")
    ax.set_ylabel("time per call [ms]")


def plot_rates(ax: Axes, x: ArrayLike, precision: ArrayLike, recall: ArrayLike, logx: bool = True,
               undefined_label: str = "no pairing made: precision undefined (0/0)") -> tuple[float, float] | None:
    """Precision (circles) and recall (squares) of :func:`~helpers.association.evaluation.rates` against ``x``;
    where precision is NaN the line has a gap and the x-range is shaded grey (its legend entry says why).
    Returns the shaded x-range or None."""
    logx = boolean(logx, "logx")
    x, precision, recall = (float_array(a, n) for a, n in ((x, "x"), (precision, "precision"), (recall, "recall")))
    if not (x.shape == precision.shape == recall.shape) or x.ndim != 1:
        raise ValueError("x, precision and recall must be 1-D arrays of the same length")
    if not np.all(np.isfinite(x)) or (logx and np.any(x <= 0)):
        raise ValueError(f"x must be finite{' and positive (log axis)' if logx else ''}, got {x.tolist()}")
    plot = ax.semilogx if logx else ax.plot
    plot(x, precision, "o-", color=COLORS["estimate"], label="precision")
    plot(x, recall, "s-", color=COLORS["bound"], label="recall")
    undefined = ~np.isfinite(precision)
    if not undefined.any():
        return None
    lo, hi = x[undefined].min(), x[undefined].max()
    defined_below = x[~undefined & (x < lo)]
    left = np.sqrt(lo * defined_below.max()) if (logx and defined_below.size) else lo
    ax.axvspan(left, hi, color=COLORS["muted"], alpha=0.18, lw=0, label=undefined_label)
    return float(left), float(hi)
