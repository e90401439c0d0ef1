"""Data association on photographs of a chessboard, scored against the board's own corners.

One photograph of a calibrated folder (:func:`helpers.calibration.calibrate_folder`) gives a Lab 8 problem with
ground truth:

- landmarks: the board's N inner corners r_j in the board frame {n} (the world frame);
- the true camera pose η★: the calibration's board pose of that photograph, [rCNn; Θnc];
- features Y: the workbook's detector on the photograph (``detect_features`` with ``DEMO_DETECTOR`` by default);
- truth: the feature of landmark j is the detected feature nearest to the corner's sub-pixel position y_j
  (``find_board_corners``) if it lies within ``tol`` px (2 px), and none otherwise ("should stay unassociated").

The prior (:class:`PhotoPrior`): the state x = [ν; η; r_1 … r_N] of ``StateSLAM`` with the camera at the body origin,
mean η̂ = η★ + e with the pose error e ~ N(0, k² P_η), P_η = diag(σ_r² I₃, σ_Θ² I₃) (k = ``error_scale``: 1 draws
the errors from the prior's own covariance, k > 1 makes them k times larger than the prior believes); ν and the
landmarks are exact (zero square-root blocks). The predicted bundle of the landmarks in the field of view adds pixel
noise N(0, σ_px² I₂) to every feature (the detector's error). Every algorithm f(density, Y) → Association runs
on every draw; its pairings are kept, so they can be scored at any ``tol`` with ``evaluation.trial_counts``:
precision = TP / pairings made, recall = TP / landmarks with a true feature, counts summed over the draws.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..calibration import Calibration
from ..camera import Camera
from ..features import Features, detect_features
from ..gaussian import Gaussian
from ..state_slam import StateSLAM
from ..validation import integer, nonnegative_number, positive_number, rng_seed
from .evaluation import TrialResults, _check_algorithms, trial_counts
from .lab_demo import DEMO_DETECTOR

__all__ = ["PhotoPrior", "Photo", "PhotoTrial", "PhotoEvaluation", "prepare_photos", "photo_trial", "evaluate_photos",
           "merge_results", "feature_truth"]


@dataclass(frozen=True)
class PhotoPrior:
    """Pose prior and pixel noise of the photograph problems: σ_r (m) per position axis, σ_Θ (rad) per angle, σ_px
    (px) per pixel axis."""

    position_sigma: float = 0.002
    angle_sigma: float = 0.005
    pixel_sigma: float = 0.5

    def __post_init__(self) -> None:
        for name in ("position_sigma", "angle_sigma", "pixel_sigma"):
            positive_number(getattr(self, name), name)

    @property
    def pose_sqrt(self) -> np.ndarray:
        """Upper-triangular square root of P_η (6, 6)."""
        return np.diag([self.position_sigma] * 3 + [self.angle_sigma] * 3)

    @property
    def noise(self) -> Gaussian:
        """N(0, σ_px² I₂): one feature's pixel error."""
        return Gaussian(np.zeros(2), self.pixel_sigma * np.eye(2))

    def state(self, board: np.ndarray, pose_mean: np.ndarray) -> StateSLAM:
        """The SLAM state with camera pose mean ``pose_mean`` [rCNn; Θnc] and the landmarks ``board`` (3, N)."""
        n = board.shape[1]
        S = np.zeros((12 + 3 * n, 12 + 3 * n))
        S[6:12, 6:12] = self.pose_sqrt
        return StateSLAM(Gaussian(np.concatenate([np.zeros(6), pose_mean, board.T.ravel()]), S))


@dataclass(frozen=True)
class Photo:
    """One calibrated photograph: its ``name``, gray ``image``, true camera ``pose``, sub-pixel ``corners`` (2, N),
    detected ``features``, and per landmark the ``truth`` (feature column or −1) and the distance to the nearest
    feature (px)."""

    name: str
    image: np.ndarray
    pose: np.ndarray
    corners: np.ndarray
    features: Features
    truth: np.ndarray
    nearest_distance: np.ndarray


@dataclass(frozen=True)
class PhotoTrial:
    """One draw on one photograph: the prior's mean pose ``pose_est``, the selected landmarks ``selection``, their
    predicted bundle ``density``, the features ``Y`` and the selection's ``truth``."""

    pose_est: np.ndarray
    selection: np.ndarray
    density: Gaussian
    Y: np.ndarray
    truth: np.ndarray


