"""helpers.drivebot.q1_support: χ² intervals, the online estimate recorder, fraction inside bounds."""
import numpy as np
import pytest
from scipy import stats

from helpers.drivebot import run_question
from helpers.drivebot.q1_support import OnlineEstimate, chi2_interval, fraction_inside, jacobian_error
from helpers.graph import EdgeHeadingPrior


@pytest.mark.parametrize("dof, p", [(1, 0.99), (4, 0.95), (26, 0.99), (1048, 0.999)])
def test_chi2_interval_matches_scipy_quantiles(dof, p):
    lo, hi = chi2_interval(dof, p)
    assert lo > 0 and lo < dof < hi
    assert np.isclose(lo, stats.chi2.ppf((1 - p) / 2, dof), rtol=1e-10)
    assert np.isclose(hi, stats.chi2.ppf((1 + p) / 2, dof), rtol=1e-10)
    assert np.isclose(stats.chi2.cdf(hi, dof) - stats.chi2.cdf(lo, dof), p, atol=1e-10)


@pytest.mark.parametrize("dof, p, match", [(0, 0.99, "dof"), (2.5, 0.99, "dof"), (True, 0.99, "dof"),
                                           (4, 1.0, "probability"), (4, 0.0, "probability"),
                                           (4, "0.9", "probability")])
def test_chi2_interval_bad_input(dof, p, match):
    with pytest.raises(ValueError, match=match):
        chi2_interval(dof, p)


def test_online_estimate_records_newest_vertex_each_tick():
    rec = OnlineEstimate()
    res = run_question("q1_b", maximum_step_number=30, step_hook=rec)
    assert rec.time.shape == (res.n_steps,) and rec.state.shape == (3, res.n_steps)
    assert np.allclose(rec.time, res.vehicle_state_time)
    # odometry only: the graph is a tree, so the online estimate is the final (smoothed) one
    assert np.allclose(rec.state, res.vehicle_state_history, atol=1e-9)


def test_fraction_inside():
    err = np.array([[0.0, 1.0, 3.0, 0.5], [0.1, 0.1, 0.1, 0.1]])
    var = np.array([[0.0, 1.0, 1.0, 1.0], [1.0, 1.0, np.nan, 1.0]])
    assert np.allclose(fraction_inside(err, var), [2 / 3, 1.0])
    assert np.allclose(fraction_inside(err, var, n_sigma=3.0), [1.0, 1.0])
    with pytest.raises(ValueError, match="shape"):
        fraction_inside(err, var[:, :2])
    with pytest.raises(ValueError, match="n_sigma"):
        fraction_inside(err, var, n_sigma=0)
    with pytest.raises(ValueError, match="positive"):
        fraction_inside(err, np.zeros_like(var))


def test_jacobian_error_small_for_model_edges_and_large_for_a_wrong_one():
    res = run_question("q1_e", enable_compass=True, maximum_step_number=15)
    edges = res.system.graph.edges()
    assert len(edges) > 20
    before = [v.estimate.copy() for v in res.system.graph.vertices()]
    assert max(jacobian_error(e) for e in edges) < 1e-6
    assert all(np.array_equal(a, v.estimate) for a, v in zip(before, res.system.graph.vertices()))

    class WrongJacobian(EdgeHeadingPrior):
        @staticmethod
        def evaluate(states, z, params, jacobians=True):
            e, jac = EdgeHeadingPrior.evaluate(states, z, params, jacobians)
            if jac is not None:
                jac[0][:, 0, 2] = 2.0
            return e, jac

    v = res.system.vehicle_vertices[3]
    wrong = WrongJacobian([v], measurement=[0.1], information=np.eye(1))
    assert abs(jacobian_error(wrong) - 1.0) < 1e-6
    with pytest.raises(ValueError, match="eps"):
        jacobian_error(wrong, eps=0.0)
