"""Ground truth of the rendered lab scene: from a pixel back to the scene, the fiducials, and how exact the
renderer's pixel→ray interpolation is.

    P = pixel_to_plane(camera, pose, pixel, z0)       # where the pixel's ray meets the plane z = z0
    half = fiducial_half_size(marker)                  # half-size of the white square of a fiducial
    err = ray_interpolation_error(camera)              # px, interpolated rays vs the exact lens model
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .camera import Camera
from .scene import CARD_HALF, STICKER_HALF, _plane_intersector, _ray_splines
from .state_slam import _check_camera
from .validation import finite_number, finite_vector, integer, rng_seed

__all__ = ["pixel_to_plane", "fiducial_half_size", "ray_interpolation_error"]


def pixel_to_plane(camera: Camera, pose: ArrayLike, pixels: ArrayLike, z0: float = 0.0) -> np.ndarray:
    """World point(s) where the ray(s) of pixel(s) ((2,) or (2, N)) from the camera at ``pose`` = [rCNn; Θnc]
    meet the plane z = ``z0`` (the renderer's ray–plane intersection, rays from ``camera.pixel_to_vector``).
    Rays that never reach the plane give NaN. Returns (3,) or (3, N)."""
    _check_camera(camera)
    pose = finite_vector(pose, "pose", 6)
    z0 = finite_number(z0, "z0")
    V = camera.pixel_to_vector(pixels, strict=False)                  # z > 0: inside the lens fold
    X, Y = _plane_intersector(pose)(V[0] / V[2], V[1] / V[2], z0)
    P = np.array([X, Y, np.full_like(X, z0)])
    return np.where(np.isfinite(P[0]), P, np.nan)


def fiducial_half_size(marker: ArrayLike) -> float:
    """Half-size (m) of the white square that carries the checker of a fiducial at world point ``marker``:
    a sticker on the plane (z = 0) or a floating card (z < 0)."""
    marker = finite_vector(marker, "marker", 3)
    return STICKER_HALF if marker[2] == 0.0 else CARD_HALF


def ray_interpolation_error(camera: Camera, n_samples: int = 2000, seed: int = 0, inside: float = 0.9) -> float:
    """Largest pixel error of the renderer's interpolated rays: at ``n_samples`` random sub-pixel positions
    (seeded) whose distorted radius is below ``inside`` × the largest radius the lens model produces, the
    interpolated ray is projected back with the exact model and compared with the pixel. Returns px."""
    _check_camera(camera)
    n_samples = integer(n_samples, "n_samples", minimum=1)
    seed = rng_seed(seed)
    if not 0 < finite_number(inside, "inside") <= 1:
        raise ValueError(f"inside must lie in (0, 1], got {inside!r}")
    W, H = camera.image_size
    fx, fy, cx, cy = camera.K[0, 0], camera.K[1, 1], camera.K[0, 2], camera.K[1, 2]
    rf = camera.fold_radius
    rd_max = np.hypot(*camera.distort(rf, 0.0)) if np.isfinite(rf) else np.inf
    rng = np.random.default_rng(seed)
    pts = rng.uniform([0.0, 0.0], [W - 1.0, H - 1.0], size=(4 * n_samples, 2)).T
    pts = pts[:, np.hypot((pts[0] - cx) / fx, (pts[1] - cy) / fy) < inside * rd_max][:, :n_samples]
    spline_x, spline_y = _ray_splines(camera, W, H)
    rays = np.vstack([spline_x.ev(pts[1], pts[0]), spline_y.ev(pts[1], pts[0]), np.ones(pts.shape[1])])
    return float(np.abs(camera.vector_to_pixel(rays) - pts).max())