def feature_truth(Y: np.ndarray, corners: np.ndarray, tol: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """(truth, distance): for every corner (column of ``corners``), the column of Y nearest to it if within ``tol``
    px, else −1; and that nearest distance (inf without features)."""
    if Y.shape[1] == 0:
        return np.full(corners.shape[1], -1, dtype=np.intp), np.full(corners.shape[1], np.inf)
    d = np.hypot(Y[0][:, None] - corners[0][None], Y[1][:, None] - corners[1][None])       # (m, N)
    nearest, dist = np.argmin(d, axis=0), np.min(d, axis=0)
    return np.where(dist <= tol, nearest, -1).astype(np.intp), dist


def prepare_photos(calibration: Calibration, detector: Mapping | None = None, tol: float = 2.0) -> list[Photo]:
    """Detect the features of every photograph of ``calibration`` (``detector``: keyword arguments of
    ``detect_features``, default ``DEMO_DETECTOR``) and find each corner's true feature (:func:`feature_truth`)."""
    if not isinstance(calibration, Calibration):
        raise ValueError(f"calibration must be a Calibration (calibrate_folder), got {type(calibration).__name__}")
    tol = positive_number(tol, "tol")
    views, photos = calibration.views, []
    for name, image, pose, corners in zip(views.names, views.images, calibration.poses, views.corners):
        features = detect_features(image, **(DEMO_DETECTOR if detector is None else dict(detector)))
        truth, dist = feature_truth(features.Y, corners, tol)
        photos.append(Photo(name, image, pose, corners, features, truth, dist))
    return photos


def photo_trial(seed, photo: Photo, camera: Camera, board: np.ndarray, prior: PhotoPrior,
                error_scale: float = 1.0) -> PhotoTrial:
    """One seeded draw (module docstring): e = error_scale · (σ_r z₁₋₃, σ_Θ z₄₋₆), z ~ N(0, I₆), mean pose
    η★ + e; the landmarks whose mean is in the field of view at that pose are selected (as in ``association_demo``)."""
    rng = np.random.default_rng(rng_seed(seed))
    error = error_scale * (np.diag(prior.pose_sqrt) * rng.standard_normal(6))
    state = prior.state(board, photo.pose + error)
    pose = state.camera_pose(camera)
    selection = np.flatnonzero(np.asarray(camera.is_world_within_fov(board, pose), dtype=bool).reshape(-1))
    if selection.size == 0:
        raise ValueError(f"photo {photo.name}: no landmark is in the field of view at the drawn pose")
    density = state.predict_feature_bundle_density(camera, selection, noise=prior.noise)
    return PhotoTrial(pose, selection, density, photo.features.Y, photo.truth[selection])


@dataclass(frozen=True)
class PhotoEvaluation:
    """The associations of every algorithm on every draw: ``idx[name]`` (n_photos, n_draws, N), the feature column
    of each landmark (−1: none, or not selected); ``exhausted[name]`` (n_photos, n_draws) whether a search stopped
    at its budget (``Association.budget_exhausted``); the ``photos`` and the ``error_scale``."""

    names: tuple
    photos: tuple
    idx: dict
    exhausted: dict
    error_scale: float

    def results(self, tol: float = 2.0) -> dict[str, TrialResults]:
        """{photo name: TrialResults} scored with the truth at ``tol`` px (:func:`feature_truth`)."""
        tol = positive_number(tol, "tol")
        out = {}
        for p, photo in enumerate(self.photos):
            Y = photo.features.Y
            truth = feature_truth(Y, photo.corners, tol)[0]
            res = TrialResults(names=list(self.names), n_trials=self.idx[self.names[0]].shape[1])
            for name in self.names:
                rows = [trial_counts(idx, truth, Y.shape[1]) for idx in self.idx[name][p]]
                res.counts[name] = {key: np.array([r[key] for r in rows]) for key in rows[0]}
                res.counts[name]["exhausted"] = self.exhausted[name][p]
            out[photo.name] = res
        return out

    def overall(self, tol: float = 2.0) -> TrialResults:
        """All photographs and draws as one TrialResults (counts summed by ``summary`` and ``interval``)."""
        return merge_results(self.results(tol))


def evaluate_photos(algorithms: Mapping[str, Callable], photos: list[Photo], camera: Camera, board: np.ndarray,
                    prior: PhotoPrior, n_draws: int, seed: int, error_scale: float = 1.0) -> PhotoEvaluation:
    """Run every algorithm {name: f(density, Y) → Association} on ``n_draws`` draws per photograph
    (:func:`photo_trial`; photograph i, draw t uses the seed (seed, i, t))."""
    _check_algorithms(algorithms)
    if not isinstance(photos, list) or not photos or not all(isinstance(p, Photo) for p in photos):
        raise ValueError("photos must be a non-empty list of Photo (prepare_photos)")
    if len({p.name for p in photos}) != len(photos):
        raise ValueError("photos must have distinct names (the results are keyed by name)")
    if not isinstance(prior, PhotoPrior):
        raise ValueError(f"prior must be a PhotoPrior, got {type(prior).__name__}")
    n_draws = integer(n_draws, "n_draws", minimum=1)
    seed = integer(seed, "seed", minimum=0)
    error_scale = nonnegative_number(error_scale, "error_scale")
    n = board.shape[1]
    idx = {name: np.full((len(photos), n_draws, n), -1, dtype=np.intp) for name in algorithms}
    exhausted = {name: np.zeros((len(photos), n_draws), dtype=bool) for name in algorithms}
    for p, photo in enumerate(photos):
        for t in range(n_draws):
            trial = photo_trial((seed, p, t), photo, camera, board, prior, error_scale)
            for name, f in algorithms.items():
                a = f(trial.density, trial.Y)
                idx[name][p, t, trial.selection] = a.idx
                exhausted[name][p, t] = a.budget_exhausted
    return PhotoEvaluation(tuple(algorithms), tuple(photos), idx, exhausted, float(error_scale))


def merge_results(results: Mapping[str, TrialResults]) -> TrialResults:
    """All trials of several TrialResults (same algorithms) as one: the counts concatenated."""
    parts = list(results.values())
    if not parts:
        raise ValueError("results must hold at least one TrialResults")
    names = parts[0].names
    if any(p.names != names for p in parts):
        raise ValueError("results must all have the same algorithms")
    merged = TrialResults(names=list(names), n_trials=sum(p.n_trials for p in parts))
    for name in names:
        merged.counts[name] = {key: np.concatenate([p.counts[name][key] for p in parts])
                               for key in parts[0].counts[name]}
    return merged
