"""New landmarks need confirmation over several observations (lecture L09, Mahalanobis NN).

An observation that no mapped landmark explains may be a new landmark, or clutter: added to the map at once,
every spurious detection stays there for good. Instead it starts a *tentative* landmark. Each later frame, the
observations the map does not explain are associated with the tentative landmarks (Mahalanobis NN, χ² gate); a
re-observed one gains a hit and its estimate becomes the mean of its observations (covariance R / hits). After
``n_confirm`` hits it is **confirmed** and joins the map; after ``n_miss`` consecutive frames without a hit it is
**dropped** (a real landmark is seen again while the robot is near it, clutter is not).

:func:`confirmation_sequence` draws a seeded sequence: a robot driving straight with a *known pose*, a map that
holds some of the landmarks, and clutter uniform in the sensed disc; world-frame points with noise σ.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import block_diag

from ..gaussian import Gaussian, confidence_level
from ..validation import integer, positive_number, probability, rng_seed
from .nearest_neighbour import mahalanobis_nn

__all__ = ["ConfirmationSequence", "Track", "confirmation_sequence", "confirm_landmarks"]


@dataclass(frozen=True)
class ConfirmationSequence:
    """robot (T, 2) positions; landmarks (L, 2); known (L,): in the initial map; frames: (2, m_t) observations;
    sources: (m_t,) the landmark behind each observation (−1: clutter)."""

    robot: np.ndarray
    landmarks: np.ndarray
    known: np.ndarray
    frames: list
    sources: list
    meas_sigma: float
    max_range: float


@dataclass
class Track:
    """A tentative landmark: ``birth`` frame, ``mean`` of its observations and their ``sources``, ``hits``,
    consecutive ``misses``; ``status`` "tentative", "confirmed" or "dropped" (at frame ``end``)."""

    birth: int
    mean: np.ndarray
    sources: list = field(default_factory=list)
    hits: int = 1
    misses: int = 0
    status: str = "tentative"
    end: int = -1

    @property
    def source(self) -> int:
        """The landmark behind most of its observations (−1: clutter)."""
        vals, counts = np.unique(self.sources, return_counts=True)
        return int(vals[np.argmax(counts)])


def confirmation_sequence(seed: int, n_frames: int = 10, n_landmarks: int = 14, n_known: int = 8,
                          n_clutter: int = 2, max_range: float = 6.0, step: float = 1.0,
                          meas_sigma: float = 0.1, p_detect: float = 1.0) -> ConfirmationSequence:
    """Draw the sequence (module docstring): landmarks uniform in x ∈ [−2, (n_frames − 1)·step + 2] m, |y| ≤ 4 m,
    the first ``n_known`` in the map."""
    rng = np.random.default_rng(rng_seed(seed))
    n_frames = integer(n_frames, "n_frames", 1)
    n_landmarks = integer(n_landmarks, "n_landmarks", 1)
    n_known = integer(n_known, "n_known", minimum=0, below=n_landmarks + 1)
    n_clutter = integer(n_clutter, "n_clutter", 0)
    max_range = positive_number(max_range, "max_range")
    step, meas_sigma = positive_number(step, "step"), positive_number(meas_sigma, "meas_sigma")
    p_detect = probability(p_detect, "p_detect")
    robot = np.column_stack([step * np.arange(n_frames), np.zeros(n_frames)])
    x_hi = (n_frames - 1) * step + 2.0
    lm = np.column_stack([rng.uniform(-2.0, x_hi, n_landmarks), rng.uniform(-4.0, 4.0, n_landmarks)])
    frames, sources = [], []
    for r in robot:
        seen = np.flatnonzero(np.hypot(*(lm - r).T) <= max_range)
        seen = seen[rng.uniform(size=seen.size) < p_detect]
        z = lm[seen] + meas_sigma * rng.standard_normal((seen.size, 2))
        rad = max_range * np.sqrt(rng.uniform(size=n_clutter))
        ang = rng.uniform(-np.pi, np.pi, n_clutter)
        clutter = r + np.column_stack([rad * np.cos(ang), rad * np.sin(ang)])
        Z = np.vstack([z, clutter])
        perm = rng.permutation(Z.shape[0])
        frames.append(Z[perm].T.copy())
        sources.append(np.concatenate([seen, np.full(n_clutter, -1)])[perm].astype(np.intp))
    known = np.zeros(n_landmarks, dtype=bool)
    known[:n_known] = True
    return ConfirmationSequence(robot=robot, landmarks=lm, known=known, frames=frames, sources=sources,
                                meas_sigma=meas_sigma, max_range=max_range)


def _associate(means: list, covs: list, Y: np.ndarray, n_sigma: float) -> np.ndarray:
    """Mahalanobis NN of the columns of Y with landmarks N(means_k, covs_k + R); labels per column."""
    if len(means) == 0 or Y.shape[1] == 0:
        return np.full(Y.shape[1], -1, dtype=np.intp)
    density = Gaussian.from_cov(np.ravel(means), block_diag(*covs))
    return mahalanobis_nn(density, Y, n_sigma).observation_labels(Y.shape[1])


def confirm_landmarks(seq: ConfirmationSequence, n_confirm: int = 3, n_miss: int = 2,
                      n_sigma: float = 3.0) -> tuple[list[Track], np.ndarray]:
    """Run the confirmation rule (module docstring; ``n_confirm = 1`` maps every unexplained observation at once).
    Returns every :class:`Track` started (birth order) and, per entry of the final map, the landmark it came from
    (the known landmarks first, then the confirmed tracks; −1 for a confirmed clutter track)."""
    if not isinstance(seq, ConfirmationSequence):
        raise ValueError(f"seq must be a ConfirmationSequence (confirmation_sequence), got {type(seq).__name__}")
    n_confirm = integer(n_confirm, "n_confirm", 1)
    n_miss = integer(n_miss, "n_miss", 1)
    confidence_level(n_sigma)                               # checks n_sigma before any frame is processed
    R = seq.meas_sigma ** 2 * np.eye(2)
    map_mean = [p for p in seq.landmarks[seq.known]]
    map_cov = [R.copy() for _ in map_mean]                  # map landmarks: known to about σ
    map_sources = list(np.flatnonzero(seq.known))
    tracks: list[Track] = []
    for t, (Y, src) in enumerate(zip(seq.frames, seq.sources)):
        lab = _associate(map_mean, [c + R for c in map_cov], Y, n_sigma)
        free = np.flatnonzero(lab < 0)
        live = [tr for tr in tracks if tr.status == "tentative"]
        lab_t = _associate([tr.mean for tr in live], [R / tr.hits + R for tr in live], Y[:, free], n_sigma)
        for j, tr in enumerate(live):
            cols = free[lab_t == j]
            if cols.size:
                tr.mean = (tr.hits * tr.mean + Y[:, cols[0]]) / (tr.hits + 1)
                tr.hits += 1
                tr.misses = 0
                tr.sources.append(int(src[cols[0]]))
                if tr.hits >= n_confirm:
                    tr.status, tr.end = "confirmed", t
            else:
                tr.misses += 1
                if tr.misses >= n_miss:
                    tr.status, tr.end = "dropped", t
        for c in free[lab_t < 0]:
            tr = Track(birth=t, mean=Y[:, c].copy(), sources=[int(src[c])])
            if n_confirm == 1:
                tr.status, tr.end = "confirmed", t
            tracks.append(tr)
        for tr in tracks:
            if tr.status == "confirmed" and tr.end == t:
                map_mean.append(tr.mean.copy())
                map_cov.append(R / tr.hits)
                map_sources.append(tr.source)
    return tracks, np.asarray(map_sources, dtype=np.intp)
