"""SparseOptimizer: LM / GN against a dense reference, marginals, structure semantics, gauge, bad inputs."""

import numpy as np
import pytest

from helpers.graph import (BaseEdge, EdgeHeadingPrior, EdgePointPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2,
                           EdgeSE2Prior, GaugeFreedomError, GraphError, SparseOptimizer, VertexPointXY, VertexSE2,
                           wrap_angle)
from helpers.advanced.fast_graph import FastOptimizer, VertexSE2Exp


def small_slam(seed=0, n_poses=6, n_points=4, fix_first=True, pose_class=VertexSE2, optimizer=SparseOptimizer):
    """Noisy poses on a circle, points around it, odometry + range-bearing + one GPS + one compass edge."""
    rng = np.random.default_rng(seed)
    ang = np.linspace(0, 1.5 * np.pi, n_poses)
    truth = np.c_[5 * np.cos(ang), 5 * np.sin(ang), wrap_angle(ang + np.pi / 2)]
    pts = rng.uniform(-7, 7, (n_points, 2))
    g = optimizer()
    poses = [pose_class(i, truth[i] + rng.normal(0, [0.3, 0.3, 0.1]), fixed=(fix_first and i == 0))
             for i in range(n_poses)]
    lms = [VertexPointXY(j, pts[j] + rng.normal(0, 0.5, 2)) for j in range(n_points)]
    for v in poses + lms:
        g.add_vertex(v)
    for i in range(n_poses - 1):
        a, b = truth[i], truth[i + 1]
        c, s = np.cos(a[2]), np.sin(a[2])
        d = b[:2] - a[:2]
        z = [c * d[0] + s * d[1], -s * d[0] + c * d[1], wrap_angle(b[2] - a[2])] + rng.normal(0, 0.05, 3)
        g.add_edge(EdgeSE2([poses[i], poses[i + 1]], measurement=z, information=np.diag([400, 400, 1000])))
    for i in range(n_poses):
        for j in range(n_points):
            d = pts[j] - truth[i, :2]
            z = [np.hypot(*d) + rng.normal(0, 0.1), wrap_angle(np.arctan2(d[1], d[0]) - truth[i, 2])]
            g.add_edge(EdgeRangeBearing([poses[i], lms[j]], measurement=z, information=np.diag([100, 400])))
    g.add_edge(EdgePositionPrior([poses[2]], measurement=truth[2, :2] + [0.3, -0.1], information=np.eye(2),
                                 lever_arm=[0.5, -0.2]))
    g.add_edge(EdgeHeadingPrior([poses[3]], measurement=wrap_angle(truth[3, 2] + 0.4), information=[[100.0]],
                                offset=0.4))
    return g, poses, lms


def whitened_residual(edges):
    """Stacked whitened residuals Wᵢ eᵢ (WᵢᵀWᵢ = Ωᵢ) of ``edges`` at the vertices' current estimates."""
    return np.concatenate([np.linalg.cholesky(e.information).T @ e.error() for e in edges])


def numeric_jacobian(free, edges, h=1e-7):
    """Central-difference Jacobian of the whitened residual w.r.t. the free vertices' estimates (dense)."""
    cols = []
    for v in free:
        for a in range(v.dimension):
            x0 = v.estimate
            dx = np.zeros(v.dimension)
            dx[a] = h
            v.set_estimate(x0 + dx)
            rp = whitened_residual(edges)
            v.set_estimate(x0 - dx)
            rm = whitened_residual(edges)
            v.set_estimate(x0)
            cols.append((rp - rm) / (2 * h))
    return np.stack(cols, axis=1)


def dense_gauss_newton(g, iters=30):
    """Reference: dense numerical Jacobian + dense normal equations over the free vertices."""
    free = [v for v in g.vertices() if not v.fixed]
    edges = g.edges()
    for _ in range(iters):
        r0 = whitened_residual(edges)
        J = numeric_jacobian(free, edges)
        step = np.linalg.solve(J.T @ J, J.T @ r0)
        k = 0
        for v in free:
            v.oplus(-step[k:k + v.dimension])
            k += v.dimension
    r = whitened_residual(edges)
    return float(r @ r), np.linalg.inv(J.T @ J)


