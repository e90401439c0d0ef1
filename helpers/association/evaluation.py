"""Scoring associations against ground truth, and many seeded trials at once.

For one trial with truth ``truth`` (one entry per landmark: its observation column or −1) and an
association ``idx`` (same convention):

- true positives  TP = #{k : idx_k = truth_k ≥ 0}            (correct pairings)
- precision = TP / #{k : idx_k ≥ 0}                            (how many claimed pairings are right)
- recall    = TP / #{k : truth_k ≥ 0}                          (how many true pairings were found)
- accuracy  = fraction of the m *observations* whose label is right, the label of an observation being
  the landmark it is paired with, or "none" (clutter / new landmark); as in the usual definition, "fraction
  of correct labels".

Over many trials the counts are summed first (micro-average), so a trial with more observations weighs
more. Scoring is vectorised over all trials (the associations are concatenated with offsets); generating
the trials and running the algorithms is one call per trial.
"""
from __future__ import annotations

import numbers
import time
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from helpers.association.scenarios import range_bearing_scenario

__all__ = ["score", "score_many", "run_trials", "TrialResults"]


def score_many(idx_list, truth_list, m_list) -> dict:
    """Counts for many trials at once: dict of int arrays (one entry per trial) ``tp``, ``n_pred``,
    ``n_true``, ``correct`` (observations labelled right) and ``m``.

    idx_list, truth_list: sequences of int arrays (n_t,) with observation columns or −1; m_list: m_t.
    """
    if not (len(idx_list) == len(truth_list) == len(m_list)):
        raise ValueError("idx_list, truth_list and m_list must have the same length "
                         f"(got {len(idx_list)}, {len(truth_list)}, {len(m_list)})")
    n_trials = len(idx_list)
    if n_trials == 0:
        z = np.zeros(0, dtype=np.int64)
        return {"tp": z, "n_pred": z, "n_true": z, "correct": z, "m": z}
    idx_arrs, truth_arrs = [], []
    for t, (a, b) in enumerate(zip(idx_list, truth_list)):
        a = np.asarray(a)
        b = np.asarray(b)
        if a.ndim != 1 or a.shape != b.shape:
            raise ValueError(f"trial {t}: idx and truth must be 1-D arrays of the same length, "
                             f"got shapes {a.shape} and {b.shape}")
        idx_arrs.append(a.astype(np.int64))
        truth_arrs.append(b.astype(np.int64))
    m = np.asarray(m_list, dtype=np.int64)
    n = np.array([a.size for a in idx_arrs], dtype=np.int64)
    idx = np.concatenate(idx_arrs)
    truth = np.concatenate(truth_arrs)
    trial = np.repeat(np.arange(n_trials), n)
    if np.any(idx >= m[trial]) or np.any(truth >= m[trial]) or np.any(idx < -1) or np.any(truth < -1):
        raise ValueError("idx and truth entries must be −1 or an observation column < m of their trial")
    tp = np.bincount(trial, weights=(idx >= 0) & (idx == truth), minlength=n_trials).astype(np.int64)
    n_pred = np.bincount(trial, weights=idx >= 0, minlength=n_trials).astype(np.int64)
    n_true = np.bincount(trial, weights=truth >= 0, minlength=n_trials).astype(np.int64)
    # observation labels: global observation id = offset of its trial + column; label = global landmark id
    obs_off = np.concatenate([[0], np.cumsum(m)[:-1]])
    lm_global = np.arange(idx.size)
    pred_lab = np.full(int(m.sum()), -1, dtype=np.int64)
    true_lab = np.full(int(m.sum()), -1, dtype=np.int64)
    k = idx >= 0
    pred_lab[obs_off[trial[k]] + idx[k]] = lm_global[k]
    k = truth >= 0
    true_lab[obs_off[trial[k]] + truth[k]] = lm_global[k]
    obs_trial = np.repeat(np.arange(n_trials), m)
    correct = np.bincount(obs_trial, weights=pred_lab == true_lab, minlength=n_trials).astype(np.int64)
    return {"tp": tp, "n_pred": n_pred, "n_true": n_true, "correct": correct, "m": m}


