"""Sparse factorisation of the optimiser's damped Hessian: qdldl (LDLᵀ) against CHOLMOD (supernodal LLᵀ, via cvxopt).

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/factorisation.py [--rounds 7] [--graphs w100 w10000 ...]

For every benchmark graph the Hessian the optimiser factorises is taken from the optimiser's own linearisation
(``SparseOptimizer._free_state().linearise()`` at the initial estimate: the pattern and values of the first
iteration; q2_e: the graph the DriveBot run ends with, at its final estimate) and damped as an LM iteration does
(H + λI, λ = 1e−5, GTSAM's and the default algorithm's initial λ).
Timed in the same process, interleaved (one call of each variant per round, in turn), best of ``--rounds``, as
process CPU time (single-threaded: run with OPENBLAS_NUM_THREADS=1; robust against other jobs on a shared
machine) and as wall time:

    qdldl build        qdldl.Solver(H): AMD ordering + symbolic + numeric factorisation
    qdldl refactor     Solver.update(H) + solve — what every iteration does with the qdldl backend
    cvx pattern        the cvxopt spmatrix with H's pattern (built once per pattern by the CHOLMOD backend)
    CHOLMOD symbolic   cholmod.symbolic(H) — own ordering (cvxopt's default: options['nmethods'] = 0, AMD and
                       the others CHOLMOD was built with), and with qdldl's AMD permutation (nmethods = 1, p given)
    CHOLMOD refactor   copy the values into the spmatrix + cholmod.numeric + cholmod.solve — every iteration

The header of each graph gives the statistics ``LDLSolver(backend="auto")`` decides by (nnz(L), flops = Σ c_j²
over the column counts of qdldl's L; CHOLMOD when flops/nnz(L) ≥ 40 and flops ≥ 1e6:
``helpers.graph.cholmod_backend``) and its choice.

Ratios are CHOLMOD / qdldl (below 1: CHOLMOD faster). Every solution is checked: relative residual
‖H x − b‖ / ‖b‖ < 1e−10, and the relative difference between the qdldl and CHOLMOD solutions is printed.
``--graphs`` picks the graphs (w100, w10000, w20000, victoria_park, q2_e: the DriveBot q2_e final graph, which
takes a few seconds to simulate). The machine's load average is printed: on a shared machine only the interleaved
best-of values are meaningful.
"""

import argparse
import os
import sys
import time

import numpy as np
import qdldl

try:
    import cvxopt
    from cvxopt import cholmod
except ImportError:
    sys.exit("benchmarks/factorisation.py needs cvxopt (pip install cvxopt)")

from helpers.advanced.fast_graph import FastOptimizer, cholmod_backend
from helpers.advanced.fast_graph.cholmod_backend import pattern_matrix
from helpers.datasets import load_dataset

GRAPHS = ("w100", "w10000", "w20000", "victoria_park", "q2_e")
LAMBDA = 1e-5


def damped_hessian(name):
    """(pattern, upper-triangle CSC data of H + λI, b) of graph ``name`` at its initial estimate."""
    if name == "q2_e":
        from helpers.advanced.drivebot_variants import run_fast
        opt = run_fast("q2_e").system.graph
        opt.initialize_optimization()
    else:
        opt = load_dataset(name, optimizer_class=FastOptimizer)
    system = opt._free_state().linearise()
    pattern = opt._structure.pattern
    data = system.hessian_data.copy()
    data[pattern.diag_pos] += LAMBDA
    return pattern, data, system.gradient.copy()


def cholmod_options(nmethods=None):
    cholmod.options.clear()
    cholmod.options["supernodal"] = 2
    if nmethods is not None:
        cholmod.options["nmethods"] = nmethods