def test_lm_and_gn_reach_the_same_optimum_as_dense_reference():
    g_lm, poses_lm, _ = small_slam()
    g_gn, poses_gn, _ = small_slam()
    g_ref, poses_ref, _ = small_slam()
    g_lm.initialize_optimization()
    g_gn.initialize_optimization()
    chi_lm = g_lm.optimize(100, algorithm="lm")
    chi_gn = g_gn.optimize(100, algorithm="gn")
    chi_ref, _ = dense_gauss_newton(g_ref)
    assert chi_lm == pytest.approx(chi_ref, rel=1e-7)
    assert chi_gn == pytest.approx(chi_ref, rel=1e-7)
    for a, b, c in zip(poses_lm, poses_gn, poses_ref):
        np.testing.assert_allclose(a.estimate, c.estimate, atol=1e-6)
        np.testing.assert_allclose(b.estimate, c.estimate, atol=1e-6)
    assert g_lm.chi2() == pytest.approx(chi_lm, rel=1e-12)
    assert g_lm.iterations == len(g_lm.chi2_history) > 0
    assert all(np.diff(g_lm.chi2_history) <= 1e-9)


@pytest.mark.parametrize("algorithm", ["gn", "lm", "lm-gtsam", "default"])
def test_optimize_after_hessian_factors_reuses_its_work_and_gives_the_same_numbers(algorithm):
    fresh, poses_fresh, _ = small_slam(seed=2, optimizer=FastOptimizer)
    warm, poses_warm, _ = small_slam(seed=2, optimizer=FastOptimizer)
    for g in (fresh, warm):
        g.initialize_optimization()
    lower, d, perm = warm.hessian_factors()                 # H at the start: linearised and factorised once
    count = warm.linear_solver.factorisations
    assert warm.optimize(1, algorithm=algorithm) == fresh.optimize(1, algorithm=algorithm)
    for a, b in zip(poses_warm, poses_fresh):
        assert np.array_equal(a.estimate, b.estimate)
    if algorithm == "gn":                                    # its one undamped solve used the factorisation above
        assert warm.linear_solver.factorisations == count
    # a factorisation of another matrix in between: optimize must not take the solver's factor as H's
    other, poses_other, _ = small_slam(seed=2, optimizer=FastOptimizer)
    other.initialize_optimization()
    other.hessian_factors()
    solver = other.linear_solver
    solver.factor(solver.pattern, 2.0 * other._current_linear_system().hessian_data)
    assert other.optimize(1, algorithm="gn") == small_slam_gn_once(2, FastOptimizer)
    # an estimate changed after hessian_factors: the cached linearisation is not used
    moved, poses_moved, _ = small_slam(seed=2, optimizer=FastOptimizer)
    moved.initialize_optimization()
    moved.hessian_factors()
    poses_moved[1].set_estimate(poses_moved[1].estimate + 0.01)
    reference, poses_reference, _ = small_slam(seed=2, optimizer=FastOptimizer)
    reference.initialize_optimization()
    poses_reference[1].set_estimate(poses_reference[1].estimate + 0.01)
    assert moved.optimize(1, algorithm="gn") == reference.optimize(1, algorithm="gn")


def small_slam_gn_once(seed, optimizer=SparseOptimizer):
    g, _, _ = small_slam(seed=seed, optimizer=optimizer)
    g.initialize_optimization()
    return g.optimize(1, algorithm="gn")


def test_marginals_equal_dense_inverse():
    g, poses, lms = small_slam(seed=1)
    g.initialize_optimization()
    g.optimize(50)
    H = g.hessian().toarray()
    np.testing.assert_allclose(H, H.T)
    cov = np.linalg.inv(H)
    marg = g.compute_marginals()
    assert list(marg) == g.vertices()
    np.testing.assert_array_equal(marg[poses[0]], np.zeros((3, 3)))  # fixed vertex
    for v in poses[1:] + lms:
        i, d = v.hessian_index, v.dimension
        np.testing.assert_allclose(marg[v], cov[i:i + d, i:i + d], rtol=1e-6, atol=1e-12 * np.abs(cov).max())
    assert poses[0].hessian_index is None


def test_hessian_and_gradient_match_dense_jacobian():
    g, poses, lms = small_slam(seed=2)
    g.initialize_optimization()
    free = [v for v in g.vertices() if not v.fixed]
    edges = g.edges()
    r0 = whitened_residual(edges)
    J = numeric_jacobian(free, edges)
    np.testing.assert_allclose(g.hessian().toarray(), J.T @ J, rtol=1e-5, atol=1e-4)
    np.testing.assert_allclose(g.gradient(), J.T @ r0, rtol=1e-5, atol=1e-5)
    assert g.chi2() == pytest.approx(float(r0 @ r0), rel=1e-12)


