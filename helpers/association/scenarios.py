"""Seeded 2-D association scenarios with ground truth: a robot with a range sensor among point landmarks.

World: N landmarks uniform in a square of side ``size``; the robot (pose x = [t_x, t_y, θ]) stands in the
middle part of the square with a random heading. The SLAM estimate is a Gaussian over
[pose; landmarks] with *correlated* pose uncertainty (σ_x, σ_y, σ_θ and a correlation matrix) and
independent isotropic landmark uncertainty; the truth is drawn from it (estimate = truth + error).

Sensor: sees the ``n_visible`` nearest landmarks (or those within ``max_range``), each detected with
probability ``p_detect`` (missed detections), plus ``n_clutter`` spurious points uniform in the sensed disc.

**Observation space — Cartesian points in the robot frame.** A range-bearing sensor's (r, φ) is converted
to the point z = r [cos φ, sin φ] in the robot frame, with isotropic noise σ_z (a common
choice for simulated point-landmark scans). Measurement model and Jacobians:

    z_k = R(θ)ᵀ (m_k − t),   ∂z/∂t = −R(θ)ᵀ,   ∂z/∂θ = (dR/dθ)ᵀ (m_k − t),   ∂z/∂m_k = R(θ)ᵀ.

Why not (r, φ) directly: bearing innovations must be wrapped to (−π, π] before any distance is computed,
and the common interface forms innovations as plain differences y_i − μ_k. In the Cartesian robot frame
there is no angle to wrap, the units of both components agree (so even Euclidean NN is meaningful), and
the model is smooth for any heading. Heading uncertainty still shows up as it should: it rotates every
predicted point about the robot, so far landmarks get long, correlated gates.

The predicted-measurement density of the n candidate landmarks is the first-order transform of the state
density through h (``Gaussian.transform``, QR form) with the measurement noise added, so it carries the
full cross-covariance that joint compatibility needs. Ground truth ``truth`` has one entry per candidate
landmark: the column of Y holding its observation, or −1 (not observed or missed).

:func:`lab_camera_scenario` is the same idea for the lab's camera scene (Lab 8): the 39-dimensional demo
state and the calibrated camera, truth drawn from the state density, pixel observations of the nine
landmarks plus uniform clutter over the image (the corner detector's self-similar texture).
"""
from __future__ import annotations

import functools
import numbers
from dataclasses import dataclass

import numpy as np

from ..gaussian import Gaussian
from ..validation import float_array, positive_number, rng_seed

__all__ = ["Scenario", "observe_points", "range_bearing_scenario", "lab_camera_scenario",
           "DEFAULT_POSE_CORRELATION"]

#: Correlation of the pose estimate errors (x, y, θ) used unless another is given.
DEFAULT_POSE_CORRELATION = np.array([[1.0, 0.3, 0.2],
                                     [0.3, 1.0, -0.2],
                                     [0.2, -0.2, 1.0]])


@dataclass(frozen=True)
class Scenario:
    """One association problem with ground truth.

    density : predicted measurements of the candidate landmarks (size 2n, noise included)
    Y : (2, m) observations in the robot frame (columns in random order)
    truth : (n,) true observation column of each candidate landmark, or −1
    candidates : (n,) indices of the candidate landmarks in the map
    is_clutter : (m,) True for spurious observations
    pose_true, pose_est : (3,) true and estimated pose; pose_cov : (3, 3)
    landmarks_true, landmarks_est : (N, 2) map positions
    state : the SLAM estimate N(ȳ, Σ) over [pose; candidate landmarks] the density was predicted from
        (range_bearing_scenario; None for the camera scenario)
    meas_sigma : σ of the isotropic measurement noise (R = σ² I per observation)
    """

    density: Gaussian
    Y: np.ndarray
    truth: np.ndarray
    candidates: np.ndarray
    is_clutter: np.ndarray
    pose_true: np.ndarray
    pose_est: np.ndarray
    pose_cov: np.ndarray
    landmarks_true: np.ndarray
    landmarks_est: np.ndarray
    state: Gaussian | None = None
    meas_sigma: float | None = None

    @property
    def m(self) -> int:
        return int(self.Y.shape[1])

    @property
    def n(self) -> int:
        return int(self.candidates.size)

    def observation_truth(self) -> np.ndarray:
        """For each observation, the candidate landmark (position in ``candidates``) it came from, or −1."""
        labels = np.full(self.m, -1, dtype=np.intp)
        k = np.flatnonzero(self.truth >= 0)
        labels[self.truth[k]] = k
        return labels