def variants(pattern, data, rhs):
    """{name: callable} of the timed operations (each returns its solution or None)."""
    upper = pattern.upper(data)
    solver = qdldl.Solver(upper, upper=True)
    perm = np.asarray(solver.factors()[2], dtype=np.int64)
    a = pattern_matrix(pattern, data)
    values = cvxopt.matrix(np.ascontiguousarray(data, dtype=float))
    view = np.asarray(values).reshape(-1)
    b = cvxopt.matrix(np.zeros(pattern.n))
    bview = np.asarray(b).reshape(-1)
    cholmod_options()
    f_own = cholmod.symbolic(a, uplo="U")
    p = cvxopt.matrix(perm, tc="i")
    cholmod_options(1)
    f_q = cholmod.symbolic(a, p=p, uplo="U")

    def qdldl_refactor():
        solver.update(pattern.upper(data), upper=True)
        return np.asarray(solver.solve(rhs))

    def cholmod_refactor(factor):
        def run():
            cholmod_options()
            view[:] = data
            a.V = values
            cholmod.numeric(a, factor)
            bview[:] = rhs
            cholmod.solve(factor, b)
            return bview.copy()
        return run

    def symbolic_own():
        cholmod_options()
        cholmod.symbolic(a, uplo="U")

    def symbolic_q():
        cholmod_options(1)
        cholmod.symbolic(a, p=p, uplo="U")

    def qdldl_build():
        qdldl.Solver(upper, upper=True)

    def pattern_build():
        pattern_matrix(pattern, data)

    return {"qdldl build": qdldl_build,
            "qdldl refactor+solve": qdldl_refactor,
            "cvx pattern": pattern_build,
            "CHOLMOD symbolic (own)": symbolic_own,
            "CHOLMOD refactor+solve (own)": cholmod_refactor(f_own),
            "CHOLMOD symbolic (qdldl perm)": symbolic_q,
            "CHOLMOD refactor+solve (qdldl perm)": cholmod_refactor(f_q)}


def measure(name, rounds):
    pattern, data, rhs = damped_hessian(name)
    full = pattern.full_matrix(data)
    ops = variants(pattern, data, rhs)
    best = {k: [np.inf, np.inf] for k in ops}   # [wall, CPU]
    solutions = {}
    for _ in range(rounds):
        for k, op in ops.items():
            t, c = time.perf_counter(), time.process_time()
            out = op()
            c, t = time.process_time() - c, time.perf_counter() - t
            best[k] = [min(best[k][0], t), min(best[k][1], c)]
            if out is not None:
                solutions[k] = out
    nb = np.linalg.norm(rhs)
    residual = {k: np.linalg.norm(full @ x - rhs) / nb for k, x in solutions.items()}
    xq = solutions["qdldl refactor+solve"]
    diff = {k: np.linalg.norm(x - xq) / np.linalg.norm(xq) for k, x in solutions.items()}
    lower = qdldl.Solver(pattern.upper(data), upper=True).factors()[0]
    counts = np.diff(lower.indptr) + 1
    return pattern, best, residual, diff, counts


def report(name, pattern, best, residual, diff, counts):
    wall = {k: 1e3 * v[0] for k, v in best.items()}
    ms = {k: 1e3 * v[1] for k, v in best.items()}
    nnz, flops = cholmod_backend.factor_statistics(counts)
    choice = "CHOLMOD" if cholmod_backend.prefers_cholmod(counts) else "qdldl"
    print(f"\n== {name}: n = {pattern.n}, nnz(upper H) = {pattern.nnz}, nnz(L) = {int(nnz)}, flops = {flops:.2e}, "
          f"flops/nnz(L) = {flops / nnz:.1f} -> LDLSolver(backend='auto') uses {choice} ==")
    for k, v in ms.items():
        extra = ""
        if k in residual:
            extra = f"   residual {residual[k]:.1e}   vs qdldl {diff[k]:.1e}"
        print(f"  {k:38s} {v:9.2f} ms CPU {wall[k]:9.2f} ms wall{extra}")
    for label, t in (("CPU", ms), ("wall", wall)):
        q_build, q_ref = t["qdldl build"], t["qdldl refactor+solve"]
        for order in ("own", "qdldl perm"):
            c_sym, c_ref = t[f"CHOLMOD symbolic ({order})"], t[f"CHOLMOD refactor+solve ({order})"]
            print(f"  ratios CHOLMOD/qdldl, {label:4s} ({order} ordering): refactor+solve {c_ref / q_ref:.2f}, "
                  f"pattern+symbolic+refactor vs build {(t['cvx pattern'] + c_sym + c_ref) / q_build:.2f}")
    bad = {k: r for k, r in residual.items() if not r < 1e-10}
    if bad:
        print(f"  RESIDUAL CHECK FAILED: {bad}")
    return not bad


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7, help="interleaved rounds (best of; default 7)")
    parser.add_argument("--graphs", nargs="+", choices=GRAPHS, default=list(GRAPHS))
    args = parser.parse_args()
    print(f"cvxopt {cvxopt.__version__}, qdldl {getattr(qdldl, '__version__', '?')}, "
          f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
          f"load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}, best of {args.rounds} interleaved")
    ok = True
    for name in args.graphs:
        ok &= report(name, *measure(name, max(args.rounds, 1)))
    print(f"\nload average at the end {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
