"""Evaluation harness of the Q3 notebooks (coursework Q3a(iv), Q3b(iii)): several variants × several seeds.

One run is one draw of the noise, so the notebooks compare variants by the mean and spread over seeds of
machine-independent quantities (``run_metrics``): graph size (``hessian_nnz``: non-zeros of the final H, a proxy
for the work per iteration), consistency (``chi2_in_band``: inside the 4σ interval), accuracy (RMS, m) and
certainty (median variances); wall times too, which depend on the machine and its load.
"""
from __future__ import annotations

import math

import numpy as np

from ..gaussian import chi2_interval, confidence_level
from ..validation import index_list
from .analysis import position_error_rms
from .runner import Results, run_variants

__all__ = ["run_metrics", "evaluate_seeds", "seed_summary", "format_seed_table", "plot_seed_bars",
           "failures", "spy_hessian", "paired", "format_relative", "METRIC_LABELS"]

#: axis labels (with units) of the metrics, for plots
METRIC_LABELS = {
    "vehicle_vertices": "vehicle vertices", "landmark_vertices": "landmark vertices",
    "kinematics_edges": "kinematics edges", "landmark_edges": "landmark (range-bearing) edges",
    "edges": "edges", "hessian_nnz": "non-zeros of H", "chi2": "χ²", "dof": "χ² degrees of freedom",
    "chi2_per_dof": "χ² / dof", "pose_rms": "vehicle position RMS error (m)",
    "landmark_rms": "landmark position RMS error (m)", "pos_var_median": "median P_xx + P_yy (m²)",
    "psi_var_median": "median P_ψψ (rad²)", "opt_time_total": "total optimisation time (s)",
    "opt_time_final": "final optimisation time (s)", "run_time": "whole run (s)",
}


def run_metrics(results: Results) -> dict:
    """The machine-independent quantities (module docstring) and the wall times of one run."""
    system = results.system
    graph = system.graph
    system.ensure_structure()
    # counted from the system's own lists and the graph, not with graph_statistics (the Q2c exercise), so that the
    # Q3 notebooks run without it: the vertices still in the graph, the kinematics edges still in it, and the
    # landmark (range-bearing) edges as the edges of the landmark vertices (each edge touches one landmark)
    edges = graph.edges()
    landmarks = [v for v in system.landmark_vertices.values() if v.graph is graph]
    dof = sum(e.measurement_dimension for e in edges) - graph.dimension
    lo, hi = chi2_interval(dof, confidence_level(4.0)) if dof >= 1 else (0.0, 0.0)   # = Results.chi2_bounds()
    chi2 = results.final_chi2
    ig = results.vehicle_in_graph
    P = results.vehicle_covariance_history
    pos_var = P[0] + P[1]
    free = ig & (pos_var > 0)
    x_l, _, ids = results.landmark_estimates()
    truth = results.scenario.landmarks[:, np.searchsorted(results.scenario.landmark_ids, ids)]
    ot = results.optimization_times
    return {
        "vehicle_vertices": sum(v.graph is graph for v in system.vehicle_vertices), "landmark_vertices": len(landmarks),
        "kinematics_edges": sum(e.graph is graph for e in system.process_model_edges),
        "landmark_edges": sum(v.number_of_edges() for v in landmarks), "edges": len(edges),
        "hessian_nnz": int(graph.hessian().nnz), "chi2": chi2, "dof": dof,
        "chi2_per_dof": chi2 / dof, "chi2_in_band": bool(lo <= chi2 <= hi),
        "pose_rms": position_error_rms(results.vehicle_state_history[:2], results.vehicle_true_state_history[:2], ig),
        "landmark_rms": position_error_rms(x_l, truth),
        "pos_var_median": float(np.median(pos_var[free])), "psi_var_median": float(np.median(P[2, free])),
        "opt_time_total": float(np.nansum(ot)), "opt_time_final": float(ot[-1]), "run_time": float(results.run_time),
    }


def evaluate_seeds(question: str, variants: dict, seeds: list[int], keep: tuple = (),
                   **overrides: object) -> tuple[dict, dict]:
    """Run every variant for every seed (one ``run_variants`` pass per seed); returns ``(evaluation, kept)``.

    ``variants``: name → SLAM options, a dict or ``options(seed) -> dict`` (for a hook that must be new for every
    run); ``overrides`` apply to all. ``evaluation`` is {variant: {seed: metrics or {"failed": message}}},
    ``kept`` {(variant, seed): Results} for the seeds listed in ``keep``.
    """
    seeds = [int(s) for s in index_list(seeds, 2 ** 63 - 1, "seeds", distinct=True)]
    if not set(keep) <= set(seeds):
        raise ValueError(f"keep must list seeds that are run, got {sorted(set(keep) - set(seeds))} not in {seeds}")
    out, kept = {name: {} for name in variants}, {}
    for s in seeds:
        options = {name: (v(s) if callable(v) else dict(v)) for name, v in variants.items()}
        for name, r in run_variants(question, options, seed=s, **overrides).items():
            if isinstance(r, Exception):     # a GraphError (e.g. GaugeFreedomError) of that variant's system
                out[name][s] = {"failed": f"{type(r).__name__}: {str(r)[:120]}"}
                continue
            out[name][s] = run_metrics(r)
            if s in keep:
                kept[(name, s)] = r
    return out, kept


def _check_metric(evaluation, metric) -> None:
    """ValueError unless every successful run of ``evaluation`` recorded ``metric``."""
    if any(metric not in m for per in evaluation.values() for m in per.values() if "failed" not in m):
        raise ValueError(f"unknown metric {metric!r}; the runs recorded "
                         f"{sorted({k for per in evaluation.values() for m in per.values() for k in m})}")


