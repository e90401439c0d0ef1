"""The Lab 8 association demo: features → FOV pre-selection → bundle density → SNN, the lab's console lines,
its Figure 1, and a ground-truth check that the original photograph could never have.

    result = association_demo(image, camera, state, image_name="rendered scene")   # prints like the lab
    fig, ax = plot_association(image, result)                                        # Figure 1 conventions
    table = ground_truth_check(result, camera, true_pose, true_landmarks)
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from numpy.typing import ArrayLike

from ..camera import Camera
from ..features import Features, detect_features
from ..gaussian import Gaussian
from ..state_slam import StateSLAM
from ..validation import float_array, positive_number
from .compatibility import uniform_surprisal
from .snn import snn

__all__ = ["DEMO_DETECTOR", "AssociationResult", "association_demo", "ground_truth_check", "verdicts",
           "plot_association", "figure1_legend_handles", "FIGURE1_COLORS"]

#: Detector settings of the workbook demo: Shi–Tomasi, the lab's cap of 10 000, 1 % quality level, a 5 × 5
#: window; the response is smoothed (σ = 1 px) and non-maximum suppressed (7 × 7) so that one corner gives
#: one feature at the pixel nearest to it (the lab's detector had no suppression).
DEMO_DETECTOR = dict(max_features=10000, method="shi-tomasi", threshold=0.01, block_size=5, nms_radius=3,
                     smoothing=1.0)

#: Contrast of the image under Figure 1's markers: 0.6 lightens black to 40 % grey (white stays white), so the
#: dark-red feature dots stand out on the dark texture as well as on the light.
IMAGE_CONTRAST = 0.6

#: Figure 1 colours (RGB in [0, 1]).
FIGURE1_COLORS = {
    "feature": (127 / 255, 0.0, 0.0),        # dark red dots: all detected features
    "associated": (0.0, 0.0, 1.0),           # blue '+', ellipse and label: landmark associated
    "unassociated": (1.0, 0.0, 0.0),         # bright red: landmark not associated
    "match": (0.0, 1.0, 0.0),                # green '×' on matched features
    "truth": (0.0, 0.0, 0.0),                # workbook addition: black circle at a landmark's true pixel
    "wrong": (1.0, 0.55, 0.0),               # workbook addition: orange dashes, wrong pairing → truth
}


@dataclass
class AssociationResult:
    """Outcome of :func:`association_demo`: the detected ``features``; ``in_fov`` (n_L,) the FOV pre-selection;
    ``idx_landmarks`` the selected landmarks; ``idx`` (n_sel,) their feature columns or −1; the ``surprisal``; the
    selection's predicted bundle ``density`` (None if nothing was selected); the console ``lines``."""

    features: Features
    in_fov: np.ndarray
    idx_landmarks: np.ndarray
    idx: np.ndarray
    surprisal: float
    density: Gaussian | None
    sU: float
    lines: list = field(default_factory=list)

    @property
    def text(self) -> str:
        return "\n".join(self.lines) + "\n"

    @property
    def n_associated(self) -> int:
        return int(np.sum(self.idx >= 0))

    def landmark_density(self, k: int) -> Gaussian:
        """Predicted feature density (size 2, no noise) of the k-th selected landmark: the bundle marginal."""
        return self.density.marginal([2 * k, 2 * k + 1])


def _console_lines(image_name, m, in_fov, idx_landmarks, idx, s, Y, surprisal_format) -> list[str]:
    """The lab's console output: "<m> features found in <image>", one "Landmark j is [NOT ]expected to be within
    camera FOV" line per landmark, "Surprisal = <s>", one line per selected landmark, a blank line."""
    lines = [f"{m} features found in {image_name}"]
    lines += [f"Landmark {j} is {'' if inside else 'NOT '}expected to be within camera FOV" for j, inside in
              enumerate(in_fov)]
    if idx_landmarks.size == 0:
        return lines + ["No landmark is expected to be within camera FOV: nothing to associate.", ""]
    lines.append(f"Surprisal = {s:{surprisal_format}}")
    for j, i in zip(idx_landmarks, idx):
        if i < 0:
            lines.append(f"No feature associated with landmark {j}.")
        else:
            x, y = (int(round(v)) for v in Y[:, i])
            lines.append(f"Feature {i} located at [{x} {y}] in image matches landmark {j}.")
    return lines + [""]


