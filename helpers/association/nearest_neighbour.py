"""Nearest-neighbour association: Euclidean NN and Mahalanobis (individually compatible) NN.

Both are greedy and one-to-one (an observation is never given to two landmarks): all (landmark k,
observation i) pairs are visited in increasing cost and a pair is accepted when both ends are still free
and the pair passes the gate (the global greedy assignment; ties → lower landmark, then lower observation
index). Cost O(n·m log(n·m)).

- Euclidean NN (lecture: c^i = argmin_j ‖m_j − z^i‖₂): cost ‖y_i − μ_k‖₂, optional distance gate.
  Ignores the uncertainty completely.
- Mahalanobis NN (the IC-NN baseline of Neira & Tardós): cost d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki with
  ν_ki = y_i − μ_k, gate d²_ki ≤ χ²_d(c), c = 2Φ(n_σ) − 1. Uses each pairing's uncertainty but treats the
  innovations of different pairings as independent (no cross-covariance) — hence still greedy.
- Surprisal NN (the lab's SNN, ``helpers.association.snn``) wrapped into the common interface: greedy
  landmark by landmark in index order, each landmark takes the free compatible observation that lowers the
  total surprisal n_U·s_U − log N(y_A; μ_A, P_A) most (joint density of the whole bundle), or none.
"""
from __future__ import annotations

import numbers

import numpy as np

from .common import Association, empty_association, finish, greedy_one_to_one, prepare
from .snn import snn

__all__ = ["nearest_neighbour", "mahalanobis_nn", "surprisal_nn"]


def nearest_neighbour(density, Y, max_distance: float | None = None, n_sigma: float = 3.0) -> Association:
    """Euclidean nearest neighbour, one-to-one.

    max_distance: pairs farther than this (in measurement units) are never associated; None = no gate
    (every landmark gets an observation while both remain). n_sigma only sets the reported
    ``jointly_compatible`` flag. stats: ``{"gate": max_distance}``.
    """
    if max_distance is not None and (isinstance(max_distance, bool) or not isinstance(max_distance, numbers.Real)
                                     or not np.isfinite(max_distance) or max_distance <= 0):
        raise ValueError(f"max_distance must be a positive finite number or None, got {max_distance!r}")
    problem = prepare(density, Y, n_sigma)
    stats = {"gate": max_distance}
    if problem.m == 0:
        return empty_association(problem, "nearest_neighbour", stats)
    diff = problem.Y.T[None, :, :] - problem.mu[:, None, :]
    dist = np.sqrt(np.sum(diff * diff, axis=-1))                      # (n, m)
    allowed = np.ones_like(dist, dtype=bool) if max_distance is None else dist <= max_distance
    return finish(problem, greedy_one_to_one(dist, allowed), "nearest_neighbour", stats)


def mahalanobis_nn(density, Y, n_sigma: float = 3.0) -> Association:
    """Individually-compatible nearest neighbour (ICNN), one-to-one: smallest d²_ki first, gate χ²_d(c).

    stats: ``{"ic_threshold": χ²_d(c), "ic_pairs": number of individually compatible pairs}``.
    """
    problem = prepare(density, Y, n_sigma)
    allowed = problem.ic_d2 <= problem.ic_threshold
    stats = {"ic_threshold": problem.ic_threshold, "ic_pairs": int(np.count_nonzero(allowed))}
    if problem.m == 0:
        return empty_association(problem, "mahalanobis_nn", stats)
    return finish(problem, greedy_one_to_one(problem.ic_d2, allowed), "mahalanobis_nn", stats)


def surprisal_nn(density, Y, sU: float, n_sigma: float = 3.0, enforce_joint_compatibility: bool = False) -> Association:
    """The lab's SNN (``helpers.association.snn.snn``) behind the common interface.

    sU: surprisal of an unassociated landmark, log of the area over which a spurious observation is
    uniform (image area in the lab; for metric scenes e.g. log(π r²) of the sensed disc).
    stats: ``{"surprisal": total surprisal of the association, "sU": sU}``.
    """
    problem = prepare(density, Y, n_sigma)
    if problem.d != 2:
        raise ValueError(f"surprisal_nn needs 2-D observations (the lab's SNN), got d = {problem.d}")
    idx, s = snn(density, problem.Y, sU, n_sigma=n_sigma, enforce_joint_compatibility=enforce_joint_compatibility)
    return finish(problem, idx, "surprisal_nn", {"surprisal": float(s), "sU": float(sU)})