def _generator(seed, rng):
    """The scenario's random generator: ``rng`` if given, else one seeded with ``seed`` (exactly one of them)."""
    if rng is not None and seed is not None:
        raise ValueError("give seed or rng, not both (the scene would come from rng and seed would be ignored)")
    if rng is None:
        if seed is None:
            raise ValueError("give seed or rng: every scenario must be reproducible")
        return np.random.default_rng(rng_seed(seed))
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    return rng


def _rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def observe_points(pose, landmarks):
    """Cartesian robot-frame observations of landmarks and their analytic Jacobians.

    pose (3,) = [t_x, t_y, θ]; landmarks (n, 2). Returns z (n, 2) with z_k = R(θ)ᵀ(m_k − t),
    J_pose (n, 2, 3) = [−Rᵀ, (dR/dθ)ᵀ(m_k − t)] and J_landmark (2, 2) = Rᵀ (the same for every k).
    """
    pose = float_array(pose, "pose")
    landmarks = float_array(landmarks, "landmarks")
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ValueError(f"pose must be a finite array of shape (3,), got shape {pose.shape}")
    if landmarks.ndim != 2 or landmarks.shape[1] != 2 or not np.all(np.isfinite(landmarks)):
        raise ValueError(f"landmarks must be a finite array of shape (n, 2), got shape {landmarks.shape}")
    R = _rot(pose[2])
    c, s = np.cos(pose[2]), np.sin(pose[2])
    dR = np.array([[-s, -c], [c, -s]])
    rel = landmarks - pose[:2]
    z = rel @ R                                  # rows: (Rᵀ rel)ᵀ
    J_pose = np.empty((landmarks.shape[0], 2, 3))
    J_pose[:, :, :2] = -R.T
    J_pose[:, :, 2] = rel @ dR
    return z, J_pose, R.T.copy()


