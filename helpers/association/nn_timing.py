"""The O(K·N) cost of nearest-neighbour association, measured (lecture L09).

The lecture's nearest neighbour is a double loop over the K observations and the N landmarks, so its cost grows
with K·N. :func:`per_observation_nn` is that loop with the Mahalanobis distance, vectorised over all pairs:

    d²_ji = ν_jiᵀ S_j⁻¹ ν_ji,  ν_ji = z^i − ẑ_j,   c^i = argmin_j d²_ji  (−1 if d²_ji > gate),

each observation on its own (two may take the same landmark). :func:`time_nn` times it over a grid of (K, N) and
:func:`loglog_slope` fits log t = p log(K·N) + b: p ≈ 1 is the O(K·N) law.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..timing import best_of
from ..validation import float_array, int_array, integer, positive_number, rng_seed

__all__ = ["inverse_2x2", "pair_distances", "per_observation_nn", "time_nn", "loglog_slope"]


def inverse_2x2(S: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(a, b, c) with S_j⁻¹ = [[a_j, b_j], [b_j, c_j]] for symmetric positive-definite S (N, 2, 2), closed form."""
    det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
    return S[:, 1, 1] / det, -0.5 * (S[:, 0, 1] + S[:, 1, 0]) / det, S[:, 0, 0] / det


def pair_distances(inv: tuple[np.ndarray, np.ndarray, np.ndarray], mu: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """d² with one row per observation (columns of Y) and one column per landmark."""
    a, b, c = inv
    dx = Y[0][:, None] - mu[:, 0][None, :]
    dy = Y[1][:, None] - mu[:, 1][None, :]
    return a * dx * dx + 2.0 * b * dx * dy + c * dy * dy


def per_observation_nn(mu: ArrayLike, S: ArrayLike, Y: ArrayLike, gate: float | None = None,
                       block_pairs: int = 16384) -> np.ndarray:
    """c^i = argmin_j d²_ji for every observation (ties → lower j), −1 if above ``gate`` or N = 0.

    mu (N, 2) predicted observations, S (N, 2, 2) their innovation covariances (symmetric positive definite),
    Y (2, K) observations. The observations are taken in blocks of about ``block_pairs`` (observation,
    landmark) pairs, so the working arrays stay in the CPU cache whatever K and N are.
    """
    gate = None if gate is None else positive_number(gate, "gate")
    block_pairs = integer(block_pairs, "block_pairs", minimum=1)
    mu, S, Y = float_array(mu, "mu"), float_array(S, "S"), float_array(Y, "Y")
    N = len(mu) if mu.ndim else -1
    if mu.shape != (N, 2) or S.shape != (N, 2, 2) or Y.ndim != 2 or Y.shape[0] != 2:
        raise ValueError(f"mu, S and Y must have shapes (N, 2), (N, 2, 2) and (2, K), got {mu.shape}, {S.shape} "
                         f"and {Y.shape}")
    for name, arr in (("mu", mu), ("S", S), ("Y", Y)):
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
    if not np.allclose(S[:, 0, 1], S[:, 1, 0], rtol=1e-10, atol=0.0) or np.any(S[:, 0, 0] <= 0) \
            or np.any(np.linalg.det(S) <= 0):
        raise ValueError("S: every innovation covariance must be symmetric positive definite")
    labels = np.full(Y.shape[1], -1, dtype=np.intp)
    if N == 0:
        return labels
    inv = inverse_2x2(S)
    step = max(1, block_pairs // N)
    for start in range(0, Y.shape[1], step):
        d2 = pair_distances(inv, mu, Y[:, start:start + step])             # (block, N): observation × landmark
        j = np.argmin(d2, axis=1)
        if gate is not None:
            j = np.where(d2[np.arange(d2.shape[0]), j] <= gate, j, -1)
        labels[start:start + step] = j
    return labels


def _random_problem(rng: np.random.Generator, n_landmarks: int, n_observations: int) -> tuple:
    """(mu, S, Y): N landmarks and K observations uniform in a 100 m square, random SPD covariances S."""
    mu = rng.uniform(0.0, 100.0, (n_landmarks, 2))
    A = rng.normal(0.0, 0.5, (n_landmarks, 2, 2))
    S = A @ np.swapaxes(A, 1, 2) + 0.01 * np.eye(2)
    Y = rng.uniform(0.0, 100.0, (2, n_observations))
    return mu, S, Y


def time_nn(Ks: ArrayLike, Ns: ArrayLike, seed: int = 0, repeats: int = 5) -> tuple[np.ndarray, ...]:
    """Best-of-``repeats`` wall time [s] of :func:`per_observation_nn` on a random problem for every (K, N) of
    the grid. Returns (K, N, seconds) as flat arrays of equal length (K varies fastest within each N)."""
    repeats = integer(repeats, "repeats", minimum=1)
    Ks, Ns = int_array(Ks, "Ks"), int_array(Ns, "Ns")
    for name, grid in (("Ks", Ks), ("Ns", Ns)):
        if grid.size == 0 or np.any(grid < 1):
            raise ValueError(f"{name} must be a non-empty list of positive integers, got {grid.tolist()}")
    rng = np.random.default_rng(rng_seed(seed))
    out = []
    for n in Ns.tolist():
        for k in Ks.tolist():
            mu, S, Y = _random_problem(rng, n, k)
            out.append((k, n, best_of(repeats, per_observation_nn, mu, S, Y)[1]))
    K, N, t = np.array(out).T
    return K.astype(int), N.astype(int), t


def loglog_slope(x: ArrayLike, y: ArrayLike) -> float:
    """Least-squares slope p of log y = p log x + b (x, y positive, at least two distinct x)."""
    x, y = float_array(x, "x"), float_array(y, "y")
    if x.shape != y.shape or x.ndim != 1 or not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))) \
            or np.any(x <= 0) or np.any(y <= 0) or np.unique(x).size < 2:
        raise ValueError("x and y must be 1-D positive arrays of equal length with at least two distinct x")
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])
