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

:func:`true_hypothesis` judges a scene's true pairings as the gates judge any hypothesis: when the truth
itself fails the joint gate, no algorithm that respects the gate can return it.

Uncertainty of a rate: :func:`wilson_interval` gives the Wilson score interval of a binomial proportion
(Wilson 1927), treating each counted pairing / observation as an independent Bernoulli trial — an
approximation, since the pairings of one scene share its pose error. :func:`sweep` runs one factor of a
scene over several values (with a cache, so a setting shared by several sweeps runs once) and
:func:`sweep_table` prints the result.
"""
from __future__ import annotations

import numbers
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm

from ..timing import best_of
from ..validation import broadcastable, float_array
from .common import Association, check_hypothesis, joint_sq_mahalanobis, prepare
from .scenarios import range_bearing_scenario

__all__ = ["score", "score_many", "run_trials", "TrialResults", "RATES", "wilson_interval", "sweep",
           "sweep_table", "check_results", "true_hypothesis"]

#: numerator and denominator counts of each rate
RATES = {"precision": ("tp", "n_pred"), "recall": ("tp", "n_true"), "accuracy": ("correct", "m")}


def score_many(idx_list, truth_list, m_list) -> dict:
    """Counts for many trials at once: dict of int arrays (one entry per trial) ``tp``, ``n_pred``,
    ``n_true``, ``correct`` (observations labelled right) and ``m``.

    idx_list, truth_list: sequences of int arrays (n_t,) with observation columns or −1, no column used twice
    in one array; m_list: m_t (non-negative integers).
    """
    for name, seq in (("idx_list", idx_list), ("truth_list", truth_list), ("m_list", m_list)):
        if isinstance(seq, (str, bytes)) or not hasattr(seq, "__len__"):
            raise ValueError(f"{name} must be a sequence with one entry per trial, got {type(seq).__name__}")
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
        for name, arr in (("idx", a), ("truth", b)):
            if arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer)):
                raise ValueError(f"trial {t}: {name} must contain integers (observation column or -1), "
                                 f"got dtype {arr.dtype}")
            if np.unique(arr[arr >= 0]).size != np.count_nonzero(arr >= 0):
                raise ValueError(f"trial {t}: {name} gives one observation to several landmarks: {arr.tolist()}")
        idx_arrs.append(a.astype(np.int64))
        truth_arrs.append(b.astype(np.int64))
    m_arr = np.asarray(m_list)
    if m_arr.ndim != 1 or m_arr.dtype == bool or not np.issubdtype(m_arr.dtype, np.integer) or np.any(m_arr < 0):
        raise ValueError(f"m_list must hold one non-negative integer per trial, got {m_list!r}")
    m = m_arr.astype(np.int64)
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
    ``time`` (s per call, the fastest of ``repeat`` calls), ``nodes`` (stats["nodes"] or 0), ``exhausted``
    (budget cut) and ``n_pairings``.
    """

    names: list
    counts: dict = field(default_factory=dict)
    n_trials: int = 0

    def summary(self) -> dict:
        """{name: {"precision", "recall", "accuracy"}} micro-averaged over all trials."""
        out = {}
        for name in self.names:
            c = self.counts[name]
            out[name] = {key: _ratio(c[num], c[den]) for key, (num, den) in RATES.items()}
        return out

    def interval(self, name: str, key: str, confidence: float = 0.95) -> tuple:
        """(lower, upper) Wilson interval of the micro-averaged rate ``key`` of algorithm ``name``."""
        if name not in self.counts:
            raise ValueError(f"name must be one of {list(self.counts)}, got {name!r}")
        if key not in RATES:
            raise ValueError(f"key must be one of {list(RATES)}, got {key!r}")
        num, den = RATES[key]
        lo, hi = wilson_interval(int(np.sum(self.counts[name][num])), int(np.sum(self.counts[name][den])),
                                 confidence)
        return float(lo), float(hi)


