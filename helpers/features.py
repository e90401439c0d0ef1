"""Point features (corners) for data association — Lab 8 task 3a.

With the image gradient (I_x, I_y) and a ``block_size`` × ``block_size`` window w, the structure tensor is

    M = Σ_w [[I_x², I_x I_y], [I_x I_y, I_y²]]      with eigenvalues λ1 ≥ λ2 ≥ 0,

and the corner response (OpenCV, over the whole image) is

    Shi–Tomasi:  R = λ2                                          (cv2.cornerMinEigenVal)
    Harris:      R = det M − k (tr M)² = λ1λ2 − k(λ1 + λ2)²      (cv2.cornerHarris)

A feature is a pixel with R > ``threshold`` · max(R), optionally after Gaussian smoothing of R and non-maximum
suppression (the lab had neither). Features are sorted by descending score (ties in raster order) and capped at
``max_features``. Coordinates are integer pixels: x to the right, y down, origin at the top-left pixel.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .validation import finite_number, integer, nonnegative_number, one_of

__all__ = ["Features", "corner_response", "detect_features", "METHODS"]

METHODS = ("shi-tomasi", "harris")


@dataclass(frozen=True)
class Features:
    """Detected point features, sorted by descending ``score``.

    ``score``, ``x``, ``y`` are arrays of equal length m; ``Y`` is the lab's 2 × m measurement matrix
    (column i = (x_i, y_i) as floats).
    """

    score: np.ndarray
    x: np.ndarray
    y: np.ndarray
    method: str = "shi-tomasi"

    def __post_init__(self) -> None:
        arrays = (self.score, self.x, self.y)
        if not all(isinstance(a, np.ndarray) and a.ndim == 1 for a in arrays) or len({a.size for a in arrays}) != 1:
            raise ValueError(f"score, x and y must be 1-D arrays of one length, got shapes "
                             f"{[np.shape(a) for a in arrays]}")
        if self.method not in METHODS:
            raise ValueError(f"method must be one of {METHODS}, got {self.method!r}")

    def __len__(self) -> int:
        return int(self.score.shape[0])

    @property
    def Y(self) -> np.ndarray:
        """Features as the 2 × m matrix Y = [y_1 … y_m] of pixel coordinates (float)."""
        return np.vstack([self.x, self.y]).astype(float)

    def __repr__(self) -> str:
        return f"Features(m={len(self)}, method={self.method!r})"


def _as_gray_float(image: np.ndarray) -> np.ndarray:
    if not isinstance(image, np.ndarray):
        raise ValueError(f"image must be a numpy array, got {type(image).__name__}")
    if image.ndim == 3 and image.shape[2] in (3, 4):
        if image.dtype != np.uint8:
            raise ValueError(f"a colour image must be uint8 BGR(A), got dtype {image.dtype}")
        code = cv2.COLOR_BGR2GRAY if image.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        image = cv2.cvtColor(image, code)
    if image.ndim != 2:
        raise ValueError(f"image must be 2-D gray (H, W) or BGR (H, W, 3), got shape {image.shape}")
    if image.shape[0] < 3 or image.shape[1] < 3:
        raise ValueError(f"image must be at least 3 × 3 pixels, got shape {image.shape}")
    if image.dtype == np.uint8:
        return image.astype(np.float32) / 255.0
    if image.dtype in (np.float32, np.float64):
        if not np.all(np.isfinite(image)):
            raise ValueError("image must not contain NaN or inf")
        return image.astype(np.float32)
    raise ValueError(f"image dtype must be uint8, float32 or float64, got {image.dtype}")


def corner_response(image: np.ndarray, method: str = "shi-tomasi", block_size: int = 5, aperture_size: int = 3,
                    harris_k: float = 0.04) -> np.ndarray:
    """Corner response map R (float32, same height × width as ``image``), computed by OpenCV.

    ``image`` is uint8 (scaled to [0, 1]) or float gray, or uint8 BGR. ``method`` is ``"shi-tomasi"``
    (R = λ2, the smaller eigenvalue of the structure tensor) or ``"harris"`` (R = det M − k (tr M)²).
    """
    one_of(method, "method", METHODS)
    block_size = integer(block_size, "block_size", minimum=2)
    if isinstance(aperture_size, bool) or aperture_size not in (1, 3, 5, 7):
        raise ValueError(f"aperture_size must be 1, 3, 5 or 7, got {aperture_size!r}")
    if not 0.0 < finite_number(harris_k, "harris_k") < 0.25:
        raise ValueError(f"harris_k must lie in (0, 0.25), got {harris_k!r}")
    gray = _as_gray_float(image)
    if block_size > min(gray.shape):
        raise ValueError(f"block_size must not exceed the image's smaller side ({min(gray.shape)} px): the "
                         f"window must fit in the image, got {block_size}")
    if method == "shi-tomasi":
        return cv2.cornerMinEigenVal(gray, int(block_size), ksize=int(aperture_size))
    return cv2.cornerHarris(gray, int(block_size), int(aperture_size), float(harris_k))


def detect_features(image: np.ndarray, max_features: int = 10000, method: str = "shi-tomasi", threshold: float = 0.01,
                    block_size: int = 5, aperture_size: int = 3, harris_k: float = 0.04,
                    nms_radius: int = 0, smoothing: float = 0.0, border: int = 4) -> Features:
    """Detect corner features (Lab 8 task 3a): pixels with a strong corner response R, strongest first.

    Parameters
    ----------
    image : (H, W) uint8/float gray or (H, W, 3) uint8 BGR image.
    max_features : keep at most this many features (the strongest ones); an integer ≥ 1.
    method : ``"shi-tomasi"`` (minimum eigenvalue) or ``"harris"``.
    threshold : relative quality level in [0, 1): a pixel qualifies when R > threshold · max(R) and R > 0,
        max(R) taken over the pixels at least ``border`` from the image edge. 0 keeps every positive response.
    block_size, aperture_size, harris_k : the corner response's window size, Sobel size and Harris k
        (``corner_response(image, method, block_size, aperture_size, harris_k)`` computes R and checks them).
    nms_radius : 0 for none (the lab); r > 0 keeps only pixels whose R is the maximum of R over their
        (2r + 1) × (2r + 1) neighbourhood in the image (clipped at the edge; equal neighbours all stay).
    smoothing : σ (px) of a Gaussian blur of R before anything else, ``cv2.GaussianBlur(R, (0, 0), smoothing)``
        (0 = none, the lab). The box-window response of a corner is a plateau about block_size wide; smoothing
        turns it into a peak, so non-maximum suppression keeps one pixel per corner.
    border : ignore the pixels fewer than ``border`` from the image edge (the response there is unreliable).

    Returns
    -------
    Features with ``score`` (R at the pixel, after smoothing), ``x``, ``y`` (integer pixel coordinates: x to the
    right, y down) sorted by descending score, ties in raster order (y, then x), at most ``max_features``.
    An image without corners (e.g. constant) gives an empty ``Features`` (m = 0), not an error.

    Raises
    ------
    ValueError naming ``max_features``, ``threshold``, ``nms_radius``, ``smoothing`` (negative) or ``border``
    (leaving no pixel), and, through corner_response, ``image``, ``method``, ``block_size``, ``aperture_size``
    or ``harris_k``.
    """
    max_features = integer(max_features, "max_features", minimum=1)
    if not 0.0 <= finite_number(threshold, "threshold") < 1.0:
        raise ValueError(f"threshold must be a relative level in [0, 1), got {threshold!r}")
    nms_radius = integer(nms_radius, "nms_radius", minimum=0)
    border = integer(border, "border", minimum=0)
    smoothing = nonnegative_number(smoothing, "smoothing")
    R = corner_response(image, method, block_size, aperture_size, harris_k)
    if smoothing > 0:
        R = cv2.GaussianBlur(R, (0, 0), smoothing)
    h, w = R.shape
    if 2 * border >= min(h, w):
        raise ValueError(f"border={border} leaves no pixels in an image of shape {(h, w)}")
    mask = np.zeros((h, w), dtype=bool)
    mask[border:h - border, border:w - border] = True
    rmax = float(R[mask].max())
    if not rmax > 0.0:
        return Features(np.zeros(0, np.float32), np.zeros(0, int), np.zeros(0, int), method)
    mask &= R > max(threshold * rmax, 0.0)
    if nms_radius > 0:
        kernel = np.ones((2 * nms_radius + 1, 2 * nms_radius + 1), np.uint8)
        mask &= R >= cv2.dilate(R, kernel)
    ys, xs = np.nonzero(mask)                      # raster order
    score = R[ys, xs]
    order = np.argsort(-score, kind="stable")[:max_features]
    return Features(score[order], xs[order].astype(int), ys[order].astype(int), method)
