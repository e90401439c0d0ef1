"""The calibrated camera: OpenCV's 12-coefficient distortion model, its Jacobians and FOV (the inverse model:
``helpers.camera_inverse``; reading the calibration file: ``helpers.camera_io``).

Model (course Lab 7/8; identical to ``cv2.projectPoints`` with the RATIONAL + THIN_PRISM model, no tilt).
For a point rPCc = [x, y, z] in the camera frame {c} (z along the optical axis, x right, y down):

    u = x/z,  v = y/z,  ρ = r² = u² + v²                      (no check on the sign of z)
    α = k1 ρ + k2 ρ² + k3 ρ³,   β = k4 ρ + k5 ρ² + k6 ρ³,   c = (1 + α)/(1 + β)
    u' = c u + 2 p1 u v + p2 (ρ + 2u²) + s1 ρ + s2 ρ²
    v' = c v + p1 (ρ + 2v²) + 2 p2 u v + s3 ρ + s4 ρ²
    pixel = [fx u' + cx, fy v' + cy]

Jacobian (r²-form, finite on the optical axis): with α_ρ = k1 + 2k2 ρ + 3k3 ρ², β_ρ = k4 + 2k5 ρ + 3k6 ρ²,
c_ρ = (α_ρ (1 + β) − (1 + α) β_ρ)/(1 + β)²,

    ∂u'/∂u = c + 2u² c_ρ + 2p1 v + 6p2 u + 2s1 u + 4s2 ρ u
    ∂u'/∂v = 2uv c_ρ + 2p1 u + 2p2 v + 2s1 v + 4s2 ρ v
    ∂v'/∂u = 2uv c_ρ + 2p1 u + 2p2 v + 2s3 u + 4s4 ρ u
    ∂v'/∂v = c + 2v² c_ρ + 6p1 v + 2p2 u + 2s3 v + 4s4 ρ v
    ∂pixel/∂rPCc = diag(fx, fy) · [∂(u', v')/∂(u, v)] · [[1/z, 0, −x/z²], [0, 1/z, −y/z²]]

World points: with the camera pose η = [rCNn; Θnc] and Rnc = rpy2rot(Θnc), rPCc = Rncᵀ (rPNn − rCNn), and

    ∂pixel/∂rPNn = J Rncᵀ,   ∂pixel/∂rCNn = −J Rncᵀ,   ∂pixel/∂Θk = J (∂Rnc/∂Θk)ᵀ (rPNn − rCNn).

From the body pose [rBNn; Θnb] (camera mounted at rCBb with orientation Rbc in {b}):
rCNn = rBNn + Rnb rCBb, Rnc = Rnb Rbc, so rPCc = Rbcᵀ (Rnbᵀ (rPNn − rBNn) − rCBb) and

    ∂pixel/∂rPNn = J Rbcᵀ Rnbᵀ,   ∂pixel/∂rBNn = −J Rbcᵀ Rnbᵀ,   ∂pixel/∂Θk = J Rbcᵀ (∂Rnb/∂Θk)ᵀ (rPNn − rBNn).

Everything is vectorised over N points: a point is (3,) and N points are (3, N); pixels are (2,) / (2, N);
Jacobians are (2, 3) / (N, 2, 3).
"""
from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from .camera_inverse import fold_radius, undistort
from .camera_io import REQUIRED_FLAGS, check_calibration, read_camera_xml
from .paths import data_dir
from .rotation import rot2rpy, rpy2rot, rpy2rot_derivatives
from .validation import boolean, finite_vector, float_array, integer, positive_number

__all__ = ["Camera", "ProjectionError", "PoseJacobians", "FOVAngles", "load_lab_camera"]


def load_lab_camera() -> Camera:
    """The Lab 8 reference calibration (``data/camera.xml``, 1920 × 1440 wide-angle action camera)."""
    return Camera.from_xml(data_dir() / "camera.xml")


class PoseJacobians(NamedTuple):
    """Jacobians of pixel coordinates, each (2, 3) for one point or (N, 2, 3) for N points.

    ``wrt_point``: ∂pixel/∂rPNn.  ``wrt_position``: ∂pixel/∂(camera or body position).
    ``wrt_angles``: ∂pixel/∂[φ, θ, ψ] (columns: roll, pitch, yaw of the camera or body).
    """

    wrt_point: np.ndarray
    wrt_position: np.ndarray
    wrt_angles: np.ndarray


class FOVAngles(NamedTuple):
    """Full field-of-view angles in radians."""

    horizontal: float
    vertical: float
    diagonal: float