def wilson_interval(successes, trials, confidence: float = 0.95):
    """Wilson score interval of a binomial proportion (arrays broadcast): returns (lower, upper).

    With p̂ = k/n and z the two-sided normal quantile of ``confidence``:
    centre = (p̂ + z²/2n) / (1 + z²/n),  half-width = z √(p̂(1 − p̂)/n + z²/4n²) / (1 + z²/n).
    Unlike p̂ ± z√(p̂(1−p̂)/n) it stays inside [0, 1] and does not collapse to zero width at p̂ = 0 or 1.
    n = 0 gives the uninformative interval (0, 1).
    """
    k = float_array(successes, "successes")
    n = float_array(trials, "trials")
    if np.any(~np.isfinite(k)) or np.any(k < 0) or np.any(k != np.round(k)):
        raise ValueError(f"successes must be non-negative integers, got {successes!r}")
    if np.any(~np.isfinite(n)) or np.any(n < 0) or np.any(n != np.round(n)):
        raise ValueError(f"trials must be non-negative integers, got {trials!r}")
    broadcastable(successes=k, trials=n)
    if np.any(k > n):
        raise ValueError("successes must not exceed trials")
    if isinstance(confidence, bool) or not isinstance(confidence, numbers.Real) or not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must be a number in (0, 1), got {confidence!r}")
    z = float(norm.ppf(0.5 + 0.5 * confidence))
    n_safe = np.where(n > 0, n, 1.0)
    p = k / n_safe
    den = 1.0 + z * z / n_safe
    centre = (p + z * z / (2.0 * n_safe)) / den
    half = z * np.sqrt(p * (1.0 - p) / n_safe + z * z / (4.0 * n_safe * n_safe)) / den
    # the interval contains p̂ exactly; min/max only remove round-off (e.g. hi = 1 − ε at p̂ = 1)
    lo = np.where(n > 0, np.minimum(np.clip(centre - half, 0.0, 1.0), p), 0.0)
    hi = np.where(n > 0, np.maximum(np.clip(centre + half, 0.0, 1.0), p), 1.0)
    return lo, hi


def _check_algorithms(algorithms):
    """ValueError unless ``algorithms`` is a non-empty mapping {name: callable}."""
    if not isinstance(algorithms, Mapping) or not algorithms:
        raise ValueError(f"algorithms must be a non-empty mapping {{name: callable}}, got {type(algorithms).__name__}")
    for name, f in algorithms.items():
        if not callable(f):
            raise ValueError(f"algorithms[{name!r}] must be callable, got {type(f).__name__}")


def run_trials(algorithms: Mapping[str, Callable], n_trials: int, seed: int,
               scenario: Callable = range_bearing_scenario, repeat: int = 1, **scenario_kwargs) -> TrialResults:
    """Run every algorithm on ``n_trials`` seeded scenarios (trial t uses seed (seed, t)).

    algorithms: {name: f(density, Y) → Association}; scenario: a scenario generator taking ``seed`` and
    ``scenario_kwargs`` and returning an object with ``density``, ``Y`` and ``truth`` (default
    :func:`range_bearing_scenario`). repeat: each algorithm is called this many times per scene and its
    ``time`` is the fastest call (best-of-k timing: less sensitive to other processes and to which
    algorithm runs first on a freshly generated scene); the association of the last call is scored.
    """
    _check_algorithms(algorithms)
    if isinstance(n_trials, bool) or not isinstance(n_trials, numbers.Integral) or n_trials < 1:
        raise ValueError(f"n_trials must be a positive integer, got {n_trials!r}")
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if isinstance(repeat, bool) or not isinstance(repeat, numbers.Integral) or repeat < 1:
        raise ValueError(f"repeat must be a positive integer, got {repeat!r}")
    names = list(algorithms)
    idx = {name: [] for name in names}
    extra = {name: {"time": [], "nodes": [], "exhausted": [], "n_pairings": []} for name in names}
    truths, ms = [], []
    if not callable(scenario):
        raise ValueError(f"scenario must be callable (seed=…, **scenario_kwargs) → scenario, got {scenario!r}")
    for t in range(int(n_trials)):
        sc = scenario(seed=(int(seed), t), **scenario_kwargs)
        if not all(hasattr(sc, attr) for attr in ("density", "Y", "truth")):
            raise ValueError(f"scenario must return an object with density, Y and truth, got {type(sc).__name__}")
        truths.append(sc.truth)
        ms.append(sc.Y.shape[1])
        for name in names:
            a, best = _call_algorithm(algorithms[name], name, t, int(repeat), sc)
            extra[name]["time"].append(best)
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


def _call_algorithm(f, name, t, repeat, sc):
    """(association, fastest time) of ``repeat`` calls f(sc.density, sc.Y); an exception raised by the
    algorithm propagates unchanged with a note naming it and the trial, a result that is not an Association
    raises ValueError."""
    try:
        a, best = best_of(repeat, f, sc.density, sc.Y)
    except Exception as exc:
        exc.add_note(f"raised by algorithms[{name!r}] on trial {t} of run_trials")
        raise
    if not isinstance(a, Association):
        raise ValueError(f"algorithms[{name!r}] must return an Association, got {type(a).__name__}")
    return a, best