def test_edge_class_defined_outside_the_package():
    class OffsetPrior(BaseEdge):
        vertex_types = (VertexPointXY,)
        measurement_dimension = 2
        parameters = {"shift": (0.0, 0.0)}

        @staticmethod
        def evaluate(states, z, params, jacobians=True):
            e = states[0] + params["shift"] - z
            return e, ([np.broadcast_to(np.eye(2), (len(z), 2, 2)).copy()] if jacobians else None)

    g = SparseOptimizer()
    p = VertexPointXY(estimate=[5, 5])
    g.add_vertex(p)
    g.add_edge(OffsetPrior([p], measurement=[1, 2], shift=[0.5, 0.5]))
    g.add_edge(OffsetPrior([p], measurement=[1, 2], information=4 * np.eye(2), shift=[0.5, 0.5]))
    g.initialize_optimization()
    assert g.optimize(10) == pytest.approx(0.0, abs=1e-18)
    np.testing.assert_allclose(p.estimate, [0.5, 1.5])


def test_remove_edge_removes_orphaned_vertices_and_clears_index():
    g = SparseOptimizer()
    vs = [VertexSE2(i, [i, 0, 0], fixed=(i == 0)) for i in range(3)]
    for v in vs:
        g.add_vertex(v)
    e01 = EdgeSE2([vs[0], vs[1]], measurement=[1, 0, 0])
    e12 = EdgeSE2([vs[1], vs[2]], measurement=[1, 0, 0])
    g.add_edge(e01)
    g.add_edge(e12)
    g.initialize_optimization()
    assert vs[2].hessian_index == 3
    removed = g.remove_edge(e12)
    assert removed == [vs[2]]
    assert g.vertices() == vs[:2] and g.edges() == [e01]
    assert vs[2].graph is None and vs[2].hessian_index is None and vs[1].edges() == [e01]
    np.testing.assert_allclose(vs[2].estimate, [2, 0, 0])  # keeps its last estimate
    removed = g.remove_edge(e01)  # both ends orphaned, including the fixed one
    assert set(removed) == {vs[0], vs[1]} and g.vertices() == [] and g.edges() == []
    with pytest.raises(GraphError, match="not in this graph"):
        g.remove_edge(e01)


def test_remove_vertex_removes_its_edges():
    g, poses, lms = small_slam(seed=3)
    n_edges = len(g.edges())
    k = lms[0].number_of_edges()
    g.remove_vertex(lms[0])
    assert lms[0] not in g.vertices() and len(g.edges()) == n_edges - k
    g.initialize_optimization()
    assert np.isfinite(g.optimize(20))


def test_gauge_freedom_error_names_the_component():
    g, poses, lms = small_slam(seed=4, fix_first=False)
    # remove the unary edges: the whole graph floats
    for e in g.edges():
        if len(e.vertices()) == 1:
            g.remove_edge(e)
    with pytest.raises(GaugeFreedomError, match="gauge") as info:
        g.initialize_optimization()
    assert len(info.value.component) == len(poses) + len(lms)
    assert "VertexSE2 0" in str(info.value)
    assert isinstance(info.value, GraphError)


def test_gauge_detects_a_second_floating_component():
    g = SparseOptimizer()
    a, b = VertexSE2(0, fixed=True), VertexSE2(1)
    c, d = VertexSE2(2), VertexSE2(3)
    for v in (a, b, c, d):
        g.add_vertex(v)
    g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0]))
    g.add_edge(EdgeSE2([c, d], measurement=[1, 0, 0]))
    with pytest.raises(GaugeFreedomError, match="2 vertices") as info:
        g.initialize_optimization()
    assert set(info.value.component) == {c, d}
    g.add_edge(EdgeSE2Prior([c], measurement=[5, 0, 0]))
    g.initialize_optimization()
    assert g.optimize(20) == pytest.approx(0.0, abs=1e-12)
    np.testing.assert_allclose(d.estimate, [6, 0, 0], atol=1e-9)


