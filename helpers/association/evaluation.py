"""Scoring associations against ground truth, over many seeded trials.

For one trial with truth ``truth`` and an association ``idx`` (one entry per landmark: its observation column or
−1):

- true positives  TP = #{k : idx_k = truth_k ≥ 0}            (correct pairings)
- precision = TP / #{k : idx_k ≥ 0}                            (how many claimed pairings are right)
- recall    = TP / #{k : truth_k ≥ 0}                          (how many true pairings were found)
- accuracy  = fraction of the m *observations* whose label is right, the label of an observation being the
  landmark it is paired with, or "none" (clutter / new landmark).

Over many trials the counts are summed before dividing (micro-average). The uncertainty of a rate is the
Wilson score interval of a binomial proportion (Wilson 1927), treating each counted pairing / observation as an
independent Bernoulli trial (an approximation: the pairings of one scene share its pose error).
``TrialResults.summary()`` reports precision 1 when no pairing was made (0/0: nothing claimed, so nothing claimed
wrong); :func:`rates` reports NaN there instead, and :func:`fmt_rate` prints it as "n/a".
"""
from __future__ import annotations

import numbers
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.stats import norm

from ..gaussian import Gaussian
from ..timing import best_of
from ..validation import float_array, function, integer, one_of
from .common import Association, AssociationProblem, check_hypothesis, joint_sq_mahalanobis, prepare
from .scenarios import range_bearing_scenario

__all__ = ["run_trials", "trial_counts", "TrialResults", "RATES", "wilson_interval", "sweep", "sweep_table",
           "check_results", "true_hypothesis", "rates", "fmt_rate"]

#: numerator and denominator counts of each rate
RATES = {"precision": ("tp", "n_pred"), "recall": ("tp", "n_true"), "accuracy": ("correct", "m")}


def trial_counts(idx: np.ndarray, truth: np.ndarray, m: int) -> dict:
    """The counts of one trial (module docstring): tp, n_pred, n_true, correct (observations labelled right) and m,
    for the association ``idx`` and the ``truth`` (one entry per landmark: observation column or −1) with m
    observations."""
    labels = np.full((2, m), -1)                        # row 0: the label idx gives each observation, row 1: truth's
    for row, hypothesis in enumerate((idx, truth)):
        k = np.flatnonzero(hypothesis >= 0)
        labels[row, hypothesis[k]] = k
    return {"tp": int(np.count_nonzero((idx >= 0) & (idx == truth))), "n_pred": int(np.count_nonzero(idx >= 0)),
            "n_true": int(np.count_nonzero(truth >= 0)), "correct": int(np.count_nonzero(labels[0] == labels[1])),
            "m": m}


