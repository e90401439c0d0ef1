"""Surprisal nearest neighbour (SNN): the lab's association (Lab 8 §3), landmarks choosing features.

For n selected landmarks with predicted feature-bundle density N(μ, P) (``density``; landmark k in rows 2k,
2k+1) and features Y = [y_0 … y_{m−1}] ∈ R^{2×m}, SNN builds an association idx (idx[k] = feature column
or −1) greedily, landmark by landmark in selection order:

    s(idx) = n_U·s_U − log N(y_A; μ_A, P_A)          (total surprisal, s_U = log W + log H)

Starting from "nothing associated" (s = n·s_U), each landmark j = 0 … n−1 in turn (never revisited) considers
the features not taken by an earlier landmark and individually compatible with it (eq 12, d²_ji ≤ χ²₂(c), from
``prepare``) and picks the one whose pairing changes the surprisal least, Δs = s(idx ∪ {j ↦ i}) − s(idx) (ties →
lowest feature index); it keeps it iff Δs ≤ 0 (the null hypothesis "j unassociated" has Δs = 0 and wins only when
strictly better). With ``enforce_joint_compatibility`` a candidate must also pass the joint gate
wᵀw ≤ χ²_{2(n_A+1)}(c) of the enlarged association.

Δs of all candidates of landmark j at once: order the associated landmarks A first and j last, and factor the
marginal of the bundle over those rows by one QR, S[:, rows] = Q [[R11, R12], [0, R22]]. Then

    log N(y_A, y; μ, P) = log N(y_A; μ_A, R11ᵀR11) + log N(y; μ_{j|A}, R22ᵀR22),
    μ_{j|A} = μ_j + R12ᵀ w_A,   R11ᵀ w_A = y_A − μ_A,

so for a candidate feature y_i (v_i solves R22ᵀ v_i = y_i − μ_{j|A})

    Δs_i = −s_U + log 2π + log|det R22| + ½ v_iᵀv_i,     joint wᵀw = w_Aᵀw_A + v_iᵀv_i.

The returned surprisal is :func:`~helpers.association.compatibility.joint_compatibility` of the final
association (the lab's eqs 14–17, evaluated once).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from scipy import linalg

from ..gaussian import Gaussian, square_r_factor
from ..validation import boolean, feature_columns, finite_number
from .common import prepare
from .compatibility import check_bundle_density, joint_compatibility

__all__ = ["snn"]

_LOG_2PI = float(np.log(2.0 * np.pi))


def _surprisal_changes(density: Gaussian, Y: np.ndarray, idx: np.ndarray, j: int, cand: np.ndarray,
                       sU: float) -> tuple[np.ndarray, np.ndarray]:
    """(Δs, joint wᵀw) of pairing landmark j with each candidate feature (columns ``cand`` of Y), given the
    pairings ``idx`` of the landmarks before j (module docstring)."""
    mu = density.mean
    assoc = np.flatnonzero(idx >= 0)
    rows = np.concatenate([(2 * assoc[:, None] + np.arange(2)).ravel(), [2 * j, 2 * j + 1]]).astype(np.intp)
    R = square_r_factor(density.sqrt_cov[:, rows])
    k = rows.size - 2
    R11, R12, R22 = R[:k, :k], R[:k, k:], R[k:, k:]
    if np.any(np.diag(R) == 0):
        raise ValueError("density is singular on the rows of this association; cannot evaluate surprisal")
    mu_j, dA2 = mu[2 * j:2 * j + 2], 0.0
    if k:
        yA = Y[:, idx[assoc]].T.ravel()
        wA = linalg.solve_triangular(R11, yA - mu[rows[:k]], trans="T", check_finite=False)
        mu_j = mu_j + R12.T @ wA                                     # μ_{j|A}
        dA2 = float(wA @ wA)
    r = Y[:, cand] - mu_j[:, None]                                   # R22ᵀ v = y − μ_{j|A}, R22 upper-triangular
    v0 = r[0] / R22[0, 0]
    v1 = (r[1] - R22[0, 1] * v0) / R22[1, 1]
    v2 = v0 * v0 + v1 * v1
    return -sU + _LOG_2PI + np.log(abs(R22[0, 0] * R22[1, 1])) + 0.5 * v2, dA2 + v2


def snn(density: Gaussian, Y: ArrayLike, sU: float, n_sigma: float = 3.0,
        enforce_joint_compatibility: bool = False) -> tuple[np.ndarray, float]:
    """Surprisal nearest neighbour association (module docstring) of the n selected landmarks of the bundle
    ``density`` (size 2n, no measurement noise in the lab) with the features Y (2, m; m = 0 allowed), with the
    surprisal sU = log W + log H of an unassociated landmark (``uniform_surprisal``), gate width ``n_sigma`` (3 in
    the lab), and with ``enforce_joint_compatibility`` also the joint gate.

    Returns (idx, surprisal): idx (n,) the feature column of each selected landmark or −1, and s(idx).
    """
    n = check_bundle_density(density, allow_empty=False)
    Y = feature_columns(Y)
    sU = finite_number(sU, "sU")
    enforce = boolean(enforce_joint_compatibility, "enforce_joint_compatibility")
    problem = prepare(density, Y, n_sigma)
    compatible = problem.ic_d2 <= problem.ic_threshold               # (n, m): eq 12 for every pair
    idx = np.full(n, -1, dtype=np.intp)
    if Y.shape[1] == 0:
        return idx, n * sU
    taken = np.zeros(Y.shape[1], dtype=bool)
    for j in range(n):                                               # loop over landmarks, not features
        cand = np.flatnonzero(compatible[j] & ~taken)                # ascending feature index
        if cand.size == 0:
            continue
        ds, joint = _surprisal_changes(density, Y, idx, j, cand, sU)
        if enforce:
            ok = joint <= problem.jc_threshold(np.count_nonzero(idx >= 0) + 1)
            cand, ds = cand[ok], ds[ok]
            if cand.size == 0:
                continue
        best = int(np.argmin(ds))                                    # first minimum → lowest feature index
        if ds[best] <= 0.0:                                          # null hypothesis only if strictly better
            idx[j] = cand[best]
            taken[cand[best]] = True
    return idx, joint_compatibility(idx, sU, Y, density, n_sigma)[1]    # one exact evaluation of s(idx)
