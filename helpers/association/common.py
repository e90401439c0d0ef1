"""What every data-association algorithm shares: the problem, the result and the joint distance.

The common interface (lecture L09; roles as in the lab's SNN: *landmarks choose observations*)::

    association = algorithm(density, Y, **options)

- ``density``: a :class:`helpers.gaussian.Gaussian` of size d·n, the joint predicted measurement of the n
  candidate landmarks (landmark k in rows d·k … d·k+d−1) **with the full cross-covariance** (shared pose
  uncertainty correlates the landmarks). It is the distribution of the observation each landmark would
  produce, so it already contains the measurement noise: for a pairing (k, i) the innovation is
  ν = y_i − μ_k and its covariance is the block P_kk of ``density.cov``.
- ``Y``: the d×m observations, one per column.
- the result :class:`Association` has ``idx`` with one entry per landmark: the observation column paired
  with it, or −1 (the star: not observed / not associated). An observation is never used twice.

Joint squared Mahalanobis distance of a hypothesis H = {(k₁, i₁), …, (k_a, i_a)} (Neira & Tardós 2001):

    f_H = [y_{i₁} − μ_{k₁}; …; y_{i_a} − μ_{k_a}],   C_H = P[rows(H), rows(H)],   D²_H = f_Hᵀ C_H⁻¹ f_H,

jointly compatible iff D²_H ≤ χ²_{d·a}(c) with c = 2Φ(n_σ) − 1 (the lab's confidence level; ``≤`` as in
the lab). Every algorithm reports D²_H of the association it returns, so their outputs are comparable.
"""
from __future__ import annotations

import numbers
from dataclasses import dataclass, field, replace

import numpy as np

from ..gaussian import Gaussian, chi2inv, confidence_level
from ..validation import check_symmetric, float_array

__all__ = ["Association", "AssociationProblem", "prepare", "problem_from_cov", "joint_sq_mahalanobis",
           "empty_association", "check_hypothesis", "finish", "greedy_one_to_one"]


@dataclass(frozen=True)
class Association:
    """Result of a data-association algorithm.

    Attributes
    ----------
    idx : int array (n,)
        For each landmark, the observation column paired with it, or −1.
    d2 : float
        Joint squared Mahalanobis distance D²_H of the paired set (full cross-covariance); 0 if empty.
    n_pairings : int
        Number of landmarks paired with an observation.
    jointly_compatible : bool
        D²_H ≤ χ²_{d·n_pairings}(c) at the confidence level of ``n_sigma`` (True for no pairings).
    algorithm : str
        Name of the algorithm that produced the result.
    n_sigma : float
        Gate width used for ``jointly_compatible`` (and by the algorithm's gates, where it has one).
    stats : dict
        Algorithm-specific statistics (e.g. ``nodes`` for JCBB).
    budget_exhausted : bool
        True when a search budget cut the search short (the result is then the best found so far).
    """

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
        if isinstance(m, bool) or not isinstance(m, numbers.Integral) or m < 0:
            raise ValueError(f"m must be a non-negative integer, got {m!r}")
        if np.any(self.idx >= m):
            raise ValueError(f"m = {m} is smaller than an observation index in idx ({int(self.idx.max())})")
        labels = np.full(int(m), -1, dtype=np.intp)
        k = np.flatnonzero(self.idx >= 0)
        labels[self.idx[k]] = k
        return labels


