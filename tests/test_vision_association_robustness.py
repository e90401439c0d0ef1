"""Bad input to the camera, the Lab 8 state, features, scene, Gaussian maths, rotation and data association.

Every row of ``BAD_INPUT`` must raise ValueError whose message names the argument (the regex); every row of
``EDGE_CASES`` is valid input at an edge (an empty scan, an empty landmark set, …) that must give the stated
result. The tables are also read by the sweep script, so each row calls only public API.
"""
from __future__ import annotations

import functools

import matplotlib
import numpy as np
import pytest

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402

from helpers import camera as camera_mod  # noqa: E402
from helpers import camera_io, features, gaussian, rotation, scene, scene_truth, state_slam  # noqa: E402
from helpers.association import (  # noqa: E402
    common,
    compatibility,
    evaluation,
    jcbb,
    lab_demo,
    landmark_confirmation,
    maximum_likelihood,
    ml_tree,
    nearest_neighbour,
    nn_timing,
    plots,
    scenarios,
    snn,
)
from helpers.gaussian import Gaussian  # noqa: E402


# ------------------------------------------------------------------------------------------- fixtures
@functools.cache
def cam():
    return camera_mod.load_lab_camera()


@functools.cache
def state():
    return state_slam.lab_demo_state()


def pose():
    return state().camera_pose(cam())


def camera_point(x, y, z):
    """The world point at camera-frame coordinates (x, y, z) for the demo camera pose."""
    p = pose()
    return p[:3] + rotation.rpy2rot(p[3:]) @ np.array([x, y, z], dtype=float)


def state_with_landmark_at(j, point):
    mu = state().density.mean
    mu[12 + 3 * j:15 + 3 * j] = point
    return state_slam.StateSLAM(Gaussian(mu, state().density.sqrt_cov))


@functools.cache
def fx():
    return compatibility.lab_test_fixture()


@functools.cache
def sc():
    return scenarios.range_bearing_scenario(seed=0, n_landmarks=12, n_visible=6, n_clutter=2)


def problem():
    return common.prepare(sc().density, sc().Y)


def img():
    image = np.zeros((60, 80), np.uint8)
    image[20:40, 20:50] = 200
    return image


def g2():
    return Gaussian([0.0, 0.0], np.eye(2))


@functools.cache
def trials():
    return evaluation.run_trials({"NN": nearest_neighbour.nearest_neighbour}, 2, 0, n_landmarks=10, n_visible=4)


@functools.cache
def demo_result():
    return lab_demo.association_demo(img(), cam(), state(), verbose=False)


@functools.cache
def seq():
    return landmark_confirmation.confirmation_sequence(0, n_frames=3, n_landmarks=5, n_known=2)


def ax():
    return plt.figure().add_subplot()


def nn_data(S=None, Y=None):
    mu = np.array([[0.0, 0.0], [5.0, 5.0]])
    S = np.stack([np.eye(2), np.eye(2)]) if S is None else S
    Y = np.array([[0.1, 4.9], [0.0, 5.2]]) if Y is None else Y
    return mu, S, Y


def idx_with(first):
    return [first] + [-1] * (sc().n - 1)


def ell():
    return np.array([[1.0, 2.0], [3.0, 0.5]])


def bad(fn, match, id):
    return pytest.param(fn, match, id=id)


