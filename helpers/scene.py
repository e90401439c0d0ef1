"""The lab scene, rendered: a chessboard on a self-similar textured plane seen through the calibrated camera.

The Lab 8 demo photograph is not available, so the workbook renders its own. The world frame {n} is the chessboard
frame: origin at the first inner corner, x along the 10-corner direction, y along the 7-corner direction, the board
in the plane z = 0, z pointing away from the camera. On that plane: a 10 × 7-inner-corner chessboard (squares of
22 mm) on a white sheet; elsewhere fractal value noise (six octaves, 1.5 mm … 48 mm) through a soft threshold, with
thousands of corners; fiducial stickers (a 2 × 2 checker) on the lab landmarks off the board, a floating card for
landmark 8 (0.148 m in front of the plane); optional grey "occluder" squares.

Rendering, vectorised over all pixels: (1) pixel → ray: the lens model is inverted exactly every 16 px and
(x/z, y/z) interpolated bicubically (``scene_truth.ray_interpolation_error``); (2) ray → plane: d = Rnc [x/z, y/z, 1]ᵀ
from rCNn meets z = z₀ at t = (z₀ − r_z)/d_z; (3) albedo there, each texture octave faded out as the pixel's
footprint approaches its wavelength, the sharp-edged objects supersampled; (4) shading, vignetting, a mild blur,
seeded sensor noise, uint8. The same seed gives the same bytes.

``recover_pose`` repeats the lab's pose recovery: findChessboardCorners → cornerSubPix → solvePnP with the
12-coefficient model, Rnc = Rcnᵀ, rCNn = −Rcnᵀ t, Θnc = rot2rpy(Rnc).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import RectBivariateSpline

from .camera import Camera
from .rotation import rot2rpy, rpy2rot
from .state_slam import LAB_DEMO_CAMERA_POSE, _check_camera, lab_demo_state
from .validation import finite_vector, float_array, integer, nonnegative_number, positive_number, rng_seed

__all__ = ["REFERENCE_POSE", "LAB_LANDMARKS", "PATTERN_SIZE", "SQUARE_SIZE", "TEXTURE_WAVELENGTHS", "RenderedScene",
           "board_points", "render_lab_scene", "find_board_corners", "recover_pose", "pose_from_board_extrinsics",
           "ChessboardNotFoundError"]

#: Camera pose recovered from the original photograph: [rCNn (m); Θnc (rad)].
REFERENCE_POSE = LAB_DEMO_CAMERA_POSE.copy()

#: Landmark positions of the lab demo, metres, world frame; row j = landmark j.
LAB_LANDMARKS = lab_demo_state().landmark_positions().T.copy()

PATTERN_SIZE = (10, 7)      # inner corners per row (x direction), per column (y direction)
SQUARE_SIZE = 0.022         # m
SHEET_MARGIN = 0.014        # white border around the squares, m
STICKER_HALF = 0.018        # white sticker half-size, m
CHECKER_HALF = 0.011        # 2 × 2 checker: squares of 11 mm around the centre
CARD_HALF = 0.020           # floating card half-size (landmark 8), m
OCCLUDER_GREY = 0.55

TEXTURE_WAVELENGTHS = (0.0015, 0.003, 0.006, 0.012, 0.024, 0.048)   # m, the six octaves of the floor texture
_LATTICE = (257, 263, 269, 271, 277, 281)                 # periodic lattices (co-prime sizes)
_GRID_STEP = 16                                           # px between exact pixel→ray inversions


class ChessboardNotFoundError(RuntimeError):
    """The chessboard could not be found in the image."""


@dataclass(frozen=True)
class RenderedScene:
    """A rendered image with its ground truth.

    image : (H, W) uint8 gray image. pose : the true camera pose [rCNn; Θnc] (6,).
    markers : (3, k) world positions that carry a fiducial (true corner) in the image.
    occluders : (2, q) plane positions covered by a blank patch of half-size occluder_half (m). seed : the seed.
    """

    image: np.ndarray
    pose: np.ndarray
    markers: np.ndarray
    occluders: np.ndarray
    seed: int
    occluder_half: float = 0.03


def board_points(pattern_size: tuple[int, int] = PATTERN_SIZE, square_size: float = SQUARE_SIZE) -> np.ndarray:
    """Inner-corner positions (j·a, i·a, 0) for rows i and columns j, row-major, shape (3, nx·ny)."""
    nx, ny = _check_pattern(pattern_size)
    square_size = positive_number(square_size, "square_size")
    j, i = np.meshgrid(np.arange(nx), np.arange(ny))
    return np.vstack([j.ravel() * square_size, i.ravel() * square_size, np.zeros(nx * ny)])


def _check_pattern(pattern_size: tuple[int, int]) -> tuple[int, int]:
    """(nx, ny): inner corners per row and column, each an integer ≥ 3 (OpenCV's chessboard detector)."""
    if not isinstance(pattern_size, (tuple, list, np.ndarray)) or len(pattern_size) != 2:
        raise ValueError(f"pattern_size must be (nx, ny) inner corners, got {pattern_size!r}")
    return tuple(integer(n, "pattern_size", minimum=3) for n in pattern_size)


def _check_points(P: ArrayLike, name: str, rows: int) -> np.ndarray:
    P = float_array(P, name)
    if P.ndim == 1 and P.size == 0:
        P = P.reshape(rows, 0)
    if P.ndim != 2 or P.shape[0] != rows or not np.all(np.isfinite(P)):
        raise ValueError(f"{name} must be a finite ({rows}, k) array of positions, got shape {P.shape}")
    return P


def _smoothstep01(x):
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _make_lattices(rng):
    lat = [rng.standard_normal((n, n)).astype(np.float32) for n in _LATTICE]
    angles = rng.uniform(0.0, 2.0 * np.pi, len(TEXTURE_WAVELENGTHS))
    shifts = rng.uniform(0.0, 1.0, (len(TEXTURE_WAVELENGTHS), 2))
    return lat, angles, shifts


def _texture(X, Y, footprint, lattices):
    """Blob/speckle reflectance at plane points (X, Y): fractal value noise (octave k sampled bicubically
    from a random periodic lattice of spacing λ_k, rotated), each octave faded out as the pixel footprint
    approaches λ_k, then a soft threshold 0.5 + 0.34 tanh(2.2 n)."""
    lat, angles, shifts = lattices
    total = np.zeros(X.shape, np.float32)
    for k, lam in enumerate(TEXTURE_WAVELENGTHS):
        fade = _smoothstep01(2.0 - 2.5 * footprint / lam)        # 1 while footprint < 0.4 λ, 0 beyond 0.8 λ
        if not np.any(fade > 0):
            continue
        c, s = np.cos(angles[k]), np.sin(angles[k])
        n = lat[k].shape[0]
        u = np.mod((c * X - s * Y) / lam + shifts[k, 0] * n, n).astype(np.float32)
        v = np.mod((s * X + c * Y) / lam + shifts[k, 1] * n, n).astype(np.float32)
        octave = cv2.remap(lat[k], u, v, cv2.INTER_CUBIC, borderMode=cv2.BORDER_WRAP)
        total += np.float32((lam / TEXTURE_WAVELENGTHS[-1]) ** 0.35) * fade * octave
    return 0.5 + 0.34 * np.tanh(2.2 * total)


def _checker(X, Y, cx, cy, half):
    """2 × 2 checker (black where the quadrant signs agree) inside |X−cx|, |Y−cy| < half; mask and value."""
    dx, dy = X - cx, Y - cy
    inside = (np.abs(dx) < half) & (np.abs(dy) < half)
    return inside, np.where(dx * dy > 0, 0.06, 0.94)


def _sheet_bounds():
    a = SQUARE_SIZE
    return (-a - SHEET_MARGIN, PATTERN_SIZE[0] * a + SHEET_MARGIN,
            -a - SHEET_MARGIN, PATTERN_SIZE[1] * a + SHEET_MARGIN)


def _sharp_albedo(X, Y, Xc, Yc, background, plane_markers, occluders, occluder_half, card_markers):
    """Reflectance of the sharp-edged objects at sample points; ``background`` where there is none.

    (X, Y): sample on the plane z = 0; (Xc[q], Yc[q]): the same ray on the plane of floating card q."""
    a = SQUARE_SIZE
    x0, x1, y0, y1 = _sheet_bounds()
    out = background
    sheet = (X > x0) & (X < x1) & (Y > y0) & (Y < y1)
    squares = (X > -a) & (X < PATTERN_SIZE[0] * a) & (Y > -a) & (Y < PATTERN_SIZE[1] * a)
    parity = (np.floor(X / a) + np.floor(Y / a)).astype(np.int64) % 2
    out = np.where(sheet, np.where(squares & (parity == 0), 0.06, 0.94), out)
    for mx, my in plane_markers.T:
        sticker = (np.abs(X - mx) < STICKER_HALF) & (np.abs(Y - my) < STICKER_HALF)
        inside, value = _checker(X, Y, mx, my, CHECKER_HALF)
        out = np.where(sticker, np.where(inside, value, 0.94), out)
    for ox, oy in occluders.T:
        patch = (np.abs(X - ox) < occluder_half) & (np.abs(Y - oy) < occluder_half)
        out = np.where(patch, OCCLUDER_GREY, out)
    for q, (mx, my, _) in enumerate(card_markers.T):
        on_card = (np.abs(Xc[q] - mx) < CARD_HALF) & (np.abs(Yc[q] - my) < CARD_HALF)
        inside, value = _checker(Xc[q], Yc[q], mx, my, CHECKER_HALF)
        out = np.where(on_card, np.where(inside, value, 0.94), out)
    return out


def _ray_splines(camera, width, height):
    """Bicubic splines (row, column) ↦ x/z and ↦ y/z of the exact inverse lens model, fitted on nodes every
    _GRID_STEP px (the model is inverted exactly there, by Camera.pixel_to_vector)."""
    g = _GRID_STEP
    us = np.arange(-2 * g, width + 3 * g, g, dtype=float)
    vs = np.arange(-2 * g, height + 3 * g, g, dtype=float)
    U, V = np.meshgrid(us, vs)
    rays = camera.pixel_to_vector(np.vstack([U.ravel(), V.ravel()]), strict=False)
    if np.any(rays[2] <= 0):
        raise ValueError("camera has pixels whose rays point backwards; cannot render this lens")
    return (RectBivariateSpline(vs, us, (rays[0] / rays[2]).reshape(U.shape)),
            RectBivariateSpline(vs, us, (rays[1] / rays[2]).reshape(U.shape)))


def _normalised_rays(camera, width, height):
    """Undistorted normalised coordinates (x/z, y/z) at every pixel centre, (H, W) each.

    The model is inverted exactly (Camera.pixel_to_vector) on nodes every _GRID_STEP px and interpolated
    with a bicubic tensor spline, evaluated in floating point (no fixed-point remap). Also returns a mask
    of the pixels beyond the fold of the lens model (no preimage: rendered black, like a lens hood)."""
    spline_x, spline_y = _ray_splines(camera, width, height)
    pu, pv = np.arange(width, dtype=float), np.arange(height, dtype=float)
    xn = spline_x(pv, pu)
    yn = spline_y(pv, pu)
    # beyond the fold: distorted radius larger than the largest radius the model can produce
    fx, fy, cx, cy = camera.K[0, 0], camera.K[1, 1], camera.K[0, 2], camera.K[1, 2]
    rf = camera.fold_radius
    dark = np.zeros((height, width), bool)
    if np.isfinite(rf):
        rd_max = np.hypot(*camera.vector_to_pixel(np.array([rf, 0.0, 1.0])) - np.array([cx, cy])) / fx
        rd = np.hypot((pu[None, :] - cx) / fx, (pv[:, None] - cy) / fy)
        iy, ix = np.nonzero(rd > 0.9 * rd_max)              # only near the corners: check the round trip
        if iy.size:
            back = camera.vector_to_pixel(np.vstack([xn[iy, ix], yn[iy, ix], np.ones(iy.size)]))
            dark[iy, ix] = np.hypot(back[0] - ix, back[1] - iy) > 0.05
    return xn, yn, dark


def _plane_intersector(pose):
    """f(x, y, z0): where the rays of normalised image points (x, y) meet the plane z = z0 (world frame);
    rays that never reach the plane give inf."""
    r = pose[:3]
    Rnc = rpy2rot(pose[3:])

    def intersect(x, y, z0):
        dx = Rnc[0, 0] * x + Rnc[0, 1] * y + Rnc[0, 2]
        dy = Rnc[1, 0] * x + Rnc[1, 1] * y + Rnc[1, 2]
        dz = Rnc[2, 0] * x + Rnc[2, 1] * y + Rnc[2, 2]
        with np.errstate(divide="ignore"):
            t = (z0 - r[2]) / dz
        t = np.where(t > 0, t, np.inf)                     # rays that never reach the plane
        return r[0] + t * dx, r[1] + t * dy

    return intersect


def _sharp_objects(albedo, intersect, xn, yn, X, Y, Xu, Xv, Yu, Yv, plane_markers, occluders, occluder_half,
                   card_markers, supersample):
    """Supersample the albedo (in place) at the pixels near the board, stickers, occluders and cards."""
    pad = 2.0 * np.hypot(np.hypot(Xu, Xv), np.hypot(Yu, Yv))
    x0, x1, y0, y1 = _sheet_bounds()
    near = (X > x0 - pad) & (X < x1 + pad) & (Y > y0 - pad) & (Y < y1 + pad)
    for mx, my in plane_markers.T:
        near |= (np.abs(X - mx) < STICKER_HALF + pad) & (np.abs(Y - my) < STICKER_HALF + pad)
    for ox, oy in occluders.T:
        near |= (np.abs(X - ox) < occluder_half + pad) & (np.abs(Y - oy) < occluder_half + pad)
    for mx, my, mz in card_markers.T:
        Xc, Yc = intersect(xn, yn, mz)
        near |= (np.abs(Xc - mx) < CARD_HALF + 4 * pad) & (np.abs(Yc - my) < CARD_HALF + 4 * pad)
    iy, ix = np.nonzero(near)
    if iy.size:
        s = supersample
        o = (np.arange(s) + 0.5) / s - 0.5
        ou, ov = [a.ravel() for a in np.meshgrid(o, o)]
        xnu, xnv = np.gradient(xn, axis=1)[iy, ix], np.gradient(xn, axis=0)[iy, ix]
        ynu, ynv = np.gradient(yn, axis=1)[iy, ix], np.gradient(yn, axis=0)[iy, ix]
        xs = xn[iy, ix, None] + xnu[:, None] * ou + xnv[:, None] * ov      # (K, s²) sub-pixel rays
        ys = yn[iy, ix, None] + ynu[:, None] * ou + ynv[:, None] * ov
        Xs, Ys = intersect(xs, ys, 0.0)
        cards = [intersect(xs, ys, mz) for mz in card_markers[2]]
        vals = _sharp_albedo(Xs, Ys, [c[0] for c in cards], [c[1] for c in cards], albedo[iy, ix, None],
                             plane_markers, occluders, occluder_half, card_markers)
        albedo[iy, ix] = vals.mean(axis=1)


def _expose(camera, albedo, X, Y, dark, W, H):
    """Grey levels before blur and noise: smooth illumination over the plane, radial vignetting, and black
    beyond the lens fold."""
    light = 0.88 + 0.12 * np.tanh(1.5 * (0.6 * np.clip(X, -5, 5) + 0.4 * np.clip(Y, -5, 5)))
    uu = (np.arange(W) - W / 2) / (W / 2)
    vv = (np.arange(H) - H / 2) / (W / 2)
    shade = light * (1.0 - 0.18 * (uu[None, :] ** 2 + vv[:, None] ** 2))
    img = 18.0 + 225.0 * albedo * shade
    if np.any(dark):
        # beyond the fold the lens has no image: fade to black along a smooth arc inside the fold (a real
        # wide-angle lens shows a dark, blurred circle there), so the border makes no corners
        fx, fy, cx, cy = camera.K[0, 0], camera.K[1, 1], camera.K[0, 2], camera.K[1, 2]
        rd = np.hypot((np.arange(W)[None, :] - cx) / fx, (np.arange(H)[:, None] - cy) / fy)
        r_edge = rd[dark].min() * fx - 4.0                             # px, just inside the first dark pixel
        keep = _smoothstep01((r_edge - rd * fx) / 25.0)
        img = 6.0 + (img - 6.0) * keep
    return img


def render_lab_scene(camera: Camera, pose: ArrayLike | None = None, seed: int = 0, markers: ArrayLike | None = None,
                     occluders: ArrayLike | None = None, occluder_half: float = 0.03, card: bool = True,
                     supersample: int = 4, blur_sigma: float = 0.6, noise_sigma: float = 1.5) -> RenderedScene:
    """Render the lab scene at the camera's resolution (1920 × 1440 for the lab camera).

    Parameters
    ----------
    camera : helpers.camera.Camera (full 12-coefficient model).
    pose : true camera pose [rCNn; Θnc] (default ``REFERENCE_POSE``, the Lab 8 handout).
    seed : seeds the texture and the sensor noise (same seed → same bytes).
    markers : (3, k) world points that get a fiducial: points with z = 0 get a sticker on the plane,
        others (z < 0, camera side) a floating card if ``card``. Default: the lab landmarks off the
        board (0–4, 7, 8); landmarks 5 and 6 are board corners.
    occluders : (2, q) plane positions (x, y) covered by a blank grey square of half-size
        ``occluder_half`` m (hides stickers and texture there). Default: none.
    supersample : s × s samples per pixel for the sharp-edged objects (board, stickers, cards; 1–8);
        the texture is anti-aliased analytically. blur_sigma : optics blur (px, ≥ 0).
    noise_sigma : sensor noise standard deviation in grey levels (≥ 0).
    """
    _check_camera(camera)
    pose = REFERENCE_POSE.copy() if pose is None else finite_vector(pose, "pose", 6)
    seed = integer(rng_seed(seed), "seed")
    markers = LAB_LANDMARKS[[0, 1, 2, 3, 4, 7, 8]].T if markers is None else _check_points(markers, "markers", 3)
    occluders = np.zeros((2, 0)) if occluders is None else _check_points(occluders, "occluders", 2)
    occluder_half = positive_number(occluder_half, "occluder_half")
    supersample = integer(supersample, "supersample", minimum=1, below=9)
    blur_sigma = nonnegative_number(blur_sigma, "blur_sigma")
    noise_sigma = nonnegative_number(noise_sigma, "noise_sigma")
    on_plane = markers[2] == 0.0
    plane_markers = markers[:2, on_plane]
    card_markers = markers[:, ~on_plane] if card else np.zeros((3, 0))
    if np.any(card_markers[2] >= 0):
        raise ValueError("markers off the plane must lie on the camera side (z < 0)")

    W, H = camera.image_size
    rng = np.random.default_rng(seed)
    lattices = _make_lattices(rng)
    intersect = _plane_intersector(pose)
    xn, yn, dark = _normalised_rays(camera, W, H)
    X, Y = intersect(xn, yn, 0.0)
    X = np.where(np.isfinite(X), X, 1e3)
    Y = np.where(np.isfinite(Y), Y, 1e3)
    # footprint of a pixel on the plane: sqrt |det ∂(X, Y)/∂(u, v)|
    Xu, Xv = np.gradient(X, axis=1), np.gradient(X, axis=0)
    Yu, Yv = np.gradient(Y, axis=1), np.gradient(Y, axis=0)
    footprint = np.sqrt(np.abs(Xu * Yv - Xv * Yu)).astype(np.float32)
    albedo = _texture(X.astype(np.float32), Y.astype(np.float32), footprint, lattices).astype(float)
    _sharp_objects(albedo, intersect, xn, yn, X, Y, Xu, Xv, Yu, Yv, plane_markers, occluders, occluder_half,
                   card_markers, supersample)   # board, stickers, occluders and cards: supersampled
    img = _expose(camera, albedo, X, Y, dark, W, H)
    if blur_sigma > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_sigma)
    if noise_sigma > 0:
        img = img + noise_sigma * rng.standard_normal(img.shape)
    image = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return RenderedScene(image=image, pose=pose, markers=markers, occluders=occluders, seed=int(seed),
                         occluder_half=float(occluder_half))