@dataclass(frozen=True)
class AssociationProblem:
    """Validated inputs plus the per-landmark quantities every algorithm needs.

    mu (n, d) predicted means; P (d·n, d·n) joint covariance; Y (d, m); ic_d2 (n, m) individual squared
    Mahalanobis distances d²_ki = ν_kiᵀ P_kk⁻¹ ν_ki; logdet (n,) log det(2π P_kk); n_sigma and the IC
    threshold χ²_d(c).
    """

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

    def subset(self, landmarks) -> AssociationProblem:
        """The problem of the landmarks ``landmarks`` (ascending or not, each at most once) with the same
        observations: every number is taken from this problem, none recomputed, so a search on the subset sees
        exactly the distances of the full problem (the front-end re-runs an algorithm without one candidate)."""
        rows = np.asarray(landmarks)
        if rows.ndim != 1 or (rows.size and not np.issubdtype(rows.dtype, np.integer)) \
                or np.any(rows < 0) or np.any(rows >= self.n) or np.unique(rows).size != rows.size:
            raise ValueError(f"landmarks must be distinct landmark indices in [0, {self.n}), got {rows.tolist()}")
        d = self.d
        r = (d * rows.astype(np.int64)[:, None] + np.arange(d)).ravel()
        return AssociationProblem(mu=self.mu[rows], P=self.P[np.ix_(r, r)], Y=self.Y,
                                  ic_d2=self.ic_d2[rows], logdet=self.logdet[rows], n_sigma=self.n_sigma,
                                  ic_threshold=self.ic_threshold)

    def jc_threshold(self, n_pairings):
        """χ²_{d·a}(c) for a pairings (array-friendly)."""
        if isinstance(n_pairings, (int, np.integer)):
            return chi2inv(confidence_level(self.n_sigma), self.d * int(n_pairings))     # cached scalar
        return chi2inv(confidence_level(self.n_sigma), self.d * np.asarray(n_pairings))


def _observations(Y):
    """``Y`` checked: a finite (d, m) float array with d ≥ 1 (ValueError naming Y otherwise)."""
    Y = float_array(Y, "Y")
    if Y.ndim != 2:
        raise ValueError(f"Y must be a 2-D array of shape (d, m) (one observation per column), got shape {Y.shape}")
    if Y.shape[0] == 0:
        raise ValueError("Y must have at least one row (the observation dimension d), got shape (0, m)")
    if not np.all(np.isfinite(Y)):
        bad = np.flatnonzero(~np.all(np.isfinite(Y), axis=0))
        raise ValueError(f"Y must be finite (no NaN/inf); bad columns: {bad.tolist()}")
    return Y


def _given_problem(problem, Y, n_sigma):
    """A problem handed to an algorithm instead of a density: Y must be None or its observations; the gate
    follows ``n_sigma``."""
    if Y is not None and not (Y is problem.Y or np.array_equal(np.asarray(Y), problem.Y)):
        raise ValueError("Y must be None or the observations of the AssociationProblem given as density")
    c = confidence_level(n_sigma)  # validates n_sigma
    if float(n_sigma) == problem.n_sigma:
        return problem
    return replace(problem, n_sigma=float(n_sigma), ic_threshold=float(chi2inv(c, problem.d)))


def prepare(density, Y, n_sigma: float = 3.0) -> AssociationProblem:
    """Validate ``(density, Y)`` for the common interface and precompute the individual distances.

    ``density`` may also be an :class:`AssociationProblem` (from :func:`problem_from_cov` or an earlier
    ``prepare``): it is returned as it is (its gate set by ``n_sigma``), and Y must then be None or its
    observations. This is how a caller that runs several algorithms on one problem prepares it once.

    Raises ValueError naming the argument when: ``density`` is not a Gaussian; ``Y`` is not a finite 2-D
    array; ``density.size`` is not a multiple of d = Y.shape[0]; ``n_sigma`` is not positive; a landmark's
    predicted covariance block is not positive definite. An empty observation set (m = 0, Y of shape
    (d, 0)) is valid: every algorithm then returns all −1.
    """
    if isinstance(density, AssociationProblem):
        return _given_problem(density, Y, n_sigma)
    if not isinstance(density, Gaussian):
        raise ValueError(f"density must be a helpers.gaussian.Gaussian, got {type(density).__name__}")
    Y = _observations(Y)
    d = Y.shape[0]
    if density.size % d:
        raise ValueError(f"density has size {density.size}, which is not a multiple of the observation "
                         f"dimension d = Y.shape[0] = {d}")
    return _problem(density.mean.reshape(-1, d), density.cov, Y, n_sigma,
                    "density: a landmark's predicted covariance block is not positive definite "
                    "(add measurement noise to the density)")


