"""The Lab 8 association demo: features → FOV pre-selection → bundle density → SNN, the lab's
console lines, its Figure 1, and a ground-truth check that the original photograph could never have.

    result = association_demo(image, camera, state, image_name="rendered scene")   # prints like the lab
    fig, ax = plot_association(image, result)                                        # Figure 1 conventions
    table = ground_truth_check(result, camera, true_pose, true_landmarks)

Console format: "<m> features found in <image name>", one "Landmark j is [NOT ]expected to be
within camera FOV" line per landmark, "Surprisal = <s>", one line per selected landmark
("No feature associated with landmark j." or "Feature i located at [x y] in image matches landmark j."),
then a blank line.
"""
from __future__ import annotations

import inspect
from dataclasses import dataclass, field

import numpy as np

from ..camera import Camera
from ..features import Features, detect_features
from ..state_slam import StateSLAM
from ..validation import finite_number, float_array
from .compatibility import uniform_surprisal
from .snn import snn

__all__ = [
    "DEMO_DETECTOR",
    "AssociationResult",
    "association_demo",
    "ground_truth_check",
    "plot_association",
    "figure1_legend_handles",
    "FIGURE1_COLORS",
]

#: Detector settings of the workbook demo: Shi–Tomasi, the lab's cap of 10 000, 1 % quality level, a 5 × 5
#: window; the response is smoothed (σ = 1 px) and non-maximum suppressed (7 × 7) so that one corner gives
#: one feature at the pixel nearest to it (the lab's detector had no suppression).
DEMO_DETECTOR = dict(max_features=10000, method="shi-tomasi", threshold=0.01, block_size=5, nms_radius=3,
                     smoothing=1.0)

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
    """Outcome of :func:`association_demo`.

    features : the detected Features (Y = features.Y). in_fov : (n_L,) bool, FOV pre-selection of each
    landmark. idx_landmarks : state indices of the selected landmarks (ascending). idx : (n_sel,) feature
    column per selected landmark or −1. surprisal : total surprisal of the association. density : the
    predicted bundle density of the selection (None if nothing was selected). lines : the console lines.
    """

    image_name: str
    features: Features
    in_fov: np.ndarray
    idx_landmarks: np.ndarray
    idx: np.ndarray
    surprisal: float
    density: object
    sU: float
    enforce_joint_compatibility: bool
    lines: list = field(default_factory=list)

    @property
    def text(self) -> str:
        return "\n".join(self.lines) + "\n"

    @property
    def matches(self) -> dict:
        """{landmark j: feature i or −1} for the selected landmarks."""
        return {int(j): int(i) for j, i in zip(self.idx_landmarks, self.idx)}

    @property
    def n_associated(self) -> int:
        return int(np.sum(self.idx >= 0))

    def landmark_density(self, k: int):
        """Predicted feature density (size 2, no noise) of the k-th selected landmark: the bundle marginal."""
        return self.density.marginal([2 * k, 2 * k + 1])


def _console_lines(image_name, m, in_fov, idx_landmarks, idx, s, Y, surprisal_format=".6g"):
    lines = [f"{m} features found in {image_name}"]
    for j, inside in enumerate(in_fov):
        lines.append(f"Landmark {j} is {'' if inside else 'NOT '}expected to be within camera FOV")
    if idx_landmarks.size == 0:
        lines.append("No landmark is expected to be within camera FOV: nothing to associate.")
        lines.append("")
        return lines
    lines.append(f"Surprisal = {s:{surprisal_format}}")
    for j, i in zip(idx_landmarks, idx):
        if i < 0:
            lines.append(f"No feature associated with landmark {j}.")
        else:
            x, y = (int(round(v)) for v in Y[:, i])
            lines.append(f"Feature {i} located at [{x} {y}] in image matches landmark {j}.")
    lines.append("")
    return lines


