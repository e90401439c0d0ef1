"""The base edge's default model: an edge that defines only ``error_batch`` gets central-difference Jacobians."""
import numpy as np
import pytest

from helpers.graph import (BaseEdge, EdgeRangeBearing, SparseOptimizer, VertexPointXY, VertexSE2, batch_matrix,
                           numeric_jacobians, wrap_angle)
from helpers.advanced.fast_graph import VertexSE2Exp


class RangeBearingErrorOnly(BaseEdge):
    """EdgeRangeBearing's error without its Jacobians."""

    vertex_types = (VertexSE2, VertexPointXY)
    measurement_dimension = 2

    @staticmethod
    def error_batch(states, z, params):
        x, m = states
        d = m - x[:, :2]
        return np.column_stack([np.hypot(d[:, 0], d[:, 1]) - z[:, 0],
                                wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - x[:, 2] - z[:, 1])])


def _range_bearing_case(seed, n=50):
    rng = np.random.default_rng(seed)
    x = np.c_[rng.normal(size=(n, 2)) * 3, rng.uniform(-3.1, 3.1, n)]
    m = rng.normal(size=(n, 2)) * 5 + 1
    z = np.c_[rng.uniform(1, 5, n), rng.uniform(-3, 3, n)]
    return [x, m], z


def test_numeric_jacobians_match_the_analytic_range_bearing_edge():
    states, z = _range_bearing_case(1)
    e, jac = RangeBearingErrorOnly.evaluate(states, z, {})
    e_ref, jac_ref = EdgeRangeBearing.evaluate(states, z, {})
    # the same error by another formula (a student's edge in the student edition): |e| ≤ 15 here, so a reordered
    # arctan2 and wrap differ by a few ulps of 10 (~1e-14); atol 1e-12 leaves a wide margin
    np.testing.assert_allclose(e, e_ref, rtol=1e-13, atol=1e-12)
    for j, j_ref in zip(jac, jac_ref, strict=True):
        assert j.shape == j_ref.shape
        np.testing.assert_allclose(j, j_ref, rtol=1e-6, atol=1e-7)
    assert RangeBearingErrorOnly.evaluate(states, z, {}, jacobians=False)[1] is None


def test_numeric_jacobians_across_the_bearing_cut():
    """A bearing error of exactly ±π between the two evaluations would jump by 2π without the wrap."""
    x = np.array([[0.0, 0.0, 0.0]])
    m = np.array([[-2.0, 0.0]])                        # bearing π: on the cut
    z = np.array([[2.0, 0.0]])
    _, (jx, jm) = RangeBearingErrorOnly.evaluate([x, m], z, {})
    _, (jx_ref, jm_ref) = EdgeRangeBearing.evaluate([x, m], z, {})
    np.testing.assert_allclose(jx, jx_ref, atol=1e-7)
    np.testing.assert_allclose(jm, jm_ref, atol=1e-7)


def test_numeric_default_per_object_and_in_the_optimiser():
    a = VertexSE2(0, [0.0, 0.0, 0.3], fixed=True)
    m = VertexPointXY(0, [2.0, 1.0])
    edge = RangeBearingErrorOnly([a, m], measurement=[2.5, 0.2], information=np.eye(2))
    ref = EdgeRangeBearing([a, m], measurement=[2.5, 0.2], information=np.eye(2))
    np.testing.assert_allclose(edge.error(), ref.error(), rtol=1e-13, atol=1e-12)     # as above
    for j, j_ref in zip(edge.jacobians(), ref.jacobians(), strict=True):
        np.testing.assert_allclose(j, j_ref, rtol=1e-6, atol=1e-8)
    g = SparseOptimizer()
    g.add_vertex(a)
    g.add_vertex(m)
    g.add_edge(edge)
    g.initialize_optimization()
    assert g.optimize(20) < 1e-20
    np.testing.assert_allclose(edge.error(), 0.0, atol=1e-10)


def test_declared_non_additive_slot_is_differenced_in_coordinates():
    """A slot declared as VertexSE2Exp (⊞ = x ∘ Exp(δ)) still gets ∂e/∂(coordinates), like analytic edges."""

    class Exp(RangeBearingErrorOnly):
        vertex_types = (VertexSE2Exp, VertexPointXY)

    states, z = _range_bearing_case(2, n=10)
    _, jac = Exp.evaluate(states, z, {})
    _, jac_ref = EdgeRangeBearing.evaluate(states, z, {})
    np.testing.assert_allclose(jac[0], jac_ref[0], rtol=1e-6, atol=1e-7)
    coarse = numeric_jacobians(Exp, states, z, {}, step=1e-4)
    np.testing.assert_allclose(coarse[0], jac_ref[0], rtol=1e-4, atol=1e-6)
    for bad in (0.0, -1e-6, np.nan):
        with pytest.raises(ValueError, match="step"):
            numeric_jacobians(Exp, states, z, {}, step=bad)


def test_an_edge_without_a_model_says_what_to_define():
    class Nothing(BaseEdge):
        vertex_types = (VertexPointXY,)
        measurement_dimension = 2

    with pytest.raises(NotImplementedError, match="error_batch"):
        Nothing.evaluate([np.zeros((1, 2))], np.zeros((1, 2)), {})


def test_batch_matrix_rows_scalars_and_bad_input():
    c, s = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    r = batch_matrix([[c, -s], [s, c]])
    assert r.shape == (2, 2, 2) and r.flags.c_contiguous
    np.testing.assert_array_equal(r[1], [[0.0, -1.0], [1.0, 0.0]])
    np.testing.assert_array_equal(batch_matrix([[c, 0], [0, 1]])[0], np.eye(2))
    for bad in ([], [[]], [[c, s], [c]]):
        with pytest.raises(ValueError, match="rows"):
            batch_matrix(bad)
