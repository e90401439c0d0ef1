"""Calibrating a camera from photographs of a chessboard, with the workbook's camera model.

Zhang's method as OpenCV implements it (``cv2.calibrateCamera``): each photograph i shows the board's inner corners
P_k = (j·a, i·a, 0) (``board_points``: a the square size, row-major) at the sub-pixel positions y_ik found by
``find_board_corners``. The intrinsics θ (fx, fy, cx, cy and the free distortion coefficients) and one board pose
per photograph minimise the sum of squared reprojection errors

    E(θ, η_1 … η_n) = Σ_i Σ_k ‖y_ik − pixel(P_k; η_i, θ)‖²,

pixel() being :class:`~helpers.camera.Camera`'s model. The per-image error is RMS_i = √(Σ_k ‖e_ik‖² / N) over its N
corners, the overall error RMS = √(E / (n N)); both are recomputed here with the workbook's ``Camera``.

**Which distortion terms.** A model with more coefficients always lowers E on the photographs it was fitted to, so E
cannot choose. :func:`compare_models` scores each model by leave-one-image-out cross-validation: calibrate on all
photographs but one, fit that one's board pose alone (``solvePnP``) with those intrinsics, and pool its squared
errors; LOO-RMS = √(pooled / (n N)). Coefficients the data cannot determine make the held-out error *rise*.
:func:`choose_model` takes the model with the fewest coefficients whose LOO-RMS is within ``tolerance`` (1 %) of the
smallest. The camera file always holds the 12 coefficients of the lab's format; a model's fixed ones are zero and
its OpenCV flags (written with it) say which were fixed.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .camera import Camera, ProjectionError
from .camera_io import write_camera_xml
from .scene import ChessboardNotFoundError, _check_pattern, board_points, find_board_corners, pose_from_board_extrinsics
from .validation import one_of, positive_number

__all__ = ["DISTORTION_MODELS", "BoardViews", "Calibration", "find_boards", "calibrate", "compare_models",
           "choose_model", "calibrate_folder", "reprojection_errors", "IMAGE_SUFFIXES"]

_BASE = cv2.CALIB_RATIONAL_MODEL | cv2.CALIB_THIN_PRISM_MODEL          # the lab's 12-coefficient format
_NO_RATIONAL = cv2.CALIB_FIX_K4 | cv2.CALIB_FIX_K5 | cv2.CALIB_FIX_K6
_NO_PRISM = cv2.CALIB_FIX_S1_S2_S3_S4

#: name → (OpenCV flags, free distortion coefficients), from the fewest coefficients to the most.
DISTORTION_MODELS = {
    "k1k2": (_BASE | _NO_RATIONAL | _NO_PRISM | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST, ("k1", "k2")),
    "k1k2p1p2": (_BASE | _NO_RATIONAL | _NO_PRISM | cv2.CALIB_FIX_K3, ("k1", "k2", "p1", "p2")),
    "k1k2p1p2k3": (_BASE | _NO_RATIONAL | _NO_PRISM, ("k1", "k2", "p1", "p2", "k3")),
    "rational": (_BASE | _NO_PRISM, ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6")),
    "rational+thin-prism": (_BASE, ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4")),
}

#: File name endings read as photographs (any case).
IMAGE_SUFFIXES = (".jpg", ".jpeg", ".png", ".bmp", ".tif", ".tiff")

_CRITERIA = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 100, 1e-12)
_MIN_VIEWS = 3


@dataclass(frozen=True)
class BoardViews:
    """The photographs of a folder in which the board was found (``names``, ``images``: uint8 gray) with their
    sub-pixel inner corners ``corners`` (n, 2, N) in OpenCV's order; ``skipped``: the image files without the board.
    """

    folder: Path
    names: tuple
    images: tuple = field(repr=False)
    corners: np.ndarray = field(repr=False)
    skipped: tuple
    image_size: tuple
    pattern_size: tuple
    square_size: float

    @property
    def board(self) -> np.ndarray:
        """The inner corners in the board frame (3, N), metres."""
        return board_points(self.pattern_size, self.square_size)


@dataclass(frozen=True)
class Calibration:
    """A fitted ``camera`` (its ``model``), the board pose of every view as the camera pose [rCNn; Θnc] in the
    board frame (``poses`` (n, 6)), the per-image and overall RMS reprojection errors (px), the standard deviations
    OpenCV estimates for the intrinsics (``std``: name → σ), and the model comparison when the model was chosen."""

    camera: Camera
    model: str
    views: BoardViews = field(repr=False)
    poses: np.ndarray = field(repr=False)
    per_image_rms: np.ndarray = field(repr=False)
    rms: float
    std: dict = field(repr=False)
    comparison: tuple = field(default=(), repr=False)

    def write(self, path: str | Path) -> Path:
        """Write the camera in the lab's format (``data/camera.xml``), flags included."""
        cam = self.camera
        return write_camera_xml(path, cam.K, cam.dist_coeffs, cam.image_size, cam.flags)

    def report(self) -> str:
        """One line per photograph (its RMS reprojection error) and the overall RMS."""
        lines = [f"{name:>16}  RMS {e:.2f} px" for name, e in zip(self.views.names, self.per_image_rms)]
        return "\n".join(lines + [f"{'all':>16}  RMS {self.rms:.2f} px ({self.model}, "
                                  f"{len(self.views.names)} photographs)"])


