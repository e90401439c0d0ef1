"""Maximum-likelihood association with the independence approximation and a new-landmark likelihood α.

Lecture L09: with the observations independent given the correspondences, p(z | c) ≈ Π_i p(z^i | c^i), each
pairing is scored on its own by p(z^i | c^i = k) = N(z^i; μ_k, P_kk), in negative-log form

    ℓ_ki = ½ d²_ki + ½ log det(2π P_kk)          (Mahalanobis NN plus a penalty on uncertain landmarks).

"New landmark" has the constant likelihood α (Probabilistic Robotics, p. 322): an observation stays unpaired
when min_k ℓ_ki ≥ −log α. α is a density in measurement space (1/m² for 2-D points) and hard to tune; with
``alpha=None`` the χ² gate d²_ki ≤ χ²_d(c) decides instead. Pairs are accepted in increasing ℓ_ki while both
ends are free (global greedy, ties → lower landmark, then lower observation).
"""
from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from ..gaussian import Gaussian
from .common import Association, AssociationProblem, finish, greedy_one_to_one, prepare

__all__ = ["maximum_likelihood", "ml_scores"]


def ml_scores(density: Gaussian | AssociationProblem, Y: ArrayLike | None) -> np.ndarray:
    """ℓ_ki = ½ d²_ki + ½ log det(2π P_kk), shape (n, m): the negative log-likelihood of each pairing."""
    problem = prepare(density, Y)
    return 0.5 * problem.ic_d2 + 0.5 * problem.logdet[:, None]


def maximum_likelihood(density: Gaussian | AssociationProblem, Y: ArrayLike | None, alpha: float | None = None,
                       n_sigma: float = 3.0) -> Association:
    """Maximum-likelihood association with the new-landmark likelihood α (lecture L09), greedy and one-to-one.

    The cost of a pair (landmark k, observation i) is its negative log-likelihood ℓ_ki (module docstring). With
    ``alpha`` given a pair is allowed when its likelihood beats α, ℓ_ki < −log α (the χ² gate plays no part);
    with ``alpha`` None when it passes the χ² gate d²_ki ≤ χ²_d(c), c = 2Φ(n_σ) − 1. Allowed pairs are accepted
    in increasing ℓ_ki (ties → lower landmark, then lower observation) while both ends are free.

    Args:
        density: the predicted measurements of the n landmarks (module ``common``), or a prepared problem.
        Y: (d, m) observations, one per column, any d ≥ 1; m = 0 is allowed.
        alpha: the likelihood of "new landmark", a positive finite density in measurement space, or None.
        n_sigma: the χ² gate's confidence in standard deviations (used when ``alpha`` is None; it also sets the
            reported ``jointly_compatible``).

    Returns:
        The :class:`Association` of ``finish``, named ``"maximum_likelihood"``, with stats ``{"alpha": alpha,
        "neg_log_alpha": −log α, or None when alpha is None}``.

    Raises:
        ValueError: naming ``alpha`` when it is neither None nor a positive finite number; ``prepare``'s errors
        for ``density``, ``Y`` and ``n_sigma``.
    """
    if alpha is not None and (isinstance(alpha, bool) or not isinstance(alpha, numbers.Real)
                              or not np.isfinite(alpha) or alpha <= 0):
        raise ValueError(f"alpha must be a positive finite likelihood or None, got {alpha!r}")
    problem = prepare(density, Y, n_sigma)
    stats = {"alpha": alpha, "neg_log_alpha": None if alpha is None else float(-np.log(alpha))}
    score = ml_scores(problem, None)
    allowed = problem.ic_d2 <= problem.ic_threshold if alpha is None else score < -np.log(alpha)
    return finish(problem, greedy_one_to_one(score, allowed), "maximum_likelihood", stats)
