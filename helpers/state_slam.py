"""The landmark-SLAM state and the predicted feature bundle (Lab 8 §1, eqs 1–9).

State layout (size n = 12 + 3 n_L), held as a square-root :class:`~helpers.gaussian.Gaussian`:

    x = [ν; η; r_1; …; r_nL],  ν = [vBNb (0..2); ωBNb (3..5)],  η = [rBNn (6..8); Θnb (9..11)],
    landmark j at indices 12 + 3j .. 14 + 3j.

Feature prediction (eq 4): h_j(x) = w2p(r_j; camera pose) = v2p(Rncᵀ (r_j − rCNn)), with the camera pose
from the body pose (eq 5) rCNn = rBNn + Rnb rCBb, Rnc = Rnb Rbc. Its Jacobian (eq 6) is 2 × n and non-zero
only in the columns of rBNn (6..8), Θnb (9..11) and r_j (12 + 3j .. 14 + 3j).

Feature bundle (eqs 8–9) for a selection idx_landmarks = [j_0, j_1, …]: h = [h_{j_0}; h_{j_1}; …] (length 2k)
and J = [∂h_{j_0}/∂x; ∂h_{j_1}/∂x; …] (2k × n): row pair k belongs to the k-th *selected* landmark. The predicted
densities are first-order transforms of the state density through h (``Gaussian.transform``).
"""
from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from .camera import Camera, ProjectionError
from .gaussian import Gaussian
from .rotation import rot2rpy, rpy2rot
from .validation import finite_vector, float_array, index_list, integer

__all__ = ["StateSLAM", "lab_demo_state", "LAB_DEMO_CAMERA_POSE"]

#: Camera pose [rCNn (m); Θnc (rad)] of the Lab 8 demo scene (body pose = camera pose).
LAB_DEMO_CAMERA_POSE = np.array([-0.00114, 0.05088, -0.44589, 0.12179, 0.06344, 1.56839])

_IDX_POSITION = np.arange(6, 9)
_IDX_ANGLES = np.arange(9, 12)


