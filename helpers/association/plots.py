"""Figures for the association notebooks: gates, pairings and the JCBB interpretation tree."""
from __future__ import annotations

import numpy as np

from helpers.association.jcbb import TRACE_BEST, TRACE_BOUND, TRACE_EXPANDED, TRACE_JC_FAIL, JCBBTrace
from helpers.figures import COLORS

__all__ = ["draw_gates", "draw_association", "draw_interpretation_tree", "tree_layout"]


def draw_gates(ax, density, n_sigma: float = 3.0, landmarks=None, color=None, label_landmarks=True):
    """Each landmark's predicted mean ('+') and its n_σ gate (the marginal confidence ellipse)."""
    n = density.size // 2
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
    draw_gates(ax, density, n_sigma, landmarks=landmarks, label_landmarks=label_landmarks)
    Y = np.asarray(Y)
    mu = density.mean.reshape(-1, 2)
    ax.plot(Y[0], Y[1], "o", color=COLORS["truth"], ms=4, label="observations")
    idx = np.asarray(idx)
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
