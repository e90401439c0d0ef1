"""Seeded 2-D association scenarios with ground truth: a robot with a range sensor among point landmarks.

N landmarks lie uniform in a square of side ``size``; the robot (pose [t_x, t_y, θ]) stands in its middle part.
The SLAM estimate is a Gaussian over [pose; landmarks] with correlated pose errors (σ_x, σ_y, σ_θ and
:data:`POSE_CORRELATION`) and isotropic landmark errors; the truth is the estimate minus a draw of its error. The
sensor sees the ``n_visible`` nearest landmarks, each with probability ``p_detect``, plus ``n_clutter`` points
uniform in the sensed disc. Observations are Cartesian points in the robot frame (a range-bearing (r, φ) as
r [cos φ, sin φ], noise σ_z): no angle to wrap in y_i − μ_k, one unit for both components, and heading
uncertainty still gives far landmarks long, correlated gates:

    z_k = R(θ)ᵀ (m_k − t),   ∂z/∂t = −R(θ)ᵀ,   ∂z/∂θ = (dR/dθ)ᵀ (m_k − t),   ∂z/∂m_k = R(θ)ᵀ.

The candidates' predicted-measurement density is the linearised transform of the state (``Gaussian.transform``)
plus the noise, with the full cross-covariance. :func:`lab_camera_scenario` does the same for the Lab 8 camera.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..gaussian import Gaussian
from ..validation import finite_vector, float_array, integer, positive_number, probability, rng_seed

__all__ = ["Scenario", "observe_points", "range_bearing_scenario", "lab_camera_scenario", "POSE_CORRELATION"]

#: Correlation of the pose estimate errors (x, y, θ).
POSE_CORRELATION = np.array([[1.0, 0.3, 0.2],
                             [0.3, 1.0, -0.2],
                             [0.2, -0.2, 1.0]])


@dataclass(frozen=True)
class Scenario:
    """One problem with ground truth: the candidates' predicted ``density``, the observations ``Y`` (2, m) in random
    column order, ``truth`` (n,) each candidate's observation column or −1, the ``candidates``' map indices; the
    ``state`` [pose; candidates] the density was predicted from (None for the camera) and ``meas_sigma``."""

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


def observe_points(pose: ArrayLike, landmarks: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robot-frame points z (n, 2), z_k = R(θ)ᵀ(m_k − t), of the landmarks (n, 2) seen from pose [t_x, t_y, θ],
    with J_pose (n, 2, 3) = [−Rᵀ, (dR/dθ)ᵀ(m_k − t)] and J_landmark (2, 2) = Rᵀ (the same for every k)."""
    pose = finite_vector(pose, "pose", size=3)
    landmarks = float_array(landmarks, "landmarks")
    if landmarks.ndim != 2 or landmarks.shape[1] != 2 or not np.all(np.isfinite(landmarks)):
        raise ValueError(f"landmarks must be a finite array of shape (n, 2), got shape {landmarks.shape}")
    c, s = np.cos(pose[2]), np.sin(pose[2])
    R = np.array([[c, -s], [s, c]])
    dR = np.array([[-s, -c], [c, -s]])
    rel = landmarks - pose[:2]
    J_pose = np.empty((landmarks.shape[0], 2, 3))
    J_pose[:, :, :2] = -R.T
    J_pose[:, :, 2] = rel @ dR
    return rel @ R, J_pose, R.T.copy()                 # rows of rel @ R: (Rᵀ rel)ᵀ


def _candidate_density(pose_est, pose_cov, lm_candidates, landmark_sigma, meas_sigma) -> tuple[Gaussian, Gaussian]:
    """(state, density): the Gaussian state [pose; candidate landmarks] and, through the linearised measurement
    model z = h(x) with noise σ_z² I, the joint predicted-measurement density of the candidates."""
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

    return state, state.transform(h, noise=Gaussian(np.zeros(2 * n), meas_sigma * np.eye(2 * n)))


def _scan(rng, z_visible, detect, clutter) -> tuple[np.ndarray, np.ndarray]:
    """(Y, source): the detected points ``z_visible[detect]`` and the ``clutter`` points in random column order,
    and the index in ``z_visible`` behind each column (−1: clutter)."""
    Z = np.vstack([z_visible[detect], clutter])
    perm = rng.permutation(Z.shape[0])                  # column j of Y is row perm[j] of Z
    return Z[perm].T.copy(), np.concatenate([detect, np.full(len(clutter), -1)])[perm]