# ------------------------------------------------------------------------------------------- bad input
ROTATION_GAUSSIAN = [
    bad(lambda: rotation.rotx("a"), r"^phi", "rotx-text"),
    bad(lambda: rotation.roty(np.inf), r"^theta", "roty-inf"),
    bad(lambda: rotation.rotz(None), r"^psi", "rotz-none"),
    bad(lambda: rotation.rpy2rot([1.0, 2.0]), r"^Theta", "rpy2rot-shape"),
    bad(lambda: rotation.rpy2rot("abc"), r"^Theta", "rpy2rot-text"),
    bad(lambda: rotation.rpy2rot_derivatives([np.nan, 0, 0]), r"^Theta", "rpy2rot_derivatives-nan"),
    bad(lambda: rotation.rot2rpy(2 * np.eye(3)), r"^R must be a rotation", "rot2rpy-scaled"),
    bad(lambda: rotation.rot2rpy(np.diag([1.0, 1.0, -1.0])), r"^R must be a rotation", "rot2rpy-reflection"),
    bad(lambda: rotation.rot2rpy("R"), r"^R must", "rot2rpy-text"),
    bad(lambda: Gaussian([0, 0], 1e300 * np.eye(2)).cov, r"^S is too large", "gaussian-cov-overflow"),
    bad(lambda: Gaussian("ab", np.eye(2)), r"^mu", "gaussian-mu-text"),
    bad(lambda: Gaussian([0, 0], "S"), r"^S must", "gaussian-S-text"),
    bad(lambda: Gaussian([0, 0], [[1, 0], [0, np.nan]]), r"^S must be finite", "gaussian-S-nan"),
    bad(lambda: Gaussian.from_cov([0, 0], [[1, 2], [2, 1]]), r"^P must be positive definite", "from_cov-indefinite"),
    bad(lambda: Gaussian.from_cov([0, 0], [[1, 0.5], [0, 1]]), r"^P must be symmetric", "from_cov-asymmetric"),
    bad(lambda: Gaussian.from_sqrt_cov(None), r"^S must", "from_sqrt_cov-none"),
    bad(lambda: g2().marginal([2]), r"^idx has an index out of range", "marginal-range"),
    bad(lambda: g2().marginal([]), r"^idx must be a non-empty", "marginal-empty"),
    bad(lambda: g2().conditional([0], [0], [1.0]), r"^idx_a and idx_b must be disjoint", "conditional-overlap"),
    bad(lambda: g2().conditional([0], [1], [np.nan]), r"^x_b must be finite", "conditional-nan"),
    bad(lambda: g2().log_pdf("x"), r"^x must", "log_pdf-text"),
    bad(lambda: g2().sq_mahalanobis(np.zeros(3)), r"^X must have shape", "sq_mahalanobis-shape"),
    bad(lambda: Gaussian([0, 0], np.diag([1.0, 0.0])).log_pdf([0, 0]), r"^S is singular", "log_pdf-singular"),
    bad(lambda: g2().is_within_confidence_region([0, 0], n_sigma=-1), r"^n_sigma", "confidence-n_sigma"),
    bad(lambda: g2().confidence_ellipse(n_samples=1), r"^n_samples", "ellipse-n_samples"),
    bad(lambda: g2().simulate(np.random), r"^rng must be", "simulate-legacy-rng"),
    bad(lambda: g2().transform(lambda x: ("ab", np.eye(2))), r"^h\(x\)\[0\]", "transform-y-text"),
    bad(lambda: g2().transform(lambda x: (x, np.full((2, 2), np.inf))), r"^h\(x\)\[1\]", "transform-J-inf"),
    bad(lambda: gaussian.chi2inv(1.0, 2), r"^p must lie", "chi2inv-p-one"),
    bad(lambda: gaussian.chi2inv("p", 2), r"^p must", "chi2inv-p-text"),
    bad(lambda: gaussian.chi2inv(0.5, 0), r"^nu must", "chi2inv-nu-zero"),
    bad(lambda: gaussian.normcdf("w"), r"^w must", "normcdf-text"),
    bad(lambda: gaussian.chi2_interval(0), r"^dof must", "chi2_interval-dof"),
    bad(lambda: gaussian.chi2_interval(3, 1.5), r"^probability must", "chi2_interval-probability"),
    bad(lambda: gaussian.confidence_level(0), r"^n_sigma must", "confidence_level-zero"),
    bad(lambda: gaussian.square_r_factor(np.ones(3)), r"^A must be a 2-D", "square_r_factor-1d"),
    bad(lambda: gaussian.square_r_factor([[np.nan]]), r"^A must be finite", "square_r_factor-nan"),
]