def test_empty_free_state():
    g = SparseOptimizer()
    v = VertexSE2(0, [1, 2, 0], fixed=True)
    g.add_vertex(v)
    g.initialize_optimization()
    assert g.dimension == 0
    assert g.optimize(10) == 0.0
    assert g.compute_marginals()[v].tolist() == np.zeros((3, 3)).tolist()
    assert g.hessian().shape == (0, 0)


def test_structure_change_requires_initialisation_and_accepts_incremental_growth():
    g = SparseOptimizer()
    prev = VertexSE2(0, fixed=True)
    g.add_vertex(prev)
    for k in range(1, 30):
        v = VertexSE2(k, [k * 0.9, 0, 0])
        g.add_vertex(v)
        g.add_edge(EdgeSE2([prev, v], measurement=[1, 0, 0.01]))
        if k % 10 == 0:
            g.add_edge(EdgeHeadingPrior([v], measurement=0.01 * k))
        with pytest.raises(GraphError, match="initialize_optimization"):
            g.optimize(5)
        g.initialize_optimization()
        g.optimize(5)
        prev = v
    g.optimize(20)
    assert g.chi2() < 1e-10


def test_accepted_state_is_left_in_the_vertices():
    g, poses, lms = small_slam(seed=5)
    g.initialize_optimization()
    chi2 = g.optimize(3)
    assert g.chi2() == pytest.approx(chi2, rel=1e-12)


@pytest.mark.parametrize("info", [np.array([[1.0, 0.5], [0.4, 1.0]]), np.diag([1.0, -1.0]), np.zeros((2, 2)),
                                  np.diag([1.0, np.nan]), np.eye(3)])
def test_bad_information(info):
    with pytest.raises(ValueError, match="information"):
        EdgePositionPrior(measurement=[0, 0], information=info)


def test_bad_measurement_and_estimate():
    with pytest.raises(ValueError, match="3 elements"):
        EdgeSE2(measurement=[1, 2])
    with pytest.raises(ValueError, match="finite"):
        VertexSE2(estimate=[0, np.nan, 0])
    v = VertexSE2()
    with pytest.raises(ValueError, match="finite"):
        v.set_estimate([np.inf, 0, 0])
    with pytest.raises(ValueError, match="lever_arm"):
        EdgePositionPrior(lever_arm=[1, 2, 3])
    with pytest.raises(ValueError, match="no parameter"):
        EdgePositionPrior(dt=0.1)


def test_unknown_duplicate_and_unset_vertices():
    g = SparseOptimizer()
    a, b = VertexSE2(0, fixed=True), VertexSE2(1)
    g.add_vertex(a)
    with pytest.raises(GraphError, match="already in this graph"):
        g.add_vertex(a)
    with pytest.raises(GraphError, match="duplicate vertex id 0"):
        g.add_vertex(VertexSE2(0))
    with pytest.raises(GraphError, match="unknown vertex"):
        g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0]))
    e = EdgeSE2([a, None], measurement=[1, 0, 0])
    with pytest.raises(GraphError, match="slot 1 is not set"):
        g.add_edge(e)
    with pytest.raises(GraphError, match="slot 1 is not set"):
        e.error()
    with pytest.raises(ValueError, match="needs a VertexPointXY"):
        EdgeRangeBearing([a, b])
    with pytest.raises(ValueError, match="max_iterations"):
        g.optimize(-1)
    with pytest.raises(ValueError, match="algorithm"):
        g.optimize(5, algorithm="newton")
    with pytest.raises(GraphError, match="not in this graph"):
        g.compute_marginals([b])


def test_add_edges_bulk_equals_one_by_one():
    g1, poses1, lms1 = small_slam(seed=6)
    g2 = SparseOptimizer()
    for v in g1.vertices():
        g2.add_vertex(type(v)(v.id, v.estimate, v.fixed))
    rb = [e for e in g1.edges() if isinstance(e, EdgeRangeBearing)]
    other = [e for e in g1.edges() if not isinstance(e, EdgeRangeBearing)]
    for e in other:
        g2.add_edge(type(e)([g2.vertex(v.id, type(v)) for v in e.vertices()], e.measurement, e.information,
                            **{k: e.parameter(k) for k in type(e)._param_defaults}))
    g2.add_edges(EdgeRangeBearing, [[g2.vertex(v.id, type(v)) for v in e.vertices()] for e in rb],
                 np.array([e.measurement for e in rb]), np.array([e.information for e in rb]))
    assert g2.chi2() == pytest.approx(g1.chi2(), rel=1e-12)
    with pytest.raises(ValueError, match="positive definite"):
        g2.add_edges(EdgeRangeBearing, [[g2.vertex(0, VertexSE2), g2.vertex(0, VertexPointXY)]], [[1.0, 0.0]],
                     -np.eye(2))