def association_demo(image: np.ndarray | None, camera: Camera, state: StateSLAM, image_name: str = "rendered scene",
                     features: Features | None = None, detector: dict | None = None, n_sigma: float = 3.0,
                     enforce_joint_compatibility: bool = False, verbose: bool = True,
                     surprisal_format: str = ".6g", noise: Gaussian | None = None) -> AssociationResult:
    """Run the lab's association demo on one image and (by default) print its console output.

    1. features = detect_features(image, **detector) (default :data:`DEMO_DETECTOR`), unless ``features`` is
       given; Y = features.Y.
    2. FOV pre-selection: landmark j is selected iff its **mean** position is within the camera's FOV at the
       state's mean camera pose (``Camera.is_world_within_fov``), in ascending j.
    3. density = state.predict_feature_bundle_density(camera, selection, noise) (the lab: no measurement noise;
       ``noise`` a zero-mean size-2 Gaussian of every feature's pixel error).
    4. (idx, s) = snn(density, Y, s_U, n_sigma, enforce_joint_compatibility), s_U = log W + log H.

    With no landmark in view the selection is empty, the surprisal 0, and the output says so.
    ``surprisal_format``: the format of the printed surprisal, ".6g" as the lab printed it; a coarser one (".1f")
    keeps the line identical across machines whose last-bit differences move the surprisal slightly.
    """
    if not isinstance(state, StateSLAM):
        raise ValueError(f"state must be a helpers.state_slam.StateSLAM, got {type(state).__name__}")
    if features is None:
        features = detect_features(image, **(DEMO_DETECTOR if detector is None else detector))
    elif not isinstance(features, Features):
        raise ValueError(f"features must be a helpers.features.Features, got {type(features).__name__}")
    Y = features.Y
    pose = state.camera_pose(camera)                       # checks camera
    in_fov = np.asarray(camera.is_world_within_fov(state.landmark_positions(), pose), dtype=bool).reshape(-1)
    idx_landmarks = np.flatnonzero(in_fov)
    sU = uniform_surprisal(camera.image_size)
    density, idx, s = None, np.zeros(0, dtype=np.intp), 0.0
    if idx_landmarks.size:
        density = state.predict_feature_bundle_density(camera, idx_landmarks, noise=noise)
        idx, s = snn(density, Y, sU, n_sigma=n_sigma, enforce_joint_compatibility=enforce_joint_compatibility)
    lines = _console_lines(image_name, len(features), in_fov, idx_landmarks, idx, s, Y, surprisal_format)
    result = AssociationResult(features, in_fov, idx_landmarks, idx, float(s), density, sU, lines)
    if verbose:
        print(result.text, end="")
    return result


def ground_truth_check(result: AssociationResult, camera: Camera, true_pose: ArrayLike, true_landmarks: ArrayLike,
                       tol: float = 2.0) -> list[dict]:
    """Compare the association with the truth the renderer knows: the true pixel of landmark j is
    t_j = world_to_pixel(true_landmarks[:, j], true_pose); :func:`verdicts` does the rest."""
    if not isinstance(result, AssociationResult):
        raise ValueError(f"result must be an AssociationResult (association_demo), got {type(result).__name__}")
    true_landmarks = float_array(true_landmarks, "true_landmarks")
    if true_landmarks.shape != (3, result.in_fov.size):
        raise ValueError(f"true_landmarks must have shape (3, {result.in_fov.size}) (one column per landmark of the "
                         f"state), got {true_landmarks.shape}")
    return verdicts(result, camera.world_to_pixel(true_landmarks, true_pose), tol)