def range_bearing_scenario(seed: int | tuple, *, n_landmarks: int = 150, size: float = 30.0, n_visible: int = 30,
                           p_detect: float = 1.0, n_clutter: int = 2,
                           pose_sigma: tuple[float, float, float] = (0.5, 0.5, 0.13962634015954636),
                           landmark_sigma: float = 0.05, meas_sigma: float = 0.1,
                           candidate_range: float | None = None) -> Scenario:
    """Draw one scenario (module docstring) from ``seed`` (an int or a sequence of them).

    pose_sigma: (σx [m], σy [m], σθ [rad]); the default σθ is 8°. candidate_range: the candidates are the
    landmarks whose *estimated* range is ≤ candidate_range (None: every landmark). Clutter is uniform in the disc
    out to the farthest visible landmark.
    """
    rng = np.random.default_rng(rng_seed(seed))
    n_landmarks = integer(n_landmarks, "n_landmarks", minimum=1)
    n_visible = integer(n_visible, "n_visible", minimum=1, below=n_landmarks + 1)
    n_clutter = integer(n_clutter, "n_clutter", minimum=0)
    size, p_detect = positive_number(size, "size"), probability(p_detect, "p_detect")
    landmark_sigma = positive_number(landmark_sigma, "landmark_sigma")
    meas_sigma = positive_number(meas_sigma, "meas_sigma")
    candidate_range = None if candidate_range is None else positive_number(candidate_range, "candidate_range")
    sig = finite_vector(pose_sigma, "pose_sigma", size=3)
    if np.any(sig <= 0):
        raise ValueError(f"pose_sigma must be three positive numbers (σx, σy, σθ), got {pose_sigma!r}")

    lm_true = rng.uniform(0.0, size, (n_landmarks, 2))
    pose_true = np.array([*rng.uniform(0.35 * size, 0.65 * size, 2), rng.uniform(-np.pi, np.pi)])
    pose_cov = POSE_CORRELATION * np.outer(sig, sig)
    pose_est = pose_true + np.linalg.cholesky(pose_cov) @ rng.standard_normal(3)
    lm_est = lm_true + landmark_sigma * rng.standard_normal((n_landmarks, 2))

    # the scan: the n_visible nearest landmarks, each detected with probability p_detect, plus clutter
    z_true = observe_points(pose_true, lm_true)[0]
    rng_true = np.hypot(z_true[:, 0], z_true[:, 1])
    visible = np.argsort(rng_true, kind="stable")[:n_visible]
    detected = visible[rng.uniform(size=visible.size) < p_detect]
    z_true[detected] += meas_sigma * rng.standard_normal((detected.size, 2))
    r_c = rng_true[visible].max() * np.sqrt(rng.uniform(size=n_clutter))
    a_c = rng.uniform(-np.pi, np.pi, n_clutter)
    Y, source = _scan(rng, z_true, detected, np.column_stack([r_c * np.cos(a_c), r_c * np.sin(a_c)]))

    candidates = np.arange(n_landmarks)
    if candidate_range is not None:
        r_est = np.hypot(*observe_points(pose_est, lm_est)[0].T)
        candidates = np.flatnonzero(r_est <= candidate_range) if np.any(r_est <= candidate_range) \
            else np.array([np.argmin(r_est)])
    state, density = _candidate_density(pose_est, pose_cov, lm_est[candidates], landmark_sigma, meas_sigma)
    position = np.full(n_landmarks, -1, dtype=np.intp)          # landmark → its place among the candidates
    position[candidates] = np.arange(candidates.size)
    truth = np.full(candidates.size, -1, dtype=np.intp)
    cols = np.flatnonzero(source >= 0)
    hit = position[source[cols]] >= 0
    truth[position[source[cols[hit]]]] = cols[hit]
    return Scenario(density=density, Y=Y, truth=truth, candidates=candidates, is_clutter=source < 0,
                    pose_true=pose_true, pose_est=pose_est, pose_cov=pose_cov, landmarks_true=lm_true,
                    landmarks_est=lm_est, state=state, meas_sigma=meas_sigma)


@functools.lru_cache(maxsize=1)
def _lab_scene() -> tuple:
    """The lab's camera and demo state, built once (reading the camera XML is the slow part)."""
    from ..camera import load_lab_camera
    from ..state_slam import lab_demo_state

    return load_lab_camera(), lab_demo_state()


def lab_camera_scenario(seed: int | tuple, *, n_clutter: int = 1000, p_detect: float = 1.0,
                        pixel_sigma: float = 1.0) -> Scenario:
    """One seeded association problem in the lab's camera scene, with ground truth.

    The true state is drawn from the Lab 8 demo state density; each of the nine landmarks is detected with
    probability ``p_detect`` at its true pixel plus N(0, pixel_sigma² I) noise; ``n_clutter`` spurious features
    are uniform over the 1920 × 1440 image. The density is the predicted bundle of the nine landmarks at the mean
    state with the pixel noise added. Pose fields hold the 6-D camera/body pose [r; Θ], landmark fields the 3-D
    positions.
    """
    rng = np.random.default_rng(rng_seed(seed))
    n_clutter = integer(n_clutter, "n_clutter", minimum=0)
    p_detect, pixel_sigma = probability(p_detect, "p_detect"), positive_number(pixel_sigma, "pixel_sigma")
    camera, state = _lab_scene()
    n = state.number_landmarks
    sel = np.arange(n)
    x_true = state.density.simulate(rng)
    h_true = state.predict_feature_bundle(camera, sel, x=x_true)[0].reshape(n, 2)
    detected = np.flatnonzero(rng.uniform(size=n) < p_detect)
    h_true[detected] += pixel_sigma * rng.standard_normal((detected.size, 2))
    W, H = camera.image_size
    Y, source = _scan(rng, h_true, detected, np.column_stack([rng.uniform(0, W, n_clutter),
                                                              rng.uniform(0, H, n_clutter)]))
    density = state.predict_feature_bundle_density(camera, sel, noise=Gaussian(np.zeros(2), pixel_sigma * np.eye(2)))
    truth = np.full(n, -1, dtype=np.intp)
    cols = np.flatnonzero(source >= 0)
    truth[source[cols]] = cols
    mean = state.density.mean
    return Scenario(density=density, Y=Y, truth=truth, candidates=sel, is_clutter=source < 0,
                    pose_true=x_true[6:12], pose_est=mean[6:12], pose_cov=state.density.cov[6:12, 6:12],
                    landmarks_true=x_true[12:].reshape(n, 3), landmarks_est=mean[12:].reshape(n, 3),
                    meas_sigma=pixel_sigma)