def association_demo(image, camera, state, image_name: str = "rendered scene", features: Features | None = None,
                     detector: dict | None = None, n_sigma: float = 3.0,
                     enforce_joint_compatibility: bool = False, verbose: bool = True,
                     surprisal_format: str = ".6g") -> AssociationResult:
    """Run the lab's association demo on one image and (by default) print its console output.

    1. features = detect_features(image, **detector) (default :data:`DEMO_DETECTOR`), unless ``features``
       is given; Y = features.Y.
    2. FOV pre-selection: landmark j is selected iff its **mean** position is within the camera's FOV at
       the state's mean camera pose (``Camera.is_world_within_fov``); selection in ascending j.
    3. density = state.predict_feature_bundle_density(camera, selection) (no measurement noise).
    4. (idx, s) = snn(density, Y, s_U, n_sigma, enforce_joint_compatibility), s_U = log W + log H.

    With no landmark in view the result has an empty selection, surprisal 0 and says so (no error).
    ``surprisal_format`` is the format spec of the printed surprisal: ".6g" (six significant digits) as the
    lab's program printed it; a coarser one (e.g. ".1f") keeps the printed line identical across machines
    whose last-bit floating-point differences move the surprisal slightly.
    """
    _check_demo_arguments(camera, state, image_name, detector, surprisal_format)
    if features is None:
        features = detect_features(image, **(DEMO_DETECTOR if detector is None else detector))
    elif not isinstance(features, Features):
        raise ValueError(f"features must be a helpers.features.Features, got {type(features).__name__}")
    Y = features.Y
    pose = state.camera_pose(camera)
    in_fov = np.asarray(camera.is_world_within_fov(state.landmark_positions(), pose), dtype=bool).reshape(-1)
    idx_landmarks = np.flatnonzero(in_fov)
    sU = uniform_surprisal(camera.image_size)
    if idx_landmarks.size:
        density = state.predict_feature_bundle_density(camera, idx_landmarks)
        idx, s = snn(density, Y, sU, n_sigma=n_sigma, enforce_joint_compatibility=enforce_joint_compatibility)
    else:
        density, idx, s = None, np.zeros(0, dtype=np.intp), 0.0
    lines = _console_lines(image_name, len(features), in_fov, idx_landmarks, idx, s, Y, surprisal_format)
    result = AssociationResult(image_name, features, in_fov, idx_landmarks, idx, float(s), density, sU,
                               bool(enforce_joint_compatibility), lines)
    if verbose:
        print(result.text, end="")
    return result


def _check_demo_arguments(camera, state, image_name, detector, surprisal_format):
    """ValueError naming the first bad argument of :func:`association_demo`."""
    if not isinstance(camera, Camera):
        raise ValueError(f"camera must be a helpers.camera.Camera, got {type(camera).__name__}")
    if not isinstance(state, StateSLAM):
        raise ValueError(f"state must be a helpers.state_slam.StateSLAM, got {type(state).__name__}")
    if not isinstance(image_name, str):
        raise ValueError(f"image_name must be a string, got {type(image_name).__name__}")
    if detector is not None:
        known = set(inspect.signature(detect_features).parameters) - {"image"}
        if not isinstance(detector, dict) or not set(detector) <= known:
            raise ValueError(f"detector must be a dict of detect_features options {sorted(known)}, got {detector!r}")
    try:
        format(0.0, surprisal_format)
    except (TypeError, ValueError):
        raise ValueError(f"surprisal_format must be a float format spec such as '.6g', got {surprisal_format!r}") \
            from None


def ground_truth_check(result: AssociationResult, camera, true_pose, true_landmarks, tol: float = 2.0):
    """Compare the association with the truth the renderer knows.

    For every selected landmark j: its true pixel t_j = world_to_pixel(true_landmarks[:, j], true_pose), the
    detected feature nearest to t_j (index and distance), and a verdict:

      "correct"       associated with the nearest feature, which lies within ``tol`` px of t_j;
      "correct null"  unassociated, and no feature lies within ``tol`` px of t_j (the detector found nothing);
      "missed"        unassociated although a feature lies within ``tol`` px of t_j;
      "wrong"         associated with another feature (or the nearest one is farther than ``tol``).

    Returns a list of dicts (one per selected landmark, selection order).
    """
    if not isinstance(result, AssociationResult):
        raise ValueError(f"result must be an AssociationResult (association_demo), got {type(result).__name__}")
    if not isinstance(camera, Camera):
        raise ValueError(f"camera must be a helpers.camera.Camera, got {type(camera).__name__}")
    true_landmarks = float_array(true_landmarks, "true_landmarks")
    n_l = result.in_fov.size
    if true_landmarks.shape != (3, n_l) or not np.all(np.isfinite(true_landmarks)):
        raise ValueError(f"true_landmarks must be a finite (3, {n_l}) array (one column per landmark of the state), "
                         f"got shape {true_landmarks.shape}")
    if not finite_number(tol, "tol") > 0:
        raise ValueError(f"tol must be a positive number of pixels, got {tol!r}")
    Y = result.features.Y
    rows = []
    for j, i in zip(result.idx_landmarks, result.idx):
        t = camera.world_to_pixel(true_landmarks[:, j], np.asarray(true_pose, dtype=float))
        if Y.shape[1]:
            d = np.hypot(Y[0] - t[0], Y[1] - t[1])
            nearest, dist = int(np.argmin(d)), float(np.min(d))
        else:
            nearest, dist = -1, np.inf
        there = dist <= tol
        if i >= 0:
            verdict = "correct" if (i == nearest and there) else "wrong"
        else:
            verdict = "missed" if there else "correct null"
        rows.append({"landmark": int(j), "true_pixel": t, "nearest": nearest, "distance": dist,
                     "associated": int(i), "verdict": verdict})
    return rows


