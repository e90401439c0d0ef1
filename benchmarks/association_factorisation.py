"""q2_e's association-update factorisations, replayed with the orderings and libraries that could replace qdldl's.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python benchmarks/association_factorisation.py [--seed 0] [--every 1]

A q2_e run with JCBB (``run_hidden_ids("q2_e", data_association="jcbb")``) updates the graph every 100 ticks for the
front-end (``helpers.advanced.hidden_ids``): one factorisation of the undamped H at the current estimates, for a
pattern that has grown since the last update. The run is made once; every matrix the update factorises is kept
(the upper triangle on the optimiser's own pattern, and the first row and dimension of every free vertex). The
pattern matters: it stores every vertex block whole (the zeros of a block included), so the columns of a vertex
are indistinguishable and AMD treats them as one supervariable; the same matrix without its explicit zeros
takes qdldl longer to build (the second row). Each matrix (or every ``--every``-th)
is then factorised by each variant in turn (best CPU time of ``--rounds`` calls), and the totals over the kept
matrices are printed:

    qdldl build          qdldl.Solver(H): its own AMD ordering of the scalar matrix, symbolic and numeric LDLᵀ —
                         what each association update pays today
    qdldl build, explicit zeros removed
                         the same on H without the zeros stored in its blocks (as ``graph.hessian()`` gives it)
    qdldl numeric        Solver.update(H) on the built solver: the numeric factorisation alone
    block ordering       AMD (cvxopt) on the vertex graph (one node per vertex, an edge per non-zero block),
                         expanded to the rows: the pattern of the blocks and the ordering
    CHOLMOD, that order  the cvxopt matrix of H (``cholmod_backend.pattern_matrix``), CHOLMOD's symbolic analysis
                         with the block ordering (nmethods 1: no other ordering tried; not postordered), simplicial
                         numeric LDLᵀ, and the factor copied out (getfactor) as the covariance columns would need it
    SuperLU, that order  H permuted by the block ordering (scipy), SuperLU without column ordering and with
                         diagonal pivots (splu, permc_spec NATURAL, diag_pivot_thresh 0, symmetric mode) and its
                         L and U

nnz(L) under qdldl's ordering and under the block ordering are printed for the largest matrix. Needs cvxopt.
"""

import argparse
import os
import sys
import time

import numpy as np
import qdldl
import scipy.sparse as sp
import scipy.sparse.linalg as sla

try:
    import cvxopt
    from cvxopt import amd, cholmod
except ImportError:
    sys.exit("benchmarks/association_factorisation.py needs cvxopt (pip install cvxopt)")

import helpers.advanced.hidden_ids as drivebot_association
from helpers.advanced.fast_graph import cholmod_backend


def capture(seed):
    """[(upper-triangle CSC H, vertex first rows, vertex dimensions, its ``HessianPattern``)] of every association
    update of the run."""
    kept = []
    original = drivebot_association.hessian_factors

    def recording(graph):
        free = sorted((v.hessian_index, type(v).dimension) for v in graph.vertices() if v.hessian_index is not None)
        data = graph._current_linear_system("association_factorisation").hessian_data
        pattern = graph._structure.pattern                          # the optimiser's pattern, whole blocks
        kept.append((pattern.upper(data).copy(), np.array([s for s, _ in free]), np.array([d for _, d in free]),
                     pattern))
        return original(graph)

    drivebot_association.hessian_factors = recording
    try:
        drivebot_association.run_hidden_ids("q2_e", data_association="jcbb", seed=seed)
    finally:
        drivebot_association.hessian_factors = original
    return kept


def block_ordering(upper, starts, dims):
    """Row permutation: AMD on the vertex graph, expanded to the rows. The last column of a vertex holds every
    block above the diagonal in its block column (whole blocks are stored), so the block pattern is read from
    those columns, consecutive repeats dropped."""
    n, nb = upper.shape[0], len(starts)
    owner = np.repeat(np.arange(nb), dims)
    last = starts + dims - 1
    lengths = np.diff(upper.indptr)[last]
    cols = np.repeat(np.arange(nb), lengths)
    offset = np.arange(lengths.sum()) - np.repeat(np.cumsum(lengths) - lengths, lengths)
    rows = owner[upper.indices[np.repeat(upper.indptr[last], lengths) + offset]]
    new = np.ones(rows.size, dtype=bool)
    new[1:] = (rows[1:] != rows[:-1]) | (cols[1:] != cols[:-1])
    pattern = cvxopt.spmatrix(1.0, cvxopt.matrix(rows[new], tc="i"), cvxopt.matrix(cols[new], tc="i"), (nb, nb))
    order = np.asarray(amd.order(pattern, uplo="U"), dtype=np.int64).reshape(-1)
    lengths = dims[order]                                  # rows of the blocks, in the blocks' new order
    first = np.cumsum(lengths) - lengths
    return np.repeat(starts[order] - first, lengths) + np.arange(n)