def verdicts(result: AssociationResult, true_pixels: ArrayLike, tol: float = 2.0) -> list[dict]:
    """Score the association against each landmark's true pixel t_j (``true_pixels`` (2, n_L), one column per
    landmark of the state). For every selected landmark j: the detected feature nearest to t_j (index and
    distance), and a verdict:

      "correct"       associated with the nearest feature, which lies within ``tol`` px of t_j;
      "correct null"  unassociated, and no feature lies within ``tol`` px of t_j (the detector found nothing);
      "missed"        unassociated although a feature lies within ``tol`` px of t_j;
      "wrong"         associated with another feature (or the nearest one is farther than ``tol``).

    Returns one dict per selected landmark (selection order).
    """
    if not isinstance(result, AssociationResult):
        raise ValueError(f"result must be an AssociationResult (association_demo), got {type(result).__name__}")
    true_pixels = float_array(true_pixels, "true_pixels")
    if true_pixels.shape != (2, result.in_fov.size) or not np.all(np.isfinite(true_pixels)):
        raise ValueError(f"true_pixels must be a finite (2, {result.in_fov.size}) array (one column per landmark of "
                         f"the state), got shape {true_pixels.shape}")
    tol = positive_number(tol, "tol")
    Y = result.features.Y
    rows = []
    for j, i in zip(result.idx_landmarks, result.idx):
        t = true_pixels[:, j]
        d = np.hypot(Y[0] - t[0], Y[1] - t[1])
        nearest, dist = (int(np.argmin(d)), float(np.min(d))) if d.size else (-1, np.inf)
        if i >= 0:
            verdict = "correct" if (i == nearest and dist <= tol) else "wrong"
        else:
            verdict = "missed" if dist <= tol else "correct null"
        rows.append({"landmark": int(j), "true_pixel": t, "nearest": nearest, "distance": dist,
                     "associated": int(i), "verdict": verdict})
    return rows


def _shown_image(image: np.ndarray, image_scale: float, window: ArrayLike | None) -> tuple:
    """The image (or its window) to draw, its extent in full-size pixel coordinates, and the view limits."""
    import cv2

    if image.dtype != np.uint8 or image.ndim not in (2, 3) or image.size == 0:
        raise ValueError(f"image must be a uint8 gray or BGR image, got dtype {image.dtype}, shape {image.shape}")
    if image_scale > 1:
        raise ValueError(f"image_scale must lie in (0, 1], got {image_scale!r}")
    H, W = image.shape[:2]
    if window is None:
        shown = image if image_scale == 1 else cv2.resize(image, None, fx=image_scale, fy=image_scale,
                                                          interpolation=cv2.INTER_AREA)
        return shown, (-0.5, W - 0.5, H - 0.5, -0.5), (-0.5, W - 0.5, -0.5, H - 0.5)
    win = float_array(window, "window")
    if win.shape != (4,) or not (win[0] < win[1] and win[2] < win[3]):
        raise ValueError(f"window must be (x0, x1, y0, y1) with x0 < x1 and y0 < y1, got {window!r}")
    x0, x1, y0, y1 = win.tolist()
    c0, c1 = max(int(np.floor(x0 + 0.5)), 0), min(int(np.ceil(x1 + 0.5)), W)
    r0, r1 = max(int(np.floor(y0 + 0.5)), 0), min(int(np.ceil(y1 + 0.5)), H)
    if c0 >= c1 or r0 >= r1:
        raise ValueError(f"window {window!r} does not overlap the image")
    return image[r0:r1, c0:c1], (c0 - 0.5, c1 - 0.5, r1 - 0.5, r0 - 0.5), (x0, x1, y0, y1)


def _halo(width: float = 3.0) -> list:
    """A white outline under a line or marker, so it stays readable on dark and on light texture."""
    import matplotlib.patheffects as pe

    return [pe.withStroke(linewidth=width, foreground="white")]