def _ratio(num, den) -> float:
    """sum(num) / sum(den); 1 when nothing was counted."""
    num, den = float(np.sum(num)), float(np.sum(den))
    return 1.0 if den == 0 else num / den


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval (lower, upper) of the binomial proportion p̂ = k/n, with z the two-sided normal
    quantile of ``confidence``:

        centre = (p̂ + z²/2n) / (1 + z²/n),   half-width = z √(p̂(1 − p̂)/n + z²/4n²) / (1 + z²/n).

    It stays inside [0, 1] and keeps a width at p̂ = 0 or 1; n = 0 gives the uninformative (0, 1).
    """
    k = integer(successes, "successes", minimum=0)
    n = integer(trials, "trials", minimum=k)
    if not 0.0 < float_array(confidence, "confidence") < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence!r}")
    if n == 0:
        return 0.0, 1.0
    z = float(norm.ppf(0.5 + 0.5 * confidence))
    p = k / n
    centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n)
    half = z * np.sqrt(p * (1.0 - p) / n + z * z / (4.0 * n * n)) / (1.0 + z * z / n)
    # the interval contains p̂ exactly; min/max only remove round-off (e.g. hi = 1 − ε at p̂ = 1)
    return min(max(centre - half, 0.0), p), max(min(centre + half, 1.0), p)


@dataclass
class TrialResults:
    """Per-trial counts of every algorithm: ``counts[name]`` maps ``tp``, ``n_pred``, ``n_true``, ``correct``,
    ``m`` (module docstring), ``time`` (s per call, the fastest of ``repeat`` calls), ``nodes`` (stats["nodes"]
    or 0), ``exhausted`` (budget cut) and ``n_pairings`` to arrays with one entry per trial."""

    names: list
    counts: dict = field(default_factory=dict)
    n_trials: int = 0

    def summary(self) -> dict:
        """{name: {"precision", "recall", "accuracy"}} micro-averaged over all trials."""
        return {name: {key: _ratio(self.counts[name][num], self.counts[name][den]) for key, (num, den) in RATES.items()}
                for name in self.names}

    def interval(self, name: str, key: str, confidence: float = 0.95) -> tuple[float, float]:
        """(lower, upper) Wilson interval of the micro-averaged rate ``key`` of algorithm ``name``."""
        num, den = RATES[one_of(key, "key", list(RATES))]
        c = self.counts[one_of(name, "name", self.names)]
        lo, hi = wilson_interval(int(np.sum(c[num])), int(np.sum(c[den])), confidence)
        return float(lo), float(hi)


def _call(f: Callable, name: str, t: int, repeat: int, sc) -> tuple[Association, float]:
    """(association, fastest time) of ``repeat`` calls f(sc.density, sc.Y); an exception of the algorithm gets a
    note naming it and the trial."""
    try:
        a, best = best_of(repeat, f, sc.density, sc.Y)
    except Exception as exc:
        exc.add_note(f"raised by algorithms[{name!r}] on trial {t} of run_trials")
        raise
    if not isinstance(a, Association):
        raise ValueError(f"algorithms[{name!r}] must return an Association, got {type(a).__name__}")
    return a, best


def _check_algorithms(algorithms: Mapping[str, Callable]) -> None:
    if not isinstance(algorithms, Mapping) or not algorithms or not all(map(callable, algorithms.values())):
        raise ValueError(f"algorithms must be a non-empty mapping {{name: callable}}, got {algorithms!r}")


def run_trials(algorithms: Mapping[str, Callable], n_trials: int, seed: int,
               scenario: Callable = range_bearing_scenario, repeat: int = 1, **scenario_kwargs: Any) -> TrialResults:
    """Run every algorithm {name: f(density, Y) → Association} on ``n_trials`` seeded scenes: trial t is
    ``scenario(seed=(seed, t), **scenario_kwargs)`` (an object with ``density``, ``Y`` and ``truth``).

    Each algorithm is called ``repeat`` times per scene and its ``time`` is the fastest call (best-of-k: less
    sensitive to other processes and to which algorithm runs first); the last call's association is scored.
    """
    _check_algorithms(algorithms)
    n_trials = integer(n_trials, "n_trials", minimum=1)
    seed = integer(seed, "seed", minimum=0)
    repeat = integer(repeat, "repeat", minimum=1)
    function(scenario, "scenario")
    rows = {name: [] for name in algorithms}
    for t in range(n_trials):
        sc = scenario(seed=(seed, t), **scenario_kwargs)
        for name, f in algorithms.items():
            a, best = _call(f, name, t, repeat, sc)
            rows[name].append({**trial_counts(a.idx, sc.truth, sc.Y.shape[1]), "time": best,
                               "nodes": int(a.stats.get("nodes", 0)), "exhausted": a.budget_exhausted,
                               "n_pairings": a.n_pairings})
    res = TrialResults(names=list(algorithms), n_trials=n_trials)
    for name, per_trial in rows.items():
        res.counts[name] = {key: np.array([row[key] for row in per_trial]) for key in per_trial[0]}
    return res


def sweep(algorithms: Mapping[str, Callable], n_trials: int, seed: int, base: Mapping, values: Iterable,
          make_kwargs: Callable, cache: dict | None = None) -> dict:
    """Run every algorithm for each value of one factor: {value: TrialResults}.

    The scene of value v is ``{**base, **make_kwargs(v)}`` (keyword arguments of the scenario); every value uses
    the same ``seed``. ``cache`` (a dict kept by the caller) maps a setting to its results, so a setting shared
    by several sweeps (the base scene) runs once.
    """
    _check_algorithms(algorithms)
    function(make_kwargs, "make_kwargs")
    if not isinstance(base, Mapping):
        raise ValueError(f"base must be a mapping of scenario keyword arguments, got {type(base).__name__}")
    values = list(values) if isinstance(values, Iterable) and not isinstance(values, (str, bytes)) else []
    if not values:
        raise ValueError("values must be a non-empty iterable of factor values")
    cache = {} if cache is None else cache
    out = {}
    for v in values:
        extra = make_kwargs(v)
        if not isinstance(extra, Mapping):
            raise ValueError(f"make_kwargs({v!r}) must return a mapping of scenario keyword arguments, got {extra!r}")
        kwargs = {**base, **extra}
        key = (tuple(algorithms), n_trials, seed, repr(sorted(kwargs.items())))
        if key not in cache:
            cache[key] = run_trials(algorithms, n_trials, seed=seed, **kwargs)
        out[v] = cache[key]
    return out


def check_results(results: Mapping, names: Iterable[str] | None = None) -> list:
    """The algorithm names of ``results`` ({factor value: TrialResults}, at least one, all with the same
    algorithms); with ``names`` also checks that each is one of them. ValueError names the argument."""
    if not (isinstance(results, Mapping) and results and all(isinstance(r, TrialResults) for r in results.values())):
        raise ValueError("results must be a non-empty mapping {factor value: TrialResults} (from run_trials or sweep)")
    known = list(next(iter(results.values())).names)
    if any(list(r.names) != known for r in results.values()):
        raise ValueError("results must hold the same algorithms for every factor value")
    if names is not None and (isinstance(names, str) or not set(names) <= set(known)):
        raise ValueError(f"names must be a list of algorithms of results {known}, got {names!r}")
    return known


def sweep_table(title: str, results: Mapping, unit: str = "",
                keys: Iterable[str] = ("precision", "recall", "accuracy")) -> str:
    """A fixed-width table of ``results`` ({value: TrialResults}): one row per value, for every algorithm the
    rates ``keys`` (ratios of integer counts, printed with 3 decimals)."""
    names = check_results(results)
    keys = [one_of(k, "keys", list(RATES)) for k in keys]
    width = 6 * len(keys) - 1
    head = {"precision": "prec", "recall": "rec", "accuracy": "acc"}
    lines = [title,
             f"{'':>10s} " + " ".join(f"{a:>{width}s}" for a in names),
             f"{'':>10s} " + " ".join(" ".join(f"{head[k]:>5s}" for k in keys) for _ in names)]
    for v, res in results.items():
        s = res.summary()
        lines.append(f"{str(v) + unit:>10s} " + " ".join(" ".join(f"{s[a][k]:5.3f}" for k in keys) for a in names))
    return "\n".join(lines)


def true_hypothesis(density: Gaussian | AssociationProblem, Y: ArrayLike | None, truth: ArrayLike,
                    n_sigma: float = 3.0) -> dict:
    """The scene's true pairings, judged as the gates judge any hypothesis: when the truth fails the joint
    gate, no algorithm that respects the gate can return it.

    ``truth``: one entry per landmark, its observation column or −1. The true pairings (k, truth_k) that pass
    the individual gate d²_k,truth_k ≤ χ²_d(c) form the hypothesis H (a of them); its joint distance D²_H is
    compared with the joint gate χ²_{d·a}(c), c = 2Φ(n_σ) − 1.

    Returns ``n_true``, ``n_individual`` (= a), ``d2`` (D²_H), ``gate`` (χ²_{d·a}(c)), both 0 when a = 0,
    ``dof`` (d·a) and ``jointly_compatible`` (D²_H ≤ gate).
    """
    problem = prepare(density, Y, n_sigma)
    truth = check_hypothesis(truth, problem.n, problem.m, "truth")
    k = np.flatnonzero(truth >= 0)
    individual = problem.ic_d2[k, truth[k]] <= problem.ic_threshold
    idx = np.full(problem.n, -1, dtype=np.intp)
    idx[k[individual]] = truth[k[individual]]
    a = int(np.count_nonzero(individual))
    d2 = joint_sq_mahalanobis(problem, idx) if a else 0.0
    gate = float(problem.jc_threshold(a)) if a else 0.0
    return {"n_true": int(k.size), "n_individual": a, "d2": float(d2), "gate": gate, "dof": problem.d * a,
            "jointly_compatible": bool(d2 <= gate)}


def rates(results: TrialResults, name: str) -> dict:
    """Micro-averaged ``precision`` = TP / pairings made and ``recall`` = TP / true pairings of algorithm ``name``
    in ``results``, NaN when the denominator is 0; and the summed counts ``tp``, ``n_pred``, ``n_true``."""
    if not isinstance(results, TrialResults):
        raise ValueError(f"results must be a TrialResults (run_trials / sweep), got {type(results).__name__}")
    c = results.counts[one_of(name, "name", results.names)]
    tp, n_pred, n_true = (int(np.sum(c[key])) for key in ("tp", "n_pred", "n_true"))
    return {"precision": tp / n_pred if n_pred else float("nan"), "recall": tp / n_true if n_true else float("nan"),
            "tp": tp, "n_pred": n_pred, "n_true": n_true}


def fmt_rate(value: float, digits: int = 3) -> str:
    """``value`` with ``digits`` decimals, or "n/a" (padded to the same width) when it is NaN."""
    digits = integer(digits, "digits", minimum=0)
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"value must be a real number (NaN prints as n/a), got {value!r}")
    return (f"{value:.{digits}f}" if np.isfinite(value) else "n/a").rjust(digits + 2)