class ProjectionError(ValueError):
    """World point(s) behind the camera (z ≤ 0 in {c}) or beyond the lens fold (off-axis angle ≥
    ``max_off_axis_angle()``): no valid pixel. ``columns``: offending columns; ``reason``: "behind" / "fold"."""

    def __init__(self, message: str, columns: ArrayLike, reason: str) -> None:
        super().__init__(message)
        self.columns = np.asarray(columns, dtype=np.intp)
        self.reason = reason


def _points(P: ArrayLike, name: str, rows: int = 3) -> np.ndarray:
    P = float_array(P, name)
    if P.ndim not in (1, 2) or P.shape[0] != rows:
        raise ValueError(f"{name} must have shape ({rows},) or ({rows}, N), got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    return P


def _pose(eta: ArrayLike, name: str) -> np.ndarray:
    """A pose [position (3); roll, pitch, yaw (3)] as a finite (6,) array."""
    return finite_vector(eta, name, 6)


def _check_finite_pixels(P: np.ndarray, values: np.ndarray) -> None:
    """ValueError naming the columns of rPCc whose pixel (or Jacobian) ``values`` are not finite."""
    bad = np.flatnonzero(~np.all(np.isfinite(values.reshape(-1, P.shape[1])), axis=0))
    if bad.size:
        raise ValueError(f"rPCc has point(s) at column(s) {bad.tolist()} (e.g. {P[:, bad[0]].tolist()}) too far off "
                         "the optical axis, or where the distortion denominator 1 + β vanishes: no finite pixel")


class Camera:
    """Pinhole camera with OpenCV's rational + thin-prism distortion (12 coefficients).

    Parameters
    ----------
    K : (3, 3) camera matrix [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (fx, fy > 0, no skew)
    dist_coeffs : 12 coefficients in OpenCV order k1 k2 p1 p2 k3 k4 k5 k6 s1 s2 s3 s4 (4, 5 or 8 are
        zero-padded)
    image_size : (width, height) in pixels, positive integers
    r_cb_b : camera position in the body frame {b} (default 0)
    R_bc : camera orientation relative to {b} (default I)
    flags : OpenCV calibration flags; must include RATIONAL (16384) and THIN_PRISM (32768), not TILTED
    """

    def __init__(self, K: ArrayLike, dist_coeffs: ArrayLike, image_size: tuple[int, int],
                 r_cb_b: ArrayLike | None = None, R_bc: ArrayLike | None = None, flags: int = REQUIRED_FLAGS) -> None:
        K, d, size, flags = check_calibration(K, dist_coeffs, image_size, flags)
        r_cb_b = np.zeros(3) if r_cb_b is None else finite_vector(r_cb_b, "r_cb_b", 3).copy()
        R_bc = np.eye(3) if R_bc is None else np.array(float_array(R_bc, "R_bc"))
        if R_bc.shape != (3, 3) or not np.all(np.isfinite(R_bc)) or np.linalg.det(R_bc) <= 0 \
                or not np.allclose(R_bc.T @ R_bc, np.eye(3), atol=1e-9):
            raise ValueError("R_bc must be a (3, 3) rotation matrix")
        self.K = K
        self.dist_coeffs = d
        self.image_size = size
        self.r_cb_b = r_cb_b
        self.R_bc = R_bc
        self.flags = flags
        for array in (K, d, r_cb_b, R_bc):       # read-only: fold_radius and the model depend on them
            array.setflags(write=False)
        self.fold_radius = fold_radius(d, self._distort)

    @property
    def width(self) -> int:
        return self.image_size[0]

    @property
    def height(self) -> int:
        return self.image_size[1]

    def __repr__(self) -> str:
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        return f"Camera(fx={fx:.3f}, fy={fy:.3f}, cx={cx:.3f}, cy={cy:.3f}, image_size={self.image_size})"

    @classmethod
    def from_xml(cls, path: str | Path) -> Camera:
        """Read an OpenCV FileStorage file with a map ``camera`` holding ``camera_matrix`` (3×3),
        ``distortion_coefficients`` (12×1), ``flags`` (int) and ``imageSize`` (2 ints: width height)."""
        K, d, image_size, flags = read_camera_xml(path)
        try:
            return cls(K, d, image_size, flags=flags)
        except ValueError as exc:
            raise ValueError(f"{path}: invalid camera data: {exc}") from None

    def _distort(self, u: np.ndarray, v: np.ndarray, jacobian: bool) -> tuple[np.ndarray, ...]:
        """(u', v') of the lens model at (u, v); with ``jacobian`` also ∂u'/∂u, ∂u'/∂v, ∂v'/∂u, ∂v'/∂v."""
        k1, k2, p1, p2, k3, k4, k5, k6, s1, s2, s3, s4 = self.dist_coeffs
        rho = u * u + v * v
        alpha = rho * (k1 + rho * (k2 + rho * k3))
        beta = rho * (k4 + rho * (k5 + rho * k6))
        den = 1.0 + beta
        c = (1.0 + alpha) / den
        ud = c * u + 2 * p1 * u * v + p2 * (rho + 2 * u * u) + s1 * rho + s2 * rho * rho
        vd = c * v + p1 * (rho + 2 * v * v) + 2 * p2 * u * v + s3 * rho + s4 * rho * rho
        if not jacobian:
            return ud, vd
        a_r = k1 + 2 * k2 * rho + 3 * k3 * rho * rho
        b_r = k4 + 2 * k5 * rho + 3 * k6 * rho * rho
        c_r = (a_r * den - (1.0 + alpha) * b_r) / (den * den)
        duu = c + 2 * u * u * c_r + 2 * p1 * v + 6 * p2 * u + 2 * s1 * u + 4 * s2 * rho * u
        duv = 2 * u * v * c_r + 2 * p1 * u + 2 * p2 * v + 2 * s1 * v + 4 * s2 * rho * v
        dvu = 2 * u * v * c_r + 2 * p1 * u + 2 * p2 * v + 2 * s3 * u + 4 * s4 * rho * u
        dvv = c + 2 * v * v * c_r + 6 * p1 * v + 2 * p2 * u + 2 * s3 * v + 4 * s4 * rho * v
        return ud, vd, duu, duv, dvu, dvv

    def distort(self, u: ArrayLike, v: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """The lens model in normalised coordinates: (u, v) = (x/z, y/z) ↦ (u', v') (arrays broadcast)."""
        u = float_array(u, "u")
        v = float_array(v, "v")
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(v))):
            raise ValueError("u and v must be finite (no NaN/inf)")
        return self._distort(u, v, False)

    def vector_to_pixel(self, rPCc: ArrayLike, return_jacobian: bool = False) \
            -> np.ndarray | tuple[np.ndarray, np.ndarray]:
        """Pixel of the camera-frame vector(s) rPCc ((3,) or (3, N)); with ``return_jacobian`` also
        ∂pixel/∂rPCc ((2, 3) or (N, 2, 3)). Points with z = 0 raise ValueError; z < 0 is projected through
        x/z like OpenCV (no sign check — use :meth:`is_vector_within_fov` to select visible points)."""
        return_jacobian = boolean(return_jacobian, "return_jacobian")
        P = _points(rPCc, "rPCc")
        out = self._project(P.reshape(3, -1), return_jacobian)
        if P.ndim == 2:
            return out
        return (out[0][:, 0], out[1][0]) if return_jacobian else out[:, 0]

    def _project(self, P, return_jacobian):
        """:meth:`vector_to_pixel` of the (3, N) array P, without the checks of its arguments."""
        x, y, z = P
        if np.any(z == 0):
            raise ValueError("rPCc has points with z = 0 (in the camera's focal plane); they have no pixel")
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):   # diagnosed below instead
            u, v = x / z, y / z
            out = self._distort(u, v, return_jacobian)
            Q = np.vstack([fx * out[0] + cx, fy * out[1] + cy])
        _check_finite_pixels(P, Q)
        if not return_jacobian:
            return Q
        _, _, duu, duv, dvu, dvv = out
        iz = 1.0 / z
        N = P.shape[1]
        J = np.empty((N, 2, 3))
        # [∂u'/∂u, ∂u'/∂v] · [[1/z, 0, −u/z], [0, 1/z, −v/z]]
        J[:, 0, 0] = fx * duu * iz
        J[:, 0, 1] = fx * duv * iz
        J[:, 0, 2] = -fx * (duu * u + duv * v) * iz
        J[:, 1, 0] = fy * dvu * iz
        J[:, 1, 1] = fy * dvv * iz
        J[:, 1, 2] = -fy * (dvu * u + dvv * v) * iz
        _check_finite_pixels(P, J.reshape(N, 6).T)
        return Q, J

    def world_to_vector(self, rPNn: ArrayLike, eta: ArrayLike) -> np.ndarray:
        """rPCc = Rncᵀ (rPNn − rCNn) for world point(s) rPNn ((3,) or (3, N)) and camera pose
        eta = [rCNn; Θnc] (6,)."""
        P = _points(rPNn, "rPNn")
        eta = _pose(eta, "eta")
        Rnc = rpy2rot(eta[3:])
        d = P - (eta[:3] if P.ndim == 1 else eta[:3, None])
        return Rnc.T @ d

    def _check_projectable(self, rPCc, single):
        """ProjectionError naming ``rPNn`` for world points behind the camera or beyond the lens fold."""
        bad, reason = np.flatnonzero(~(rPCc[2] > 0)), "behind the camera (camera-frame z ≤ 0)"
        if bad.size == 0:
            bad = np.flatnonzero(np.arctan2(np.hypot(rPCc[0], rPCc[1]), rPCc[2]) >= self.max_off_axis_angle())
            reason = f"beyond the lens fold (off-axis angle ≥ {np.degrees(self.max_off_axis_angle()):.1f}°)"
        if bad.size:
            raise ProjectionError(f"rPNn: {'the point' if single else f'column(s) {bad.tolist()}'} lie(s) "
                                  f"{reason}: no valid pixel (rPCc = {np.round(rPCc[:, bad[0]], 6).tolist()})",
                                  bad, "behind" if reason.startswith("behind") else "fold")

    def _world_to_pixel(self, P, r, Theta, A, t, return_jacobian):
        """Shared core: rPCc = A (Rᵀ (P − r) − t), R = rpy2rot(Θ)."""
        single = P.ndim == 1
        P = P.reshape(3, -1)
        R, *dR = rpy2rot_derivatives(Theta)
        d = P - r[:, None]
        rPCc = A @ (R.T @ d - t[:, None])
        self._check_projectable(rPCc, single)
        if not return_jacobian:
            Q = self._project(rPCc, False)
            return Q[:, 0] if single else Q
        Q, J = self._project(rPCc, True)  # (N, 2, 3)
        JA = J @ A  # (N, 2, 3)
        J_point = JA @ R.T
        # ∂rPCc/∂Θk = A (∂R/∂Θk)ᵀ d  → columns k of a (N, 3, 3) array
        dP = np.stack([(dRk.T @ d).T for dRk in dR], axis=-1)  # (N, 3, 3): [:, :, k]
        J_ang = JA @ dP
        jac = PoseJacobians(J_point, -J_point, J_ang)
        if single:
            return Q[:, 0], PoseJacobians(*(j[0] for j in jac))
        return Q, jac

    def world_to_pixel(self, rPNn: ArrayLike, eta: ArrayLike, return_jacobian: bool = False) \
            -> np.ndarray | tuple[np.ndarray, PoseJacobians]:
        """Pixel(s) of world point(s) rPNn seen from the camera pose eta = [rCNn; Θnc].

        With ``return_jacobian`` returns ``(pixels, PoseJacobians)`` with ∂pixel/∂rPNn (``wrt_point``),
        ∂pixel/∂rCNn (``wrt_position``) and ∂pixel/∂Θnc (``wrt_angles``).
        """
        P = _points(rPNn, "rPNn")
        eta = _pose(eta, "eta")
        return self._world_to_pixel(P, eta[:3], eta[3:], np.eye(3), np.zeros(3),
                                    boolean(return_jacobian, "return_jacobian"))

    def body_to_pixel(self, rPNn: ArrayLike, eta_body: ArrayLike, return_jacobian: bool = False) \
            -> np.ndarray | tuple[np.ndarray, PoseJacobians]:
        """Pixel(s) of world point(s) rPNn seen from the camera mounted on a body at pose
        eta_body = [rBNn; Θnb] (uses ``r_cb_b`` and ``R_bc``).

        With ``return_jacobian`` returns ``(pixels, PoseJacobians)`` with ∂pixel/∂rPNn, ∂pixel/∂rBNn and
        ∂pixel/∂Θnb.
        """
        P = _points(rPNn, "rPNn")
        eta_body = _pose(eta_body, "eta_body")
        return self._world_to_pixel(P, eta_body[:3], eta_body[3:], self.R_bc.T, self.r_cb_b,
                                    boolean(return_jacobian, "return_jacobian"))

    def camera_pose_from_body(self, eta_body: ArrayLike) -> np.ndarray:
        """Camera pose [rCNn; Θnc] from the body pose [rBNn; Θnb]: rCNn = rBNn + Rnb rCBb, Rnc = Rnb Rbc."""
        eta_body = _pose(eta_body, "eta_body")
        Rnb = rpy2rot(eta_body[3:])
        return np.concatenate([eta_body[:3] + Rnb @ self.r_cb_b, rot2rpy(Rnb @ self.R_bc)])

    def pixel_to_vector(self, pixels: ArrayLike, strict: bool = True, tol: float = 1e-12,
                        max_iter: int = 100) -> np.ndarray:
        """Unit vector(s) in {c} whose projection is the given pixel(s) ((2,) or (2, N) → (3,) or (3, N)).

        Exact inversion of the distortion model (``camera_inverse.undistort``), confined to the invertible range
        r < ``fold_radius``. A pixel beyond the image of that range (e.g. the extreme corners of a strongly
        distorting wide-angle lens) has no exact preimage: with ``strict`` it raises ValueError, otherwise the
        least-squares preimage (at the fold) is returned.
        """
        strict = boolean(strict, "strict")
        tol = positive_number(tol, "tol")
        max_iter = integer(max_iter, "max_iter", minimum=1)
        Qp = _points(pixels, "pixels", rows=2)
        Q2 = Qp.reshape(2, -1)
        fx, fy, cx, cy = self.K[0, 0], self.K[1, 1], self.K[0, 2], self.K[1, 2]
        u, v, cost = undistort(self._distort, (Q2[0] - cx) / fx, (Q2[1] - cy) / fy, self.fold_radius ** 2, tol,
                               max_iter)
        if strict and not np.all(cost <= (1e3 * tol) ** 2):
            raise ValueError("pixels contains pixel(s) outside the invertible range of the distortion model "
                             "(beyond the fold of the lens model); pass strict=False for the least-squares ray")
        V = np.vstack([u, v, np.ones_like(u)])
        V /= np.linalg.norm(V, axis=0)
        return V[:, 0] if Qp.ndim == 1 else V

    def fov_angles(self) -> FOVAngles:
        """Horizontal, vertical and diagonal FOV (radians) by exact inversion of the model.

        Horizontal: angle between the rays of the left and right image edges at the principal row cy;
        vertical: top and bottom edges at the principal column cx; diagonal: the larger of the angles
        between opposite image corners. Edges are the outer pixel borders (−0.5 and size − 0.5).
        """
        W, H = self.width, self.height
        cx, cy = self.K[0, 2], self.K[1, 2]
        lo_x, hi_x, lo_y, hi_y = -0.5, W - 0.5, -0.5, H - 0.5
        pts = np.array([[lo_x, hi_x, cx, cx, lo_x, hi_x, hi_x, lo_x],
                        [cy, cy, lo_y, hi_y, lo_y, hi_y, lo_y, hi_y]])
        V = self.pixel_to_vector(pts, strict=False)

        def angle(a, b):
            return float(np.arctan2(np.linalg.norm(np.cross(V[:, a], V[:, b])), V[:, a] @ V[:, b]))

        return FOVAngles(angle(0, 1), angle(2, 3), max(angle(4, 5), angle(6, 7)))

    def max_off_axis_angle(self) -> float:
        """atan(fold_radius): the largest off-axis angle (radians) for which the model is invertible."""
        return float(np.arctan(self.fold_radius))

    def is_vector_within_fov(self, rPCc: ArrayLike) -> bool | np.ndarray:
        """Whether camera-frame vector(s) are visible: z > 0, off-axis angle < :meth:`max_off_axis_angle`
        (beyond it the lens model folds back), and the pixel lies inside the image
        [−0.5, W − 0.5] × [−0.5, H − 0.5]. (3,) → bool; (3, N) → bool array (N,)."""
        P = _points(rPCc, "rPCc")
        single = P.ndim == 1
        P = P.reshape(3, -1)
        off_axis = np.arctan2(np.hypot(P[0], P[1]), P[2])
        inside = (P[2] > 0) & (off_axis < self.max_off_axis_angle())
        Q = np.full((2, P.shape[1]), -np.inf)
        if np.any(inside):
            Q[:, inside] = self._project(P[:, inside], False)
        inside &= (Q[0] >= -0.5) & (Q[0] <= self.width - 0.5) & (Q[1] >= -0.5) & (Q[1] <= self.height - 0.5)
        return bool(inside[0]) if single else inside

    def is_world_within_fov(self, rPNn: ArrayLike, eta: ArrayLike) -> bool | np.ndarray:
        """is_vector_within_fov(world_to_vector(rPNn, eta)) for the camera pose eta = [rCNn; Θnc]."""
        return self.is_vector_within_fov(self.world_to_vector(rPNn, eta))