CAMERA_STATE = [
    bad(lambda: cam().world_to_pixel(camera_point(0, 0, -1), pose()), r"^rPNn: the point lie\(s\) behind",
        "world_to_pixel-behind"),
    bad(lambda: cam().world_to_pixel(np.column_stack([camera_point(0, 0, 1), camera_point(0.1, 0, -1)]), pose()),
        r"^rPNn: column\(s\) \[1\] lie\(s\) behind", "world_to_pixel-batch-behind"),
    bad(lambda: cam().world_to_pixel(camera_point(np.tan(np.radians(80)), 0, 1), pose()),
        r"^rPNn: the point lie\(s\) beyond the lens fold", "world_to_pixel-beyond-fold"),
    bad(lambda: cam().body_to_pixel(camera_point(0, 0, -1), state().body_pose), r"^rPNn: .*behind",
        "body_to_pixel-behind"),
    bad(lambda: cam().world_to_pixel([0, 0, 0], "eta"), r"^eta must", "world_to_pixel-eta-text"),
    bad(lambda: cam().vector_to_pixel([1e300, 0, 1]), r"^rPCc .*too far off the optical axis", "vector_to_pixel-huge"),
    bad(lambda: cam().vector_to_pixel([1, 0, 1e-320]), r"^rPCc .*too far off the optical axis",
        "vector_to_pixel-tiny-z"),
    bad(lambda: cam().vector_to_pixel("abc"), r"^rPCc must", "vector_to_pixel-text"),
    bad(lambda: cam().vector_to_pixel([0, 0, 0]), r"^rPCc has points with z = 0", "vector_to_pixel-focal-plane"),
    bad(lambda: cam().pixel_to_vector([1.0, 2.0], tol=0), r"^tol must", "pixel_to_vector-tol"),
    bad(lambda: cam().pixel_to_vector([1.0, 2.0], max_iter=0), r"^max_iter must", "pixel_to_vector-max_iter"),
    bad(lambda: cam().pixel_to_vector([1.0, 2.0], strict="yes"), r"^strict must", "pixel_to_vector-strict"),
    bad(lambda: cam().distort("u", 0.0), r"^u must", "distort-text"),
    bad(lambda: cam().is_world_within_fov(np.zeros((3, 2)), "eta"), r"^eta must", "is_world_within_fov-eta"),
    bad(lambda: cam().camera_pose_from_body(np.zeros(5)), r"^eta_body must", "camera_pose_from_body-shape"),
    bad(lambda: camera_mod.Camera([[1, 1, 0], [0, 1, 0], [0, 0, 1]], np.zeros(12), (10, 10)), r"^K must have the form",
        "Camera-K-skew"),
    bad(lambda: camera_mod.Camera(cam().K, cam().dist_coeffs, ("a", "b")), r"^image_size must", "Camera-size-text"),
    bad(lambda: camera_mod.Camera(cam().K, cam().dist_coeffs, (1920, 1440), R_bc=2 * np.eye(3)), r"^R_bc must",
        "Camera-R_bc-scaled"),
    bad(lambda: camera_mod.Camera(cam().K, np.zeros(3), (1920, 1440)), r"^dist_coeffs must", "Camera-dist-size"),
    bad(lambda: camera_mod.Camera(cam().K, cam().dist_coeffs, (1920, 1440), flags=0), r"^flags must",
        "Camera-flags"),
    bad(lambda: camera_mod.Camera.from_xml(None), r"^path", "from_xml-none"),
    bad(lambda: camera_io.check_calibration(np.eye(2), np.zeros(12), (4, 4), 49152), r"^K must", "calibration-K"),
    bad(lambda: cam().K.__setitem__((0, 0), -1.0), r"read-only", "Camera-K-edit-after-init"),
    bad(lambda: state_slam.StateSLAM.landmark_indices(-1), r"^j must be an integer", "landmark_indices-negative"),
    bad(lambda: state_slam.StateSLAM.landmark_indices(1.5), r"^j must be an integer", "landmark_indices-float"),
    bad(lambda: state_slam.StateSLAM.landmark_indices(9, 9), r"^j must be an integer in \[0, 9\)",
        "landmark_indices-range"),
    bad(lambda: state_with_landmark_at(0, camera_point(0, 0, -1)).predict_feature(cam(), 0),
        r"^landmark\(s\) \[0\] lie behind the camera", "predict_feature-behind"),
    bad(lambda: state_with_landmark_at(4, camera_point(0, 0, -1)).predict_feature_bundle_density(cam(), [1, 4]),
        r"^landmark\(s\) \[4\] lie behind the camera", "predict_bundle_density-behind"),
    bad(lambda: state().predict_feature_bundle(cam(), [0, 0]), r"^idx_landmarks must not repeat",
        "predict_bundle-duplicate"),
    bad(lambda: state().predict_feature_bundle(cam(), [0], x="x"), r"^x must", "predict_bundle-x-text"),
    bad(lambda: state().predict_feature_bundle_density(cam(), [0], noise=np.eye(2)), r"^noise must be a Gaussian",
        "predict_bundle_density-noise"),
    bad(lambda: state().predict_feature(cam(), True), r"^j must be an integer", "predict_feature-bool"),
    bad(lambda: state_slam.lab_demo_state("pose"), r"^camera_pose must", "lab_demo_state-text"),
    bad(lambda: state_slam.StateSLAM(Gaussian(np.zeros(13), np.eye(13))), r"^density must have size",
        "StateSLAM-size"),
    bad(lambda: state().camera_pose(None), r"^camera must be", "camera_pose-none"),
]