def _ratio(num, den, empty=1.0):
    num, den = float(np.sum(num)), float(np.sum(den))
    return empty if den == 0 else num / den


def score(idx, truth, m: int) -> dict:
    """Precision, recall and accuracy of one association (see the module docstring), plus the counts."""
    if isinstance(m, bool) or not isinstance(m, numbers.Integral) or m < 0:
        raise ValueError(f"m must be a non-negative integer, got {m!r}")
    c = score_many([idx], [truth], [m])
    out = {key: int(v[0]) for key, v in c.items()}
    out.update(precision=_ratio(c["tp"], c["n_pred"]), recall=_ratio(c["tp"], c["n_true"]),
               accuracy=_ratio(c["correct"], c["m"]))
    return out


@dataclass
class TrialResults:
    """Per-trial counts for every algorithm: ``counts[name]`` is a dict of arrays (see score_many) plus
    ``time`` (s per call), ``nodes`` (stats["nodes"] or 0), ``exhausted`` (budget cut) and ``n_pairings``.
    """

    names: list
    counts: dict = field(default_factory=dict)
    n_trials: int = 0

    def summary(self) -> dict:
        """{name: {"precision", "recall", "accuracy"}} micro-averaged over all trials."""
        out = {}
        for name in self.names:
            c = self.counts[name]
            out[name] = {"precision": _ratio(c["tp"], c["n_pred"]), "recall": _ratio(c["tp"], c["n_true"]),
                         "accuracy": _ratio(c["correct"], c["m"])}
        return out


def run_trials(algorithms: Mapping[str, Callable], n_trials: int, seed: int,
               scenario: Callable = range_bearing_scenario, **scenario_kwargs) -> TrialResults:
    """Run every algorithm on ``n_trials`` seeded scenarios (trial t uses seed (seed, t)).

    algorithms: {name: f(density, Y) → Association}; scenario: a scenario generator taking ``seed`` and
    ``scenario_kwargs`` and returning an object with ``density``, ``Y`` and ``truth`` (default
    :func:`range_bearing_scenario`).
    """
    if not isinstance(algorithms, Mapping) or not algorithms:
        raise ValueError("algorithms must be a non-empty mapping {name: callable}")
    for name, f in algorithms.items():
        if not callable(f):
            raise ValueError(f"algorithms[{name!r}] must be callable, got {type(f).__name__}")
    if isinstance(n_trials, bool) or not isinstance(n_trials, numbers.Integral) or n_trials < 1:
        raise ValueError(f"n_trials must be a positive integer, got {n_trials!r}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    names = list(algorithms)
    idx = {name: [] for name in names}
    extra = {name: {"time": [], "nodes": [], "exhausted": [], "n_pairings": []} for name in names}
    truths, ms = [], []
    for t in range(int(n_trials)):
        sc = scenario(seed=(int(seed), t), **scenario_kwargs)
        truths.append(sc.truth)
        ms.append(sc.Y.shape[1])
        for name in names:
            t0 = time.perf_counter()
            a = algorithms[name](sc.density, sc.Y)
            extra[name]["time"].append(time.perf_counter() - t0)
            idx[name].append(a.idx)
            extra[name]["nodes"].append(int(a.stats.get("nodes", 0)))
            extra[name]["exhausted"].append(bool(a.budget_exhausted))
            extra[name]["n_pairings"].append(a.n_pairings)
    res = TrialResults(names=names, n_trials=int(n_trials))
    for name in names:
        c = score_many(idx[name], truths, ms)
        c["time"] = np.asarray(extra[name]["time"])
        c["nodes"] = np.asarray(extra[name]["nodes"], dtype=np.int64)
        c["exhausted"] = np.asarray(extra[name]["exhausted"], dtype=bool)
        c["n_pairings"] = np.asarray(extra[name]["n_pairings"], dtype=np.int64)
        res.counts[name] = c
    return res
