"""The CHOLMOD backend of LDLSolver (helpers.advanced.fast_graph.cholmod_backend) against the qdldl path: the same
steps, the same positive-definiteness verdicts, the same optimisation results and marginals; the per-pattern choice;
the fallback to qdldl when cvxopt is not installed (no wheel for macOS arm64 + CPython 3.13)."""
import numpy as np
import pytest

from helpers.advanced.fast_graph import FastOptimizer, VertexSE2Exp, cholmod_backend
from helpers.advanced.fast_graph.linear import HessianPattern, LDLSolver
from helpers.datasets import load_dataset
from helpers.graph import GraphError, VertexSE2

requires_cvxopt = pytest.mark.skipif(
    not cholmod_backend.AVAILABLE,
    reason="cvxopt is not installed (it has no wheel for macOS arm64 + CPython 3.13): the CHOLMOD backend is off "
           "and qdldl does every factorisation")


def _random_spd(rng, n, density, shift=1.0):
    """A random sparse symmetric matrix on a HessianPattern: (pattern, upper CSC data); positive definite for
    ``shift`` > 0 (diagonally dominant), indefinite for a negative shift."""
    pairs = np.array([(i, j) for i in range(n) for j in range(i, n) if i == j or rng.random() < density])
    pattern = HessianPattern(n, pairs[:, 0], pairs[:, 1], np.ones(len(pairs), dtype=bool))
    vals = np.where(pairs[:, 0] == pairs[:, 1], 0.0, rng.normal(size=len(pairs)))
    data = pattern.assemble(vals)
    data[pattern.diag_pos] += np.abs(pattern.full_matrix(data)).sum(axis=1).A1 + shift
    return pattern, data


def _graph_system(name, damping):
    """(pattern, upper CSC data of H + damping·I, b) of a dataset at its initial estimate."""
    opt = load_dataset(name, optimizer_class=FastOptimizer)
    system = opt._free_state().linearise()
    pattern = opt._structure.pattern
    data = system.hessian_data.copy()
    data[pattern.diag_pos] += damping
    return pattern, data, system.gradient


def _rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@requires_cvxopt
@pytest.mark.parametrize("seed", range(6))
def test_random_spd_systems_give_the_same_step(seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(5, 400))
    pattern, data = _random_spd(rng, n, min(0.5, 8.0 / n), shift=10.0 ** rng.uniform(-6, 1))
    b = rng.normal(size=n)
    q = LDLSolver(backend="qdldl").factor(pattern, data)
    c = LDLSolver(backend="cholmod").factor(pattern, data)
    assert q.active_backend == "qdldl" and c.active_backend == "cholmod"
    assert q.ok and c.ok
    assert _rel(c.solve(b), q.solve(b)) < 1e-10
    H = pattern.full_matrix(data)
    assert np.linalg.norm(H @ c.solve(b) - b) / np.linalg.norm(b) < 1e-10
    # a refactorisation with new values on the same pattern (LM: only the diagonal changes)
    damped = data.copy()
    damped[pattern.diag_pos] += 0.37
    assert _rel(c.factor(pattern, damped, damping=0.37).solve(b), q.factor(pattern, damped, damping=0.37).solve(b)) \
        < 1e-10


@requires_cvxopt
@pytest.mark.parametrize("name, damping", [("w100", 0.0), ("w100", 1e-5), ("w10000", 1e-5), ("victoria_park", 1e-5)])
def test_a_real_hessian_gives_the_same_step(name, damping):
    pattern, data, b = _graph_system(name, damping)
    q = LDLSolver(backend="qdldl").factor(pattern, data, damping=damping)
    c = LDLSolver(backend="cholmod").factor(pattern, data, damping=damping)
    assert q.ok and c.ok
    xq, xc = q.solve(b), c.solve(b)
    H = pattern.full_matrix(data)
    for x in (xq, xc):          # backward stable: ≤ 8e−12 measured (Victoria Park), the others ≤ 1.4e−15
        assert np.linalg.norm(H @ x - b) / np.linalg.norm(b) < 1e-10
    # Two factorisations (other orderings) agree to about ε·κ(H) along H's weakest directions. Measured: W100
    # (κ ≈ 5e4) 1.2e−13, W10000 (κ ≈ 9e9) 7.8e−12, Victoria Park (initial estimate, λ = 1e−5, κ ≈ 5e10) 2.8e−9.
    assert _rel(xc, xq) < {"w100": 1e-10, "w10000": 1e-9, "victoria_park": 1e-7}[name]


