"""The tests the front-end applies to an association before it commits to it.

All work on one scan's problem in the association space: the candidates' predicted observations ŷ (k, d), their
joint covariance C (d·k × d·k, measurement noise included), the observations Y (d, m). The individual distances
d²_ki = ν_kiᵀ C_kk⁻¹ ν_ki come from the scan's ``AssociationProblem`` (``association.common.problem_from_cov``),
computed once per scan and read by every test here and in ``closure``.

``relative_sigma``           the largest standard deviation (m) of each landmark's position in the vehicle frame,
                             q = R(ψ)ᵀ(m − p), from the joint state covariance — the sensor noise left out.
                             A few centimetres for a landmark tracked scan after scan; metres for a landmark
                             last seen long ago (a loop closure), whatever its range.

``ambiguous_pairings``       the pairings with an equally good alternative: with candidate k removed the
                             algorithm still pairs k's observation (with another candidate) and as many
                             observations in all (a confirmed landmark takes precedence over a tentative one).
                             At a loop closure seen through one observation, two old landmarks may both explain
                             it; waiting for a constellation is far cheaper than a wrong loop closure. Only
                             pairings whose observation or candidate has a second individually compatible partner
                             are re-run (the others cannot change).

``sub_problem``              the density and observations restricted to some candidates and observations.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ...graph import EdgeSE2PointXY
from .algorithms import associate

__all__ = ["relative_sigma", "largest_sd", "ambiguous_pairings", "sub_problem"]


def relative_sigma(x, means, sig_v) -> np.ndarray:
    """Largest standard deviation (k,) of q_i = R(ψ)ᵀ(m_i − p) for the k landmarks ``means`` (k, 2) seen from
    pose x, with Σ_v the joint covariance of [x; m_1; …; m_k] (``EdgeSE2PointXY``'s Jacobians)."""
    k = len(means)
    if k == 0:
        return np.zeros(0)
    states = [np.broadcast_to(np.asarray(x, dtype=float), (k, 3)).copy(), np.asarray(means, dtype=float)]
    _, (jx, jm) = EdgeSE2PointXY.evaluate(states, np.zeros((k, 2)), {}, jacobians=True)
    ar = np.arange(k)
    sxx = sig_v[:3, :3]
    sxm = sig_v[:3, 3:].reshape(3, k, 2).transpose(1, 0, 2)                  # (k, 3, 2) Σ_x,m_i
    smm = sig_v[3:, 3:].reshape(k, 2, k, 2)[ar, :, ar, :]                      # (k, 2, 2) Σ_m_i
    cross = jx @ sxm @ jm.transpose(0, 2, 1)
    return largest_sd(jx @ sxx @ jx.transpose(0, 2, 1) + cross + cross.transpose(0, 2, 1)
                      + jm @ smm @ jm.transpose(0, 2, 1))


def largest_sd(P, check: bool = True) -> np.ndarray:
    """(k,) square roots of the largest eigenvalues of the symmetric 2 × 2 covariances P (k, 2, 2), closed
    form. In the Cartesian association space the front-end reads ``relative_sigma`` this way from the diagonal
    blocks of the scan's density: C_kk − R_k = J_k Σ_v J_kᵀ, the same covariance of q_k. ``check`` False skips
    the shape check (the front-end's own float arrays, every scan)."""
    if check:
        P = np.asarray(P, dtype=float)
        if P.ndim != 3 or P.shape[1:] != (2, 2):
            raise ValueError(f"P must be a (k, 2, 2) array of 2 × 2 covariances, got shape {P.shape}")
    half = 0.5 * (P[:, 0, 0] + P[:, 1, 1])
    det = P[:, 0, 0] * P[:, 1, 1] - P[:, 0, 1] * P[:, 1, 0]
    return np.sqrt(np.maximum(half + np.sqrt(np.maximum(half * half - det, 0.0)), 0.0))


def sub_problem(yhat, C, Y, cand, obs):
    """(ŷ, C, Y) restricted to candidates ``cand`` and observation columns ``obs``."""
    d = yhat.shape[1]
    cand = np.asarray(cand, dtype=np.int64)
    rows = (d * cand[:, None] + np.arange(d)).ravel()
    return yhat[cand], C[np.ix_(rows, rows)], Y[:, np.asarray(obs, dtype=np.int64)]


def ambiguous_pairings(algorithm, problem, R, idx, options, tentative) -> list:
    """Candidates whose pairing in ``idx`` has an equally good alternative (module docstring), on the scan's
    ``AssociationProblem`` (``problem_from_cov``; the re-runs use its subsets, so they see the same distances).
    ``tentative`` (k,) marks tentative landmarks: a confirmed landmark takes precedence over a tentative one — a
    pairing with a confirmed landmark whose only alternative is a tentative landmark stands (that tentative
    landmark is most likely its duplicate, started by an observation just outside the gate), while a pairing
    with a tentative landmark that a confirmed one explains as well is ambiguous."""
    n_pairings = int(np.count_nonzero(idx >= 0))
    ic = problem.ic_d2 <= problem.ic_threshold
    per_obs, per_cand = ic.sum(axis=0), ic.sum(axis=1)
    out = []
    paired = np.flatnonzero(idx >= 0)
    for k in paired[(per_obs[idx[paired]] >= 2) | (per_cand[paired] >= 2)]:
        i = idx[k]
        keep = np.flatnonzero(np.arange(len(idx)) != k)
        if keep.size == 0:                  # no other candidate: no alternative
            continue
        r = (problem.d * keep[:, None] + np.arange(problem.d)).ravel()     # the problem without candidate k
        sub = replace(problem, mu=problem.mu[keep], P=problem.P[np.ix_(r, r)], ic_d2=problem.ic_d2[keep],
                      logdet=problem.logdet[keep])
        alt = associate(algorithm, sub, None, problem.n_sigma, options, R)
        other = keep[np.flatnonzero(alt.idx == i)]
        if alt.n_pairings >= n_pairings and other.size and not (tentative[other[0]] and not tentative[k]):
            out.append(int(k))
    return out