def _image_files(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in IMAGE_SUFFIXES)


def find_boards(folder: str | Path, pattern_size: tuple[int, int], square_size: float) -> BoardViews:
    """Read every photograph of ``folder`` (by name; endings in ``IMAGE_SUFFIXES``) and find the board of
    ``pattern_size`` inner corners (nx, ny) in it. Raises ValueError when the folder is missing, holds no
    photograph, holds one that cannot be read or of another size, or when fewer than 3 show the board."""
    if not isinstance(folder, (str, Path)) or not str(folder):
        raise ValueError(f"folder must be a folder name (str or pathlib.Path), got {folder!r}")
    folder = Path(folder)
    pattern_size = _check_pattern(pattern_size)
    square_size = positive_number(square_size, "square_size")
    if not folder.is_dir():
        raise ValueError(f"folder: {folder} is not a folder")
    files = _image_files(folder)
    if not files:
        raise ValueError(f"folder: {folder} holds no photograph (file names ending in {', '.join(IMAGE_SUFFIXES)})")
    names, images, corners, skipped, size = [], [], [], [], None
    for path in files:
        image = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
        if image is None:
            raise ValueError(f"folder: {path.name} in {folder} is not a readable image")
        if size is not None and image.shape[::-1] != size:
            raise ValueError(f"folder: {path.name} is {image.shape[1]} × {image.shape[0]} px, the photographs before "
                             f"it {size[0]} × {size[1]} px: one camera, one image size")
        size = image.shape[::-1]
        try:
            corners.append(find_board_corners(image, pattern_size))
        except ChessboardNotFoundError:
            skipped.append(path.name)
            continue
        names.append(path.name)
        images.append(image)
    if len(names) < _MIN_VIEWS:
        raise ValueError(f"folder: a {pattern_size[0]} × {pattern_size[1]} chessboard (inner corners) was found in "
                         f"{len(names)} of the {len(files)} photographs in {folder}; calibration needs at least "
                         f"{_MIN_VIEWS}")
    return BoardViews(folder, tuple(names), tuple(images), np.array(corners), tuple(skipped), size,
                      pattern_size, square_size)


def _calibrate_cv(board: np.ndarray, corners: np.ndarray, image_size: tuple, flags: int) -> tuple:
    """OpenCV's fit: (K, 12 coefficients, rvecs, tvecs, σ of the 18 intrinsics)."""
    obj = [board.T.astype(np.float32)] * len(corners)
    img = [c.T.reshape(-1, 1, 2).astype(np.float32) for c in corners]
    _, K, d, rvecs, tvecs, std, _, _ = cv2.calibrateCameraExtended(obj, img, image_size, None, None, flags=flags,
                                                                     criteria=_CRITERIA)
    return K, d.ravel()[:12], rvecs, tvecs, std.ravel()


def reprojection_errors(camera: Camera, views: BoardViews, poses: np.ndarray) -> tuple[np.ndarray, float]:
    """(RMS_i per photograph, overall RMS) of the board corners projected with ``camera`` at ``poses`` (n, 6)."""
    board = views.board
    sq = np.array([np.sum((camera.world_to_pixel(board, pose) - c) ** 2) for pose, c in zip(poses, views.corners)])
    n_corners = board.shape[1]
    return np.sqrt(sq / n_corners), float(np.sqrt(sq.sum() / (n_corners * len(sq))))


