"""New landmarks need confirmation over several observations (lecture L09, Mahalanobis NN).

An observation that no mapped landmark explains may be a new landmark — or clutter. Adding it to the map
at once puts every spurious detection into the map for good. Instead it becomes a *tentative* landmark:

- each later frame, observations not explained by the map are associated (Mahalanobis NN, χ² gate) with
  the tentative landmarks; a tentative landmark that is re-observed gains a hit and its
  position estimate becomes the mean of its observations (covariance R / hits);
- after ``n_confirm`` hits it is **confirmed** and joins the map;
- after ``n_miss`` consecutive frames without being re-observed it is **dropped** (a landmark that is
  really there is seen again while the robot is near it; clutter is not);
- observations explained by neither start new tentative landmarks.

:func:`confirmation_sequence` draws a small seeded sequence for this: a robot driving along a straight
line with a *known pose* (so the only question is the confirmation rule), a map that holds some of the
landmarks, the others new, and clutter uniform in the sensed disc every frame. Observations are world-frame
points with isotropic noise σ.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass, field

import numpy as np

from ..gaussian import Gaussian, confidence_level
from ..validation import integer, positive_number, rng_seed
from .nearest_neighbour import mahalanobis_nn

__all__ = ["ConfirmationSequence", "Track", "confirmation_sequence", "confirm_landmarks"]


@dataclass(frozen=True)
class ConfirmationSequence:
    """robot (T, 2) positions; landmarks (L, 2) true positions; known (L,) True for landmarks in the
    initial map; frames: list of (2, m_t) observations; sources: list of (m_t,) true landmark of each
    observation (−1 = clutter); meas_sigma; max_range."""

    robot: np.ndarray
    landmarks: np.ndarray
    known: np.ndarray
    frames: list
    sources: list
    meas_sigma: float
    max_range: float


@dataclass
class Track:
    """A tentative landmark: ``birth`` frame, observation ``sources`` (true landmark or −1 each), running
    ``mean`` of its observations, ``hits``, consecutive ``misses``; ``status`` is "tentative",
    "confirmed" or "dropped", decided at frame ``end``."""

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






def confirmation_sequence(seed, n_frames: int = 10, n_landmarks: int = 14, n_known: int = 8,
                          n_clutter: int = 2, max_range: float = 6.0, step: float = 1.0,
                          meas_sigma: float = 0.1, p_detect: float = 1.0) -> ConfirmationSequence:
    """Draw the sequence (see the module docstring). Landmarks are uniform in the strip swept by the
    sensor (x in [−2, (n_frames − 1)·step + 2] m, |y| ≤ 4 m); the first ``n_known`` are in the map."""
    rng = np.random.default_rng(rng_seed(seed))
    n_frames = integer(n_frames, "n_frames", 1)
    n_landmarks = integer(n_landmarks, "n_landmarks", 1)
    n_known = integer(n_known, "n_known", 0)
    if n_known > n_landmarks:
        raise ValueError(f"n_known must be <= n_landmarks = {n_landmarks}, got {n_known}")
    n_clutter = integer(n_clutter, "n_clutter", 0)
    max_range = positive_number(max_range, "max_range")
    step, meas_sigma = positive_number(step, "step"), positive_number(meas_sigma, "meas_sigma")
    if isinstance(p_detect, bool) or not isinstance(p_detect, numbers.Real) or not 0.0 <= p_detect <= 1.0:
        raise ValueError(f"p_detect must be a probability in [0, 1], got {p_detect!r}")
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


def _associate(means, covs, Y, n_sigma):
    """Mahalanobis NN of the columns of Y with landmarks N(means_k, covs_k + R); labels per column."""
    if len(means) == 0 or Y.shape[1] == 0:
        return np.full(Y.shape[1], -1, dtype=np.intp)
    cov = np.zeros((2 * len(means), 2 * len(means)))
    for k, c in enumerate(covs):
        cov[2 * k:2 * k + 2, 2 * k:2 * k + 2] = c
    return mahalanobis_nn(Gaussian.from_cov(np.ravel(means), cov), Y, n_sigma).observation_labels(Y.shape[1])


def confirm_landmarks(seq: ConfirmationSequence, n_confirm: int = 3, n_miss: int = 2, n_sigma: float = 3.0):
    """Run the confirmation rule over the sequence (see the module docstring).

    Returns (tracks, map_sources): every :class:`Track` ever started, in birth order, and for every entry
    of the final map the landmark it came from (known landmarks first, then confirmed tracks; a confirmed
    clutter track has source −1). ``n_confirm = 1`` adds every unexplained observation at once.
    """
    if not isinstance(seq, ConfirmationSequence):
        raise ValueError(f"seq must be a ConfirmationSequence (confirmation_sequence), got {type(seq).__name__}")
    n_confirm = integer(n_confirm, "n_confirm", 1)
    n_miss = integer(n_miss, "n_miss", 1)
    confidence_level(n_sigma)                               # validates n_sigma before any frame is processed
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