def failures(evaluation: dict) -> dict:
    """{variant: [seeds whose run failed]}."""
    return {name: [s for s, m in per.items() if "failed" in m] for name, per in evaluation.items()}


def seed_summary(evaluation: dict, metric: str) -> dict:
    """{variant: (mean, sample std (0 for one run), min, max, number of successful runs)} of one metric."""
    _check_metric(evaluation, metric)
    out = {}
    for name, per in evaluation.items():
        vals = np.array([m[metric] for m in per.values() if "failed" not in m], dtype=float)
        if vals.size == 0:
            out[name] = (math.nan, math.nan, math.nan, math.nan, 0)
        else:
            sd = float(vals.std(ddof=1)) if vals.size > 1 else 0.0
            out[name] = (float(vals.mean()), sd, float(vals.min()), float(vals.max()), int(vals.size))
    return out


def format_seed_table(evaluation: dict, columns: list[tuple[str, str, str]]) -> str:
    """A text table, one row per variant, of ``mean ± std`` per column.

    ``columns``: list of (metric, header, format spec), e.g. ``("pose_rms", "pose RMS (m)", ".3f")``.
    """
    name_w = max(len(n) for n in evaluation) + 1
    cells = {}
    for metric, _header, spec in columns:
        summ = seed_summary(evaluation, metric)
        cells[metric] = {n: (f"{format(m, spec)} ± {format(s, spec)}" if k else "failed")
                         for n, (m, s, _, _, k) in summ.items()}
    widths = {metric: max(len(header), *(len(c) for c in cells[metric].values())) for metric, header, _ in columns}
    lines = ["".ljust(name_w) + " ".join(h.rjust(widths[m]) for m, h, _ in columns)]
    for n in evaluation:
        lines.append(n.rjust(name_w - 1) + " " + " ".join(cells[m][n].rjust(widths[m]) for m, _, _ in columns))
    return "\n".join(lines)


def paired(evaluation: dict, name: str, reference: str, metric: str) -> list:
    """[(value of ``name``, value of ``reference``)] of one metric, for each seed in which both runs succeeded."""
    _check_metric(evaluation, metric)
    runs, ref = evaluation[name], evaluation[reference]
    return [(runs[s][metric], ref[s][metric]) for s in runs
            if s in ref and "failed" not in runs[s] and "failed" not in ref[s]]


def format_relative(evaluation: dict, reference: str, name_width: int = 24) -> str:
    """One line per variant comparing its seed means with ``reference``'s: edges removed, landmark edges and
    non-zeros of H as fractions of the reference's, and the median position variance as a factor."""
    mean = {m: {n: v[0] for n, v in seed_summary(evaluation, m).items()}
            for m in ("edges", "landmark_edges", "hessian_nnz", "pos_var_median")}
    width = max(name_width, *(len(n) for n in evaluation))
    lines = []
    for n in evaluation:
        ratio = {m: mean[m][n] / mean[m][reference] for m in ("landmark_edges", "hessian_nnz", "pos_var_median")}
        lines.append(f"{n:>{width}}: edges removed {mean['edges'][reference] - mean['edges'][n]:5.0f}, "
                     f"landmark edges {ratio['landmark_edges']:.2f}, nnz(H) {ratio['hessian_nnz']:.2f}, "
                     f"median position variance ×{ratio['pos_var_median']:.1f}")
    return "\n".join(lines)


def plot_seed_bars(axes: object, evaluation: dict, metrics: list[str], colors: list | None = None) -> None:
    """One horizontal bar panel per metric: mean over seeds (bar), ± one std (error bar), each seed (dot).

    Variant names label the bars of the panels in the first column of the figure's grid.
    """
    axes = np.atleast_1d(axes).ravel()
    names = list(evaluation)
    y = np.arange(len(names))[::-1]
    for ax, metric in zip(axes, metrics):
        summ = seed_summary(evaluation, metric)
        mean = [summ[n][0] for n in names]
        std = [summ[n][1] for n in names]
        ax.barh(y, mean, xerr=std, color=colors, alpha=0.8, capsize=3, height=0.6)
        for yi, n in zip(y, names):
            vals = [m[metric] for m in evaluation[n].values() if "failed" not in m]
            ax.plot(vals, np.full(len(vals), yi), "k.", ms=4, zorder=3)
        ax.set_xlabel(METRIC_LABELS.get(metric, metric))
        spec = ax.get_subplotspec()
        first_col = spec is None or spec.is_first_col()
        ax.set_yticks(y, names if first_col else [""] * len(names))
        ax.grid(axis="y", visible=False)


def spy_hessian(ax: object, H: np.ndarray, starts: np.ndarray, n_vehicle: int, title: str = "") -> int:
    """Sparsity pattern of a re-ordered H (from ``marginalisation.hessian_blocks``), one pixel per entry (black:
    non-zero), with a line between the vehicle and landmark blocks; returns the number of non-zeros."""
    H = np.asarray(H)
    ax.imshow(H != 0, cmap="Greys", vmin=0, vmax=1, interpolation="nearest")
    if 0 < n_vehicle < len(starts):
        edge = starts[n_vehicle] - 0.5
        ax.axhline(edge, color="C3", lw=0.8)
        ax.axvline(edge, color="C3", lw=0.8)
    nnz = int(np.count_nonzero(H))
    ax.set_title(f"{title}\n{H.shape[0]}×{H.shape[1]}, {nnz} non-zeros", fontsize=9)
    ax.set_xlabel("column (vehicle states | landmark states)")
    ax.set_ylabel("row")
    return nnz