@pytest.mark.parametrize("algorithm, pose_class", [("lm", VertexSE2Exp), ("gn", VertexSE2Exp),
                                                   ("lm-gtsam", VertexSE2), ("lm-gtsam", VertexSE2Exp)])
def test_other_algorithms_and_exp_update_reach_the_same_optimum(algorithm, pose_class):
    g_ref, poses_ref, _ = small_slam(seed=8)
    g_ref.initialize_optimization()
    chi_ref = g_ref.optimize(100, algorithm="gn")
    g, poses, _ = small_slam(seed=8, pose_class=pose_class, optimizer=FastOptimizer)
    g.initialize_optimization()
    assert g.optimize(100, algorithm=algorithm) == pytest.approx(chi_ref, rel=1e-6)
    for a, b in zip(poses, poses_ref):
        np.testing.assert_allclose(a.estimate, b.estimate, atol=1e-5)


def test_exp_update_matches_gtsam_retract_and_its_jacobian():
    gtsam = pytest.importorskip("gtsam", reason="gtsam's Pose2.retract is the oracle")
    rng = np.random.default_rng(9)
    x = np.c_[rng.normal(size=(20, 2)), rng.uniform(-3, 3, 20)]
    d = np.c_[rng.normal(size=(20, 2)), rng.uniform(-2, 2, 20)]
    d[0, 2] = 0.0
    out = VertexSE2Exp.oplus_batch(x, d)
    for t in range(20):
        p = gtsam.Pose2(*x[t]).retract(d[t])
        np.testing.assert_allclose(out[t], [p.x(), p.y(), p.theta()], atol=1e-9)
    h = 1e-6
    num = np.stack([(VertexSE2Exp.oplus_batch(x, np.eye(3)[a] * h + 0 * x) -
                     VertexSE2Exp.oplus_batch(x, -np.eye(3)[a] * h + 0 * x)) / (2 * h) for a in range(3)], axis=2)
    np.testing.assert_allclose(VertexSE2Exp.oplus_jacobian_batch(x), num, atol=1e-6)


@pytest.mark.parametrize("pose_class", [VertexSE2, VertexSE2Exp])
def test_pose_graph_marginals_equal_dense_inverse(pose_class):
    """Pose graph (all free vertices of dimension 3) and the same graph with a point: compare with dense algebra."""
    rng = np.random.default_rng(12)
    g = FastOptimizer() if pose_class is VertexSE2Exp else SparseOptimizer()
    poses = [pose_class(i, [i + rng.normal(0, 0.1), rng.normal(0, 0.1), rng.normal(0, 0.05)], fixed=(i == 0))
             for i in range(12)]
    for v in poses:
        g.add_vertex(v)
    for i in range(11):
        g.add_edge(EdgeSE2([poses[i], poses[i + 1]], measurement=[1, 0, 0.05], information=np.diag([50, 80, 300])))
    for i, j in [(0, 5), (2, 9), (4, 11), (7, 10)]:
        g.add_edge(EdgeSE2([poses[i], poses[j]], measurement=[j - i, 0.2, 0.1], information=np.diag([5, 5, 20])))
    g.initialize_optimization()
    chi2 = g.optimize(50)
    H = g.hessian().toarray()
    np.testing.assert_allclose(g.gradient(), 0.0, atol=1e-6)
    cov = np.linalg.inv(H)
    marg = g.compute_marginals()
    for v in poses[1:]:
        i = v.hessian_index
        np.testing.assert_allclose(marg[v], cov[i:i + 3, i:i + 3], rtol=1e-8, atol=1e-14)
    # the same problem with a decoupled point vertex (mixed dimensions, different ordering)
    p = VertexPointXY(99, [0, 0])
    g.add_vertex(p)
    g.add_edge(EdgePointPrior([p], measurement=[0, 0]))
    g.initialize_optimization()
    assert g.optimize(50) == pytest.approx(chi2, rel=1e-9, abs=1e-12)
    marg2 = g.compute_marginals(poses[1:])
    for v in poses[1:]:
        np.testing.assert_allclose(marg2[v], marg[v], rtol=1e-7, atol=1e-14)