def calibrate(views: BoardViews, model: str = "k1k2p1p2") -> Calibration:
    """Fit the camera of ``model`` (a key of ``DISTORTION_MODELS``) to ``views`` (from :func:`find_boards`)."""
    if not isinstance(views, BoardViews):
        raise ValueError(f"views must be a BoardViews (find_boards), got {type(views).__name__}")
    model = one_of(model, "model", DISTORTION_MODELS)
    flags, free = DISTORTION_MODELS[model]
    K, d, rvecs, tvecs, std = _calibrate_cv(views.board, views.corners, views.image_size, flags)
    camera = Camera(K, d, views.image_size, flags=flags)
    poses = np.array([pose_from_board_extrinsics(r, t) for r, t in zip(rvecs, tvecs)])
    per_image, rms = reprojection_errors(camera, views, poses)
    names = ("fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4")
    sigma = {name: float(s) for name, s in zip(names, std) if name in ("fx", "fy", "cx", "cy") + free}
    return Calibration(camera, model, views, poses, per_image, rms, sigma)


def _held_out_sq(views: BoardViews, flags: int, k: int) -> float:
    """Squared reprojection error of photograph k with the intrinsics fitted to all the others (inf when that
    lens model cannot project all of its corners)."""
    keep = np.arange(len(views.names)) != k
    K, d, _, _, _ = _calibrate_cv(views.board, views.corners[keep], views.image_size, flags)
    obj, img = views.board.T.astype(np.float64), views.corners[k].T.astype(np.float64)
    _, rvec, tvec = cv2.solvePnP(obj, img, K, d, flags=cv2.SOLVEPNP_ITERATIVE)
    camera = Camera(K, d, views.image_size, flags=flags)
    try:
        pixels = camera.world_to_pixel(views.board, pose_from_board_extrinsics(rvec, tvec))
    except ProjectionError:                  # the fitted lens folds back before the held-out corners: no prediction
        return float("inf")
    return float(np.sum((pixels - views.corners[k]) ** 2))


def compare_models(views: BoardViews, models: tuple = tuple(DISTORTION_MODELS)) -> tuple:
    """One row per model: its fitted ``rms``, ``loo_rms`` (leave-one-image-out, module docstring), the largest
    per-image RMS, the number of free coefficients, k1 with its σ, and the calibration itself."""
    if not isinstance(views, BoardViews):
        raise ValueError(f"views must be a BoardViews (find_boards), got {type(views).__name__}")
    rows = []
    for model in models:
        cal = calibrate(views, model)
        held = [_held_out_sq(views, DISTORTION_MODELS[model][0], k) for k in range(len(views.names))]
        loo = float(np.sqrt(np.sum(held) / (len(held) * views.board.shape[1])))
        rows.append({"model": model, "n_coefficients": len(DISTORTION_MODELS[model][1]), "rms": cal.rms,
                     "loo_rms": loo, "max_image_rms": float(cal.per_image_rms.max()),
                     "k1": float(cal.camera.dist_coeffs[0]), "k1_sigma": cal.std["k1"], "calibration": cal})
    return tuple(rows)


def choose_model(rows: tuple, tolerance: float = 0.01) -> str:
    """The model of ``rows`` (:func:`compare_models`) with the fewest coefficients whose leave-one-out RMS is within
    a factor 1 + ``tolerance`` of the smallest."""
    tolerance = positive_number(tolerance, "tolerance")
    best = min(r["loo_rms"] for r in rows)
    good = [r for r in rows if r["loo_rms"] <= (1 + tolerance) * best]
    return min(good, key=lambda r: r["n_coefficients"])["model"]


def calibrate_folder(folder: str | Path, pattern_size: tuple[int, int], square_size: float,
                     model: str = "auto") -> Calibration:
    """Calibrate from the chessboard photographs in ``folder`` (:func:`find_boards`). ``model``: a key of
    ``DISTORTION_MODELS``, or "auto" to compare them all and keep :func:`choose_model`'s (the comparison is kept
    in ``Calibration.comparison``)."""
    model = one_of(model, "model", ("auto", *DISTORTION_MODELS))
    views = find_boards(folder, pattern_size, square_size)
    if model != "auto":
        return calibrate(views, model)
    rows = compare_models(views)
    chosen = next(r for r in rows if r["model"] == choose_model(rows))
    cal = chosen["calibration"]
    return Calibration(cal.camera, cal.model, views, cal.poses, cal.per_image_rms, cal.rms, cal.std,
                       tuple({k: v for k, v in r.items() if k != "calibration"} for r in rows))