@requires_cvxopt
def test_not_positive_definite_is_reported_like_qdldl_and_the_factor_recovers():
    rng = np.random.default_rng(7)
    pattern, good = _random_spd(rng, 40, 0.15)
    bad = good.copy()
    bad[pattern.diag_pos[5]] = -1.0                   # indefinite
    singular = np.zeros_like(good)                     # singular (all zero)
    nonfinite = [good.copy() for _ in range(3)]         # NaN / inf on the diagonal, NaN off it
    nonfinite[0][pattern.diag_pos[3]] = np.nan
    nonfinite[1][pattern.diag_pos[3]] = np.inf
    nonfinite[2][np.setdiff1d(np.arange(pattern.nnz), pattern.diag_pos)[4]] = np.nan
    b = rng.normal(size=40)
    for backend in ("qdldl", "cholmod"):
        solver = LDLSolver(backend=backend)
        for data in (bad, singular, *nonfinite):
            assert not solver.factor(pattern, data).ok, backend
            assert np.isnan(solver.solve(b)).all()
        assert solver.factor(pattern, good).ok       # the same solver factorises a good matrix again
        assert np.isfinite(solver.solve(b)).all()
    # a failed damped step (numerical breakdown) is a NaN step for CHOLMOD, which the algorithms reject
    solver = LDLSolver(backend="cholmod")
    assert not solver.factor(pattern, bad, damping=1.0).ok
    assert np.isnan(solver.solve(b)).all()


#: A relative χ² decrease above this is a step of the run, below it round-off. Measured on the runs below: the
#: smallest step decreases χ² by 2.2e−13 (W10000, default), the largest round-off change is 1.2e−15 (W100, "lm");
#: the threshold sits at their geometric mean, a factor ≈ 13 from each.
ROUND_OFF_DECREASE = 1.6e-14


def _steps(chi2_0, history):
    """The number of leading iterations of a run that each decrease χ² by more than round-off, and the relative
    decreases of all its iterations."""
    h = np.r_[chi2_0, history]
    rel = (h[:-1] - h[1:]) / h[1:]
    tail = np.flatnonzero(rel <= ROUND_OFF_DECREASE)
    return (int(tail[0]) if len(tail) else len(rel)), rel


@requires_cvxopt
@pytest.mark.parametrize("name, algorithm, pose_class", [("w100", "default", None), ("w100", "lm", None),
                                                         ("w100", "gn", None), ("w10000", "default", None),
                                                         ("w10000", "lm-gtsam", VertexSE2Exp)])
def test_the_optimisation_result_is_the_same(name, algorithm, pose_class):
    results = {}
    for backend in ("qdldl", "cholmod"):
        opt = load_dataset(name, pose_class or VertexSE2, optimizer_class=FastOptimizer)
        opt.linear_solver.backend = backend
        opt.initialize_optimization()
        assert opt.linear_solver.active_backend == backend
        chi2_0 = opt.chi2()
        chi2 = opt.optimize(100, algorithm=algorithm)
        count, rel = _steps(chi2_0, opt.chi2_history)
        # the premise: no iteration decreases χ² by an amount near the threshold, so both runs split alike
        assert not np.any((rel > ROUND_OFF_DECREASE / 3) & (rel < 3 * ROUND_OFF_DECREASE)), rel
        results[backend] = (chi2, opt.iterations, np.array([v.estimate for v in opt.vertices()]), count,
                            np.array(opt.chi2_history[:count]), [s["rejected"] for s in opt.statistics[:count]])
    (cq, iq, xq, nq, hq, rq), (cc, ic, xc, nc, hc, rc) = results["qdldl"], results["cholmod"]
    assert abs(cc - cq) <= 1e-9 * cq
    np.testing.assert_allclose(xc, xq, rtol=0, atol=1e-6)
    # The steps are the same: as many, with the same rejected trials, to the same χ². Far from the optimum the
    # iterates amplify round-off: W10000's intermediate χ² differ by up to 1.4e−8 between the backends (the converged
    # χ² by < 1e−12), hence 1e−6 there. In the round-off tail whether a change of a few ulps is accepted is luck: it
    # decides the total count of "lm" on W100 (12, but 13 in 1 of 60 runs from initial estimates moved by an ulp),
    # so the totals are not compared; both runs stop by their own rule, not at max_iterations.
    assert nc == nq and rc == rq
    np.testing.assert_allclose(hc, hq, rtol=1e-6)
    assert iq < 100 and ic < 100


