"""Surprisal nearest neighbour (SNN) data association — Lab 8 §3.

Given the predicted feature-bundle density p(h) = N(μ, P), P = SᵀS, of n selected landmarks (landmark k of
the selection in rows 2k, 2k+1) and m measured features Y = [y_0 … y_{m−1}] ∈ R^{2×m}, SNN builds an
association idx (idx[k] = feature column or −1) greedily, landmark by landmark in selection order:

    s(idx) = n_U·s_U − log N(y_A; μ_A, P_A)          (total surprisal, s_U = log W + log H)

1. Start from "nothing associated": s = n·s_U.
2. For landmark j = 0 … n−1 (never revisited): among the features not taken by an earlier landmark and
   individually compatible with j (3σ gate, wᵀw ≤ χ²₂(c), c = 2Φ(n_σ) − 1), pick the one whose pairing
   changes the surprisal least, Δs = s(idx ∪ {j ↦ i}) − s(idx); ties go to the lowest feature index.
   Keep it iff Δs ≤ 0 (the null hypothesis "j unassociated" has Δs = 0 and wins only when strictly
   better). With ``enforce_joint_compatibility`` a candidate must also pass the joint gate
   wᵀw ≤ χ²_{2(n_A+1)}(c) on the enlarged association.

Fast evaluation (mathematically identical to calling ``joint_compatibility`` per candidate). Order the
associated landmarks A first and landmark j last, and factor the marginal of the bundle over those rows
by one QR, S[:, rows] = Q [[R11, R12], [0, R22]]. Then

    log N(y_A, y; μ, P) = log N(y_A; μ_A, R11ᵀR11) + log N(y; μ_{j|A}, R22ᵀR22),
    μ_{j|A} = μ_j + R12ᵀ w_A,   R11ᵀ w_A = y_A − μ_A,

so for every candidate feature y_i at once (v_i solves R22ᵀ v_i = y_i − μ_{j|A})

    Δs_i = −s_U + log 2π + log|det R22| + ½ v_iᵀv_i,
    joint wᵀw = w_Aᵀw_A + v_iᵀv_i.

The individual gate is ``individual_compatibility_matrix`` (the n 2×2 marginals from one batched QR, all
m·n pairs in one vectorised expression), and the returned surprisal is one exact ``joint_compatibility``
evaluation of the final association. ``snn_reference`` is the literal per-pair loop of the lab
(individual_compatibility / joint_compatibility for every pair) and serves as the oracle and the naive
benchmark.
"""
from __future__ import annotations


import numpy as np
from scipy import linalg

from .compatibility import (check_bundle_density, individual_compatibility, individual_compatibility_matrix,
                            joint_compatibility)
from ..gaussian import chi2inv, confidence_level, square_r_factor
from ..validation import boolean, feature_columns, finite_number, float_array

__all__ = ["snn", "snn_reference"]

_LOG_2PI = float(np.log(2.0 * np.pi))


# ----------------------------------------------------------------------------------------------------
# validation
# ----------------------------------------------------------------------------------------------------
def _check_inputs(density, Y, sU, n_sigma, enforce_joint_compatibility):
    """(μ, Y, sU, enforce) of a valid SNN call; bad input raises ValueError naming the argument."""
    check_bundle_density(density, allow_empty=False)
    Y = feature_columns(float_array(Y, "Y"))
    sU = finite_number(sU, "sU")
    enforce = boolean(enforce_joint_compatibility, "enforce_joint_compatibility")
    _gate(n_sigma, 2)
    return density.mean, Y, sU, enforce


def _gate(n_sigma, dof):
    return chi2inv(confidence_level(n_sigma), dof)     # validates n_sigma