def _ellipse_path(dens, image_size, n_sigma) -> np.ndarray:
    """The n_σ ellipse (2, 101) with NaN where a segment leaves the image, and a NaN column to end it."""
    W, H = image_size
    E = dens.confidence_ellipse(n_sigma, 100)
    inside = (E[0] >= -0.5) & (E[0] <= W - 0.5) & (E[1] >= -0.5) & (E[1] <= H - 0.5)
    E = E.copy()
    E[:, 1:][:, ~(inside[:-1] & inside[1:])] = np.nan      # break the curve where a segment leaves the image
    return np.hstack([E, np.full((2, 1), np.nan)])


def _draw_landmarks(ax, result, image_size, n_sigma) -> None:
    """Per selected landmark: '+' at the predicted mean, the n_σ ellipse and the label j, blue if associated and
    bright red if not (one line per colour for the ellipses and one for the '+', so many landmarks draw fast)."""
    for associated in (True, False):
        colour = FIGURE1_COLORS["associated" if associated else "unassociated"]
        ks = [k for k, i in enumerate(result.idx) if (i >= 0) == associated]
        if not ks:
            continue
        dens = [result.landmark_density(k) for k in ks]
        E = np.hstack([_ellipse_path(d, image_size, n_sigma) for d in dens])
        mu = np.array([d.mean for d in dens]).T
        ax.plot(E[0], E[1], "-", color=colour, linewidth=1.6, zorder=4, path_effects=_halo(3.2))
        ax.plot(mu[0], mu[1], "+", color=colour, markersize=12, markeredgewidth=1.8, linestyle="none", zorder=5,
                path_effects=_halo())
        for k, (x, y) in zip(ks, mu.T):
            ax.annotate(str(result.idx_landmarks[k]), (x, y), xytext=(5, 4), textcoords="offset points",
                        color=colour, fontsize=11, fontweight="bold", annotation_clip=True, zorder=7,
                        path_effects=_halo(2.5))      # beside the '+'


def _draw_truth(ax, rows, Y) -> None:
    """True landmark pixels (hollow circles) and, for each wrong pairing, a dashed line from the chosen feature
    to the truth (one line each)."""
    t = np.array([np.asarray(r["true_pixel"], dtype=float) for r in rows]).reshape(-1, 2).T
    ax.plot(t[0], t[1], "o", mfc="none", mec=FIGURE1_COLORS["truth"], markersize=9, markeredgewidth=1.6,
            linestyle="none", zorder=6, path_effects=_halo())
    wrong = [(Y[:, r["associated"]], np.asarray(r["true_pixel"], dtype=float)) for r in rows
             if r["verdict"] == "wrong" and r["associated"] >= 0]
    if wrong:
        seg = np.hstack([np.column_stack([y, t, [np.nan, np.nan]]) for y, t in wrong])
        ax.plot(seg[0], seg[1], "--", color=FIGURE1_COLORS["wrong"], linewidth=2.0, zorder=6, path_effects=_halo())


def figure1_legend_handles(truth: bool = False) -> list[Line2D]:
    """Legend entries of :func:`plot_association` (with ``truth`` also the true landmark pixel and the
    wrong-pairing line)."""
    c = FIGURE1_COLORS
    handles = [
        Line2D([], [], ls="none", marker=".", color=c["feature"], markersize=7,
               label="feature not associated with any landmark"),
        Line2D([], [], color=c["associated"], marker="+", markersize=10, mew=1.8,
               label="predicted landmark + 3σ region, associated"),
        Line2D([], [], color=c["unassociated"], marker="+", markersize=10, mew=1.8,
               label="predicted landmark + 3σ region, not associated"),
        Line2D([], [], ls="none", marker="x", color=c["match"], markersize=9, mew=1.8,
               label="feature associated with a landmark"),
    ]
    if truth:
        handles += [
            Line2D([], [], ls="none", marker="o", mfc="none", mec=c["truth"], markersize=9, mew=1.6,
                   label="true landmark pixel"),
            Line2D([], [], ls="--", color=c["wrong"], lw=2.0, label="wrong pairing: chosen feature → truth"),
        ]
    return handles