@requires_cvxopt
def test_marginals_and_hessian_factors_stay_on_qdldl():
    opts = {}
    for backend in ("qdldl", "cholmod"):
        opt = load_dataset("w100", optimizer_class=FastOptimizer)
        opt.linear_solver.backend = backend
        opt.initialize_optimization()
        opt.optimize(20)
        opts[backend] = opt
    mq = opts["qdldl"].compute_marginals()
    mc = opts["cholmod"].compute_marginals()
    for vq, vc in zip(mq, mc):
        np.testing.assert_allclose(mc[vc], mq[vq], rtol=1e-8, atol=1e-14)
    lq, dq, pq = opts["qdldl"].hessian_factors()
    lc, dc, pc = opts["cholmod"].hessian_factors()
    np.testing.assert_array_equal(pc, pq)
    np.testing.assert_allclose(dc, dq, rtol=1e-8)
    assert abs(lc - lq).max() < 1e-8 * abs(lq).max()


@requires_cvxopt
def test_qdldl_follows_the_last_cholmod_factorisation():
    rng = np.random.default_rng(11)
    pattern, data = _random_spd(rng, 60, 0.1)
    solver = LDLSolver(backend="cholmod").factor(pattern, data)
    first = solver.qdldl
    b = rng.normal(size=60)
    np.testing.assert_allclose(first.solve(b), solver.solve(b), rtol=1e-10)
    damped = data.copy()
    damped[pattern.diag_pos] += 3.0
    solver.factor(pattern, damped, damping=3.0)
    assert solver.qdldl is first                       # one qdldl.Solver per pattern, refactorised on demand
    np.testing.assert_allclose(first.solve(b), solver.solve(b), rtol=1e-10)


@requires_cvxopt
def test_the_cvxopt_matrix_has_the_patterns_csc_order():
    rng = np.random.default_rng(5)
    pattern, data = _random_spd(rng, 80, 0.08)
    factor = cholmod_backend.CholmodFactor(pattern, np.arange(80))
    factor.factor(data)
    colptr, rowind, values = factor._matrix.CCS
    np.testing.assert_array_equal(np.asarray(colptr).ravel(), pattern.indptr)
    np.testing.assert_array_equal(np.asarray(rowind).ravel(), pattern.indices)
    np.testing.assert_array_equal(np.asarray(values).ravel(), data)
    with pytest.raises(ValueError, match="permutation"):
        cholmod_backend.CholmodFactor(pattern, np.zeros(80, dtype=int))


@requires_cvxopt
def test_the_choice_per_pattern():
    w10000 = load_dataset("w10000", optimizer_class=FastOptimizer)
    assert w10000.linear_solver.active_backend == "cholmod"  # dense factor columns (loop closures)
    for name in ("w100", "victoria_park"):
        assert load_dataset(name, optimizer_class=FastOptimizer).linear_solver.active_backend == "qdldl", name
    assert not cholmod_backend.prefers_cholmod(np.full(10_000, 5))       # sparse factor
    assert not cholmod_backend.prefers_cholmod(np.full(100, 50))         # dense but tiny (0.25 Mflop)
    assert cholmod_backend.prefers_cholmod(np.full(1_000, 60))


@requires_cvxopt
def test_the_callers_cholmod_options_are_left_alone():
    from cvxopt import cholmod
    saved = dict(cholmod.options)
    try:
        cholmod.options.clear()
        cholmod.options["supernodal"] = 0
        rng = np.random.default_rng(2)
        pattern, data = _random_spd(rng, 50, 0.1)
        solver = LDLSolver(backend="cholmod").factor(pattern, data)
        solver.solve(np.ones(50))
        assert cholmod.options == {"supernodal": 0}
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)


def test_without_cvxopt_everything_runs_on_qdldl(monkeypatch):
    monkeypatch.setattr(cholmod_backend, "AVAILABLE", False)
    assert not cholmod_backend.prefers_cholmod(np.full(1_000, 60))
    with pytest.raises(GraphError, match="needs cvxopt"):
        LDLSolver(backend="cholmod")
    opt = load_dataset("w10000", optimizer_class=FastOptimizer)
    assert opt.linear_solver.active_backend == "qdldl"


def test_backend_names_are_checked():
    with pytest.raises(ValueError, match="backend must be one of"):
        LDLSolver(backend="umfpack")