FEATURES_SCENE = [
    bad(lambda: features.detect_features(img(), block_size=1001), r"^block_size must not exceed",
        "detect-block-1001"),
    bad(lambda: features.detect_features(img(), block_size=61), r"^block_size must not exceed", "detect-block-61"),
    bad(lambda: features.detect_features(img(), harris_k="a"), r"^harris_k must", "detect-harris_k-text"),
    bad(lambda: features.detect_features(img(), nms_radius=True), r"^nms_radius must", "detect-nms-bool"),
    bad(lambda: features.detect_features(img(), threshold=np.nan), r"^threshold must", "detect-threshold-nan"),
    bad(lambda: features.detect_features(img(), smoothing=-1.0), r"^smoothing must", "detect-smoothing-negative"),
    bad(lambda: features.detect_features(img(), max_features=-5), r"^max_features must", "detect-max_features"),
    bad(lambda: features.detect_features(img(), method=None), r"^method must", "detect-method-none"),
    bad(lambda: features.detect_features(np.zeros((0, 0), np.uint8)), r"^image must", "detect-empty-image"),
    bad(lambda: features.detect_features(img().astype(np.int16)), r"^image dtype", "detect-int16"),
    bad(lambda: features.detect_features(img().astype(bool)), r"^image dtype", "detect-bool"),
    bad(lambda: features.detect_features(np.zeros((10, 10, 3), np.float32)), r"^a colour image must be uint8",
        "detect-float-colour"),
    bad(lambda: features.corner_response(img(), aperture_size=True), r"^aperture_size must", "corner-aperture-bool"),
    bad(lambda: features.Features(np.zeros(2), np.zeros(3, int), np.zeros(2, int)), r"^score, x and y",
        "Features-lengths"),
    bad(lambda: scene.recover_pose(np.zeros((100, 100), np.uint8), cam(), pattern_size=(0, 0)), r"^pattern_size",
        "recover_pose-pattern-0"),
    bad(lambda: scene.find_board_corners(np.zeros((100, 100), np.uint8), pattern_size=(10,)), r"^pattern_size",
        "find_board_corners-pattern-short"),
    bad(lambda: scene.recover_pose(np.zeros((100, 100), np.uint8), cam(), square_size=-0.02), r"^square_size",
        "recover_pose-square-negative"),
    bad(lambda: scene.find_board_corners(np.zeros((0, 0), np.uint8)), r"^image must", "find_board_corners-empty"),
    bad(lambda: scene.find_board_corners(np.zeros((10, 10, 2), np.uint8)), r"^image must",
        "find_board_corners-2-channels"),
    bad(lambda: scene.board_points((10, 7), square_size=np.nan), r"^square_size", "board_points-nan"),
    bad(lambda: scene.render_lab_scene(cam(), blur_sigma="a"), r"^blur_sigma", "render-blur-text"),
    bad(lambda: scene.render_lab_scene(cam(), occluder_half="a"), r"^occluder_half", "render-occluder-text"),
    bad(lambda: scene.render_lab_scene(cam(), seed=-1), r"^seed must", "render-seed-negative"),
    bad(lambda: scene.render_lab_scene(cam(), pose="p"), r"^pose must", "render-pose-text"),
    bad(lambda: scene.render_lab_scene(cam(), markers=[[0.0, 0.0]]), r"^markers must", "render-markers-shape"),
    bad(lambda: scene_truth.pixel_to_plane(cam(), pose(), [100.0, 100.0], z0="a"), r"^z0 must", "pixel_to_plane-z0"),
    bad(lambda: scene_truth.pixel_to_plane(None, pose(), [1.0, 1.0]), r"^camera must", "pixel_to_plane-camera"),
    bad(lambda: scene_truth.fiducial_half_size("m"), r"^marker must", "fiducial-text"),
    bad(lambda: scene_truth.ray_interpolation_error(cam(), seed=-1), r"^seed must", "ray_error-seed"),
    bad(lambda: scene_truth.ray_interpolation_error(cam(), inside="a"), r"^inside must", "ray_error-inside"),
]

