"""What every data-association algorithm shares: the problem, the result and the joint distance.

The common interface (lecture L09; roles as in the lab's SNN: *landmarks choose observations*)::

    association = algorithm(density, Y, **options)

- ``density``: a :class:`helpers.gaussian.Gaussian` N(μ, P) of size d·n, the predicted measurement of the n
  candidate landmarks (landmark k in rows d·k … d·k+d−1) with the full cross-covariance and the measurement
  noise: a pairing (k, i) has the innovation ν = y_i − μ_k with covariance P_kk.
- ``Y``: the d×m observations, one per column.
- the result :class:`Association` has ``idx``, one entry per landmark: its observation column, or −1 (the
  star: not associated). An observation is never used twice.

Joint squared Mahalanobis distance of a hypothesis H = {(k₁, i₁), …, (k_a, i_a)} (Neira & Tardós 2001):

    f_H = [y_{i₁} − μ_{k₁}; …; y_{i_a} − μ_{k_a}],   C_H = P[rows(H), rows(H)],   D²_H = f_Hᵀ C_H⁻¹ f_H,

jointly compatible iff D²_H ≤ χ²_{d·a}(c) with c = 2Φ(n_σ) − 1 (``≤`` as in the lab). Every algorithm reports
D²_H of the association it returns, so their outputs are comparable.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from ..gaussian import Gaussian, chi2inv, confidence_level
from ..validation import check_symmetric, float_array, integer

__all__ = ["Association", "AssociationProblem", "prepare", "problem_from_cov", "joint_sq_mahalanobis",
           "empty_association", "check_hypothesis", "finish", "greedy_one_to_one"]


@dataclass(frozen=True)
class Association:
    """Result of an algorithm: idx (n,), each landmark's observation or −1; d2 = D²_H of the pairings (0 if none);
    jointly_compatible: D²_H ≤ χ²_{d·n_pairings}(c) at ``n_sigma``; stats: e.g. ``nodes`` for JCBB;
    budget_exhausted: a search budget cut the search short (the result is the best found)."""

    idx: np.ndarray
    d2: float
    n_pairings: int
    jointly_compatible: bool
    algorithm: str
    n_sigma: float = 3.0
    stats: dict = field(default_factory=dict)
    budget_exhausted: bool = False

    def pairs(self) -> np.ndarray:
        """Array (n_pairings, 2) of [landmark, observation] rows, in landmark order."""
        k = np.flatnonzero(self.idx >= 0)
        return np.column_stack([k, self.idx[k]]).astype(np.intp)

    def observation_labels(self, m: int) -> np.ndarray:
        """For each of the m observations, the landmark it was paired with, or −1."""
        m = integer(m, "m", minimum=int(self.idx.max(initial=-1)) + 1)
        labels = np.full(m, -1, dtype=np.intp)
        k = np.flatnonzero(self.idx >= 0)
        labels[self.idx[k]] = k
        return labels


@dataclass(frozen=True)
class AssociationProblem:
    """Checked inputs and what every algorithm needs: mu (n, d), P (d·n, d·n), Y (d, m); ic_d2 (n, m) the
    individual distances d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki; logdet (n,) log det(2π P_kk); the gate ic_threshold = χ²_d(c)."""

    mu: np.ndarray
    P: np.ndarray
    Y: np.ndarray
    ic_d2: np.ndarray
    logdet: np.ndarray
    n_sigma: float
    ic_threshold: float

    @property
    def d(self) -> int:
        return int(self.Y.shape[0])

    @property
    def n(self) -> int:
        return int(self.mu.shape[0])

    @property
    def m(self) -> int:
        return int(self.Y.shape[1])

    def jc_threshold(self, n_pairings: int | np.ndarray) -> float | np.ndarray:
        """The joint gate χ²_{d·a}(c) for a pairings (arrays too)."""
        return chi2inv(confidence_level(self.n_sigma), self.d * np.asarray(n_pairings))


def _observations(Y: ArrayLike) -> np.ndarray:
    """``Y`` as a finite (d, m) float array with d ≥ 1 (ValueError naming Y otherwise)."""
    Y = float_array(Y, "Y")
    if Y.ndim != 2 or Y.shape[0] == 0:
        raise ValueError(f"Y must be a 2-D array of shape (d, m), d ≥ 1 (one observation per column), got shape "
                         f"{Y.shape}")
    if not np.all(np.isfinite(Y)):
        bad = np.flatnonzero(~np.all(np.isfinite(Y), axis=0))
        raise ValueError(f"Y must be finite (no NaN/inf); bad columns: {bad.tolist()}")
    return Y


def prepare(density: Gaussian | AssociationProblem, Y: ArrayLike | None, n_sigma: float = 3.0) -> AssociationProblem:
    """Check ``(density, Y)`` and compute the individual distances. ``density`` may also be an
    :class:`AssociationProblem` (then Y is None or its observations): it gets the gate of ``n_sigma``. Y of shape
    (d, 0) is valid (every algorithm then returns all −1).

    ValueError naming the argument: ``density`` not a Gaussian; ``Y`` not a finite 2-D array; ``density.size``
    not a multiple of d = Y.shape[0]; ``n_sigma`` not positive; a covariance block P_kk not positive definite.
    """
    if isinstance(density, AssociationProblem):
        if Y is not None and not (Y is density.Y or np.array_equal(np.asarray(Y), density.Y)):
            raise ValueError("Y must be None or the observations of the AssociationProblem given as density")
        c = confidence_level(n_sigma)
        if float(n_sigma) == density.n_sigma:
            return density
        return replace(density, n_sigma=float(n_sigma), ic_threshold=float(chi2inv(c, density.d)))
    if not isinstance(density, Gaussian):
        raise ValueError(f"density must be a helpers.gaussian.Gaussian, got {type(density).__name__}")
    Y = _observations(Y)
    if density.size % Y.shape[0]:
        raise ValueError(f"density has size {density.size}, which is not a multiple of the observation dimension "
                         f"d = Y.shape[0] = {Y.shape[0]}")
    return _problem(density.mean.reshape(-1, Y.shape[0]), density.cov, Y, n_sigma,
                    "density: a landmark's predicted covariance block is not positive definite "
                    "(add measurement noise to the density)")


def problem_from_cov(mu: ArrayLike, P: ArrayLike, Y: ArrayLike, n_sigma: float = 3.0) -> AssociationProblem:
    """The problem of predictions ``mu`` (n, d) with covariance ``P`` (d·n, d·n, noise included) and observations
    ``Y`` (d, m), for a caller that holds P rather than a Gaussian (the online front-end). Pass it as ``density``
    (with Y None) to any algorithm but ``surprisal_nn``. ValueError naming the argument as in :func:`prepare`, and
    for P not finite and symmetric; only the blocks P_kk are checked for positive definiteness."""
    Y = _observations(Y)
    mu, P = float_array(mu, "mu"), float_array(P, "P")
    d = Y.shape[0]
    if mu.ndim != 2 or mu.shape[1] != d or not np.all(np.isfinite(mu)):
        raise ValueError(f"mu must be a finite (n, {d}) array (one predicted observation per row), got shape "
                         f"{mu.shape}")
    if P.shape != (mu.size, mu.size) or not np.all(np.isfinite(P)):
        raise ValueError(f"P must be a finite ({mu.size}, {mu.size}) covariance, got shape {P.shape}")
    check_symmetric(P, "P")
    return _problem(mu, P, Y, n_sigma, "P: a landmark's covariance block is not positive definite")


def _problem(mu: np.ndarray, P: np.ndarray, Y: np.ndarray, n_sigma: float, not_pd: str) -> AssociationProblem:
    """The per-landmark numbers from the Cholesky factors of the diagonal blocks P_kk = L_k L_kᵀ:
    d²_ki = ‖L_k⁻¹ ν_ki‖² with ν_ki = y_i − μ_k (forward substitution, all pairs at once) and
    log det(2π P_kk) = 2 Σ_a log (L_k)_aa + d log 2π."""
    c = confidence_level(n_sigma)
    n, d = mu.shape
    P = 0.5 * (P + P.T)
    blocks = P.reshape(n, d, n, d)[np.arange(n), :, np.arange(n), :]   # (n, d, d) diagonal blocks P_kk
    try:
        L = np.linalg.cholesky(blocks)
    except np.linalg.LinAlgError:
        raise ValueError(not_pd) from None
    logdet = 2.0 * np.sum(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1) + d * np.log(2.0 * np.pi)
    nu = Y[None, :, :] - mu[:, :, None]                                # (n, d, m) innovations ν_ki
    w = np.empty_like(nu)
    for a in range(d):                                                 # w = L_k⁻¹ ν_ki, row a of L_k
        w[:, a] = (nu[:, a] - np.einsum("ku,kum->km", L[:, a, :a], w[:, :a])) / L[:, a, a, None]
    return AssociationProblem(mu=np.ascontiguousarray(mu), P=P, Y=Y, ic_d2=np.einsum("kam,kam->km", w, w),
                              logdet=logdet, n_sigma=float(n_sigma), ic_threshold=float(chi2inv(c, d)))


def check_hypothesis(idx: ArrayLike, n: int, m: int, name: str = "idx", what: str = "observation") -> np.ndarray:
    """``idx`` as n intp entries, each −1 or a column in [0, m), none used twice; else ValueError naming ``name``."""
    arr = np.asarray(idx)
    if arr.ndim != 1 or arr.size != n:
        raise ValueError(f"{name} must have one entry per landmark (length {n}), got shape {arr.shape}")
    if arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must contain integers ({what} column or -1), got dtype {arr.dtype}")
    if np.any(arr < -1) or np.any(arr >= m):
        raise ValueError(f"{name} entries must be -1 or {what} columns in [0, {m}): {arr.tolist()}")
    if np.unique(arr[arr >= 0]).size != np.count_nonzero(arr >= 0):
        raise ValueError(f"{name} gives one {what} to several landmarks: {arr.tolist()}")
    return arr.astype(np.intp)


def joint_sq_mahalanobis(problem: AssociationProblem, idx: ArrayLike) -> float:
    """D²_H of the hypothesis ``idx`` (one entry per landmark, observation column or −1), from scratch."""
    if not isinstance(problem, AssociationProblem):
        raise ValueError(f"problem must be an AssociationProblem (from prepare), got {type(problem).__name__}")
    return _joint_d2(problem, check_hypothesis(idx, problem.n, problem.m))


def _joint_d2(problem: AssociationProblem, idx: np.ndarray) -> float:
    """D²_H = ‖L⁻¹ f_H‖² with C_H = L Lᵀ (the module docstring), for a checked ``idx``."""
    k = np.flatnonzero(idx >= 0)
    if k.size == 0:
        return 0.0
    rows = (problem.d * k[:, None] + np.arange(problem.d)).ravel()
    f = (problem.Y[:, idx[k]].T - problem.mu[k]).ravel()
    try:
        L = np.linalg.cholesky(problem.P[np.ix_(rows, rows)])
    except np.linalg.LinAlgError:
        raise ValueError(f"P is not positive definite: the joint covariance of landmarks {k.tolist()} has no "
                         "Cholesky factor (problem_from_cov checks only each landmark's own block)") from None
    w = np.linalg.solve(L, f)
    return float(w @ w)


def finish(problem: AssociationProblem, idx: ArrayLike, algorithm: str, stats: dict | None = None,
           budget_exhausted: bool = False, d2: float | None = None) -> Association:
    """Wrap an ``idx`` into an :class:`Association`, with its joint D² (computed here unless given)."""
    idx = np.asarray(idx, dtype=np.intp).copy()
    idx.setflags(write=False)
    a = int(np.count_nonzero(idx >= 0))
    d2 = _joint_d2(problem, idx) if d2 is None else float(d2)
    jc = a == 0 or bool(d2 <= problem.jc_threshold(a))
    return Association(idx=idx, d2=d2, n_pairings=a, jointly_compatible=jc, algorithm=algorithm,
                       n_sigma=problem.n_sigma, stats=dict(stats or {}), budget_exhausted=bool(budget_exhausted))


def empty_association(problem: AssociationProblem, algorithm: str, stats: dict | None = None) -> Association:
    """All landmarks unassociated (e.g. no observations)."""
    return finish(problem, np.full(problem.n, -1), algorithm, stats=stats, d2=0.0)


def greedy_one_to_one(cost: np.ndarray, allowed: np.ndarray) -> np.ndarray:
    """Global greedy one-to-one assignment: the pairs (k, i) with ``allowed[k, i]``, in increasing ``cost[k, i]``
    (ties: lower landmark, then lower observation), each accepted while both ends are free. cost, allowed: (n, m).
    Returns idx (n,): the observation of each landmark, or −1."""
    n, m = cost.shape
    idx = np.full(n, -1, dtype=np.intp)
    taken = np.zeros(m, dtype=bool)
    rows, cols = np.nonzero(allowed)                           # row-major: landmark, then observation order
    order = np.argsort(cost[rows, cols], kind="stable")
    for k, i in zip(rows[order].tolist(), cols[order].tolist()):
        if idx[k] < 0 and not taken[i]:
            idx[k], taken[i] = i, True
    return idx