class StateSLAM:
    """SLAM state x = [ν(6); rBNn(3); Θnb(3); 3 per landmark] with density N(μ, SᵀS)."""

    def __init__(self, density: Gaussian) -> None:
        if not isinstance(density, Gaussian):
            raise ValueError(f"density must be a Gaussian, got {type(density).__name__}")
        n = density.size
        if n < 12 or (n - 12) % 3:
            raise ValueError(f"density must have size 12 + 3·n_landmarks, got size {n}")
        self._density = density

    @property
    def density(self) -> Gaussian:
        """The state density N(μ, SᵀS)."""
        return self._density

    @property
    def size(self) -> int:
        """n = 12 + 3 n_L."""
        return self._density.size

    @property
    def number_landmarks(self) -> int:
        """n_L."""
        return (self.size - 12) // 3

    @staticmethod
    def landmark_indices(j: int, number_landmarks: int | None = None) -> np.ndarray:
        """State indices [12 + 3j, 13 + 3j, 14 + 3j] of landmark j (an integer ≥ 0, and < ``number_landmarks``
        when that is given, e.g. ``state.landmark_indices(j, state.number_landmarks)``)."""
        number_landmarks = integer(number_landmarks, "number_landmarks", minimum=0, allow_none=True)
        j = integer(j, "j", minimum=0, below=number_landmarks)
        return 12 + 3 * j + np.arange(3)

    @property
    def body_pose(self) -> np.ndarray:
        """Mean body pose η = [rBNn; Θnb], shape (6,)."""
        return self._density.mean[6:12]

    def camera_pose(self, camera: Camera) -> np.ndarray:
        """Mean camera pose [rCNn; Θnc] from the body pose (eq 5) and the camera's mounting."""
        _check_camera(camera)
        return camera.camera_pose_from_body(self.body_pose)

    def landmark_positions(self) -> np.ndarray:
        """Mean landmark positions, shape (3, n_L)."""
        return self._density.mean[12:].reshape(-1, 3).T

    def _landmark_selection(self, idx_landmarks: ArrayLike, name: str = "idx_landmarks") -> np.ndarray:
        return index_list(idx_landmarks, self.number_landmarks, name, kind="landmark ", distinct=True)

    def _one_landmark(self, j: int) -> np.ndarray:
        if isinstance(j, bool) or not isinstance(j, numbers.Integral):
            raise ValueError(f"j must be an integer landmark index, got {j!r}")
        return self._landmark_selection([j], name="j")

    def _check_x(self, x: ArrayLike | None) -> np.ndarray:
        if x is None:
            return self._density.mean
        x = float_array(x, "x")
        if x.shape != (self.size,) or not np.all(np.isfinite(x)):
            raise ValueError(f"x must be a finite state vector of shape ({self.size},), got shape {x.shape}")
        return x

    def predict_feature_bundle(self, camera: Camera, idx_landmarks: ArrayLike, x: ArrayLike | None = None) \
            -> tuple[np.ndarray, np.ndarray]:
        """The predicted feature bundle h(x) (Lab 8 eq 8) and its Jacobian J = ∂h/∂x (eq 9) at the state x.

        Parameters
        ----------
        camera : helpers.camera.Camera; ``camera.body_to_pixel(r_j, eta_body, return_jacobian=True)`` gives the
            pixel h_j(x) = v2p(Rncᵀ (r_j − rCNn)) of eq 4 (camera pose from the body pose, eq 5) and its
            Jacobians with respect to r_j, rBNn and Θnb.
        idx_landmarks : the k ≥ 1 selected landmarks [j_0, j_1, …], distinct integers in [0, n_L).
        x : the state (n,) at which h and J are evaluated; None (default) for the mean of the state density.

        Returns
        -------
        h : (2k,) [h_{j_0}; h_{j_1}; …]: rows 2i, 2i+1 are the pixel (x, y) of landmark idx_landmarks[i].
        J : (2k, n) [∂h_{j_0}/∂x; ∂h_{j_1}/∂x; …] (eq 6 per block row): each block row is zero except in the
            body-pose columns 6..11 and its landmark's columns 12 + 3j .. 14 + 3j.

        Raises
        ------
        ValueError naming ``idx_landmarks`` (empty, not integers, out of range or repeated), ``x`` (not a finite
        (n,) vector) or ``camera`` (not a Camera); the camera's ProjectionError (a ValueError) when a selected
        landmark has no pixel at x (behind the camera or beyond the lens fold).
        """
        _check_camera(camera)
        idx = self._landmark_selection(idx_landmarks)
        x = self._check_x(x)
        cols = 12 + 3 * idx[:, None] + np.arange(3)  # (k, 3)
        P = x[cols].T  # (3, k)
        try:
            Q, jac = camera.body_to_pixel(P, x[6:12], return_jacobian=True)
        except ProjectionError as exc:
            where = "behind the camera" if exc.reason == "behind" else "beyond the lens fold"
            raise ProjectionError(f"landmark(s) {idx[exc.columns].tolist()} lie {where} at this state: no predicted "
                                  f"feature ({exc})", exc.columns, exc.reason) from None
        k = idx.size
        J = np.zeros((k, 2, self.size))
        J[:, :, _IDX_POSITION] = jac.wrt_position
        J[:, :, _IDX_ANGLES] = jac.wrt_angles
        J[np.arange(k)[:, None, None], np.arange(2)[None, :, None], cols[:, None, :]] = jac.wrt_point
        return Q.T.reshape(-1), J.reshape(2 * k, self.size)

    def predict_feature(self, camera: Camera, j: int, x: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(h_j, J_j) of eqs (4) and (6) at the state x (default: the mean): h_j (2,), J_j (2, n)."""
        return self.predict_feature_bundle(camera, self._one_landmark(j), x)

    def predict_feature_bundle_density(self, camera: Camera, idx_landmarks: ArrayLike,
                                       noise: Gaussian | None = None) -> Gaussian:
        """Predicted density of the feature bundle (affine transform of the state density through h).

        ``noise``: None (the 2023 lab), a zero-mean size-2 Gaussian applied independently to every selected
        landmark, or a zero-mean Gaussian of size 2k for the whole bundle.
        """
        idx = self._landmark_selection(idx_landmarks)
        _check_camera(camera)
        if noise is not None:
            if not isinstance(noise, Gaussian):
                raise ValueError(f"noise must be a Gaussian or None, got {type(noise).__name__}")
            if noise.size == 2 and idx.size > 1:
                if np.any(noise.mean != 0):
                    raise ValueError("noise must have zero mean")
                noise = Gaussian.from_sqrt_cov(np.kron(np.eye(idx.size), noise.sqrt_cov))
            elif noise.size != 2 * idx.size:
                raise ValueError(f"noise must have size 2 or {2 * idx.size}, got {noise.size}")
        return self._density.transform(lambda x: self.predict_feature_bundle(camera, idx, x), noise=noise)

    def predict_feature_density(self, camera: Camera, j: int, noise: Gaussian | None = None) -> Gaussian:
        """Predicted density of the feature of landmark j (size 2); ``noise`` optional, zero-mean, size 2."""
        return self.predict_feature_bundle_density(camera, self._one_landmark(j), noise)


def _check_camera(camera: Camera) -> None:
    if not isinstance(camera, Camera):
        raise ValueError(f"camera must be a helpers.camera.Camera, got {type(camera).__name__}")


# The Lab 8 demo state
_DEMO_LANDMARKS = np.array([
    [-0.2, 0.1, 0.0], [0.0, -0.3, 0.0], [0.0, 0.6, 0.0], [0.4, 0.6, 0.0], [0.4, -0.4, 0.0],
    [0.088, 0.066, 0.0], [0.022, 0.132, 0.0], [0.297, 0.0, 0.0], [0.29029, 0.09502, -0.14843]])
_DEMO_LANDMARK_SQRT_DIAG = np.array([
    [.0015, .0015, .0015], [.0045, .0015, .0015], [.0015, .006, .0015], [.0015, .0015, .0045],
    [.0015, .0015, .0015], [.0045, .0015, .0015], [.0015, .006, .0015], [.0015, .0015, .0045],
    [.0015, .0015, .0015]])
_DEMO_POSE_SQRT = np.array([
    [0.001427830283, 0.001229097682, 0.003320690394, -0.002585376784, 0.004103269664, -0.002795866555],
    [0.0, 0.0003924364969, 0.001926923125, 0.004464152406, -0.00231243553, 0.0001452205508],
    [0.0, 0.0, 0.0005341369799, 0.0006053459295, 0.0009182405056, -0.00099283847],
    [0.0, 0.0, 0.0, 0.001328048581, 0.00308475703, -0.0007088613796],
    [0.0, 0.0, 0.0, 0.0, 0.00300904338, -0.001734500276],
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.002043219303]])


def lab_demo_state(camera_pose: ArrayLike | None = None) -> StateSLAM:
    """The 39-dimensional demo state of Lab 8: ν = 0 with a zero square-root block, the body
    pose equal to the camera pose (rCBb = 0, Rbc = I, Θnb = rot2rpy(Rnc)), nine landmarks with diagonal
    square-root blocks, and the published 6 × 6 upper-triangular pose block.

    ``camera_pose`` defaults to :data:`LAB_DEMO_CAMERA_POSE`.
    """
    pose = LAB_DEMO_CAMERA_POSE if camera_pose is None else finite_vector(camera_pose, "camera_pose", 6)
    mu = np.concatenate([np.zeros(6), pose[:3], rot2rpy(rpy2rot(pose[3:])), _DEMO_LANDMARKS.ravel()])
    S = np.zeros((39, 39))
    S[6:12, 6:12] = _DEMO_POSE_SQRT
    S[np.arange(12, 39), np.arange(12, 39)] = _DEMO_LANDMARK_SQRT_DIAG.ravel()
    return StateSLAM(Gaussian(mu, S))