def _shown_image(image, image_scale, window):
    """The image (or its window) to draw and its extent in full-size pixel coordinates; the view limits."""
    import cv2

    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim not in (2, 3) or (image.ndim == 3 and image.shape[2] != 3) \
            or image.size == 0:
        raise ValueError(f"image must be a uint8 gray or BGR image, got dtype {image.dtype}, shape {image.shape}")
    if not 0 < finite_number(image_scale, "image_scale") <= 1:
        raise ValueError(f"image_scale must lie in (0, 1], got {image_scale!r}")
    H, W = image.shape[:2]
    if window is None:
        shown = image if image_scale == 1 else cv2.resize(image, None, fx=image_scale, fy=image_scale,
                                                          interpolation=cv2.INTER_AREA)
        return shown, (-0.5, W - 0.5, H - 0.5, -0.5), (-0.5, W - 0.5, -0.5, H - 0.5)
    win = float_array(window, "window")
    if win.shape != (4,) or not np.all(np.isfinite(win)):
        raise ValueError(f"window must be four finite numbers (x0, x1, y0, y1), got {window!r}")
    x0, x1, y0, y1 = (float(v) for v in win)
    if not (x0 < x1 and y0 < y1):
        raise ValueError(f"window must be (x0, x1, y0, y1) with x0 < x1 and y0 < y1, got {window!r}")
    c0, c1 = max(int(np.floor(x0 + 0.5)), 0), min(int(np.ceil(x1 + 0.5)), W)
    r0, r1 = max(int(np.floor(y0 + 0.5)), 0), min(int(np.ceil(y1 + 0.5)), H)
    if c0 >= c1 or r0 >= r1:
        raise ValueError(f"window {window!r} does not overlap the image")
    return image[r0:r1, c0:c1], (c0 - 0.5, c1 - 0.5, r1 - 0.5, r0 - 0.5), (x0, x1, y0, y1)


def _halo(width=3.0):
    """A white outline under a line or marker, so it stays readable on dark and on light texture."""
    import matplotlib.patheffects as pe

    return [pe.withStroke(linewidth=width, foreground="white")]


def _draw_landmark(ax, dens, j, colour, image_size, n_sigma):
    """'+' at the predicted mean, the 3σ ellipse (segments with both ends inside the image) and the label."""
    W, H = image_size
    E = dens.confidence_ellipse(n_sigma, 100)
    inside = (E[0] >= -0.5) & (E[0] <= W - 0.5) & (E[1] >= -0.5) & (E[1] <= H - 0.5)
    seg_ok = inside[:-1] & inside[1:]
    Ex, Ey = E[0].copy(), E[1].copy()
    Ex[1:][~seg_ok], Ey[1:][~seg_ok] = np.nan, np.nan        # break the curve where a segment leaves the image
    ax.plot(Ex, Ey, "-", color=colour, linewidth=1.6, zorder=4, path_effects=_halo(3.2))
    mu = dens.mean
    ax.plot(mu[0], mu[1], "+", color=colour, markersize=12, markeredgewidth=1.8, zorder=5, path_effects=_halo())
    ax.text(mu[0] + 20, mu[1] - 20, str(j), color=colour, fontsize=11, fontweight="bold", clip_on=True, zorder=7,
            path_effects=_halo(2.5))


