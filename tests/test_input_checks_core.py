"""Bad inputs found by an audit of the public helpers: each gets a ValueError (or, for a class definition, a
TypeError) that names the argument, instead of a raw numpy error or a silently wrong or ignored value."""
import numpy as np
import pytest

from helpers.association.common import problem_from_cov
from helpers.association.evaluation import check_results, run_trials, sweep, sweep_table
from helpers.association.nearest_neighbour import mahalanobis_nn
from helpers.gaussian import Gaussian, chi2inv
from helpers.graph import BaseEdge, EdgeSE2, VertexSE2
from helpers.graph.edge import information_from_covariance
from helpers.validation import feature_columns, finite_vector


def test_conditional_rejects_a_repeated_conditioning_index():
    g = Gaussian.from_cov([0.0, 0.0], [[1.0, 0.5], [0.5, 1.0]])
    with pytest.raises(ValueError, match="idx_b must not repeat"):
        g.conditional([0], [1, 1], [1.0, 1.0])           # used to return a silently wrong mean (0.749)
    assert g.conditional([0, 0], [1], [1.0]).mean.tolist() == pytest.approx([0.5, 0.5])   # (x0, x0): degenerate, fine
    c = Gaussian.from_cov([0.0, 0.0], [[1.0, 0.5], [0.5, 1.0]]).conditional([0], [1], [1.0])
    assert abs(c.mean[0] - 0.5) < 1e-12                  # distinct indices: unchanged


@pytest.mark.parametrize("values", [[1j], ["a"], [None]])
def test_finite_vector_names_the_argument(values):
    with pytest.raises(ValueError, match="x_b must be an array of real numbers"):
        finite_vector(values, "x_b")
    with pytest.raises(ValueError, match="x_b must be an array of real numbers"):
        Gaussian([0.0, 0.0], np.eye(2)).conditional([0], [1], values)


def test_feature_columns_rejects_bools():
    with pytest.raises(ValueError, match="Y must be an array of real numbers"):
        feature_columns([[True], [False]])


def test_edge_class_methods_must_be_static():
    with pytest.raises(TypeError, match="evaluate must be a @staticmethod"):
        class Forgot(BaseEdge):                             # noqa: F841 (the definition itself must fail)
            vertex_types = (VertexSE2,)
            measurement_dimension = 3

            def evaluate(self, states, z, params, jacobians=True):
                return states[0] - z, None


def test_edge_vertex_slot_is_checked():
    a, b = VertexSE2(0, [0.0, 0.0, 0.0]), VertexSE2(1, [1.0, 0.0, 0.0])
    e = EdgeSE2([a, b], [1.0, 0.0, 0.0])
    assert e.vertex(0) is a and e.vertex(np.int64(1)) is b
    for k in (5, -1, 1.0, True):
        with pytest.raises(ValueError, match="EdgeSE2.vertex: slot k must be in 0..1"):
            e.vertex(k)


def test_information_from_a_nearly_singular_covariance():
    with pytest.raises(ValueError, match="too close to singular"):
        information_from_covariance(np.diag([1e-320, 1.0]))


def test_problem_with_a_joint_covariance_that_is_not_positive_definite():
    P = np.eye(6)
    P[0, 2] = P[2, 0] = 2.0                                 # each block is fine, the joint one is not
    pb = problem_from_cov(np.array([[0, 0], [5, 5], [10, 0.0]]), P, np.array([[0.1, 5.1, 20], [0, 4.9, 20]]))
    with pytest.raises(ValueError, match="P is not positive definite"):
        mahalanobis_nn(pb, None)


def test_broadcasting_errors_name_the_arguments():
    with pytest.raises(ValueError, match=r"p and nu must broadcast.*p \(1, 2\), nu \(3,\)"):
        chi2inv([[0.9, 0.5]], [2, 3, 4])


def test_evaluation_helpers_name_bad_arguments():
    with pytest.raises(ValueError, match="algorithms must be a non-empty mapping"):
        sweep(None, 1, 0, {}, [1], lambda v: {"n_clutter": v})
    res = {1: run_trials({"nn": mahalanobis_nn}, 1, 0, n_landmarks=20, n_visible=4)}
    with pytest.raises(ValueError, match="keys must be one of"):
        sweep_table("t", res, keys=["precision", "f1"])
    assert "prec" in sweep_table("t", res, keys=(k for k in ["precision"]))      # any iterable of rates
    with pytest.raises(ValueError, match="names must be a list of algorithms of results"):
        check_results(res, names="nn")
    assert check_results(res, names=["nn"]) == ["nn"]


def test_option_flags_must_be_booleans():
    import matplotlib.pyplot as plt

    from helpers.association.plots import plot_rates
    from helpers.association.snn import snn
    from helpers.camera import Camera

    cam = Camera([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]], np.zeros(12), (640, 480))
    with pytest.raises(ValueError, match="return_jacobian must be True or False"):
        cam.vector_to_pixel([0.0, 0.0, 1.0], return_jacobian="no")
    with pytest.raises(ValueError, match="return_jacobian must be True or False"):
        cam.world_to_pixel([0.0, 0.0, 1.0], np.zeros(6), return_jacobian=1)
    fig, ax = plt.subplots()
    try:
        with pytest.raises(ValueError, match="logx must be True or False"):
            plot_rates(ax, [1.0, 2.0], [0.5, 0.5], [0.5, 0.5], logx="no")
    finally:
        plt.close(fig)
    with pytest.raises(ValueError, match="enforce_joint_compatibility must be True or False"):
        snn(Gaussian([0.0, 0.0], np.eye(2)), np.zeros((2, 1)), 1.0, enforce_joint_compatibility="yes")


def test_same_setting_tells_a_changed_option_from_its_default():
    from helpers.advanced.online_slam.victoria_park import _same_setting as same_setting
    assert same_setting(True, True) and same_setting(np.bool_(False), False) and same_setting(3, 3.0)
    assert same_setting("jcbb", "jcbb") and same_setting(None, None)
    assert not same_setting(1, True) and not same_setting(True, 1) and not same_setting("5", 5)
    assert not same_setting(2.5, 3.0) and not same_setting(np.eye(2), None)