COMPATIBILITY_ALGORITHMS = [
    bad(lambda: compatibility.joint_compatibility([0, 0, 0], fx()["sU"], fx()["Y3"], fx()["density_3"]),
        r"^idx gives one feature to several landmarks", "joint_compatibility-duplicate"),
    bad(lambda: compatibility.joint_compatibility([0, 1], fx()["sU"], fx()["Y3"], fx()["density_3"]),
        r"^idx must have one entry", "joint_compatibility-length"),
    bad(lambda: compatibility.joint_compatibility([0, 1, 5], fx()["sU"], fx()["Y3"], fx()["density_3"]),
        r"^idx entries", "joint_compatibility-range"),
    bad(lambda: compatibility.joint_compatibility([0, -1, -1], "sU", fx()["Y3"], fx()["density_3"]), r"^sU must",
        "joint_compatibility-sU"),
    bad(lambda: compatibility.individual_compatibility(0, 0, "Y", fx()["density_3"]), r"^Y must",
        "individual_compatibility-text"),
    bad(lambda: compatibility.uniform_surprisal(("a", "b")), r"^image_size must", "uniform_surprisal-text"),
    bad(lambda: compatibility.uniform_surprisal((0, 10)), r"^image_size must", "uniform_surprisal-zero"),
    bad(lambda: compatibility.check_bundle_density(None), r"^density must", "check_bundle_density-none"),
    bad(lambda: snn.snn(fx()["density_3"], "Y", fx()["sU"]), r"^Y must", "snn-text"),
    bad(lambda: snn.snn(fx()["density_3"], fx()["Y3"], fx()["sU"], n_sigma=0), r"^n_sigma", "snn-n_sigma"),
    bad(lambda: snn.snn(fx()["density_3"], fx()["Y3"], fx()["sU"], enforce_joint_compatibility="yes"),
        r"^enforce_joint_compatibility", "snn-enforce"),
    bad(lambda: snn.snn(fx()["density_3"], fx()["Y3"], np.inf), r"^sU must", "snn-sU-inf"),
    bad(lambda: snn.snn(fx()["density_3"], fx()["Y3"].T, fx()["sU"]), r"^Y must have shape", "snn-transposed"),
    bad(lambda: snn.snn(fx()["density_3"], np.full((2, 3), np.nan), fx()["sU"]), r"^Y must be finite", "snn-nan"),
    bad(lambda: nearest_neighbour.nearest_neighbour(sc().density, "Y"), r"^Y must", "nn-text"),
    bad(lambda: nearest_neighbour.nearest_neighbour(sc().density, sc().Y, max_distance=-1), r"^max_distance",
        "nn-max_distance"),
    bad(lambda: nearest_neighbour.mahalanobis_nn(sc().density, sc().Y, n_sigma=np.nan), r"^n_sigma",
        "mahalanobis_nn-n_sigma"),
    bad(lambda: nearest_neighbour.mahalanobis_nn(sc().density, np.zeros((5, 4))), r"^density has size",
        "mahalanobis_nn-dimension"),
    bad(lambda: nearest_neighbour.mahalanobis_nn(None, sc().Y), r"^density must", "mahalanobis_nn-none"),
    bad(lambda: nearest_neighbour.mahalanobis_nn(Gaussian(np.zeros(4), np.zeros((4, 4))), np.zeros((2, 1))),
        r"^density: a landmark's predicted covariance", "mahalanobis_nn-singular"),
    bad(lambda: nearest_neighbour.surprisal_nn(sc().density, sc().Y, sU="a"), r"^sU must", "surprisal_nn-sU"),
    bad(lambda: maximum_likelihood.maximum_likelihood(sc().density, sc().Y, alpha=0), r"^alpha", "ml-alpha-zero"),
    bad(lambda: maximum_likelihood.maximum_likelihood(sc().density, sc().Y, alpha=np.nan), r"^alpha", "ml-alpha-nan"),
    bad(lambda: maximum_likelihood.ml_scores(sc().density, sc().Y[:, :, None]), r"^Y must be a 2-D",
        "ml_scores-3d"),
    bad(lambda: jcbb.jcbb(sc().density, sc().Y, max_nodes=0), r"^max_nodes", "jcbb-max_nodes"),
    bad(lambda: jcbb.jcbb(sc().density, sc().Y, trace=1), r"^trace must", "jcbb-trace"),
    bad(lambda: jcbb.jcbb(sc().density, np.full((2, 3), np.inf)), r"^Y must be finite", "jcbb-inf"),
    bad(lambda: common.joint_sq_mahalanobis(problem(), idx_with(99)), r"^idx entries", "joint_sq-range"),
    bad(lambda: common.joint_sq_mahalanobis(problem(), [0, 0] + [-1] * (sc().n - 2)),
        r"^idx gives one observation to several", "joint_sq-duplicate"),
    bad(lambda: common.joint_sq_mahalanobis(None, [0]), r"^problem must", "joint_sq-problem"),
    bad(lambda: ml_tree.ml_tree_search(sc().density, sc().Y, -1), r"^alpha", "ml_tree_search-alpha"),
    bad(lambda: ml_tree.ml_tree_search(sc().density, sc().Y, 1e-3, max_nodes=0), r"^max_nodes",
        "ml_tree_search-max_nodes"),
    bad(lambda: ml_tree.hypothesis_cost(ell(), 1.0, [5, -1]), r"^labels must", "hypothesis_cost-range"),
    bad(lambda: ml_tree.hypothesis_cost(ell(), 1.0, [0]), r"^labels must", "hypothesis_cost-length"),
    bad(lambda: ml_tree.tree_size(-1, 2), r"^n_landmarks", "tree_size-negative"),
    bad(lambda: ml_tree.greedy_descent(sc().density, sc().Y, np.inf), r"^alpha", "greedy_descent-alpha"),
    bad(lambda: ml_tree.independent_ml(sc().density, sc().Y, True), r"^alpha", "independent_ml-bool"),
    bad(lambda: nearest_neighbour.nearest_neighbour(sc().density, sc().Y).observation_labels(-1), r"^m must",
        "observation_labels-negative"),
]