def plot_association(image: np.ndarray, result: AssociationResult, ax: Axes | None = None, n_sigma: float = 3.0,
                     title: str | None = None, image_scale: float = 0.5, window: ArrayLike | None = None,
                     truth: list[dict] | None = None, legend: bool = True) -> tuple[Figure, Axes]:
    """Figure 1 of the lab over the image (a uint8 gray or BGR image).

    All features: dark-red dots *under* everything else, over the image shown at 60 % contrast (lightened
    towards white) so that they stay visible on dark texture. Each selected landmark: '+' at the predicted mean
    and its n_σ ellipse, blue if associated and bright red if not, labelled with j; matched features: green '×'.
    ``truth``: rows of :func:`ground_truth_check`: adds the true landmark pixels and a dashed orange line from
    every wrongly chosen feature to the truth. ``legend``: a legend below the axes (in a grid pass False and use
    :func:`figure1_legend_handles`). The image is shown resized by ``image_scale`` (the lab's 0.5; coordinates stay
    full-size pixels); ``window = (x0, x1, y0, y1)`` shows only that part, at full size. Returns (fig, ax).
    """
    import matplotlib.pyplot as plt

    if not isinstance(result, AssociationResult):
        raise ValueError(f"result must be an AssociationResult (association_demo), got {type(result).__name__}")
    image = np.asarray(image)
    shown, extent, (x0, x1, y0, y1) = _shown_image(image, positive_number(image_scale, "image_scale"), window)
    fig, ax = plt.subplots(figsize=(9.6, 7.2)) if ax is None else (ax.figure, ax)
    if shown.ndim == 2:                                 # black shown as 40 % grey, white stays white
        ax.imshow(shown, cmap="gray", vmin=-255 * (1 - IMAGE_CONTRAST) / IMAGE_CONTRAST, vmax=255, extent=extent,
                  interpolation="antialiased", zorder=0)
    else:
        light = (255 - IMAGE_CONTRAST * (255 - shown[..., ::-1].astype(float))).astype(np.uint8)   # BGR → RGB
        ax.imshow(light, extent=extent, zorder=0)
    Y = result.features.Y
    vis = (Y[0] >= x0) & (Y[0] <= x1) & (Y[1] >= y0) & (Y[1] <= y1)
    zoom = window is not None
    ax.plot(Y[0, vis], Y[1, vis], ".", color=FIGURE1_COLORS["feature"], markersize=4.5 if zoom else 2.8,
            alpha=0.9, markeredgewidth=0, linestyle="none", zorder=1)
    _draw_landmarks(ax, result, (image.shape[1], image.shape[0]), n_sigma)
    matched = result.idx[result.idx >= 0]
    ax.plot(Y[0, matched], Y[1, matched], "x", color=FIGURE1_COLORS["match"], markersize=11, markeredgewidth=2.0,
            linestyle="none", zorder=5, path_effects=_halo())
    if truth is not None:
        _draw_truth(ax, truth, Y)
    ax.set_xlim(x0, x1)
    ax.set_ylim(y1, y0)
    ax.set_aspect("equal")
    ax.grid(False)
    if zoom:                                        # a zoom window: its size is given by the caller's title
        ax.set_xticks([])
        ax.set_yticks([])
    else:
        ax.set(xlabel="x [px]", ylabel="y [px]")
    if title:
        ax.set_title(title)
    if legend:
        ax.legend(handles=figure1_legend_handles(truth is not None), loc="upper center",
                  bbox_to_anchor=(0.5, -0.09), ncol=2, fontsize=8, frameon=False)  # below the x label
    return fig, ax
