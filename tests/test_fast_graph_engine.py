"""The optimiser's modules one by one: storage, elements' hooks, structure, linearisation, algorithms, marginals."""

import numpy as np
import pytest

from helpers.advanced.fast_graph import FastOptimizer
from helpers.advanced.fast_graph.algorithms import (ALGORITHMS, GaussNewton, GaussNewtonParams, GTSAMLevenbergMarquardt,
                                                    GTSAMLevenbergMarquardtParams, LevenbergMarquardt,
                                                    LevenbergMarquardtParams, Trial, make_algorithm)
from helpers.advanced.fast_graph.linearise import (FreeState, LinearSystem, chi2_at, linearise, linearise_reference,
                                                   total_chi2)
from helpers.advanced.fast_graph.structure import EdgeClassBlock, GraphStructure, build_structure, check_gauge
from helpers.graph import (BaseEdge, EdgeRangeBearing, EdgeSE2, EdgeSE2Prior, GaugeFreedomError, GraphError,
                           VertexPointXY, VertexSE2)
from helpers.graph.marginals import marginal_blocks
from helpers.graph.storage import EdgeStore, GrowableArray, VertexStore


def chain(n=5, seed=1, full_information=False, fix_first=True):
    """Poses on a line joined by noisy odometry, one landmark seen from every pose."""
    rng = np.random.default_rng(seed)
    g = FastOptimizer()
    poses = [VertexSE2(i, [i + rng.normal(0, 0.2), rng.normal(0, 0.2), rng.normal(0, 0.05)],
                       fixed=fix_first and i == 0) for i in range(n)]
    point = VertexPointXY(0, [2.0, 3.0])
    for v in poses + [point]:
        g.add_vertex(v)
    info = np.array([[100.0, 10.0, 0.0], [10.0, 100.0, 0.0], [0.0, 0.0, 400.0]]) if full_information \
        else np.diag([100.0, 100.0, 400.0])
    for i in range(n - 1):
        g.add_edge(EdgeSE2([poses[i], poses[i + 1]], measurement=[1.0, 0.0, 0.0], information=info))
    for i, p in enumerate(poses):
        d = np.array([2.0 - i, 3.0])
        g.add_edge(EdgeRangeBearing([p, point], measurement=[np.hypot(*d), np.arctan2(d[1], d[0])],
                                    information=np.diag([50.0, 200.0])))
    return g, poses, point


def outputs(g):
    return (g.chi2_history, [s["mu"] for s in g.statistics], [v.estimate.tolist() for v in g.vertices()])


# ---------------------------------------------------------------------------------------------------- storage
def test_growable_array_keeps_rows_across_growth():
    a = GrowableArray((2,), np.int64, -1)
    assert a.size == 0 and a.values.shape == (0, 2)
    assert a.append([1, 2]) == 0
    assert a.extend(np.arange(60).reshape(30, 2)) == 1
    assert a.size == 31 and len(a.buffer) >= 31
    np.testing.assert_array_equal(a.values[0], [1, 2])
    np.testing.assert_array_equal(a.values[1:], np.arange(60).reshape(30, 2))
    assert (a.buffer[a.size:] == -1).all()


def test_vertex_and_edge_stores_follow_the_graph():
    g, poses, point = chain(4)
    store = g._vertex_store
    assert isinstance(store, VertexStore) and store.count == 5
    np.testing.assert_array_equal(store.estimate(point._h), [2.0, 3.0])
    edges = g._edge_stores[EdgeSE2]
    assert isinstance(edges, EdgeStore) and edges.slots == 2 and edges.slot_dimensions == [3, 3]
    e = poses[1].edges()[0]
    g.remove_edge(e)
    assert not edges.alive.values[0] and edges.objects[0] is None
    assert store.count == 5  # handles are never reused
    g.remove_vertex(point)
    assert point._h == -1 and not store.alive.values[4]
    np.testing.assert_array_equal(point.estimate, [2.0, 3.0])  # the estimate went back into the object


def test_element_hooks_have_clear_names():
    g, poses, _ = chain(3)
    g.initialize_optimization()
    h0 = g.hessian().toarray()
    poses[2].set_estimate([2.5, 0.3, 0.1])  # value change: H recomputed, structure kept
    assert not np.allclose(g.hessian().toarray(), h0)
    assert poses[1].hessian_index == 0
    poses[1].set_fixed(True)  # structure change
    assert poses[1].hessian_index is None
    with pytest.raises(GraphError, match="initialize_optimization"):
        g.optimize(1)