def test_ldl_solver_and_sparse_inverse_against_dense():
    """qdldl factorisation (permutation convention included): solve and the Takahashi entries equal dense algebra;
    an indefinite or singular matrix is reported (ok False, NaN solution); a refactorisation reuses the solver."""
    from helpers.advanced.fast_graph.linear import HessianPattern, LDLSolver
    from helpers.graph.marginals import sparse_inverse_on_pattern
    rng = np.random.default_rng(3)
    n = 30
    pairs = np.array([(i, j) for i in range(n) for j in range(i, n) if i == j or rng.random() < 0.12])
    pattern = HessianPattern(n, pairs[:, 0], pairs[:, 1], np.ones(len(pairs), dtype=bool))
    vals = np.where(pairs[:, 0] == pairs[:, 1], 0.0, rng.normal(size=len(pairs)))
    data = pattern.assemble(vals)
    data[pattern.diag_pos] += np.abs(pattern.full_matrix(data)).sum(axis=1).A1 + 1.0
    H = pattern.full_matrix(data).toarray()
    solver = LDLSolver().factor(pattern, data)
    assert solver.ok
    first = solver.qdldl
    b = rng.normal(size=n)
    np.testing.assert_allclose(solver.solve(b), np.linalg.solve(H, b), rtol=1e-10, atol=1e-12)
    Z = np.linalg.inv(H)
    r, c = pairs[:, 0], pairs[:, 1]
    np.testing.assert_allclose(sparse_inverse_on_pattern(solver.qdldl, r, c), Z[r, c], rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(sparse_inverse_on_pattern(solver.qdldl, c, r), Z[r, c], rtol=1e-9, atol=1e-14)
    # damping only changes the diagonal: same pattern, same qdldl.Solver, new numbers
    damped = data.copy()
    damped[pattern.diag_pos] += 2.5
    solver.factor(pattern, damped)
    assert solver.qdldl is first and solver.ok
    np.testing.assert_allclose(solver.solve(b), np.linalg.solve(H + 2.5 * np.eye(n), b), rtol=1e-10, atol=1e-12)
    bad = data.copy()
    bad[pattern.diag_pos[7]] = -1.0
    assert not solver.factor(pattern, bad).ok
    assert np.all(np.isnan(solver.solve(b)))
    # a zero matrix (qdldl's constructor would refuse it): analysed on the stand-in, reported not ok
    fresh = LDLSolver().factor(pattern, np.zeros_like(data))
    assert not fresh.ok
    assert fresh.factor(pattern, data).ok
    np.testing.assert_allclose(fresh.solve(b), np.linalg.solve(H, b), rtol=1e-10, atol=1e-12)


def test_ldl_solver_damped_psd_matrix_skips_the_pivot_check_but_stays_exact():
    """H = JᵀJ of a rank-deficient J is only semi-definite: undamped it is reported singular; H + μI with a
    declared damping μ is positive definite by construction and solves exactly; a negligible μ is still checked."""
    from helpers.advanced.fast_graph.linear import HessianPattern, LDLSolver
    rng = np.random.default_rng(5)
    n = 12
    J = rng.normal(size=(8, n))  # rank 8 < 12
    Hd = J.T @ J
    r, c = np.triu_indices(n)
    pattern = HessianPattern(n, r, c, np.ones(len(r), dtype=bool))
    data = pattern.assemble(Hd[r, c])  # H's upper triangle scattered onto the pattern
    np.testing.assert_allclose(pattern.full_matrix(data).toarray(), Hd, atol=1e-12)
    b = rng.normal(size=n)
    solver = LDLSolver()
    assert not solver.factor(pattern, data).ok  # singular: the pivot check catches it
    for mu in (1e-3, 1.0):
        damped = data.copy()
        damped[pattern.diag_pos] += mu
        solver.factor(pattern, damped, damping=mu)
        assert solver.ok
        np.testing.assert_allclose(solver.solve(b), np.linalg.solve(Hd + mu * np.eye(n), b), rtol=1e-8)
    tiny = data.copy()
    tiny[pattern.diag_pos] += 1e-300
    solver.factor(pattern, tiny, damping=1e-300)  # below round-off: checked, not assumed
    assert solver.ok == bool(np.all(solver.qdldl.factors()[1] > 0))