def sweep(algorithms: Mapping[str, Callable], n_trials: int, seed: int, base: Mapping, values,
          make_kwargs: Callable, cache: dict | None = None) -> dict:
    """Run every algorithm for each value of one factor: {value: TrialResults}.

    The scene of value v is ``{**base, **make_kwargs(v)}`` (keyword arguments of the scenario); every value
    uses the same ``seed``. ``cache`` (a dict kept by the caller) maps a setting to its results, so a
    setting shared by several sweeps (the base scene) is computed once.
    """
    _check_algorithms(algorithms)
    if not callable(make_kwargs):
        raise ValueError(f"make_kwargs must be callable (value → scenario kwargs), got {type(make_kwargs).__name__}")
    if cache is not None and not isinstance(cache, dict):
        raise ValueError(f"cache must be a dict or None, got {type(cache).__name__}")
    if not isinstance(base, Mapping):
        raise ValueError(f"base must be a mapping of scenario keyword arguments, got {type(base).__name__}")
    if isinstance(values, (str, bytes)) or not hasattr(values, "__iter__"):
        raise ValueError(f"values must be an iterable of factor values, got {type(values).__name__}")
    values = list(values)
    if not values:
        raise ValueError("values must name at least one setting of the factor")
    cache = {} if cache is None else cache
    out = {}
    for v in values:
        extra = make_kwargs(v)
        if not isinstance(extra, Mapping):
            raise ValueError(f"make_kwargs({v!r}) must return a mapping of scenario keyword arguments, got "
                             f"{type(extra).__name__}")
        kwargs = {**base, **extra}
        key = (tuple(algorithms), int(n_trials), int(seed), repr(sorted(kwargs.items())))
        if key not in cache:
            cache[key] = run_trials(algorithms, n_trials, seed=seed, **kwargs)
        out[v] = cache[key]
    return out


def check_results(results, names=None) -> list:
    """The algorithm names of ``results`` ({factor value: TrialResults}, at least one, all with the same
    algorithms); with ``names`` also checks that each is one of them. ValueError names the argument."""
    if not isinstance(results, Mapping) or not results:
        raise ValueError("results must be a non-empty mapping {factor value: TrialResults}")
    if not all(isinstance(r, TrialResults) for r in results.values()):
        raise ValueError("results must map each factor value to a TrialResults (from run_trials or sweep)")
    known = list(next(iter(results.values())).names)
    if any(list(r.names) != known for r in results.values()):
        raise ValueError("results must hold the same algorithms for every factor value")
    if isinstance(names, (str, bytes)) or not (names is None or hasattr(names, "__iter__")):
        raise ValueError(f"names must be a list of algorithm names or None, got {names!r}")
    unknown = [] if names is None else [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"names must be among the algorithms of results {known}, got {unknown}")
    return known


def sweep_table(title: str, results: Mapping, unit: str = "", keys=("precision", "recall", "accuracy")) -> str:
    """A fixed-width table of ``results`` ({value: TrialResults}): one row per value, for every algorithm
    the rates ``keys`` (ratios of integer counts, printed with 3 decimals)."""
    names = check_results(results)
    if not isinstance(title, str) or not isinstance(unit, str):
        raise ValueError(f"title and unit must be strings, got {type(title).__name__} and {type(unit).__name__}")
    keys = list(keys) if hasattr(keys, "__iter__") and not isinstance(keys, (str, bytes)) else keys
    if not isinstance(keys, list) or not keys:
        raise ValueError(f"keys must be a non-empty list of rates among {list(RATES)}, got {keys!r}")
    bad = [k for k in keys if k not in RATES]
    if bad:
        raise ValueError(f"keys must be among {list(RATES)}, got {bad}")
    width = 6 * len(keys) - 1
    head = {"precision": "prec", "recall": "rec", "accuracy": "acc"}
    lines = [title,
             f"{'':>10s} " + " ".join(f"{a:>{width}s}" for a in names),
             f"{'':>10s} " + " ".join(" ".join(f"{head[k]:>5s}" for k in keys) for _ in names)]
    for v, res in results.items():
        s = res.summary()
        lines.append(f"{str(v) + unit:>10s} " + " ".join(" ".join(f"{s[a][k]:5.3f}" for k in keys) for a in names))
    return "\n".join(lines)


def true_hypothesis(density, Y, truth, n_sigma: float = 3.0) -> dict:
    """The scene's true pairings, judged by the individual and the joint gate.

    ``truth``: one entry per landmark, its observation column or −1. The true pairings (k, truth_k) that pass
    the individual gate d²_k,truth_k ≤ χ²_d(c) form the hypothesis H (a of them); its joint distance D²_H is
    computed from scratch and compared with the joint gate χ²_{d·a}(c), c = 2Φ(n_σ) − 1.

    Returns ``n_true``, ``n_individual`` (= a), ``d2`` (D²_H; 0 when a = 0), ``gate`` (χ²_{d·a}(c); 0 when
    a = 0), ``dof`` (d·a) and ``jointly_compatible`` (D²_H ≤ gate).
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