# ---------------------------------------------------------------------------------------------------- structure
def test_structure_is_a_dataclass_with_readable_fields():
    g, poses, point = chain(4, full_information=True)
    g.initialize_optimization()
    st = g._structure
    assert isinstance(st, GraphStructure)
    assert st.dimension == g.dimension == 3 * 3 + 2
    assert st.hessian_index[poses[0]._h] == -1 and st.hessian_index[poses[1]._h] == 0
    np.testing.assert_array_equal(st.free_state_index, np.arange(3, 3 * 4 + 2))
    by_class = {b.store.cls: b for b in st.blocks}
    assert all(isinstance(b, EdgeClassBlock) for b in st.blocks)
    assert by_class[EdgeSE2].count == 3 and not by_class[EdgeSE2].diagonal_whitening
    rb = by_class[EdgeRangeBearing]
    assert rb.diagonal_whitening and rb.whitening.shape == (4, 2)
    np.testing.assert_array_equal(rb.hessian_start[1], [9, 9, 9, 9])
    assert {grp.cls for grp in st.vertex_groups} == {VertexSE2, VertexPointXY}


def test_build_structure_and_check_gauge_report_floating_components():
    g, poses, _ = chain(3, fix_first=False)
    with pytest.raises(GaugeFreedomError) as err:
        build_structure(g._vertex_store, g._edge_stores)
    assert len(err.value.component) == 4
    g.add_edge(EdgeSE2Prior([poses[0]], measurement=poses[0].estimate, information=np.eye(3)))
    assert build_structure(g._vertex_store, g._edge_stores).dimension == 3 * 3 + 2
    check_gauge(np.zeros(0, dtype=np.int64), 0, [], [], [], [])  # nothing free: nothing to check


# ---------------------------------------------------------------------------------------------------- linearise
def test_linearise_matches_the_public_hessian_gradient_and_chi2():
    g, _, _ = chain(5, full_information=True)
    g.initialize_optimization()
    st = g._structure
    est = g._vertex_store.estimates.buffer
    system = linearise(st, est)
    assert isinstance(system, LinearSystem)
    np.testing.assert_array_equal(st.pattern.full_matrix(system.hessian_data).toarray(), g.hessian().toarray())
    np.testing.assert_array_equal(system.gradient, g.gradient())
    assert system.chi2 == pytest.approx(g.chi2(), rel=1e-12)
    assert chi2_at(st, est) == pytest.approx(total_chi2(g._vertex_store, g._edge_stores), rel=1e-12)


@pytest.mark.parametrize("case", ["chain_full_information", "chain_diagonal", "w100_exp", "victoria_park_moved"])
def test_linearise_is_bit_for_bit_the_reference(case):
    """The fused scatter (fast path) adds the same products in the same order as the reference's bincount."""
    from helpers import datasets
    from helpers.advanced.fast_graph import VertexSE2Exp
    if case.startswith("chain"):
        g, _, _ = chain(7, full_information=case.endswith("information"))
    elif case == "w100_exp":
        g = datasets.build_optimizer(datasets.read_dataset("w100"), pose_class=VertexSE2Exp,
                                     optimizer_class=FastOptimizer)
    else:
        data = datasets.read_dataset("victoria_park")
        g = datasets.build_optimizer(data, optimizer_class=FastOptimizer)
        g.initialize_optimization()
        g.optimize(2)                               # moved away from the initial estimate: landmarks and poses
    g.initialize_optimization()
    est = g._vertex_store.estimates.buffer
    fast, ref = linearise(g._structure, est), linearise_reference(g._structure, est)
    np.testing.assert_array_equal(fast.hessian_data, ref.hessian_data)
    np.testing.assert_array_equal(fast.gradient, ref.gradient)
    assert fast.chi2 == ref.chi2


