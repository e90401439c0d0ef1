"""The O(K·N) cost of nearest-neighbour association, measured (lecture L09).

The lecture's nearest neighbour is a double loop — for each of the K observations, for each of the N
landmarks, one distance — so its cost grows with K·N. :func:`per_observation_nn` is that loop with the
Mahalanobis distance, vectorised over all K·N pairs:

    d²_ji = ν_jiᵀ S_j⁻¹ ν_ji,  ν_ji = z^i − ẑ_j,   c^i = argmin_j d²_ji  (−1 if d²_ji > gate).

It works from the landmarks' own innovation covariances S_j (N × 2 × 2), the data NN needs; it is
independent per observation, so two observations may take the same landmark. :func:`time_nn` times it on
random problems over a grid of (K, N); :func:`loglog_slope` fits log t = p log(K·N) + b — p ≈ 1 is the
O(K·N) law.
"""
from __future__ import annotations

import numbers

import numpy as np

from ..timing import best_of
from ..validation import float_array, rng_seed

__all__ = ["inverse_2x2", "pair_distances", "per_observation_nn", "random_nn_problem", "time_nn", "loglog_slope"]


def _check(mu, S, Y):
    mu, S, Y = (float_array(a, name) for a, name in ((mu, "mu"), (S, "S"), (Y, "Y")))
    if mu.ndim != 2 or mu.shape[1] != 2:
        raise ValueError(f"mu must have shape (N, 2), got {mu.shape}")
    if S.shape != (mu.shape[0], 2, 2):
        raise ValueError(f"S must have shape (N, 2, 2) = {(mu.shape[0], 2, 2)}, got {S.shape}")
    if Y.ndim != 2 or Y.shape[0] != 2:
        raise ValueError(f"Y must have shape (2, K), got {Y.shape}")
    for name, a in (("mu", mu), ("S", S), ("Y", Y)):
        if not np.all(np.isfinite(a)):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
    return mu, S, Y


def inverse_2x2(S):
    """(a, b, c) with S_j⁻¹ = [[a_j, b_j], [b_j, c_j]] for every 2×2 innovation covariance (closed form).
    S must be (N, 2, 2), finite, symmetric and positive definite (ValueError naming ``S``)."""
    S = float_array(S, "S")
    if S.ndim != 3 or S.shape[1:] != (2, 2) or not np.all(np.isfinite(S)):
        raise ValueError(f"S must be a finite (N, 2, 2) array of covariances, got shape {S.shape}")
    if not np.allclose(S[:, 0, 1], S[:, 1, 0], rtol=1e-10, atol=0.0):
        raise ValueError("S: every innovation covariance must be symmetric")
    det = S[:, 0, 0] * S[:, 1, 1] - S[:, 0, 1] * S[:, 1, 0]
    if np.any(det <= 0) or np.any(S[:, 0, 0] <= 0):
        raise ValueError("S: every innovation covariance must be positive definite")
    return S[:, 1, 1] / det, -0.5 * (S[:, 0, 1] + S[:, 1, 0]) / det, S[:, 0, 0] / det


def pair_distances(inv, mu, Y):
    """d² with one row per observation (columns of Y) and one column per landmark."""
    a, b, c = inv
    dx = Y[0][:, None] - mu[:, 0][None, :]
    dy = Y[1][:, None] - mu[:, 1][None, :]
    return a * dx * dx + 2.0 * b * dx * dy + c * dy * dy


def per_observation_nn(mu, S, Y, gate: float | None = None, block_pairs: int = 16384) -> np.ndarray:
    """c^i = argmin_j d²_ji for every observation (ties → lower j), −1 if above ``gate`` or N = 0.

    The lecture's loop over observations, each against all N landmarks; the observations are taken in
    blocks of about ``block_pairs`` (observation, landmark) pairs so the working arrays stay in the CPU
    cache whatever K and N are.
    """
    if gate is not None and (isinstance(gate, bool) or not isinstance(gate, numbers.Real) or not gate > 0):
        raise ValueError(f"gate must be a positive number or None, got {gate!r}")
    if isinstance(block_pairs, bool) or not isinstance(block_pairs, numbers.Integral) or block_pairs < 1:
        raise ValueError(f"block_pairs must be a positive integer, got {block_pairs!r}")
    mu, S, Y = _check(mu, S, Y)
    N, K = mu.shape[0], Y.shape[1]
    labels = np.full(K, -1, dtype=np.intp)
    if N == 0:
        return labels
    inv = inverse_2x2(S)
    step = max(1, int(block_pairs) // N)
    for start in range(0, K, step):
        d2 = pair_distances(inv, mu, Y[:, start:start + step])             # (block, N): observation × landmark
        j = np.argmin(d2, axis=1)
        if gate is not None:
            j = np.where(d2[np.arange(d2.shape[0]), j] <= gate, j, -1)
        labels[start:start + step] = j
    return labels


def random_nn_problem(rng, n_landmarks: int, n_observations: int):
    """(mu, S, Y): N landmarks uniform in a 100 m square with random SPD 2×2 innovation covariances, and K
    observations uniform in the same square. ``rng``: a numpy Generator."""
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
    for name, v in (("n_landmarks", n_landmarks), ("n_observations", n_observations)):
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    mu = rng.uniform(0.0, 100.0, (n_landmarks, 2))
    A = rng.normal(0.0, 0.5, (n_landmarks, 2, 2))
    S = A @ np.swapaxes(A, 1, 2) + 0.01 * np.eye(2)
    Y = rng.uniform(0.0, 100.0, (2, n_observations))
    return mu, S, Y


def time_nn(Ks, Ns, seed: int = 0, repeats: int = 5):
    """Best-of-``repeats`` wall time [s] of :func:`per_observation_nn` for every (K, N) of the grid.

    Returns (K, N, seconds) as flat arrays of equal length (K varies fastest within each N).
    """
    if isinstance(repeats, bool) or not isinstance(repeats, numbers.Integral) or repeats < 1:
        raise ValueError(f"repeats must be a positive integer, got {repeats!r}")
    for name, grid in (("Ks", Ks), ("Ns", Ns)):
        arr = np.asarray(grid)
        if arr.ndim != 1 or arr.size == 0 or arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer) \
                or np.any(arr < 1):
            raise ValueError(f"{name} must be a non-empty list of positive integers, got {grid!r}")
    rng = np.random.default_rng(rng_seed(seed))
    out_k, out_n, out_t = [], [], []
    for n in Ns:
        for k in Ks:
            mu, S, Y = random_nn_problem(rng, int(n), int(k))
            _, best = best_of(int(repeats), per_observation_nn, mu, S, Y)
            out_k.append(int(k))
            out_n.append(int(n))
            out_t.append(best)
    return np.array(out_k), np.array(out_n), np.array(out_t)


def loglog_slope(x, y) -> float:
    """Least-squares slope p of log y = p log x + b (x, y positive, at least two distinct x)."""
    x, y = float_array(x, "x"), float_array(y, "y")
    if x.shape != y.shape or x.ndim != 1 or not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))) \
            or np.any(x <= 0) or np.any(y <= 0) or np.unique(x).size < 2:
        raise ValueError("x and y must be 1-D positive arrays of equal length with at least two distinct x")
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])