EVALUATION_DEMO = [
    bad(lambda: evaluation.wilson_interval("a", 3), r"^successes must", "wilson-text"),
    bad(lambda: evaluation.wilson_interval(4, 3), r"^trials must be an integer", "wilson-k-over-n"),
    bad(lambda: evaluation.wilson_interval(1, 3, confidence=1.0), r"^confidence must", "wilson-confidence"),
    bad(lambda: evaluation.run_trials({"x": lambda d, Y: None}, 1, 0, n_landmarks=5, n_visible=3),
        r"^algorithms\['x'\] must return an Association", "run_trials-not-association"),
    bad(lambda: evaluation.run_trials({}, 1, 0), r"^algorithms must", "run_trials-empty"),
    bad(lambda: evaluation.run_trials({"NN": nearest_neighbour.nearest_neighbour}, 1, -1), r"^seed must",
        "run_trials-seed"),
    bad(lambda: evaluation.run_trials({"NN": nearest_neighbour.nearest_neighbour}, 1, 0, scenario=None),
        r"^scenario must", "run_trials-scenario-none"),
    bad(lambda: evaluation.sweep({"NN": nearest_neighbour.nearest_neighbour}, 1, 0, {}, 5, lambda v: {}),
        r"^values must", "sweep-values-int"),
    bad(lambda: evaluation.sweep({"NN": nearest_neighbour.nearest_neighbour}, 1, 0, {}, [1], lambda v: 3),
        r"^make_kwargs\(1\) must return a mapping", "sweep-make_kwargs-result"),
    bad(lambda: evaluation.sweep({"NN": nearest_neighbour.nearest_neighbour}, 1, 0, None, [1], lambda v: {}),
        r"^base must", "sweep-base-none"),
    bad(lambda: evaluation.sweep_table("t", {1: "x"}), r"^results must", "sweep_table-not-results"),
    bad(lambda: evaluation.sweep_table("t", {}), r"^results must", "sweep_table-empty"),
    bad(lambda: trials().interval("nope", "precision"), r"^name must", "interval-name"),
    bad(lambda: trials().interval("NN", "f1"), r"^key must", "interval-key"),
    bad(lambda: evaluation.rates(None, "NN"), r"^results must", "rates-none"),
    bad(lambda: evaluation.rates(trials(), "nope"), r"^name must be one of", "rates-name"),
    bad(lambda: evaluation.fmt_rate("a"), r"^value must", "fmt_rate-text"),
    bad(lambda: evaluation.fmt_rate(0.5, digits=-1), r"^digits must", "fmt_rate-digits"),
    bad(lambda: plots.plot_rates(ax(), [0.0, 1.0], [1.0, 1.0], [1.0, 1.0]), r"^x must be finite and positive",
        "plot_rates-log-zero"),
    bad(lambda: plots.plot_rates(ax(), "x", [1.0], [1.0]), r"^x must", "plot_rates-text"),
    bad(lambda: landmark_confirmation.confirmation_sequence(-1), r"^seed must", "confirmation_sequence-seed"),
    bad(lambda: landmark_confirmation.confirmation_sequence(0, n_landmarks=5, n_known=20), r"^n_known must",
        "confirmation_sequence-n_known"),
    bad(lambda: landmark_confirmation.confirm_landmarks(None), r"^seq must", "confirm_landmarks-none"),
    bad(lambda: landmark_confirmation.confirm_landmarks(seq(), n_sigma=0), r"^n_sigma", "confirm_landmarks-n_sigma"),
    bad(lambda: landmark_confirmation.confirm_landmarks(seq(), n_confirm=0), r"^n_confirm",
        "confirm_landmarks-n_confirm"),
    bad(lambda: scenarios.range_bearing_scenario(seed=-1), r"^seed must", "range_bearing-seed-negative"),
    bad(lambda: scenarios.range_bearing_scenario(seed=1.5), r"^seed must", "range_bearing-seed-float"),
    bad(lambda: scenarios.range_bearing_scenario(seed=0, p_detect=1.5), r"^p_detect must", "range_bearing-p_detect"),
    bad(lambda: scenarios.lab_camera_scenario(seed=-3), r"^seed must", "lab_camera_scenario-seed"),
    bad(lambda: scenarios.observe_points("p", [[0.0, 0.0]]), r"^pose must", "observe_points-pose-text"),
    bad(lambda: scenarios.observe_points([0, 0, 0], [[np.nan, 0.0]]), r"^landmarks must", "observe_points-nan"),
    bad(lambda: nn_timing.per_observation_nn(*nn_data(S=np.stack([np.eye(2), np.full((2, 2), np.nan)]))),
        r"^S must be finite", "per_observation_nn-S-nan"),
    bad(lambda: nn_timing.per_observation_nn(*nn_data(Y=np.array([[np.nan], [0.0]]))), r"^Y must be finite",
        "per_observation_nn-Y-nan"),
    bad(lambda: nn_timing.per_observation_nn(*nn_data(S=np.stack([np.eye(2), [[1.0, 5.0], [0.0, 1.0]]]))),
        r"^S: every innovation covariance must be symmetric", "per_observation_nn-asymmetric"),
    bad(lambda: nn_timing.per_observation_nn(*nn_data(), gate=-1), r"^gate must", "per_observation_nn-gate"),
    bad(lambda: nn_timing.time_nn([0], [1]), r"^Ks must", "time_nn-Ks"),
    bad(lambda: nn_timing.time_nn([1], [1], seed=-1), r"^seed must", "time_nn-seed"),
    bad(lambda: nn_timing.loglog_slope([1.0, np.nan], [1.0, 2.0]), r"^x and y must", "loglog_slope-nan"),
    bad(lambda: lab_demo.association_demo(img(), cam(), None, verbose=False), r"^state must be",
        "association_demo-state-none"),
    bad(lambda: lab_demo.association_demo(img(), None, state(), verbose=False), r"^camera must be",
        "association_demo-camera-none"),
    bad(lambda: lab_demo.ground_truth_check(None, cam(), pose(), state().landmark_positions()), r"^result must",
        "ground_truth_check-none"),
    bad(lambda: lab_demo.ground_truth_check(demo_result(), cam(), pose(), state().landmark_positions()[:, :3]),
        r"^true_landmarks must", "ground_truth_check-too-few"),
    bad(lambda: lab_demo.ground_truth_check(demo_result(), cam(), pose(), state().landmark_positions(), tol="a"),
        r"^tol must", "ground_truth_check-tol"),
    bad(lambda: lab_demo.plot_association(img(), demo_result(), window=(0, 10)), r"^window must",
        "plot_association-window"),
    bad(lambda: lab_demo.plot_association(img(), demo_result(), image_scale="a"), r"^image_scale must",
        "plot_association-scale"),
    bad(lambda: lab_demo.plot_association(img(), None), r"^result must", "plot_association-none"),
    bad(lambda: plots.draw_association(ax(), sc().density, sc().Y, idx_with(7 + sc().m)), r"^idx entries",
        "draw_association-idx-range"),
    bad(lambda: plots.draw_association(ax(), sc().density, sc().Y, [0, 0] + [-1] * (sc().n - 2)),
        r"^idx gives one observation to several", "draw_association-duplicate"),
    bad(lambda: plots.draw_association(ax(), sc().density, sc().Y, idx_with(0), truth=idx_with(99)),
        r"^truth entries", "draw_association-truth-range"),
    bad(lambda: plots.draw_gates(ax(), None), r"^density must", "draw_gates-none"),
    bad(lambda: plots.draw_gates(ax(), sc().density, landmarks=[50]), r"^landmarks has a landmark index out of range",
        "draw_gates-landmarks"),
    bad(lambda: plots.plot_rate_sweep(ax(), {1: trials()}, "f1"), r"^key must", "plot_rate_sweep-key"),
    bad(lambda: plots.plot_rate_sweep(ax(), {1: trials()}, "precision", names=["nope"]), r"^names must",
        "plot_rate_sweep-names"),
    bad(lambda: plots.draw_node_counts(ax(), {1: trials()}, name="nope"), r"^names must", "draw_node_counts-name"),
    bad(lambda: plots.draw_times(ax(), {1: trials()}, "NN"), r"^names must", "draw_times-string"),
]