def test_free_state_get_set_retract_and_solve():
    g, poses, _ = chain(4)
    g.initialize_optimization()
    state = FreeState(g._structure, g._vertex_store.estimates, g.linear_solver)
    x = state.get()
    np.testing.assert_array_equal(x[:3], poses[1].estimate)
    dx = np.full(len(x), 0.01)
    state.retract(dx)
    np.testing.assert_allclose(poses[1].estimate, x[:3] - 0.01)
    state.set(x)
    np.testing.assert_array_equal(state.get(), x)
    system = state.linearise()
    step = state.solve(system)
    np.testing.assert_allclose(g.hessian().toarray() @ step, system.gradient, atol=1e-8)
    damped = state.solve(system, 5.0)
    np.testing.assert_allclose((g.hessian().toarray() + 5.0 * np.eye(len(x))) @ damped, system.gradient, atol=1e-8)


# ---------------------------------------------------------------------------------------------------- algorithms
def test_trial_reject_restores_and_finish_leaves_the_accepted_state():
    g, _, _ = chain(4)
    g.initialize_optimization()
    state = FreeState(g._structure, g._vertex_store.estimates, g.linear_solver)
    trial = Trial(state)
    x0, chi0 = state.get(), trial.chi2
    dx = trial.solve(1.0)
    r1 = trial.try_step(dx)
    assert r1 < chi0
    trial.reject()
    np.testing.assert_array_equal(state.get(), x0)
    r1 = trial.try_step(dx)
    trial.accept(r1)
    assert trial.chi2 == r1
    x1 = state.get()
    trial.try_step(-10 * dx)                   # linearises at the accepted state before leaving it
    chi2, system = trial.finish()
    np.testing.assert_array_equal(state.get(), x1)
    assert chi2 == system.chi2 == r1
    np.testing.assert_array_equal(system.gradient, state.linearise().gradient)
    trial.accept(trial.try_step(0.5 * dx))      # accepted, then finished before anything needed (H, b) there
    x2 = state.get()
    assert trial.finish() == (trial.chi2, None)
    np.testing.assert_array_equal(state.get(), x2)


@pytest.mark.parametrize("name, params", [("lm", LevenbergMarquardtParams()), ("gn", GaussNewtonParams()),
                                          ("lm-gtsam", GTSAMLevenbergMarquardtParams())])
def test_parameters_objects_give_exactly_the_named_algorithm(name, params):
    a, _, _ = chain(6, full_information=True)
    b, _, _ = chain(6, full_information=True)
    a.initialize_optimization()
    b.initialize_optimization()
    assert a.optimize(30, algorithm=name) == b.optimize(30, algorithm=params)
    assert outputs(a) == outputs(b)


def test_lm_tau_argument_equals_the_parameters_field():
    a, _, _ = chain(6)
    b, _, _ = chain(6)
    a.initialize_optimization()
    b.initialize_optimization()
    assert a.optimize(20, algorithm="lm", tau=1e-5) == b.optimize(20, algorithm=LevenbergMarquardtParams(tau=1e-5))
    assert outputs(a) == outputs(b)


def test_gtsam_defaults_and_algorithm_table():
    p = GTSAMLevenbergMarquardtParams()
    assert (p.initial_lambda, p.lambda_factor, p.max_lambda, p.min_model_fidelity, p.relative_tolerance,
            p.absolute_tolerance) == (1e-5, 10.0, 1e5, 1e-3, 1e-5, 1e-5)
    assert LevenbergMarquardtParams().tau == 1e-3 and GaussNewtonParams().tolerance == 1e-5
    assert set(ALGORITHMS) == {"lm", "gn", "lm-gtsam"}
    assert isinstance(make_algorithm("gn", gn_tolerance=0.5), GaussNewton)
    assert make_algorithm("gn", gn_tolerance=0.5).params.tolerance == 0.5
    assert isinstance(make_algorithm("lm-gtsam"), GTSAMLevenbergMarquardt)
    assert make_algorithm(LevenbergMarquardtParams(tau=2.0)).params.tau == 2.0
    assert isinstance(make_algorithm("lm"), LevenbergMarquardt)


@pytest.mark.parametrize("make, field", [
    (lambda: LevenbergMarquardtParams(tau=0.0), "tau"),
    (lambda: LevenbergMarquardtParams(step_tolerance=-1.0), "step_tolerance"),
    (lambda: GaussNewtonParams(tolerance=float("nan")), "tolerance"),
    (lambda: GaussNewtonParams(min_step_fraction=0.0), "min_step_fraction"),
    (lambda: GTSAMLevenbergMarquardtParams(lambda_factor=1.0), "lambda_factor"),
    (lambda: GTSAMLevenbergMarquardtParams(initial_lambda="x"), "initial_lambda"),
])
def test_bad_parameters_name_the_field(make, field):
    with pytest.raises(ValueError, match=field):
        make()


