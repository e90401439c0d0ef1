"""JCBB benchmark: the course's ``jcbb`` (a Python search over compiled numerics) against the advanced part's
``jcbb_fast`` (the same search compiled as a whole, the online front-end's JCBB).

Setting (issue 4, spec §6 anchor): 150 landmarks uniform in a 30 m × 30 m square, the robot observes its
m = 30 nearest landmarks plus 2 clutter points; pose σ = (0.5 m, 0.5 m, 8°) (correlated), landmark
σ = 0.05 m, measurement σ = 0.1 m; all 150 landmarks are candidates; n_σ = 3 gates. Seeded trials.

Both walk the same interpretation tree with the same bound, so they return the same hypothesis after the same
number of expanded nodes; the benchmark checks it on every trial. The tail lines time ``jcbb_fast`` alone on
more trials (unlimited and with a node budget) and say in how many scenes the true hypothesis itself fails the
joint gate (``helpers.association.evaluation.true_hypothesis``) and how many of the slow scenes those are.

    .venv/bin/python benchmarks/jcbb.py [--trials 50] [--budget 10000] [--tail-trials 300]

BLAS is pinned to one thread (the machine is shared; multi-threaded BLAS on 300×300 matrices only adds
contention). Timings are wall-clock, best of 3 runs.
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

from helpers.advanced.jcbb_fast import jcbb as jcbb_fast  # noqa: E402
from helpers.association.evaluation import true_hypothesis  # noqa: E402
from helpers.association.jcbb import jcbb  # noqa: E402
from helpers.association.scenarios import range_bearing_scenario  # noqa: E402


def best_of_3(f, *args, **kwargs):
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        out = f(*args, **kwargs)
        times.append(time.perf_counter() - t0)
    return out, min(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=50)
    ap.add_argument("--budget", type=int, default=10000, help="node budget for the capped runs")
    ap.add_argument("--tail-trials", type=int, default=300,
                    help="jcbb_fast alone on this many seeded trials (the first --trials included): the tail")
    args = ap.parse_args()
    print(f"JCBB benchmark  {datetime.date.today().isoformat()}  trials={args.trials}  "
          "150 landmarks / 30 m square, m = 30 + 2 clutter, pose σ (0.5 m, 0.5 m, 8°)")
    compare_trials(args)
    tail(args)


def compare_trials(args):
    """Course and compiled JCBB (best of 3 each, unlimited and capped) on the first trials; one line each."""
    sc0 = range_bearing_scenario(seed=(2024, 0))
    jcbb(sc0.density, sc0.Y)                                             # compile (numba cache) before timing
    jcbb_fast(sc0.density, sc0.Y)
    t_course, t_fast, nodes, same = [], [], [], []
    for t in range(args.trials):
        sc = range_bearing_scenario(seed=(2024, t))
        a, ta = best_of_3(jcbb, sc.density, sc.Y)
        b, tb = best_of_3(jcbb_fast, sc.density, sc.Y)
        ac, bc = jcbb(sc.density, sc.Y, max_nodes=args.budget), jcbb_fast(sc.density, sc.Y, max_nodes=args.budget)
        ok = all(np.array_equal(x.idx, y.idx) and x.stats["nodes"] == y.stats["nodes"] for x, y in ((a, b), (ac, bc)))
        t_course.append(ta)
        t_fast.append(tb)
        nodes.append(a.stats["nodes"])
        same.append(ok)
        correct = int(np.sum((a.idx >= 0) & (a.idx == sc.truth)))
        print(f"trial {t:3d}: course {ta * 1e3:8.2f} ms | compiled {tb * 1e3:7.2f} ms | {a.stats['nodes']:6d} nodes "
              f"{'same' if ok else 'DIFF'} | capped: {'cut' if ac.budget_exhausted else '   '} | "
              f"pairings {a.n_pairings} correct {correct}", flush=True)
    t_course, t_fast, nodes = np.array(t_course), np.array(t_fast), np.array(nodes)
    print()
    for name, tt in (("course JCBB  ", t_course), ("compiled JCBB", t_fast)):
        print(f"{name}: median {np.median(tt) * 1e3:.2f} ms, worst {tt.max() * 1e3:.1f} ms "
              f"(trial {int(np.argmax(tt))}, {int(nodes[np.argmax(tt)])} nodes); "
              f"{int(np.sum(tt <= 0.05))}/{args.trials} trials ≤ 50 ms")
    print(f"same hypothesis and node count (unlimited and capped at {args.budget}): {int(np.sum(same))}/{args.trials}")
    print(f"time ratio course/compiled: median {np.median(t_course / t_fast):.1f}x, "
          f"total {t_course.sum() / t_fast.sum():.1f}x")


def tail(args):
    """The tail: jcbb_fast alone (unlimited and with the budget) on more seeded trials, with each scene's true
    hypothesis judged outside the timed calls."""
    tf, tb, nn, cuts, same_b, truth_jc, all_ic = [], [], [], 0, 0, [], 0
    for t in range(args.tail_trials):
        sc = range_bearing_scenario(seed=(2024, t))
        truth = true_hypothesis(sc.density, sc.Y, sc.truth)
        truth_jc.append(truth["jointly_compatible"])
        all_ic += truth["n_individual"] == truth["n_true"]
        t0 = time.perf_counter()
        a = jcbb_fast(sc.density, sc.Y)
        tf.append(time.perf_counter() - t0)
        nn.append(a.stats["nodes"])
        t0 = time.perf_counter()
        b = jcbb_fast(sc.density, sc.Y, max_nodes=args.budget)
        tb.append(time.perf_counter() - t0)
        cuts += b.budget_exhausted
        same_b += np.array_equal(a.idx, b.idx)
    if args.tail_trials:
        tf, tb, nn = np.array(tf), np.array(tb), np.array(nn)
        print(f"tail, {args.tail_trials} trials, compiled JCBB unlimited: median {np.median(tf) * 1e3:.2f} ms, "
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