BAD_INPUT = ROTATION_GAUSSIAN + CAMERA_STATE + FEATURES_SCENE + COMPATIBILITY_ALGORITHMS + EVALUATION_DEMO


@pytest.mark.parametrize("call, match", BAD_INPUT)
def test_bad_input_raises_a_named_value_error(call, match):
    try:
        with pytest.raises(ValueError, match=match):
            call()
    finally:
        plt.close("all")


# ------------------------------------------------------------------------------------------- valid edges
def _all_unassociated(a):
    return a.n_pairings == 0 and np.array_equal(a.idx, np.full(sc().n, -1)) and a.d2 == 0.0


EMPTY_SCAN = np.zeros((2, 0))

EDGE_CASES = [
    pytest.param(lambda: nearest_neighbour.nearest_neighbour(sc().density, EMPTY_SCAN), _all_unassociated,
                 id="nn-empty-scan"),
    pytest.param(lambda: nearest_neighbour.mahalanobis_nn(sc().density, EMPTY_SCAN), _all_unassociated,
                 id="mahalanobis_nn-empty-scan"),
    pytest.param(lambda: nearest_neighbour.surprisal_nn(sc().density, EMPTY_SCAN, 5.0), _all_unassociated,
                 id="surprisal_nn-empty-scan"),
    pytest.param(lambda: maximum_likelihood.maximum_likelihood(sc().density, EMPTY_SCAN, alpha=1e-3),
                 _all_unassociated, id="ml-empty-scan"),
    pytest.param(lambda: jcbb.jcbb(sc().density, EMPTY_SCAN), _all_unassociated, id="jcbb-empty-scan"),
    pytest.param(lambda: snn.snn(fx()["density_3"], EMPTY_SCAN, 2.0),
                 lambda r: r[0].tolist() == [-1, -1, -1] and r[1] == 6.0, id="snn-empty-scan"),
    pytest.param(lambda: compatibility.joint_compatibility([-1, -1, -1], 2.0, EMPTY_SCAN, fx()["density_3"]),
                 lambda r: r == (True, 6.0), id="joint_compatibility-empty-scan"),
    pytest.param(lambda: ml_tree.ml_tree_search(sc().density, EMPTY_SCAN, 1e-3),
                 lambda r: r.labels.size == 0 and r.cost == 0.0, id="ml_tree_search-empty-scan"),
    pytest.param(lambda: ml_tree.assignment_ml(sc().density, EMPTY_SCAN, 1e-3), lambda r: r[0].size == 0,
                 id="assignment_ml-empty-scan"),
    pytest.param(lambda: ml_tree.independent_ml(sc().density, EMPTY_SCAN, 1e-3), lambda r: r.size == 0,
                 id="independent_ml-empty-scan"),
    pytest.param(lambda: nn_timing.per_observation_nn(np.zeros((0, 2)), np.zeros((0, 2, 2)), np.ones((2, 3))),
                 lambda r: r.tolist() == [-1, -1, -1], id="per_observation_nn-no-landmarks"),
    pytest.param(lambda: common.greedy_one_to_one(np.zeros((0, 3)), np.zeros((0, 3), bool)), lambda r: r.size == 0,
                 id="greedy-no-landmarks"),
    pytest.param(lambda: jcbb.level_order(np.zeros((0, 3), bool)), lambda r: r.size == 0,
                 id="level_order-no-landmarks"),
    pytest.param(lambda: ml_tree.hypothesis_cost(np.zeros((0, 3)), 1.0, []), lambda r: r == 0.0,
                 id="hypothesis_cost-no-observations"),
    pytest.param(lambda: landmark_confirmation.confirm_landmarks(
        landmark_confirmation.confirmation_sequence(1, n_frames=3, n_landmarks=4, n_known=0)),
        lambda r: isinstance(r[1], np.ndarray), id="confirm_landmarks-empty-map"),
    pytest.param(lambda: cam().is_vector_within_fov(np.zeros((3, 0))), lambda r: r.shape == (0,),
                 id="is_vector_within_fov-no-points"),
    pytest.param(lambda: Gaussian([1.0, 2.0], [[1.0, 0.5], [0.0, 2.0]]).marginal([0, 0]),
                 lambda r: np.allclose(r.cov, 1.0), id="marginal-repeated-index-degenerate"),
]


