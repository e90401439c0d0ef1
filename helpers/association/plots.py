"""Figures for the association notebooks: gates, pairings, the JCBB interpretation tree, and the
ground-truth evaluation (rates with Wilson intervals against one factor, JCBB's cost against m)."""
from __future__ import annotations

import matplotlib.ticker as mticker
import numpy as np

from ..figures import COLORS
from ..validation import feature_columns, float_array, index_list
from .common import check_hypothesis
from .compatibility import check_bundle_density
from .evaluation import RATES, check_results
from .jcbb import TRACE_BEST, TRACE_BOUND, TRACE_EXPANDED, TRACE_JC_FAIL, JCBBTrace

__all__ = ["draw_gates", "draw_association", "draw_interpretation_tree", "tree_layout", "ALGORITHM_STYLE",
           "algorithm_style", "plot_rate_sweep", "log_count_axis", "draw_node_counts", "draw_times"]

#: One colour (from the workbook's palette) and marker per association algorithm.
ALGORITHM_STYLE = {
    "NN": dict(color=COLORS["muted"], marker="o"),
    "ICNN": dict(color=COLORS["estimate"], marker="s"),
    "ML": dict(color=COLORS["truth"], marker="^"),
    "SNN": dict(color=COLORS["bound"], marker="v"),
    "JCBB": dict(color=COLORS["alt"], marker="D"),
}


def draw_gates(ax, density, n_sigma: float = 3.0, landmarks=None, color=None, label_landmarks=True):
    """Each landmark's predicted mean ('+') and its n_σ gate (the marginal confidence ellipse)."""
    n = check_bundle_density(density, allow_empty=False)
    if landmarks is not None:
        empty = np.size(landmarks) == 0
        landmarks = [] if empty else index_list(landmarks, n, "landmarks", kind="landmark ")
    color = COLORS["estimate"] if color is None else color
    mu = density.mean.reshape(n, 2)
    for k in range(n) if landmarks is None else landmarks:
        E = density.marginal([2 * k, 2 * k + 1]).confidence_ellipse(n_sigma)
        ax.plot(E[0], E[1], color=color, lw=0.9, alpha=0.8)
        ax.plot(*mu[k], "+", color=color, ms=8, mew=1.5)
        if label_landmarks:
            ax.annotate(str(k), mu[k], textcoords="offset points", xytext=(4, 4), color=color, fontsize=8)


def draw_association(ax, density, Y, idx, truth=None, title=None, n_sigma: float = 3.0, landmarks=None,
                     label_landmarks=True):
    """Gates, observations (black dots) and the pairings of ``idx`` (one entry per landmark): a line from
    the predicted mean to the paired observation, green when it matches ``truth``, red when not
    (blue when no truth is given)."""
    n = check_bundle_density(density, allow_empty=False)
    Y = feature_columns(float_array(Y, "Y"))
    idx = check_hypothesis(idx, n, Y.shape[1], "idx")
    truth = None if truth is None else check_hypothesis(truth, n, Y.shape[1], "truth")
    draw_gates(ax, density, n_sigma, landmarks=landmarks, label_landmarks=label_landmarks)
    mu = density.mean.reshape(-1, 2)
    ax.plot(Y[0], Y[1], "o", color=COLORS["truth"], ms=4, label="observations")
    for k in np.flatnonzero(idx >= 0):
        ok = None if truth is None else bool(truth[k] == idx[k])
        col = COLORS["estimate"] if ok is None else (COLORS["alt"] if ok else COLORS["bound"])
        ax.plot([mu[k, 0], Y[0, idx[k]]], [mu[k, 1], Y[1, idx[k]]], "-", color=col, lw=2.0)
    if truth is not None:
        ax.plot([], [], "-", color=COLORS["alt"], lw=2, label="correct pairing")
        ax.plot([], [], "-", color=COLORS["bound"], lw=2, label="wrong pairing")
    ax.set_aspect("equal")
    if title:
        ax.set_title(title)


def tree_layout(trace: JCBBTrace):
    """(x, y) of every trace node: leaves of the recorded tree at consecutive x in visiting order,
    parents centred over their children, y = −depth."""
    if not isinstance(trace, JCBBTrace):
        raise ValueError(f"trace must be a JCBBTrace (jcbb(..., trace=True).stats['trace']), "
                         f"got {type(trace).__name__}")
    n = trace.parent.size
    children = [[] for _ in range(n)]
    for i in range(1, n):
        children[trace.parent[i]].append(i)
    x = np.zeros(n)
    y = -(trace.level + 1).astype(float)
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
    return x, y


def draw_interpretation_tree(ax, trace: JCBBTrace, best_idx=None):
    """Draw the searched interpretation tree. Edges are labelled with the observation taken (∗ = star).
    Expanded nodes: dots; the incumbents (new Best): green; JC-gate rejections: red ×; bound cuts: grey
    squares. If ``best_idx`` is given, the path of the final hypothesis is drawn thick."""
    x, y = tree_layout(trace)
    n = trace.parent.size
    on_best = np.zeros(n, dtype=bool)
    if best_idx is not None:
        # the final hypothesis: the last BEST node; walk up to the root
        best_nodes = np.flatnonzero(trace.status == TRACE_BEST)
        if best_nodes.size:
            i = int(best_nodes[-1])
            while i >= 0:
                on_best[i] = True
                i = int(trace.parent[i])
    style = {TRACE_EXPANDED: dict(color=COLORS["truth"], ls="-"), TRACE_BEST: dict(color=COLORS["alt"], ls="-"),
             TRACE_JC_FAIL: dict(color=COLORS["bound"], ls=":"), TRACE_BOUND: dict(color=COLORS["muted"], ls="--")}
    for i in range(1, n):
        p = trace.parent[i]
        st = style[int(trace.status[i])]
        ax.plot([x[p], x[i]], [y[p], y[i]], color=st["color"], ls=st["ls"],
                lw=2.6 if on_best[i] else 0.9, zorder=1)
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