def _draw_truth(ax, rows, Y):
    """True landmark pixels (hollow circles) and, for each wrong pairing, a dashed line from the chosen
    feature to the truth."""
    if not all(isinstance(r, dict) and {"true_pixel", "verdict", "associated"} <= r.keys() for r in rows):
        raise ValueError("truth must be the list of rows returned by ground_truth_check")
    for r in rows:
        t = np.asarray(r["true_pixel"], dtype=float)
        ax.plot(t[0], t[1], "o", mfc="none", mec=FIGURE1_COLORS["truth"], markersize=9, markeredgewidth=1.6,
                zorder=6, path_effects=_halo())
        if r["verdict"] == "wrong" and r["associated"] >= 0:
            y = Y[:, r["associated"]]
            ax.plot([y[0], t[0]], [y[1], t[1]], "--", color=FIGURE1_COLORS["wrong"], linewidth=2.0, zorder=6,
                    path_effects=_halo())


def figure1_legend_handles(truth: bool = False):
    """Legend entries of :func:`plot_association` (Figure 1 conventions; with ``truth`` also the true
    landmark pixel and the wrong-pairing line)."""
    from matplotlib.lines import Line2D

    c = FIGURE1_COLORS
    handles = [
        Line2D([], [], ls="none", marker=".", color=c["feature"], markersize=6, label="detected feature"),
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
                   label="true landmark pixel (renderer)"),
            Line2D([], [], ls="--", color=c["wrong"], lw=2.0, label="wrong pairing: chosen feature → truth"),
        ]
    return handles


def plot_association(image, result: AssociationResult, ax=None, n_sigma: float = 3.0, title: str | None = None,
                     image_scale: float = 0.5, window=None, truth=None, legend: bool = True):
    """Figure 1 of the lab with matplotlib over the image.

    All features: dark-red dots, drawn small and semi-transparent *under* everything else. Each selected
    landmark: '+' at the predicted mean and its 3σ ellipse (100 points; segments drawn only where both ends
    are inside the image), blue if associated and bright red if not, labelled with j at (μx + 20, μy − 20),
    with a thin white outline so they stay visible on the texture. Matched features: green '×'.
    ``truth``: rows of :func:`ground_truth_check` — adds the true landmark pixels (hollow circles) and a
    dashed orange line from every wrongly chosen feature to the truth. ``legend``: a legend below the axes
    (pass False in a grid and use :func:`figure1_legend_handles` for one figure legend).
    The image is shown resized by ``image_scale`` (the lab showed it at 0.5; coordinates stay full-size
    pixels). ``window = (x0, x1, y0, y1)`` shows only that part of the image (a zoom; drawn at full size).
    Returns (fig, ax).
    """
    import matplotlib.pyplot as plt

    if not isinstance(result, AssociationResult):
        raise ValueError(f"result must be an AssociationResult (association_demo), got {type(result).__name__}")
    shown, extent, (x0, x1, y0, y1) = _shown_image(image, image_scale, window)
    H, W = np.asarray(image).shape[:2]
    if ax is None:
        fig, ax = plt.subplots(figsize=(9.6, 7.2))
    else:
        fig = ax.figure
    if shown.ndim == 2:
        ax.imshow(shown, cmap="gray", vmin=0, vmax=255, extent=extent, interpolation="antialiased", zorder=0)
    else:
        ax.imshow(shown[..., ::-1], extent=extent, zorder=0)               # BGR → RGB
    Y = result.features.Y
    vis = (Y[0] >= x0) & (Y[0] <= x1) & (Y[1] >= y0) & (Y[1] <= y1)
    zoom = window is not None
    ax.plot(Y[0, vis], Y[1, vis], ".", color=FIGURE1_COLORS["feature"], markersize=4.0 if zoom else 2.4,
            alpha=0.85 if zoom else 0.55, markeredgewidth=0, linestyle="none", zorder=1)
    for k, (j, i) in enumerate(zip(result.idx_landmarks, result.idx)):
        colour = FIGURE1_COLORS["associated" if i >= 0 else "unassociated"]
        _draw_landmark(ax, result.landmark_density(k), j, colour, (W, H), n_sigma)
        if i >= 0:
            ax.plot(Y[0, i], Y[1, i], "x", color=FIGURE1_COLORS["match"], markersize=11, markeredgewidth=2.0,
                    zorder=5, path_effects=_halo())
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