@pytest.mark.parametrize("call, check", EDGE_CASES)
def test_valid_edge_cases_give_the_documented_result(call, check):
    assert check(call())


# ------------------------------------------------------------------------------------------- callbacks, state
def test_exception_inside_transform_callback_propagates_and_leaves_the_gaussian_unchanged():
    g = Gaussian([1.0, 2.0], [[1.0, 0.5], [0.0, 2.0]])
    before = (g.mean, g.sqrt_cov)

    def h(x):
        raise RuntimeError("sensor model failed")

    with pytest.raises(RuntimeError, match="sensor model failed"):
        g.transform(h)
    np.testing.assert_array_equal(g.mean, before[0])
    np.testing.assert_array_equal(g.sqrt_cov, before[1])


def test_exception_inside_an_algorithm_names_it_and_the_trial():
    def broken(density, Y):
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError, match="boom") as info:
        evaluation.run_trials({"broken": broken}, 1, 0, n_landmarks=5, n_visible=3)
    assert any("algorithms['broken'] on trial 0" in note for note in info.value.__notes__)


def test_failed_sweep_leaves_the_cache_as_it_was():
    cache = {}
    with pytest.raises(ValueError, match=r"^make_kwargs"):
        evaluation.sweep({"NN": nearest_neighbour.nearest_neighbour}, 1, 0, {"n_landmarks": 5, "n_visible": 3},
                         [1, 2], lambda v: {} if v == 1 else None, cache=cache)
    assert len(cache) == 1                      # the first value's (complete) results only


def test_projection_error_carries_the_offending_columns():
    pts = np.column_stack([camera_point(0, 0, 1), camera_point(0, 0, -1), camera_point(0.1, 0, -2)])
    with pytest.raises(camera_mod.ProjectionError) as info:
        cam().world_to_pixel(pts, pose())
    assert info.value.columns.tolist() == [1, 2] and info.value.reason == "behind"
    # points in front and within the fold still project exactly as before (matches vector_to_pixel)
    q = cam().world_to_pixel(pts[:, 0], pose())
    np.testing.assert_allclose(q, cam().vector_to_pixel([0.0, 0.0, 1.0]), atol=1e-9)


def test_landmark_indices_bound_is_optional():
    assert state_slam.StateSLAM.landmark_indices(2).tolist() == [18, 19, 20]
    assert state_slam.StateSLAM.landmark_indices(8, state().number_landmarks).tolist() == [36, 37, 38]


@pytest.mark.parametrize("value, ok", [(3, True), ((3, 4), True), (np.random.SeedSequence(1), True), (-1, False),
                                       (True, False), (1.0, False), ("1", False), (None, False), ((), False),
                                       ((1, -2), False)])
def test_rng_seed_accepts_exactly_what_default_rng_reproduces(value, ok):
    from helpers.validation import rng_seed

    if ok:
        assert rng_seed(value) is value
        np.random.default_rng(value)
    else:
        with pytest.raises(ValueError, match="^seed must"):
            rng_seed(value)


@pytest.mark.parametrize("value", ["1.5", None, [1, "a"], 1j, [[1, 2], [3]], [True, False], object()])
def test_float_array_rejects_what_is_not_real_numbers(value):
    from helpers.validation import float_array

    with pytest.raises(ValueError, match="^arg must be an array of real numbers"):
        float_array(value, "arg")


def test_float_array_does_not_copy_float_arrays():
    from helpers.validation import float_array

    a = np.arange(3.0)
    assert float_array(a, "a") is a
    assert float_array([1, 2], "a").dtype == float
