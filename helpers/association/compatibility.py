"""Geometric compatibility of measured features with predicted landmarks, and the surprisal (Lab 8 §2).

``density`` is the joint predicted feature-bundle density N(μ, SᵀS) of n selected landmarks (size 2n);
row pair (2j, 2j+1) belongs to the j-th *selected* landmark. ``Y`` is 2 × m, column i = feature i (x, y px).

Individual compatibility (eqs 11–13): with the 2 × 2 marginal S_j of landmark j,
    S_jᵀ w_ij = y_i − μ_j,   compatible ⇔ w_ijᵀ w_ij ≤ χ²_2(c),   c = 2Φ(n_σ) − 1.

Joint compatibility (eqs 14–17) of an association idx (one entry per landmark: feature index or −1):
    y_A = [y_{idx[k]}] and μ_A, S_A = marginal of the rows 2k, 2k+1 of the associated landmarks (in landmark
    order);  compatible ⇔ w_Aᵀ w_A ≤ χ²_{2|A|}(c) with S_Aᵀ w_A = y_A − μ_A.

Surprisal (handout derivation): an unassociated landmark's measurement is uniform over the image,
U(y) = 1/|Y| with |Y| = W·H pixels, so
    s = −log p(y) = n_U·s_U − log N(y_A; μ_A, P_A),   s_U = log W + log H;
with nothing associated s = n·s_U and the (empty) association is vacuously compatible.
"""
from __future__ import annotations

import json

import numpy as np
from numpy.typing import ArrayLike

from ..gaussian import Gaussian, confidence_level
from ..paths import data_dir
from ..validation import feature_columns, finite_number, float_array, integer
from .common import check_hypothesis

__all__ = ["check_bundle_density", "individual_compatibility", "joint_compatibility", "uniform_surprisal",
           "lab_test_fixture"]


def check_bundle_density(density: Gaussian, allow_empty: bool = True) -> int:
    """The number n of landmarks in a feature-bundle density (a ``Gaussian`` of even size 2n); anything else
    raises ValueError naming ``density``. ``allow_empty=False`` also rejects n = 0."""
    if not isinstance(density, Gaussian):
        raise ValueError(f"density must be a Gaussian (helpers.gaussian.Gaussian), got {type(density).__name__}")
    if density.size % 2 or (density.size == 0 and not allow_empty):
        least = "" if allow_empty else " ≥ 2"
        raise ValueError(f"density must have even size 2·n_landmarks{least}, got size {density.size}")
    return density.size // 2


def individual_compatibility(i: int, j: int, Y: ArrayLike, density: Gaussian, n_sigma: float = 3.0) -> bool:
    """Whether feature i is individually compatible with landmark j (Lab 8 eqs 11–13).

    Parameters
    ----------
    i : a feature, a column of Y (integer in [0, m)).
    j : a landmark of the bundle (integer in [0, n)); its predicted feature is rows 2j, 2j+1 of ``density``.
    Y : (2, m) measured features, column i = (x, y) of feature i in pixels (eq 18), m ≥ 1.
    density : the predicted feature-bundle density N(μ, SᵀS), a ``Gaussian`` of size 2n.
    n_sigma : the confidence level c = 2Φ(n_sigma) − 1 of the gate (n_sigma > 0; default 3).

    Returns
    -------
    bool (a Python bool): w_ijᵀ w_ij ≤ χ²_2(c), where S_jᵀ w_ij = y_i − μ_j and N(μ_j, S_jᵀ S_j) is the marginal
    of landmark j's two rows of the bundle density.

    Raises
    ------
    ValueError naming ``i`` or ``j`` (not an integer, or out of range), ``Y`` (not (2, m) with m ≥ 1, or not
    finite), ``density`` (not a Gaussian of even size) or ``n_sigma`` (not positive and finite).
    """
    n = check_bundle_density(density)
    Y = feature_columns(Y, allow_empty=False)
    i = integer(i, "i", minimum=0, below=Y.shape[1])
    j = integer(j, "j", minimum=0, below=n)
    return density.marginal([2 * j, 2 * j + 1]).is_within_confidence_region(Y[:, i], n_sigma)