def algorithm_style(name: str) -> dict:
    """Colour and marker of an algorithm (``ALGORITHM_STYLE``; other names get the muted colour)."""
    if not isinstance(name, str):
        raise ValueError(f"name must be an algorithm name (str), got {type(name).__name__}")
    return dict(ALGORITHM_STYLE.get(name, dict(color=COLORS["muted"], marker="x")))


def plot_rate_sweep(ax, results, key: str, confidence: float = 0.95, names=None, jitter: float = 0.0):
    """One line per algorithm: the rate ``key`` (precision / recall / accuracy) of ``results``
    ({factor value: TrialResults}) against the factor value, with Wilson ``confidence`` intervals as error
    bars. ``jitter`` shifts the algorithms' x positions apart (in data units) so the bars do not overlap."""
    known = check_results(results, names)
    if key not in RATES:
        raise ValueError(f"key must be one of {list(RATES)}, got {key!r}")
    names = list(known if names is None else names)
    xs = float_array(list(results), "results (its keys, the factor values)")
    for j, name in enumerate(names):
        rate = np.array([results[v].summary()[name][key] for v in results])
        ci = np.array([results[v].interval(name, key, confidence) for v in results])
        shift = jitter * (j - 0.5 * (len(names) - 1))
        yerr = np.clip(np.vstack([rate - ci[:, 0], ci[:, 1] - rate]), 0.0, None)
        ax.errorbar(xs + shift, rate, yerr=yerr, capsize=2.5, ms=5, label=name, **algorithm_style(name))


def log_count_axis(ax, axis: str = "y"):
    """A log axis with plain labels at the powers of ten (1, 10, 100, 1 000, …) and unlabelled minor ticks;
    the lower limit is moved down to a power of ten, so at least one labelled tick is visible."""
    if axis not in ("x", "y"):
        raise ValueError(f"axis must be 'x' or 'y', got {axis!r}")
    target = ax.yaxis if axis == "y" else ax.xaxis
    (ax.set_yscale if axis == "y" else ax.set_xscale)("log")
    lo, hi = ax.get_ylim() if axis == "y" else ax.get_xlim()
    data_lo = ax.dataLim.y0 if axis == "y" else ax.dataLim.x0
    if lo > 0 and hi > 0 and np.isfinite(data_lo) and data_lo > 0:
        lo = min(lo, 10.0 ** np.floor(np.log10(data_lo)))      # the decade below the smallest value
        (ax.set_ylim if axis == "y" else ax.set_xlim)(lo, hi)
    target.set_major_locator(mticker.LogLocator(base=10.0, numticks=12))
    target.set_major_formatter(mticker.FuncFormatter(lambda v, _: f"{v:,.0f}".replace(",", " ") if v >= 1
                                                     else f"{v:g}"))
    target.set_minor_locator(mticker.LogLocator(base=10.0, subs=np.arange(2, 10), numticks=12))
    target.set_minor_formatter(mticker.NullFormatter())


def draw_node_counts(ax, cost, max_nodes=None, name: str = "JCBB"):
    """Median and maximum expanded nodes of algorithm ``name`` against m (``cost``: {m: TrialResults}),
    with the node budget ``max_nodes`` as a labelled horizontal line and the number of searches it cut."""
    check_results(cost, [name])
    ms = list(cost)
    nodes = [cost[m].counts[name]["nodes"] for m in ms]
    col = algorithm_style(name)["color"]
    ax.plot(ms, [np.median(v) for v in nodes], "o-", color=col, label="median")
    ax.plot(ms, [np.max(v) for v in nodes], "o--", color=col, alpha=0.6, label="maximum")
    if max_nodes is not None:
        n_cut = sum(int(cost[m].counts[name]["exhausted"].sum()) for m in ms)
        n_all = sum(cost[m].n_trials for m in ms)
        ax.axhline(max_nodes, color=COLORS["bound"], ls=":", lw=1.2,
                   label=f"node budget {max_nodes:,}".replace(",", " ") + f" (cut {n_cut} of {n_all} searches)")
    ax.set_xticks(ms)
    log_count_axis(ax)
    ax.set_xlabel("observed landmarks m (+ clutter)")
    ax.set_ylabel(f"{name} expanded nodes per scene")
    ax.legend(loc="upper left")


def draw_times(ax, cost, names):
    """Median (solid) and maximum (dashed) time per call of each algorithm in ``names`` against m, in ms
    (``cost``: {m: TrialResults})."""
    if isinstance(names, str):
        raise ValueError(f"names must be a list of algorithm names, got the string {names!r}")
    check_results(cost, list(names))
    ms = list(cost)
    for name in names:
        st = algorithm_style(name)
        times = [1e3 * cost[m].counts[name]["time"] for m in ms]
        ax.plot(ms, [np.median(t) for t in times], "-", label=f"{name} median", **st)
        ax.plot(ms, [np.max(t) for t in times], "--", alpha=0.6, label=f"{name} max", **st)
    ax.set_xticks(ms)
    log_count_axis(ax)
    ax.set_xlabel("observed landmarks m (+ clutter)")
    ax.set_ylabel("time per call [ms]")