def test_optimize_rejects_unknown_algorithms_and_bad_tolerances():
    g, _, _ = chain(3)
    g.initialize_optimization()
    with pytest.raises(ValueError, match="algorithm"):
        g.optimize(5, algorithm="newton")
    with pytest.raises(ValueError, match="algorithm"):
        g.optimize(5, algorithm=42)
    with pytest.raises(ValueError, match="tolerance"):
        g.optimize(5, algorithm="gn", gn_tolerance=-1.0)
    with pytest.raises(ValueError, match="tau"):
        g.optimize(5, tau=0.0)


# ---------------------------------------------------------------------------------------------------- marginals
def test_marginal_blocks_in_caller_order_with_zero_blocks_for_fixed_vertices():
    g, poses, point = chain(4)
    g.initialize_optimization()
    g.optimize(10)
    order = [point, poses[0], poses[2]]
    data = g._current_linear_system().hessian_data
    assert g.linear_solver.factor(g._structure.pattern, data).ok
    out = marginal_blocks(order, g._hessian_index, g.linear_solver.qdldl)
    assert list(out) == order
    np.testing.assert_array_equal(out[poses[0]], np.zeros((3, 3)))
    cov = np.linalg.inv(g.hessian().toarray())
    np.testing.assert_allclose(out[point], cov[9:11, 9:11], rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(out[poses[2]], cov[3:6, 3:6], rtol=1e-9, atol=1e-14)
    assert g.linear_solver is g._solver and g.linear_solver.qdldl.factors()[0].nnz > 0


def test_hessian_factors_reproduce_the_permuted_hessian():
    g, _, _ = chain(6)
    g.initialize_optimization()
    lower, d, perm = g.hessian_factors()
    H = g.hessian().toarray()
    unit = np.eye(len(d)) + lower.toarray()
    np.testing.assert_allclose(unit @ np.diag(d) @ unit.T, H[np.ix_(perm, perm)], atol=1e-9 * np.abs(H).max())
    assert np.all(d > 0) and np.allclose(np.triu(lower.toarray()), 0)
    d0, lower0 = d.copy(), lower.toarray()
    v = next(v for v in g.vertices() if not v.fixed)
    v.set_estimate(v.estimate + np.array([0.1, -0.2, 0.3]))        # a new state: new factors, old copies intact
    lower1, d1, perm1 = g.hessian_factors()
    H1 = g.hessian().toarray()
    unit1 = np.eye(len(d1)) + lower1.toarray()
    np.testing.assert_allclose(unit1 @ np.diag(d1) @ unit1.T, H1[np.ix_(perm1, perm1)], atol=1e-9 * np.abs(H1).max())
    assert not np.allclose(H1, H) and np.array_equal(d, d0) and np.array_equal(lower.toarray(), lower0)
    empty = FastOptimizer()
    empty.initialize_optimization()
    assert empty.hessian_factors() is None
    stale = FastOptimizer()
    with pytest.raises(GraphError, match="hessian_factors"):
        stale.hessian_factors()


@pytest.mark.parametrize("seed", range(4))
def test_csc_unique_equals_numpy_unique_on_the_keys(seed):
    from helpers.advanced.fast_graph.linear import csc_unique
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    cols = rng.integers(0, n, 300)
    rows = rng.integers(0, cols + 1)                     # upper triangle, many repeats
    indices, indptr, inverse = csc_unique(n, rows, cols)
    uniq, inv = np.unique((cols << 32) | rows, return_inverse=True)
    np.testing.assert_array_equal(indices, uniq & 0xFFFFFFFF)
    np.testing.assert_array_equal(np.repeat(np.arange(n), np.diff(indptr)), uniq >> 32)
    np.testing.assert_array_equal(inverse, inv)
    empty = csc_unique(3, np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))
    assert empty[0].size == 0 and empty[1].tolist() == [0, 0, 0, 0] and empty[2].size == 0


class _ThreeSlotEdge(BaseEdge):
    """A test edge with three slots of two classes: e = p_a + p_b − (x, y) of the pose − z."""

    vertex_types = (VertexPointXY, VertexSE2, VertexPointXY)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        e = states[0] + states[2] - states[1][:, :2] - z
        eye = np.broadcast_to(np.eye(2), (len(z), 2, 2))
        return e, ([eye, np.broadcast_to(-np.eye(2, 3), (len(z), 2, 3)), eye] if jacobians else None)