def uniform_surprisal(image_size: ArrayLike) -> float:
    """s_U = −log U(y) = log W + log H for an image of (width, height) pixels (14.8325 for 1920 × 1440)."""
    size = float_array(image_size, "image_size")
    if size.shape != (2,) or not np.all(np.isfinite(size) & (size > 0)):
        raise ValueError(f"image_size must be two positive numbers (width, height), got {image_size!r}")
    return float(np.log(float(size[0])) + np.log(float(size[1])))


def joint_compatibility(idx: ArrayLike, sU: float, Y: ArrayLike, density: Gaussian,
                        n_sigma: float = 3.0) -> tuple[bool, float]:
    """Joint compatibility of the association ``idx`` and its total surprisal (Lab 8 eqs 14–17 and §2's surprisal).

    Parameters
    ----------
    idx : one entry per landmark of the bundle (length n): the feature (a column of Y) associated with
        landmark k, or −1 when landmark k is unassociated; no feature may appear twice.
    sU : the surprisal s_U = log |𝒴| of one unassociated landmark (finite).
    Y : (2, m) measured features, column i = (x, y) of feature i in pixels (m = 0 allowed).
    density : the predicted feature-bundle density N(μ, SᵀS), a ``Gaussian`` of size 2n; landmark k is rows
        2k, 2k+1.
    n_sigma : the confidence level c = 2Φ(n_sigma) − 1 of the gate (n_sigma > 0; default 3).

    Returns
    -------
    (compatible, surprisal) as (bool, float): with A the associated landmarks, y_A their features stacked in
    landmark order and N(μ_A, P_A) the marginal of their rows, ``compatible`` is w_Aᵀ w_A ≤ χ²_{2|A|}(c) with
    S_Aᵀ w_A = y_A − μ_A (eqs 16–17) and ``surprisal`` = n_U·sU − log N(y_A; μ_A, P_A), n_U = n − |A|. With
    nothing associated: (True, n·sU).

    Raises
    ------
    ValueError naming ``idx`` (not n integers, an entry below −1 or ≥ m, or a feature used twice), ``sU`` (not
    finite), ``Y``, ``density`` or ``n_sigma`` (as in individual_compatibility).
    """
    n = check_bundle_density(density)
    Y = feature_columns(Y)
    idx_arr = check_hypothesis(idx, n, Y.shape[1], "idx", what="feature")
    sU = finite_number(sU, "sU")
    associated = np.flatnonzero(idx_arr >= 0)
    nA = associated.size
    nU = n - nA
    if nA == 0:
        confidence_level(n_sigma)  # checks n_sigma
        return True, float(nU * sU)
    rows = (2 * associated[:, None] + np.arange(2)).ravel()
    yA = Y[:, idx_arr[associated]].T.ravel()
    pA = density.marginal(rows)
    surprisal = nU * sU - pA.log_pdf(yA)
    return bool(pA.is_within_confidence_region(yA, n_sigma)), float(surprisal)


def lab_test_fixture() -> dict:
    """The Lab 8 template's compatibility fixture from ``data/lab8_compatibility_fixture.json``:
    ``mu_Y`` (6,), ``S_YY`` (6, 6), ``Y3`` (2, 3), ``Y13`` (2, 13), ``n_sigma``, ``sU``, ``image_size``,
    and the ready-made densities ``density_1`` (first landmark, size 2) and ``density_3`` (size 6)."""
    raw = json.loads((data_dir() / "lab8_compatibility_fixture.json").read_text(encoding="utf-8"))
    mu, S = np.array(raw["muY"]), np.array(raw["SYY"])
    return {"mu_Y": mu, "S_YY": S, "Y3": np.array(raw["Y3"]), "Y13": np.array(raw["Y13"]),
            "n_sigma": float(raw["n_sigma"]), "sU": float(raw["sU"]), "image_size": tuple(raw["image_size"]),
            "density_1": Gaussian(mu[:2], S[:2, :2]), "density_3": Gaussian(mu, S)}