def problem_from_cov(mu, P, Y, n_sigma: float = 3.0) -> AssociationProblem:
    """The problem of predicted observations ``mu`` (n, d) with joint covariance ``P`` (d·n, d·n, measurement
    noise included, symmetric) and observations ``Y`` (d, m), for a caller that holds the covariance rather
    than a Gaussian (the online front-end builds one per scan): the numbers of :func:`prepare`. Pass it as
    ``density`` to any algorithm (with Y None) except ``surprisal_nn``, which needs the lab's Gaussian.

    ValueError naming the argument: mu not a finite 2-D array, Y not finite (d, m) with mu's d, P not finite
    of shape (d·n, d·n) or not symmetric, a diagonal block of P not positive definite, n_sigma not positive.
    Only the diagonal blocks of P are checked for positive definiteness; the joint D² an algorithm reports
    raises ValueError when its block of P has no Cholesky factor.
    """
    Y = _observations(Y)
    d = Y.shape[0]
    mu = float_array(mu, "mu")
    if mu.ndim != 2 or mu.shape[1] != d or not np.all(np.isfinite(mu)):
        raise ValueError(f"mu must be a finite (n, {d}) array (one predicted observation per row, d = Y.shape[0]),"
                         f" got shape {mu.shape}")
    n = mu.shape[0]
    P = float_array(P, "P")
    if P.shape != (d * n, d * n) or not np.all(np.isfinite(P)):
        raise ValueError(f"P must be a finite ({d * n}, {d * n}) covariance, got shape {P.shape}")
    check_symmetric(P, "P")
    return _problem(mu, P, Y, n_sigma, "P: a landmark's covariance block is not positive definite")


def _problem(mu, P, Y, n_sigma, not_positive_definite) -> AssociationProblem:
    """The per-landmark numbers, from the Cholesky factors L_k of the diagonal blocks P_kk = L_k L_kᵀ:
    d²_ki = ‖L_k⁻¹ ν_ki‖² with ν_ki = y_i − μ_k (forward substitution, all pairs at once) and
    log det(2π P_kk) = 2 Σ_a log (L_k)_aa + d log 2π."""
    c = confidence_level(n_sigma)  # validates n_sigma
    n, d = mu.shape
    P = 0.5 * (P + P.T)
    blocks = P.reshape(n, d, n, d)[np.arange(n), :, np.arange(n), :]   # (n, d, d) diagonal blocks P_kk
    try:
        L = np.linalg.cholesky(blocks)
    except np.linalg.LinAlgError:
        raise ValueError(not_positive_definite) from None
    logdet = 2.0 * np.sum(np.log(np.diagonal(L, axis1=1, axis2=2)), axis=1) + d * np.log(2.0 * np.pi)
    nu = Y[None, :, :] - mu[:, :, None]                                # (n, d, m) innovations ν_ki
    w = np.empty_like(nu)
    for a in range(d):                                                 # w = L_k⁻¹ ν_ki, row a of L_k
        w[:, a] = (nu[:, a] - np.einsum("ku,kum->km", L[:, a, :a], w[:, :a])) / L[:, a, a, None]
    ic_d2 = np.einsum("kam,kam->km", w, w)
    return AssociationProblem(mu=np.ascontiguousarray(mu), P=P, Y=Y, ic_d2=ic_d2, logdet=logdet,
                              n_sigma=float(n_sigma), ic_threshold=float(chi2inv(c, d)))


def check_hypothesis(idx, n: int, m: int, name: str = "idx") -> np.ndarray:
    """``idx`` as an intp array of n entries, each −1 or an observation column in [0, m), no column used
    twice; anything else raises ValueError naming ``name``."""
    arr = np.asarray(idx)
    if arr.ndim != 1 or arr.size != n:
        raise ValueError(f"{name} must have one entry per landmark (length {n}), got shape {arr.shape}")
    if arr.size and (arr.dtype == bool or not np.issubdtype(arr.dtype, np.integer)):
        raise ValueError(f"{name} must contain integers (observation column or -1), got dtype {arr.dtype}")
    if np.any(arr < -1) or np.any(arr >= m):
        raise ValueError(f"{name} entries must be -1 or an observation column in [0, {m}): {arr.tolist()}")
    used = arr[arr >= 0]
    if np.unique(used).size != used.size:
        raise ValueError(f"{name} gives one observation to several landmarks: {arr.tolist()}")
    return arr.astype(np.intp)