# ----------------------------------------------------------------------------------------------------
# vectorised pieces
# ----------------------------------------------------------------------------------------------------
def snn(density, Y, sU, n_sigma: float = 3.0, enforce_joint_compatibility: bool = False):
    """Surprisal nearest neighbour association (the lab's intended semantics), vectorised over features.

    Parameters
    ----------
    density : Gaussian of size 2n — the predicted feature-bundle density of the n selected landmarks
        (no measurement noise in the lab); landmark k of the selection in rows 2k, 2k+1.
    Y : (2, m) feature pixel coordinates (m = 0 allowed: then nothing can be associated).
    sU : surprisal of an unassociated landmark, log W + log H (``uniform_surprisal(image_size)``).
    n_sigma : gate width (3 in the lab). enforce_joint_compatibility : also require the joint gate.

    Returns
    -------
    idx : (n,) int array, idx[k] = feature column associated with selected landmark k, or −1.
    surprisal : float, total surprisal s(idx) of the returned association.
    """
    mu, Y, sU, enforce = _check_inputs(density, Y, sU, n_sigma, enforce_joint_compatibility)
    S = density.sqrt_cov
    n, m = mu.size // 2, Y.shape[1]
    idx = np.full(n, -1, dtype=np.intp)
    if m == 0:
        return idx, n * sU
    compatible = individual_compatibility_matrix(Y, density, n_sigma)[1].T   # (n, m), all pairs at once
    taken = np.zeros(m, dtype=bool)
    assoc: list[int] = []                                            # selected positions with idx ≥ 0
    for j in range(n):                                               # loop over landmarks, not features
        cand = np.flatnonzero(compatible[j] & ~taken)                # ascending feature index
        if cand.size == 0:
            continue
        rows = [r for a in assoc for r in (2 * a, 2 * a + 1)] + [2 * j, 2 * j + 1]
        R = square_r_factor(S[:, rows])
        k = 2 * len(assoc)
        R11, R12, R22 = R[:k, :k], R[:k, k:], R[k:, k:]
        if np.any(np.diag(R) == 0):
            raise ValueError("density is singular on the rows of this association; cannot evaluate surprisal")
        if k:
            yA = Y[:, idx[assoc]].T.ravel()
            wA = linalg.solve_triangular(R11, yA - mu[rows[:k]], trans="T", check_finite=False)
            mu_c = mu[2 * j:2 * j + 2] + R12.T @ wA
            dA2 = float(wA @ wA)
        else:
            mu_c, dA2 = mu[2 * j:2 * j + 2], 0.0
        d = Y[:, cand] - mu_c[:, None]
        v0 = d[0] / R22[0, 0]
        v1 = (d[1] - R22[0, 1] * v0) / R22[1, 1]
        dc2 = v0 * v0 + v1 * v1
        ds = -sU + _LOG_2PI + np.log(abs(R22[0, 0] * R22[1, 1])) + 0.5 * dc2
        if enforce:
            ok = dA2 + dc2 <= _gate(n_sigma, k + 2)
            cand, ds = cand[ok], ds[ok]
            if cand.size == 0:
                continue
        best = int(np.argmin(ds))                                    # first minimum → lowest feature index
        if ds[best] <= 0.0:                                          # null hypothesis only if strictly better
            idx[j] = cand[best]
            taken[cand[best]] = True
            assoc.append(j)
    _, s = joint_compatibility(idx, sU, Y, density, n_sigma)          # one exact evaluation of s(idx)
    return idx, s


def snn_reference(density, Y, sU, n_sigma: float = 3.0, enforce_joint_compatibility: bool = False):
    """The lab's SNN written literally: Python loops over landmarks and features, calling
    ``individual_compatibility`` (a 2×2 marginal QR per pair) and ``joint_compatibility`` (a joint marginal
    QR and log-density per compatible candidate). Taken features are never offered again.

    Same inputs and outputs as :func:`snn`; kept as the oracle for tests and the naive benchmark.
    """
    mu, Y, sU, enforce = _check_inputs(density, Y, sU, n_sigma, enforce_joint_compatibility)
    n, m = mu.size // 2, Y.shape[1]
    idx = [-1] * n
    s = n * sU
    if m == 0:
        return np.array(idx, dtype=np.intp), s
    taken: set[int] = set()
    for j in range(n):
        dsmin = np.inf
        scur = s
        idxcur = list(idx)
        for i in range(m):
            if i in taken or not individual_compatibility(i, j, Y, density, n_sigma):
                continue
            idxnext = list(idxcur)
            idxnext[j] = i
            jc, snext = joint_compatibility(np.array(idxnext), sU, Y, density, n_sigma)
            if enforce and not jc:
                continue
            if snext - scur < dsmin:
                idx, dsmin, s = idxnext, snext - scur, snext
        _, snext = joint_compatibility(np.array(idxcur), sU, Y, density, n_sigma)
        if snext - scur < dsmin:
            idx, s = idxcur, snext
        if idx[j] >= 0:
            taken.add(idx[j])
    return np.array(idx, dtype=np.intp), float(s)