def find_board_corners(image: np.ndarray, pattern_size: tuple[int, int] = PATTERN_SIZE) -> np.ndarray:
    """Inner chessboard corners (2, nx·ny), sub-pixel refined, in OpenCV's order (row-major from the first
    corner). Raises ChessboardNotFoundError when the board is not found."""
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim not in (2, 3) \
            or (image.ndim == 3 and image.shape[2] != 3) or min(image.shape[:2]) < 8:
        raise ValueError(f"image must be a uint8 gray or BGR image of at least 8 × 8 pixels, got "
                         f"{type(image).__name__} {getattr(image, 'dtype', '')} {np.shape(image)}")
    pattern_size = _check_pattern(pattern_size)
    gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(gray, tuple(pattern_size), flags=flags)
    if not found:
        raise ChessboardNotFoundError(f"no {pattern_size[0]}×{pattern_size[1]} chessboard found in the image")
    criteria = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 100, 1e-4)
    corners = cv2.cornerSubPix(gray, corners, (7, 7), (-1, -1), criteria)
    return corners.reshape(-1, 2).T.astype(float)


def pose_from_board_extrinsics(rvec: ArrayLike, tvec: ArrayLike) -> np.ndarray:
    """Camera pose [rCNn; Θnc] (6,) in the board frame from OpenCV's extrinsics (rvec, tvec), which map a board
    point to the camera frame, rPCc = Rcn rPNn + t with Rcn = Rodrigues(rvec): Rnc = Rcnᵀ, rCNn = −Rcnᵀ t."""
    Rcn, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    t = np.asarray(tvec, dtype=np.float64).ravel()
    return np.concatenate([-Rcn.T @ t, rot2rpy(Rcn.T)])


def recover_pose(image: np.ndarray, camera: Camera, pattern_size: tuple[int, int] = PATTERN_SIZE,
                 square_size: float = SQUARE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """Camera pose [rCNn; Θnc] from the chessboard, as the lab does it.

    corners = findChessboardCorners + cornerSubPix; (rvec, t) = solvePnP(board points, corners, K, 12
    distortion coefficients); Rcn = Rodrigues(rvec); Rnc = Rcnᵀ, rCNn = −Rcnᵀ t, Θnc = rot2rpy(Rnc).
    Returns (pose (6,), corners (2, nx·ny)).
    """
    _check_camera(camera)
    square_size = positive_number(square_size, "square_size")
    corners = find_board_corners(image, pattern_size)
    obj = board_points(pattern_size, square_size).T.astype(np.float64)
    ok, rvec, tvec = cv2.solvePnP(obj, corners.T.astype(np.float64), camera.K, camera.dist_coeffs,
                                  flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise ChessboardNotFoundError("solvePnP failed")
    return pose_from_board_extrinsics(rvec, tvec), corners
