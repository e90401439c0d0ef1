"""JCBB benchmark: the compiled, incremental ``jcbb`` against ``jcbb_reference`` (joint D² from scratch).

Setting (issue 4, spec §6 anchor): 150 landmarks uniform in a 30 m × 30 m square, the robot observes its
m = 30 nearest landmarks plus 2 clutter points; pose σ = (0.5 m, 0.5 m, 8°) (correlated), landmark
σ = 0.05 m, measurement σ = 0.1 m; all 150 landmarks are candidates; n_σ = 3 gates. Seeded trials.

The naive JCBB is ``helpers.association.jcbb.jcbb_reference``: the textbook recursion on the *same*
interpretation tree (same level order, children nearest-first, star last, Best = most pairings, then smaller
D²) under the simple bound "pairings(H) + levels left with an unused candidate ≥ pairings(Best)", with D²_H
recomputed from scratch (Cholesky of C_H and a solve) for every candidate. Both searches are exact for the
same objective and tie-breaking, so they must return the same hypothesis; the benchmark checks it on every
trial on which the naive search finishes within its node budget.

    .venv/bin/python benchmarks/jcbb.py [--trials 50] [--naive-budget 20000] [--budget 10000]

The tail lines also say in how many scenes the true hypothesis itself fails the joint gate
(``helpers.association.evaluation.true_hypothesis``), how many of the slow scenes those are, and the worst time
where the truth passes.

BLAS is pinned to one thread (the machine is shared; multi-threaded BLAS on 300×300 matrices only adds
contention). Timings are wall-clock, best of 3 runs for the fast JCBB, one run for the naive one.
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from helpers.association.evaluation import true_hypothesis  # noqa: E402
from helpers.association.jcbb import jcbb, jcbb_reference  # noqa: E402
from helpers.association.scenarios import range_bearing_scenario  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--naive-budget", type=int, default=20000, help="node budget per naive (reference) run")
    ap.add_argument("--budget", type=int, default=10000, help="node budget for the capped fast run")
    ap.add_argument("--tail-trials", type=int, default=300,
                    help="fast JCBB alone on this many seeded trials (the first --trials included): the tail")
    args = ap.parse_args()
    print(f"JCBB benchmark  {datetime.date.today().isoformat()}  trials={args.trials}  "
          "150 landmarks / 30 m square, m = 30 + 2 clutter, pose σ (0.5 m, 0.5 m, 8°)")
    rows = compare_trials(args)
    summarise(rows, args)
    tail(args)


def compare_trials(args):
    """Fast JCBB (best of 3), the capped fast run and the naive search on the first trials; one line each."""
    sc0 = range_bearing_scenario(seed=(2024, 0))
    jcbb(sc0.density, sc0.Y)                               # compile (numba cache) before timing
    rows = []
    for t in range(args.trials):
        sc = range_bearing_scenario(seed=(2024, t))
        times = []
        for _ in range(3):
            t0 = time.perf_counter()
            a = jcbb(sc.density, sc.Y)
            times.append(time.perf_counter() - t0)
        t_fast = min(times)
        t0 = time.perf_counter()
        b = jcbb(sc.density, sc.Y, max_nodes=args.budget)
        t_budget = time.perf_counter() - t0
        t0 = time.perf_counter()
        ref = jcbb_reference(sc.density, sc.Y, max_nodes=args.naive_budget)
        t_naive = time.perf_counter() - t0
        finished, nodes_n = not ref.budget_exhausted, ref.stats["nodes"]
        same = finished and np.array_equal(ref.idx, a.idx) and abs(ref.d2 - a.d2) <= 1e-8 * max(1.0, a.d2)
        correct = int(np.sum((a.idx >= 0) & (a.idx == sc.truth)))
        rows.append((t, t_fast, a.stats["nodes"], t_naive, nodes_n, finished, same, t_budget,
                     b.budget_exhausted, np.array_equal(b.idx, a.idx), a.n_pairings, correct))
        print(f"trial {t:3d}: fast {t_fast * 1e3:8.2f} ms {a.stats['nodes']:8d} nodes | naive "
              f"{t_naive * 1e3:9.1f} ms {nodes_n:8d} nodes {'done' if finished else 'CUT '} "
              f"{'same' if same else ('DIFF' if finished else '-   ')} | budget {t_budget * 1e3:6.2f} ms "
              f"{'cut' if b.budget_exhausted else '   '} {'=' if rows[-1][9] else '≠'} | "
              f"pairings {a.n_pairings} correct {correct}", flush=True)
    return rows


def summarise(rows, args):
    """Medians, worst cases and agreement over the compared trials."""
    r = np.array([x[:5] + (x[7],) for x in rows], dtype=float)
    finished = np.array([x[5] for x in rows])
    same = np.array([x[6] for x in rows])
    t_fast, nodes, t_naive, nodes_n, t_budget = r[:, 1], r[:, 2], r[:, 3], r[:, 4], r[:, 5]
    print()
    print(f"fast JCBB      : median {np.median(t_fast) * 1e3:.2f} ms, worst {t_fast.max() * 1e3:.1f} ms "
          f"(trial {int(np.argmax(t_fast))}, {int(nodes[np.argmax(t_fast)])} nodes); "
          f"{int(np.sum(t_fast <= 0.05))}/{len(rows)} trials ≤ 50 ms")
    print(f"naive JCBB     : median {np.median(t_naive) * 1e3:.1f} ms, worst {t_naive.max() * 1e3:.0f} ms; "
          f"finished {int(finished.sum())}/{len(rows)} within {args.naive_budget} nodes")
    print(f"same hypothesis: {int(same.sum())}/{int(finished.sum())} trials where the naive search finished")
    ratio = t_naive[finished] / t_fast[finished]
    print(f"time ratio naive/fast on finished trials: median {np.median(ratio):.0f}x, "
          f"total {t_naive[finished].sum() / t_fast[finished].sum():.0f}x")
    cut = np.array([x[8] for x in rows])
    eq = np.array([x[9] for x in rows])
    print(f"fast JCBB, max_nodes={args.budget}: worst {t_budget.max() * 1e3:.1f} ms; cut on {int(cut.sum())} "
          f"trials, same hypothesis as the full search on {int(eq.sum())}/{len(rows)}")


def tail(args):
    """The tail: fast JCBB alone (unlimited and with the budget) on more seeded trials, with each scene's
    true hypothesis judged outside the timed calls."""
    tf, tb, nn, cuts, same_b, truth_jc, all_ic = [], [], [], 0, 0, [], 0
    for t in range(args.tail_trials):
        sc = range_bearing_scenario(seed=(2024, t))
        truth = true_hypothesis(sc.density, sc.Y, sc.truth)
        truth_jc.append(truth["jointly_compatible"])
        all_ic += truth["n_individual"] == truth["n_true"]
        t0 = time.perf_counter()
        a = jcbb(sc.density, sc.Y)
        tf.append(time.perf_counter() - t0)
        nn.append(a.stats["nodes"])
        t0 = time.perf_counter()
        b = jcbb(sc.density, sc.Y, max_nodes=args.budget)
        tb.append(time.perf_counter() - t0)
        cuts += b.budget_exhausted
        same_b += np.array_equal(a.idx, b.idx)
    if args.tail_trials:
        tf, tb, nn = np.array(tf), np.array(tb), np.array(nn)
        print(f"tail, {args.tail_trials} trials, fast JCBB unlimited: median {np.median(tf) * 1e3:.2f} ms, "
              f"99th pct {np.percentile(tf, 99) * 1e3:.1f} ms, worst {tf.max() * 1e3:.0f} ms "
              f"({int(nn.max())} nodes); {int(np.sum(tf <= 0.05))}/{args.tail_trials} ≤ 50 ms")
        jc, slow = np.array(truth_jc), tf > 0.05          # the scene's true hypothesis passes the joint gate
        worst_jc = (f"{tf[jc].max() * 1e3:.1f} ms ({int(nn[jc].max())} nodes)") if jc.any() else "-"
        print(f"tail: every true pairing passes its individual gate in {all_ic}/{args.tail_trials} scenes; "
              f"the true hypothesis fails the joint gate in {int(np.sum(~jc))}/{args.tail_trials} scenes, "
              f"{int(np.sum(slow & ~jc))} of the {int(slow.sum())} over 50 ms; where it passes, worst {worst_jc}")
        print(f"tail, {args.tail_trials} trials, max_nodes={args.budget}: worst {tb.max() * 1e3:.1f} ms, "
              f"{int(np.sum(tb <= 0.05))}/{args.tail_trials} ≤ 50 ms; cut on {cuts}, "
              f"same hypothesis as unlimited on {same_b}/{args.tail_trials}")


if __name__ == "__main__":
    main()
