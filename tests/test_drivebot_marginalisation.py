"""Tests for helpers.drivebot.marginalisation: the Schur complement and node pruning on a graph."""
import numpy as np
import pytest

from helpers.advanced.fast_graph import VertexSE2Exp
from helpers.drivebot import marginalisation as mg
from helpers.drivebot import run_question
from helpers.drivebot.edges import LandmarkVertex
from helpers.graph import EdgeSE2, SparseOptimizer, VertexPointXY, VertexSE2


def _spd(n, rng):
    A = rng.standard_normal((n, n))
    return A @ A.T + n * np.eye(n)


# ---------------------------------------------------------------------------------------------- numpy reference
@pytest.mark.parametrize("seed", range(5))
def test_marginal_information_is_the_inverse_of_the_covariance_block(seed):
    rng = np.random.default_rng(seed)
    H = _spd(9, rng)
    b = rng.standard_normal(9)
    marg = rng.choice(9, 3, replace=False)
    keep = np.setdiff1d(np.arange(9), marg)
    lam, eta = mg.schur_complement(H, b, keep, marg)
    cov = np.linalg.inv(H)
    np.testing.assert_allclose(lam, np.linalg.inv(cov[np.ix_(keep, keep)]), rtol=1e-10, atol=1e-10)
    # the reduced system gives the same solution on the kept indices
    np.testing.assert_allclose(np.linalg.solve(lam, eta), np.linalg.solve(H, b)[keep], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(lam, lam.T)


def test_schur_complement_bad_inputs():
    H = np.eye(4)
    with pytest.raises(ValueError, match="disjoint"):
        mg.schur_complement(H, np.zeros(4), [0, 1], [1])
    with pytest.raises(ValueError, match="marginalise has an index out of range"):
        mg.schur_complement(H, np.zeros(4), [0], [7])
    H2 = np.diag([1.0, 1.0, 0.0])
    with pytest.raises(ValueError, match="singular"):
        mg.schur_complement(H2, np.zeros(3), [0, 1], [2])


def test_linear_prior_factor_reproduces_lam_and_eta_when_rank_deficient():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((4, 7))              # rank 4 < 7
    lam = A.T @ A
    eta = A.T @ rng.standard_normal(4)           # in the range of lam
    J, r0 = mg.linear_prior_factor(lam, eta)
    assert J.shape == (4, 7) and r0.shape == (4,)
    np.testing.assert_allclose(J.T @ J, lam, atol=1e-10)
    np.testing.assert_allclose(J.T @ r0, eta, atol=1e-10)
    with pytest.raises(ValueError, match="no positive eigenvalue"):
        mg.linear_prior_factor(np.zeros((2, 2)), np.zeros(2))


def test_linear_prior_class_jacobian_and_wrapping():
    cls = mg.linear_prior_class([VertexSE2, VertexPointXY], 5)
    assert cls is mg.linear_prior_class((VertexSE2, VertexPointXY), 5)   # one class per signature
    rng = np.random.default_rng(1)
    J = rng.standard_normal((5, 5))
    a, p = VertexSE2(0, [1.0, 2.0, 3.1]), VertexPointXY(0, [4.0, 5.0])
    e = cls([a, p], measurement=np.zeros(5), information=np.eye(5), x0=[1.0, 2.0, -3.1, 4.0, 5.0], jac=J)
    d = np.array([0.0, 0.0, 6.2 - 2 * np.pi, 0.0, 0.0])          # the heading difference is wrapped
    np.testing.assert_allclose(e.error(), J @ d, atol=1e-12)
    Ja, Jp = e.jacobians()
    np.testing.assert_allclose(np.hstack([Ja, Jp]), J)


# ---------------------------------------------------------------------------------------------- on a graph
def _marginals_before_after(res, pick):
    graph = res.system.graph
    res.system.ensure_structure()
    target = pick(res.system)
    free = [v for v in graph.vertices() if not v.fixed]
    kept = [v for v in free if v is not target]
    H = graph.hessian().toarray()
    b = graph.gradient()
    idx = {v: np.arange(v.hessian_index, v.hessian_index + type(v).dimension) for v in free}
    lam_ref, eta_ref = mg.schur_complement(H, b, np.concatenate([idx[v] for v in kept]), idx[target])
    cov_before = graph.compute_marginals(kept)
    edge = mg.marginalise_vertex(graph, target)
    graph.initialize_optimization()
    H_after, _ = mg.hessian_blocks(graph, kept)
    b_after = graph.gradient()[np.concatenate([np.arange(v.hessian_index, v.hessian_index + type(v).dimension)
                                               for v in kept])]
    cov_after = graph.compute_marginals(kept)
    return target, edge, kept, (lam_ref, eta_ref), (H_after, b_after), cov_before, cov_after


@pytest.mark.parametrize("which", ["pose", "landmark", "anchor neighbour"])
def test_marginalise_vertex_equals_the_schur_complement_of_the_full_hessian(which):
    res = run_question("q3_a", seed=0, maximum_step_number=40, optimization_period=None)

    def pick(system):
        if which == "pose":
            return system.vehicle_vertices[20]
        if which == "anchor neighbour":       # vertex 1: its prior must stay attached to the fixed vertex 0
            return system.vehicle_vertices[1]
        return next(v for v in system.graph.vertices() if isinstance(v, LandmarkVertex))

    target, edge, kept, (lam, eta), (H1, b1), cov0, cov1 = _marginals_before_after(res, pick)
    assert target.graph is None and edge.graph is res.system.graph
    scale = np.abs(lam).max()
    np.testing.assert_allclose(H1, lam, atol=1e-9 * scale)
    np.testing.assert_allclose(b1, eta, atol=1e-9 * max(1.0, np.abs(eta).max()))
    for v in kept:   # marginal covariances of the vertices that stay are unchanged
        np.testing.assert_allclose(cov1[v], cov0[v], atol=1e-12, rtol=1e-8)
    # the fill-in: every pair of the removed vertex's free neighbours is now coupled in H
    nb = [v for v in edge.vertices() if not v.fixed]
    assert any(v.fixed for v in edge.vertices()) == (which == "anchor neighbour")
    for u in nb:
        for w in nb:
            iu, iw = u.hessian_index, w.hessian_index
            assert np.any(res.system.graph.hessian().toarray()[iu:iu + type(u).dimension, iw:iw + type(w).dimension])


def test_marginalise_vertex_bad_inputs_and_isolated_vertex():
    g = SparseOptimizer()
    a, b = VertexSE2(0, [0, 0, 0], fixed=True), VertexSE2(1, [1, 0, 0])
    g.add_vertex(a)
    g.add_vertex(b)
    g.add_edge(EdgeSE2([a, b], measurement=[1, 0, 0], information=np.eye(3)))
    assert mg.marginalise_vertex(g, b) is None           # only a fixed neighbour: nothing to keep
    assert b.graph is None and g.number_of_edges() == 0
    with pytest.raises(ValueError, match="free VertexSE2 or VertexPointXY of this graph"):
        mg.marginalise_vertex(g, b)
    with pytest.raises(ValueError, match="free VertexSE2 or VertexPointXY of this graph"):
        mg.marginalise_vertex(g, "not a vertex")
    with pytest.raises(ValueError, match="free VertexSE2"):
        mg.marginalise_vertex(g, a)
    g.add_vertex(c := VertexSE2Exp(5, [0, 0, 0]))
    with pytest.raises(ValueError, match="free VertexSE2"):
        mg.marginalise_vertex(g, c)
    with pytest.raises(ValueError, match="free vertex of the graph"):
        mg.hessian_blocks(g, [b])