@pytest.mark.parametrize("backend", ["qdldl", "auto"])
def test_the_first_matrix_of_a_pattern_may_be_singular_or_not_finite(backend):
    """qdldl's constructor refuses a zero pivot (update() reports it in D): a fresh solver whose first matrix is
    singular, indefinite or not finite reports it like a later one, and then factorises a good matrix."""
    rng = np.random.default_rng(11)
    pattern, good = _random_spd(rng, 30, 0.2)
    bad = good.copy()
    bad[pattern.diag_pos[5]] = -1.0
    nan = good.copy()
    nan[pattern.diag_pos[3]] = np.nan
    b = rng.normal(size=30)
    expected = np.linalg.solve(pattern.full_matrix(good).toarray(), b)
    for first in (np.zeros_like(good), bad, nan):
        solver = LDLSolver(backend=backend)
        assert not solver.factor(pattern, first).ok
        assert np.isnan(solver.solve(b)).all()
        assert solver.factor(pattern, good).ok
        np.testing.assert_allclose(solver.solve(b), expected, rtol=1e-10)


@pytest.mark.parametrize("case", ["random_0", "random_1", "random_2", "w100", "victoria_park"])
def test_column_counts_are_those_of_qdldls_factor_under_its_ordering(case):
    """The elimination-tree count of the decision, under qdldl's own permutation, gives the column counts of the
    factor qdldl computes (diagonal included)."""
    import qdldl
    if case.startswith("random"):
        pattern, _ = _random_spd(np.random.default_rng(int(case[-1])), 120, 0.04)
    else:
        pattern = load_dataset(case, optimizer_class=FastOptimizer)._structure.pattern
    lower, _, perm = qdldl.Solver(pattern.upper(pattern.surrogate()), upper=True).factors()
    counts = cholmod_backend.column_counts(pattern, perm)
    np.testing.assert_array_equal(counts, np.diff(lower.indptr) + 1)


@requires_cvxopt
def test_auto_decides_once_per_size_and_builds_qdldl_only_on_demand(monkeypatch):
    calls = []
    counts = cholmod_backend.column_counts
    monkeypatch.setattr(cholmod_backend, "column_counts", lambda *a: calls.append(a[0].n) or counts(*a))
    opt = load_dataset("w10000", optimizer_class=FastOptimizer)
    pattern, solver = opt._structure.pattern, opt.linear_solver
    assert solver.active_backend == "cholmod" and calls == [pattern.n]
    assert solver._qdldl is None                                     # nothing built that CHOLMOD does not need
    opt.optimize(2, algorithm="lm-gtsam")
    assert solver._qdldl is None
    assert solver.qdldl is not None and solver._qdldl is not None   # the marginals' solver, on demand
    solver.analyse(pattern)                                          # the same size: the decision stands
    assert solver.active_backend == "cholmod" and len(calls) == 1
    # below AUTO_MIN_NNZ: qdldl, no decision
    small = load_dataset("w100", optimizer_class=FastOptimizer)._structure.pattern
    assert small.nnz < cholmod_backend.AUTO_MIN_NNZ
    assert solver.analyse(small).active_backend == "qdldl" and len(calls) == 1
    solver.backend = "auto"                                          # a backend assignment forgets the decision
    solver.analyse(pattern)
    assert solver.active_backend == "cholmod" and len(calls) == 2
    # 5 times fewer entries: decided anew
    sparse = load_dataset("victoria_park", optimizer_class=FastOptimizer)._structure.pattern
    assert solver.analyse(sparse).active_backend == "qdldl" and len(calls) == 3
    assert solver.analyse(sparse).active_backend == "qdldl" and len(calls) == 3


def test_column_counts_and_the_ordering_reject_bad_input_by_name():
    pattern = load_dataset("w100", optimizer_class=FastOptimizer)._structure.pattern
    for perm in (np.arange(pattern.n - 1), np.zeros(pattern.n, dtype=int), np.arange(pattern.n, dtype=float)):
        with pytest.raises(ValueError, match=r"column_counts: perm must be a permutation of range\(297\)"):
            cholmod_backend.column_counts(pattern, perm)
    if cholmod_backend.AVAILABLE:
        with pytest.raises(ValueError, match="amd_ordering: matrix must be a square cvxopt spmatrix"):
            cholmod_backend.amd_ordering(pattern.upper(np.ones(pattern.nnz)))
    else:
        with pytest.raises(ImportError, match="needs cvxopt"):
            cholmod_backend.amd_ordering(None)