def _random_mixed_graph(seed):
    """Poses and points created in random order (their rows interleave), some fixed, priors, two- and three-slot
    edges, repeated pairs, and a few removed elements."""
    rng = np.random.default_rng(seed)
    g = FastOptimizer()
    vertices = []
    for i in range(int(rng.integers(8, 30))):
        cls = VertexSE2 if rng.random() < 0.6 else VertexPointXY
        v = cls(i, rng.normal(size=cls.dimension), fixed=bool(rng.random() < 0.15))
        g.add_vertex(v)
        vertices.append(v)
    poses = [v for v in vertices if isinstance(v, VertexSE2)]
    points = [v for v in vertices if isinstance(v, VertexPointXY)]
    edges = []
    for a, b in zip(poses, poses[1:]):
        edges.append(EdgeSE2([a, b], measurement=rng.normal(size=3), information=np.eye(3)))
    for _ in range(2 * len(vertices)):
        p, q = poses[rng.integers(len(poses))], points[rng.integers(len(points))]
        edges.append(EdgeRangeBearing([p, q], measurement=[1.0, 0.1], information=np.eye(2)))
    for _ in range(len(vertices) // 3):
        a, b = rng.choice(len(points), 2, replace=False)
        edges.append(_ThreeSlotEdge([points[a], poses[rng.integers(len(poses))], points[b]],
                                    measurement=[0.0, 0.0], information=np.eye(2)))
    edges.append(EdgeSE2Prior([poses[0]], measurement=[0, 0, 0], information=np.eye(3)))
    for e in edges:
        g.add_edge(e)
    for e in rng.choice(edges[:-1], 3, replace=False):
        g.remove_edge(e)
    return g


@pytest.mark.parametrize("seed", range(6))
def test_the_block_pattern_equals_the_scalar_reference(seed):
    """``build_structure``'s pattern (from vertex blocks) is, array for array, ``HessianPattern`` built from one
    (row, col) per scalar contribution: interleaved poses and points, fixed vertices, unary and three-slot edges,
    removed edges, and a point seen only by a unary edge."""
    from helpers.advanced.fast_graph.linear import HessianPattern
    from helpers.advanced.fast_graph.structure import hessian_contributions
    g = _random_mixed_graph(seed)
    lonely = VertexPointXY(99, [0.0, 0.0])          # only its diagonal block, from a unary edge
    g.add_vertex(lonely)
    g.add_edge(_PointPrior([lonely], measurement=[0.0, 0.0], information=np.eye(2)))
    structure = build_structure(g._vertex_store, g._edge_stores)
    rows, cols, valid = [], [], []
    for blk in structure.blocks:
        r, c, ok, _ = hessian_contributions(blk, structure.dimension)
        rows += r
        cols += c
        valid += ok
    ref = HessianPattern(structure.dimension, np.concatenate(rows), np.concatenate(cols), np.concatenate(valid))
    fast = structure.pattern
    assert (fast.n, fast.nnz) == (ref.n, ref.nnz)
    for name in ("indices", "indptr", "diag_pos", "keys", "scatter"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(ref, name), err_msg=name)
        assert getattr(fast, name).dtype == getattr(ref, name).dtype, name


class _PointPrior(BaseEdge):
    vertex_types = (VertexPointXY,)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        return states[0] - z, ([np.broadcast_to(np.eye(2), (len(z), 2, 2))] if jacobians else None)


@pytest.mark.parametrize("m, d, diagonal, with_oplus", [(3, 3, True, True), (3, 3, False, True), (2, 3, False, False),
                                                        (2, 2, True, False), (2, 3, False, True)])
def test_whitened_jacobians_are_bit_for_bit_the_two_step_products(m, d, diagonal, with_oplus):
    """The fused W J M equals batched_matmul(W, batched_matmul(J, M[handles])) (or w_i · (JM)_ic) exactly, and
    numpy's products to round-off."""
    from helpers.advanced.fast_graph.batched import batched_matmul, whitened_jacobians
    rng = np.random.default_rng(m * 10 + d)
    E, H = 40, 7
    jac = rng.normal(size=(E, m, d))
    oplus = rng.normal(size=(H, d, d))
    handles = rng.integers(0, H, E)
    w = rng.normal(size=(E, m)) if diagonal else rng.normal(size=(E, m, m))
    jm = batched_matmul(jac, oplus[handles]) if with_oplus else jac
    expected = w[:, :, None] * jm if diagonal else batched_matmul(w, jm)
    got = whitened_jacobians(jac[:, :, :], oplus if with_oplus else np.zeros((0, 1, 1)),
                             handles if with_oplus else np.zeros(0, dtype=np.int64),
                             w[:, :, None] if diagonal else w, diagonal)
    np.testing.assert_array_equal(got, expected)
    numpy_jm = jac @ oplus[handles] if with_oplus else jac
    np.testing.assert_allclose(got, w[:, :, None] * numpy_jm if diagonal else w @ numpy_jm, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("m, p", [(3, 3), (2, 3), (2, 2), (1, 4)])
def test_scatter_jtj_upper_is_scatter_jtj_of_a_diagonal_block(m, p):
    from helpers.advanced.fast_graph.batched import scatter_jtj, scatter_jtj_upper
    rng = np.random.default_rng(m * 7 + p)
    a = rng.normal(size=(30, m, p))
    width = p * (p + 1) // 2
    positions = rng.integers(0, 25, 30 * width + 5)              # repeated positions: the order of additions counts
    fast, ref = np.zeros(25), np.zeros(25)
    assert scatter_jtj_upper(a, positions, 5, fast) == scatter_jtj(a, a, True, positions, 5, ref) == 5 + 30 * width
    np.testing.assert_array_equal(fast, ref)


def test_the_batched_helpers_and_the_block_pattern_reject_bad_input_by_name():
    from helpers.advanced.fast_graph.batched import (plain_copy, plain_empty_int32, plain_zeros, scatter_jtj_upper,
                                                     whitened_jacobians)
    from helpers.advanced.fast_graph.block_pattern import pattern_from_blocks
    jac, oplus, handles = np.ones((4, 3, 3)), np.ones((2, 3, 3)), np.array([0, 1, 1, 0])
    with pytest.raises(ValueError, match="jac must have shape"):
        whitened_jacobians(np.ones((4, 3)), oplus, handles, np.ones((4, 3, 1)), True)
    with pytest.raises(ValueError, match=r"whitening must have shape \(4, 3, 3\)"):
        whitened_jacobians(jac, oplus, handles, np.ones((4, 3, 1)), False)
    with pytest.raises(ValueError, match="handles must have shape"):
        whitened_jacobians(jac, oplus, handles[:3], np.ones((4, 3, 1)), True)
    with pytest.raises(ValueError, match=r"handles must lie in \[0, 2\)"):
        whitened_jacobians(jac, oplus, np.array([0, 1, 2, 0]), np.ones((4, 3, 1)), True)
    with pytest.raises(ValueError, match="positions must hold"):
        scatter_jtj_upper(jac, np.zeros(10, dtype=np.int32), 0, np.zeros(5))
    with pytest.raises(ValueError, match="a must have shape"):
        scatter_jtj_upper(np.ones((4, 3)), np.zeros(30, dtype=np.int32), 0, np.zeros(5))
    for make in (plain_zeros, plain_empty_int32):
        with pytest.raises(ValueError, match="size"):
            make(-1)
        with pytest.raises(ValueError, match="size"):
            make(2.5)
    with pytest.raises(ValueError, match="1-D float64"):
        plain_copy(np.ones((2, 2)))
    hk = np.array([0, -1])
    with pytest.raises(ValueError, match="must tile the rows"):
        pattern_from_blocks(6, [0, 4], [3, 3], [(hk, hk, 3, 3, True)])
    with pytest.raises(ValueError, match="group 0: every hl must be −1 or the first row of a vertex of dimension 3"):
        pattern_from_blocks(6, [0, 3], [3, 3], [(hk, np.array([4, -1]), 3, 3, False)])
    with pytest.raises(ValueError, match="group 0: every hk"):
        pattern_from_blocks(6, [0, 3], [3, 3], [(np.array([9, 0]), hk, 3, 3, False)])
    with pytest.raises(ValueError, match="1-D arrays of one length"):
        pattern_from_blocks(6, [0, 3], [3, 3], [(hk, np.array([0]), 3, 3, False)])
    assert plain_zeros(3).tolist() == [0.0, 0.0, 0.0] and plain_empty_int32(0).dtype == np.int32