def cholmod_factor(pattern, upper, perm):
    """nnz of the strictly lower L (CHOLMOD stores D on its diagonal) of H = ``upper`` on ``pattern``."""
    matrix = cholmod_backend.pattern_matrix(pattern, upper.data)
    saved = dict(cholmod.options)
    cholmod.options.clear()
    cholmod.options.update({"supernodal": 0, "nmethods": 1, "postorder": False})
    try:
        factor = cholmod.symbolic(matrix, p=cvxopt.matrix(perm, tc="i"), uplo="U")
        cholmod.numeric(matrix, factor)
        values = cholmod.getfactor(factor).CCS[2]
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)
    return len(np.asarray(values)) - pattern.n


def superlu_factor(upper, perm):
    full = (upper + sp.triu(upper, 1).T).tocsc()
    lu = sla.splu(full[perm][:, perm].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                  options={"SymmetricMode": True})
    if not np.array_equal(lu.perm_r, np.arange(full.shape[0])):
        raise RuntimeError("SuperLU pivoted rows: its L is not the LDLᵀ factor")
    return lu.L.nnz - full.shape[0]


def best_time(run, rounds):
    """The shortest CPU time of ``rounds`` calls of ``run``."""
    best = np.inf
    for _ in range(max(rounds, 1)):
        t = time.process_time()
        run()
        best = min(best, time.process_time() - t)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--every", type=int, default=1, help="factorise every k-th kept matrix (default 1: all)")
    parser.add_argument("--rounds", type=int, default=3, help="each variant's best of this many calls (default 3)")
    args = parser.parse_args()
    print(f"cvxopt {cvxopt.__version__}, OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}, "
          f"load average {os.getloadavg()[0]:.2f}")
    kept = capture(args.seed)[::max(args.every, 1)]
    totals = dict.fromkeys(("qdldl build", "qdldl build, explicit zeros removed", "qdldl numeric", "block ordering",
                            "CHOLMOD, that order", "SuperLU, that order"), 0.0)
    fill = {}
    for upper, starts, dims, pattern in kept:
        solver = qdldl.Solver(upper, upper=True)
        perm = block_ordering(upper, starts, dims)
        stripped = upper.copy()
        stripped.eliminate_zeros()
        variants = {"qdldl build": lambda u=upper: qdldl.Solver(u, upper=True),
                    "qdldl build, explicit zeros removed": lambda s=stripped: qdldl.Solver(s, upper=True),
                    "qdldl numeric": lambda f=solver, u=upper: f.update(u, upper=True),
                    "block ordering": lambda u=upper, s=starts, d=dims: block_ordering(u, s, d),
                    "CHOLMOD, that order": lambda p=pattern, u=upper, o=perm:
                        fill.__setitem__("CHOLMOD", cholmod_factor(p, u, o)),
                    "SuperLU, that order": lambda u=upper, o=perm: fill.__setitem__("SuperLU", superlu_factor(u, o))}
        for name, run in variants.items():
            totals[name] += best_time(run, args.rounds)
        fill["qdldl"] = solver.factors()[0].nnz
    print(f"\n{len(kept)} association-update matrices of q2_e with JCBB (seed {args.seed}); the largest has n = "
          f"{kept[-1][0].shape[0]}, nnz(upper H) = {kept[-1][0].nnz}")
    print(f"nnz(L) of the largest: qdldl's AMD {fill['qdldl']}, block ordering (CHOLMOD) {fill['CHOLMOD']}, "
          f"(SuperLU) {fill['SuperLU']}\n")
    print("| variant | CPU over all kept matrices [s] |\n| --- | --- |")
    for name, seconds in totals.items():
        print(f"| {name} | {seconds:.3f} |")
    replace = totals["block ordering"] + totals["CHOLMOD, that order"]
    print(f"\nblock ordering + CHOLMOD: {replace:.3f} s against qdldl's build {totals['qdldl build']:.3f} s "
          f"(ratio {replace / totals['qdldl build']:.2f}); block ordering + SuperLU: "
          f"{(totals['block ordering'] + totals['SuperLU, that order']) / totals['qdldl build']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