def joint_sq_mahalanobis(problem: AssociationProblem, idx) -> float:
    """D²_H of the hypothesis ``idx`` (one entry per landmark, observation column or −1), from scratch.
    ``idx`` is checked (:func:`check_hypothesis`); ``problem`` must come from :func:`prepare`."""
    if not isinstance(problem, AssociationProblem):
        raise ValueError(f"problem must be an AssociationProblem (from prepare), got {type(problem).__name__}")
    return _joint_d2(problem, check_hypothesis(idx, problem.n, problem.m))


def _joint_d2(problem, idx) -> float:
    """:func:`joint_sq_mahalanobis` without the checks (the search loops call it per candidate)."""
    k = np.flatnonzero(idx >= 0)
    if k.size == 0:
        return 0.0
    d = problem.d
    rows = (d * k[:, None] + np.arange(d)).ravel()
    f = (problem.Y[:, idx[k]].T - problem.mu[k]).ravel()
    try:
        L = np.linalg.cholesky(problem.P[np.ix_(rows, rows)])
    except np.linalg.LinAlgError:
        raise ValueError(f"P is not positive definite: the joint covariance of landmarks {k.tolist()} has no "
                         "Cholesky factor (problem_from_cov checks only each landmark's own block)") from None
    w = np.linalg.solve(L, f)
    return float(w @ w)


def finish(problem: AssociationProblem, idx, algorithm: str, stats=None, budget_exhausted=False,
           d2=None, jc_gates=None) -> Association:
    """Wrap an ``idx`` into an :class:`Association` (joint D² computed here unless given; ``jc_gates[a]``, when
    given, is the joint gate χ²_{d·a}(c) the caller already holds)."""
    idx = np.asarray(idx, dtype=np.intp).copy()
    idx.setflags(write=False)
    a = int(np.count_nonzero(idx >= 0))
    d2 = _joint_d2(problem, idx) if d2 is None else float(d2)
    if a == 0:
        jc = True
    else:
        jc = bool(d2 <= (problem.jc_threshold(a) if jc_gates is None else jc_gates[a]))
    return Association(idx=idx, d2=d2, n_pairings=a, jointly_compatible=jc, algorithm=algorithm,
                       n_sigma=problem.n_sigma, stats=dict(stats or {}), budget_exhausted=bool(budget_exhausted))


def empty_association(problem: AssociationProblem, algorithm: str, stats=None) -> Association:
    """All landmarks unassociated (e.g. no observations)."""
    if not isinstance(problem, AssociationProblem):
        raise ValueError(f"problem must be an AssociationProblem (from prepare), got {type(problem).__name__}")
    if not isinstance(algorithm, str):
        raise ValueError(f"algorithm must be a name (str), got {type(algorithm).__name__}")
    return finish(problem, np.full(problem.n, -1), algorithm, stats=stats, d2=0.0)


def greedy_one_to_one(cost, allowed) -> np.ndarray:
    """Global greedy one-to-one assignment: pairs in increasing ``cost`` (ties: lower landmark, then lower
    observation index), accepted when both ends are still free and ``allowed``. cost, allowed: (n, m).
    Returns idx (n,) with the observation of each landmark or −1.
    """
    cost = float_array(cost, "cost")
    if cost.ndim != 2 or np.any(np.isnan(cost)):
        raise ValueError(f"cost must be a 2-D (n, m) array without NaN, got shape {cost.shape}")
    allowed = np.asarray(allowed)
    if allowed.shape != cost.shape or allowed.dtype != bool:
        raise ValueError(f"allowed must be a boolean array of the shape of cost {cost.shape}, got "
                         f"{allowed.dtype} {allowed.shape}")
    n, m = cost.shape
    idx = np.full(n, -1, dtype=np.intp)
    taken = np.zeros(m, dtype=bool)
    rows, cols = np.nonzero(allowed)                           # row-major: landmark, then observation order
    order = np.argsort(cost[rows, cols], kind="stable")
    for k, i in zip(rows[order].tolist(), cols[order].tolist()):
        if idx[k] < 0 and not taken[i]:
            idx[k], taken[i] = i, True
    return idx
