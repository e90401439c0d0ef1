"""Maximum-likelihood association with the independence approximation and a new-landmark likelihood α.

Lecture L09: solve the association incrementally (earlier correspondences assumed right) and assume the
observations independent given the correspondences,

    p(z | c, y) ≈ Π_i p(z^i | c^i, y),   so   max_c Π_i p(z^i | c^i) = Π_i max_{c^i} p(z^i | c^i),

each observation being scored individually with p(z^i | c^i = k) = N(z^i; μ_k, P_kk). In negative-log
form the score of pairing (k, i) is

    ℓ_ki = ½ d²_ki + ½ log det(2π P_kk),

Mahalanobis NN plus a log-determinant term that penalises very uncertain landmarks.

New landmark (Probabilistic Robotics, p. 322): "new" gets the constant likelihood α; an observation is
left unassociated (a new landmark or clutter) when no landmark beats it, i.e. when min_k ℓ_ki > −log α.
α has the units of a density in measurement space (1/m² for 2-D points) and is hard to tune; without it
nothing is ever new. With ``alpha=None`` the χ² gate d²_ki ≤ χ²_d(c) decides instead.

One-to-one: pairs are accepted in increasing ℓ_ki while both ends are free (global greedy, ties → lower
landmark, then lower observation index).
"""
from __future__ import annotations

import numbers

import numpy as np

from .common import Association, empty_association, finish, greedy_one_to_one, prepare

__all__ = ["maximum_likelihood", "ml_scores"]


def ml_scores(density, Y) -> np.ndarray:
    """ℓ_ki = ½ d²_ki + ½ log det(2π P_kk), shape (n, m): the negative log-likelihood of each pairing."""
    problem = prepare(density, Y)
    return 0.5 * problem.ic_d2 + 0.5 * problem.logdet[:, None]


def maximum_likelihood(density, Y, alpha: float | None = None, n_sigma: float = 3.0) -> Association:
    """ML association under the independence assumption, one-to-one.

    alpha: likelihood of "new landmark" (a positive density value); a pairing is allowed only when
    p(z^i | k) > α (ℓ_ki < −log α). None: use the χ² gate of ``n_sigma`` instead.
    stats: ``{"alpha": alpha, "neg_log_alpha": −log α or None}``.
    """
    if alpha is not None and (isinstance(alpha, bool) or not isinstance(alpha, numbers.Real)
                              or not np.isfinite(alpha) or alpha <= 0):
        raise ValueError(f"alpha must be a positive finite likelihood or None, got {alpha!r}")
    problem = prepare(density, Y, n_sigma)
    stats = {"alpha": alpha, "neg_log_alpha": None if alpha is None else float(-np.log(alpha))}
    if problem.m == 0:
        return empty_association(problem, "maximum_likelihood", stats)
    score = 0.5 * problem.ic_d2 + 0.5 * problem.logdet[:, None]
    allowed = problem.ic_d2 <= problem.ic_threshold if alpha is None else score < -np.log(alpha)
    return finish(problem, greedy_one_to_one(score, allowed), "maximum_likelihood", stats)
