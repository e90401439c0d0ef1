"""Nearest-neighbour association, greedy and one-to-one: all (landmark k, observation i) pairs are visited in
increasing cost and a pair is accepted while both ends are free and it passes the gate (ties → lower landmark,
then lower observation).

- Euclidean NN (lecture: c^i = argmin_j ‖m_j − z^i‖₂): cost ‖y_i − μ_k‖₂, ignoring the uncertainty.
- Mahalanobis NN (the IC-NN baseline of Neira & Tardós): cost d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki, ν_ki = y_i − μ_k, gate
  d²_ki ≤ χ²_d(c), c = 2Φ(n_σ) − 1; the innovations of different pairings are treated as independent.
- Surprisal NN: the lab's SNN (:func:`helpers.association.snn.snn`) behind the common interface.
"""
from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from ..gaussian import Gaussian
from .common import Association, AssociationProblem, finish, greedy_one_to_one, prepare
from .snn import snn

__all__ = ["nearest_neighbour", "mahalanobis_nn", "surprisal_nn"]


def nearest_neighbour(density: Gaussian | AssociationProblem, Y: ArrayLike | None, max_distance: float | None = None,
                      n_sigma: float = 3.0) -> Association:
    """Euclidean nearest neighbour (lecture L09), greedy and one-to-one; the covariance plays no part in the choice.

    The cost of a pair (landmark k, observation i) is the distance ‖y_i − μ_k‖₂; a pair farther than
    ``max_distance`` is never made (a pair exactly at it is). Pairs are accepted in increasing cost (ties → lower
    landmark, then lower observation) while both ends are free.

    Args:
        density: the predicted measurements of the n landmarks (module ``common``), or a prepared problem.
        Y: (d, m) observations, one per column, any d ≥ 1; m = 0 is allowed.
        max_distance: a positive finite gate on the distance, or None (no gate).
        n_sigma: only sets the reported ``jointly_compatible``.

    Returns:
        The :class:`Association` of ``finish``, named ``"nearest_neighbour"``, with stats ``{"gate": max_distance}``.

    Raises:
        ValueError: naming ``max_distance`` when it is neither None nor a positive finite number; ``prepare``'s
        errors for ``density``, ``Y`` and ``n_sigma``.
    """
    if max_distance is not None and (isinstance(max_distance, bool) or not isinstance(max_distance, numbers.Real)
                                     or not np.isfinite(max_distance) or max_distance <= 0):
        raise ValueError(f"max_distance must be a positive finite number or None, got {max_distance!r}")
    problem = prepare(density, Y, n_sigma)
    stats = {"gate": max_distance}
    diff = problem.Y.T[None, :, :] - problem.mu[:, None, :]
    dist = np.sqrt(np.sum(diff * diff, axis=-1))                      # (n, m)
    allowed = np.ones_like(dist, dtype=bool) if max_distance is None else dist <= max_distance
    return finish(problem, greedy_one_to_one(dist, allowed), "nearest_neighbour", stats)


def mahalanobis_nn(density: Gaussian | AssociationProblem, Y: ArrayLike | None, n_sigma: float = 3.0) -> Association:
    """Mahalanobis nearest neighbour (ICNN; lecture L09), greedy and one-to-one.

    The cost of a pair (landmark k, observation i) is d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki, ν_ki = y_i − μ_k, with P_kk
    landmark k's own d × d block of the covariance; a pair is allowed when it is individually compatible,
    d²_ki ≤ χ²_d(c) with c = 2Φ(n_σ) − 1. Allowed pairs are accepted in increasing cost (ties → lower landmark,
    then lower observation) while both ends are free.

    Args:
        density: the predicted measurements of the n landmarks (module ``common``), or a prepared problem.
        Y: (d, m) observations, one per column, any d ≥ 1; m = 0 is allowed.
        n_sigma: the gate's confidence in standard deviations (positive).

    Returns:
        The :class:`Association` of ``finish``, named ``"mahalanobis_nn"``, with stats ``{"ic_threshold": χ²_d(c),
        "ic_pairs": the number of individually compatible pairs}``.

    Raises:
        ValueError: ``prepare``'s errors, naming ``density``, ``Y`` or ``n_sigma``.
    """
    problem = prepare(density, Y, n_sigma)
    allowed = problem.ic_d2 <= problem.ic_threshold
    stats = {"ic_threshold": problem.ic_threshold, "ic_pairs": int(np.count_nonzero(allowed))}
    return finish(problem, greedy_one_to_one(problem.ic_d2, allowed), "mahalanobis_nn", stats)


def surprisal_nn(density: Gaussian, Y: ArrayLike, sU: float, n_sigma: float = 3.0,
                 enforce_joint_compatibility: bool = False) -> Association:
    """The lab's SNN; sU = log of the area over which a spurious observation is uniform (the image in the lab,
    e.g. log(π r²) of a sensed disc). stats: ``{"surprisal": s of the association, "sU": sU}``."""
    problem = prepare(density, Y, n_sigma)
    idx, s = snn(density, problem.Y, sU, n_sigma=n_sigma, enforce_joint_compatibility=enforce_joint_compatibility)
    return finish(problem, idx, "surprisal_nn", {"surprisal": float(s), "sU": float(sU)})