def _check_scenario_arguments(n_landmarks, size, n_visible, max_range, p_detect, n_clutter, pose_sigma,
                              pose_correlation, landmark_sigma, meas_sigma, candidate_range):
    """The checked scenario settings (ValueError names the argument); returns
    (size, landmark_sigma, meas_sigma, max_range, candidate_range, pose σ (3,), pose correlation (3×3))."""
    for name, value, lo in (("n_landmarks", n_landmarks, 1), ("n_clutter", n_clutter, 0)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {value!r}")
    size = positive_number(size, "size")
    landmark_sigma = positive_number(landmark_sigma, "landmark_sigma")
    meas_sigma = positive_number(meas_sigma, "meas_sigma")
    if n_visible is None:
        if max_range is None:
            raise ValueError("give n_visible or max_range")
        max_range = positive_number(max_range, "max_range")
    elif isinstance(n_visible, bool) or not isinstance(n_visible, numbers.Integral) \
            or not 1 <= n_visible <= n_landmarks:
        raise ValueError(f"n_visible must be an integer in [1, n_landmarks={n_landmarks}] or None, got {n_visible!r}")
    elif max_range is not None:
        raise ValueError(f"max_range applies only with n_visible=None (the sensor sees its n_visible={n_visible} "
                         "nearest landmarks otherwise); pass n_visible=None to use a sensor range")
    if isinstance(p_detect, bool) or not isinstance(p_detect, numbers.Real) or not 0.0 <= p_detect <= 1.0:
        raise ValueError(f"p_detect must be a probability in [0, 1], got {p_detect!r}")
    if candidate_range is not None:
        candidate_range = positive_number(candidate_range, "candidate_range")
    sig = float_array(pose_sigma, "pose_sigma")
    if sig.shape != (3,) or not np.all(np.isfinite(sig)) or np.any(sig <= 0):
        raise ValueError(f"pose_sigma must be three positive numbers (σx, σy, σθ), got {pose_sigma!r}")
    corr = DEFAULT_POSE_CORRELATION if pose_correlation is None else float_array(pose_correlation, "pose_correlation")
    if corr.shape != (3, 3) or not np.all(np.isfinite(corr)) or not np.allclose(corr, corr.T) \
            or not np.allclose(np.diag(corr), 1.0) or np.min(np.linalg.eigvalsh(corr)) <= 0:
        raise ValueError("pose_correlation must be a 3×3 symmetric positive-definite matrix with unit diagonal")
    return size, landmark_sigma, meas_sigma, max_range, candidate_range, sig, corr


def _candidate_density(pose_est, pose_cov, lm_candidates, landmark_sigma, meas_sigma):
    """(state, density): the Gaussian state [pose; candidate landmarks] and, through the linearised
    measurement model z = h(x) with noise σ_z² I, the joint predicted-measurement density of the candidates."""
    n = lm_candidates.shape[0]
    S_state = np.zeros((3 + 2 * n, 3 + 2 * n))
    S_state[:3, :3] = np.linalg.cholesky(pose_cov).T
    S_state[3:, 3:] = landmark_sigma * np.eye(2 * n)
    state = Gaussian(np.concatenate([pose_est, lm_candidates.ravel()]), S_state)

    def h(x):
        z, J_pose, J_lm = observe_points(x[:3], x[3:].reshape(n, 2))
        J = np.zeros((2 * n, 3 + 2 * n))
        J[:, :3] = J_pose.reshape(2 * n, 3)
        rows = np.arange(2 * n).reshape(n, 2)
        J[rows[:, :, None], 3 + rows[:, None, :]] = J_lm[None, :, :]
        return z.ravel(), J

    density = state.transform(h, noise=Gaussian(np.zeros(2 * n), meas_sigma * np.eye(2 * n)))
    return state, density


def _sense(rng, pose_true, lm_true, n_visible, max_range, p_detect, n_clutter, meas_sigma):
    """(Y, source): the scan — the visible landmarks detected with probability p_detect plus noise, and the
    clutter uniform in the sensed disc — in random column order, and the landmark behind each column (−1:
    clutter)."""
    z_true, _, _ = observe_points(pose_true, lm_true)
    rng_true = np.hypot(z_true[:, 0], z_true[:, 1])
    if n_visible is not None:
        visible = np.argsort(rng_true, kind="stable")[:n_visible]
        radius = float(rng_true[visible].max())
    else:
        visible = np.flatnonzero(rng_true <= max_range)
        radius = float(max_range)
    detected = visible[rng.uniform(size=visible.size) < p_detect]
    z_det = z_true[detected] + meas_sigma * rng.standard_normal((detected.size, 2))
    r_c = radius * np.sqrt(rng.uniform(size=n_clutter))
    a_c = rng.uniform(-np.pi, np.pi, n_clutter)
    z_clut = np.column_stack([r_c * np.cos(a_c), r_c * np.sin(a_c)])
    Z = np.vstack([z_det, z_clut])
    perm = rng.permutation(Z.shape[0])                  # column j of Y is row perm[j] of Z
    return Z[perm].T.copy(), np.concatenate([detected, np.full(n_clutter, -1)])[perm]


def range_bearing_scenario(seed=None, rng=None, *, n_landmarks: int = 150, size: float = 30.0,
                           n_visible: int | None = 30, max_range: float | None = None,
                           p_detect: float = 1.0, n_clutter: int = 2,
                           pose_sigma=(0.5, 0.5, 0.13962634015954636), pose_correlation=None,
                           landmark_sigma: float = 0.05, meas_sigma: float = 0.1,
                           candidate_range: float | None = None) -> Scenario:
    """Draw one scenario (see the module docstring). Give ``seed`` (int or sequence) or a ``rng``.
    pose_sigma: (σx [m], σy [m], σθ [rad]); the default σθ is 8°.

    n_visible: the sensor sees the n_visible nearest landmarks (None: all within max_range).
    max_range: sensor range; only with n_visible=None, where it decides visibility.
    candidate_range: landmarks whose *estimated* range is ≤ candidate_range are the candidates (None:
    every landmark). Clutter is uniform in the sensed disc (radius = range of the farthest visible
    landmark, or max_range).
    """
    rng = _generator(seed, rng)
    size, landmark_sigma, meas_sigma, max_range, candidate_range, sig, corr = _check_scenario_arguments(
        n_landmarks, size, n_visible, max_range, p_detect, n_clutter, pose_sigma, pose_correlation,
        landmark_sigma, meas_sigma, candidate_range)

    # --- truth and estimate ---------------------------------------------------------------------------
    lm_true = rng.uniform(0.0, size, (n_landmarks, 2))
    pose_true = np.array([*rng.uniform(0.35 * size, 0.65 * size, 2), rng.uniform(-np.pi, np.pi)])
    pose_cov = corr * np.outer(sig, sig)
    pose_est = pose_true + np.linalg.cholesky(pose_cov) @ rng.standard_normal(3)
    lm_est = lm_true + landmark_sigma * rng.standard_normal((n_landmarks, 2))

    Y, source = _sense(rng, pose_true, lm_true, n_visible, max_range, p_detect, n_clutter, meas_sigma)

    # --- candidates and their predicted-measurement density ---------------------------------------------
    if candidate_range is None:
        candidates = np.arange(n_landmarks)
    else:
        z_est, _, _ = observe_points(pose_est, lm_est)
        candidates = np.flatnonzero(np.hypot(z_est[:, 0], z_est[:, 1]) <= candidate_range)
        if candidates.size == 0:
            candidates = np.array([int(np.argmin(np.hypot(z_est[:, 0], z_est[:, 1])))])
    n = candidates.size
    state, density = _candidate_density(pose_est, pose_cov, lm_est[candidates], landmark_sigma, meas_sigma)
    truth = np.full(n, -1, dtype=np.intp)
    position = np.full(n_landmarks, -1, dtype=np.intp)
    position[candidates] = np.arange(n)
    cols = np.flatnonzero(source >= 0)
    hit = position[source[cols]] >= 0
    truth[position[source[cols[hit]]]] = cols[hit]
    return Scenario(density=density, Y=Y, truth=truth, candidates=candidates,
                    is_clutter=source < 0, pose_true=pose_true, pose_est=pose_est, pose_cov=pose_cov,
                    landmarks_true=lm_true, landmarks_est=lm_est, state=state, meas_sigma=meas_sigma)


@functools.lru_cache(maxsize=1)
def _lab_scene():
    """The lab's camera and demo state, built once (reading the camera XML is the slow part)."""
    from ..camera import load_lab_camera
    from ..state_slam import lab_demo_state

    return load_lab_camera(), lab_demo_state()


def lab_camera_scenario(seed=None, rng=None, *, n_clutter: int = 1000, p_detect: float = 1.0,
                        pixel_sigma: float = 1.0) -> Scenario:
    """One seeded association problem in the lab's camera scene, with ground truth.

    The true state is drawn from the Lab 8 demo state density (``helpers.state_slam.lab_demo_state``);
    each of the nine landmarks is detected with probability ``p_detect`` at its true pixel
    (``predict_feature_bundle`` at the true state) plus N(0, pixel_sigma² I) noise; ``n_clutter``
    spurious features are uniform over the 1920 × 1440 image. The density is the predicted bundle of the
    nine landmarks at the mean state with the pixel noise added. Pose fields hold the 6-D camera/body pose
    [r; Θ]; landmark fields hold the 3-D positions.
    """
    rng = _generator(seed, rng)
    if isinstance(n_clutter, bool) or not isinstance(n_clutter, numbers.Integral) or n_clutter < 0:
        raise ValueError(f"n_clutter must be an integer >= 0, got {n_clutter!r}")
    if isinstance(p_detect, bool) or not isinstance(p_detect, numbers.Real) or not 0.0 <= p_detect <= 1.0:
        raise ValueError(f"p_detect must be a probability in [0, 1], got {p_detect!r}")
    pixel_sigma = positive_number(pixel_sigma, "pixel_sigma")
    camera, state = _lab_scene()
    n = state.number_landmarks
    sel = np.arange(n)
    x_true = state.density.simulate(rng)
    h_true, _ = state.predict_feature_bundle(camera, sel, x=x_true)
    detected = np.flatnonzero(rng.uniform(size=n) < p_detect)
    z_det = h_true.reshape(n, 2)[detected] + pixel_sigma * rng.standard_normal((detected.size, 2))
    W, H = camera.image_size
    z_clut = np.column_stack([rng.uniform(0, W, n_clutter), rng.uniform(0, H, n_clutter)])
    Z = np.vstack([z_det, z_clut])
    perm = rng.permutation(Z.shape[0])
    Y = Z[perm].T.copy()
    source = np.concatenate([detected, np.full(n_clutter, -1)])[perm]
    density = state.predict_feature_bundle_density(camera, sel, noise=Gaussian(np.zeros(2), pixel_sigma * np.eye(2)))
    truth = np.full(n, -1, dtype=np.intp)
    cols = np.flatnonzero(source >= 0)
    truth[source[cols]] = cols
    mean = state.density.mean
    return Scenario(density=density, Y=Y, truth=truth, candidates=sel, is_clutter=source < 0,
                    pose_true=x_true[6:12], pose_est=mean[6:12], pose_cov=state.density.cov[6:12, 6:12],
                    landmarks_true=x_true[12:].reshape(n, 3), landmarks_est=mean[12:].reshape(n, 3),
                    meas_sigma=pixel_sigma)
