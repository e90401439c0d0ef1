"""The square-root Gaussian N(μ, P) with P = SᵀS and S upper-triangular (course Labs 5, 7, 8).

Every operation is a triangular solve or a QR decomposition, so covariances stay symmetric positive
semi-definite by construction. Diagonal entries of S may be negative (QR does not normalise signs).

- marginal(idx):   QR of S[:, idx] = Q R, new S = top |idx| rows of R; then RᵀR = P[idx, idx].
- conditional(A, B, x_B):  QR of [S[:, B], S[:, A]] = Q [[R1, R2], [0, R3]];
                   μ_{A|B} = μ_A + R2ᵀ R1⁻ᵀ (x_B − μ_B),  S_{A|B} = R3.
- transform(h):    y = h(μ), C = ∂h/∂x(μ);  QR of [S Cᵀ; S_R] (noise N(0, S_RᵀS_R) optional);
                   S_y = top m rows of R, so P_y = C P Cᵀ + S_RᵀS_R.
- log_pdf(x):      −½ wᵀw − (n/2) log 2π − Σ log|S_ii|  with  Sᵀ w = x − μ.
- confidence region (Lab 7 eqs 19–24): c = 2Φ(n_σ) − 1;  x is inside iff wᵀw ≤ χ²_n(c).

A singular S (a zero on its diagonal) is allowed; the methods that solve with S (log_pdf, sq_mahalanobis,
is_within_confidence_region, conditional's R1) then raise ValueError.
"""
from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike
from scipy import linalg, special

from .validation import check_symmetric, finite_vector, float_array, index_list, integer, positive_number

__all__ = ["Gaussian", "chi2inv", "chi2_interval", "normcdf", "confidence_level", "square_r_factor"]


def chi2inv(p: ArrayLike, nu: ArrayLike) -> float | np.ndarray:
    """Inverse CDF of the χ² distribution with ``nu`` degrees of freedom: 2·gammaincinv(ν/2, p).

    ``p`` must lie in [0, 1), ``nu`` must be positive. Scalars give a float; arrays broadcast.
    """
    if (type(p) is float and type(nu) in (int, float)) or (isinstance(p, numbers.Real)
                                                         and isinstance(nu, numbers.Real)):
        return _chi2inv_scalar(float(p), float(nu))    # the association gates ask for a few values very often
    return _chi2inv_array(p, nu)


@functools.lru_cache(maxsize=256)
def _chi2inv_scalar(p: float, nu: float) -> float:
    return _chi2inv_array(p, nu)


def _chi2inv_array(p: ArrayLike, nu: ArrayLike) -> float | np.ndarray:
    p_arr = float_array(p, "p")
    nu_arr = float_array(nu, "nu")
    if not np.all(np.isfinite(p_arr)) or np.any(p_arr < 0) or np.any(p_arr >= 1):
        raise ValueError(f"p must lie in [0, 1), got {p!r}")
    if not np.all(np.isfinite(nu_arr)) or np.any(nu_arr <= 0):
        raise ValueError(f"nu must be positive and finite, got {nu!r}")
    try:
        out = 2.0 * special.gammaincinv(nu_arr / 2.0, p_arr)
    except ValueError:
        raise ValueError(f"p and nu must broadcast to a common shape, got p {p_arr.shape}, nu {nu_arr.shape}") from None
    return float(out) if out.ndim == 0 else out


def normcdf(w: ArrayLike) -> float | np.ndarray:
    """Standard normal CDF Φ(w) = ½ erfc(−w/√2). Scalars give a float; arrays broadcast."""
    w_arr = float_array(w, "w")
    if np.any(np.isnan(w_arr)):
        raise ValueError(f"w must not be NaN, got {w!r}")
    out = special.ndtr(w_arr)
    return float(out) if out.ndim == 0 else out


def chi2_interval(dof: int, probability: float = 0.99) -> tuple[float, float]:
    """(lo, hi) with P(lo ≤ χ²_dof ≤ hi) = probability, equal tails: the (1 ∓ p)/2 quantiles of χ²_dof.

    The acceptance interval of a consistent graph's χ² (dof = measurement dimensions − free state dimensions).
    """
    dof = integer(dof, "dof", minimum=1)
    if isinstance(probability, bool) or not isinstance(probability, numbers.Real) or not 0 < probability < 1:
        raise ValueError(f"probability must lie in (0, 1), got {probability!r}")
    tail = 0.5 * (1.0 - float(probability))
    return chi2inv(tail, dof), chi2inv(1.0 - tail, dof)


def confidence_level(n_sigma: float) -> float:
    """c = 2Φ(n_σ) − 1, the probability mass within ±n_σ of a 1-D Gaussian (0.9973002039367398 for 3)."""
    if type(n_sigma) is float and 0.0 < n_sigma < math.inf:
        return _confidence_level(n_sigma)             # the common case, without the checks of positive_number
    return _confidence_level(positive_number(n_sigma, "n_sigma"))


@functools.lru_cache(maxsize=64)
def _confidence_level(n_sigma: float) -> float:
    return 2.0 * normcdf(n_sigma) - 1.0           # the gates ask for the same few levels very often


def square_r_factor(A: ArrayLike) -> np.ndarray:
    """The k × k upper-triangular R with AᵀA = RᵀR for A of shape (r, k): the top k rows of A's QR factor,
    zero-padded when r < k. The one QR step behind marginal, conditional and transform."""
    A = float_array(A, "A")
    if A.ndim != 2:
        raise ValueError(f"A must be a 2-D array (r, k), got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("A must be finite (no NaN/inf)")
    k = A.shape[1]
    out = np.zeros((k, k))
    if A.shape[0]:
        R = np.triu(np.linalg.qr(A, mode="r"))
        out[:min(R.shape[0], k)] = R[:k]
    return out


class Gaussian:
    """N(μ, SᵀS) with S upper-triangular.

    Parameters
    ----------
    mu : array (n,), finite, n ≥ 1
    S  : array (n, n), finite, upper-triangular (entries below the diagonal must be 0 up to 1e-12·max|S|; they
         are then set exactly to 0). A zero diagonal (singular S) is accepted.
    """

    __slots__ = ("_mu", "_S")

    def __init__(self, mu: ArrayLike, S: ArrayLike) -> None:
        mu = finite_vector(mu, "mu")
        if mu.size == 0:
            raise ValueError("mu must have at least one element")
        S = np.array(float_array(S, "S"))       # a copy: a Gaussian owns its square root
        n = mu.size
        if S.ndim != 2 or S.shape[0] != S.shape[1]:
            raise ValueError(f"S must be a square 2-D array, got shape {S.shape}")
        if S.shape[0] != n:
            raise ValueError(f"S must have shape ({n}, {n}), got {S.shape}")
        if not np.all(np.isfinite(S)):
            raise ValueError("S must be finite (no NaN/inf)")
        if np.any(np.abs(np.tril(S, -1)) > 1e-12 * np.max(np.abs(S))):
            raise ValueError("S must be upper-triangular (non-zero entries below the diagonal)")
        self._mu = mu.copy()
        self._S = np.triu(S)

    @classmethod
    def from_sqrt_cov(cls, S: ArrayLike) -> Gaussian:
        """Zero-mean Gaussian N(0, SᵀS) (used for additive noise)."""
        S = float_array(S, "S")
        if S.ndim != 2:
            raise ValueError(f"S must be a square 2-D array, got shape {S.shape}")
        return cls(np.zeros(S.shape[0]), S)

    @classmethod
    def from_cov(cls, mu: ArrayLike, P: ArrayLike) -> Gaussian:
        """N(μ, P) from a dense covariance: S = Lᵀ with P = L Lᵀ (Cholesky). P must be symmetric PD."""
        mu = finite_vector(mu, "mu")
        P = float_array(P, "P")
        if P.shape != (mu.size, mu.size):
            raise ValueError(f"P must have shape ({mu.size}, {mu.size}), got {P.shape}")
        if not np.all(np.isfinite(P)):
            raise ValueError("P must be finite (no NaN/inf)")
        check_symmetric(P, "P")
        try:
            L = np.linalg.cholesky(0.5 * (P + P.T))
        except np.linalg.LinAlgError:
            raise ValueError("P must be positive definite (Cholesky factorisation failed)") from None
        return cls(mu, L.T)

    @property
    def mean(self) -> np.ndarray:
        """μ, shape (n,) (a copy)."""
        return self._mu.copy()

    @property
    def sqrt_cov(self) -> np.ndarray:
        """S, shape (n, n), upper-triangular (a copy)."""
        return self._S.copy()

    @property
    def cov(self) -> np.ndarray:
        """P = SᵀS, shape (n, n); ValueError when an entry overflows float64 (|S| near 1e154 or more)."""
        with np.errstate(over="ignore", invalid="ignore"):
            P = self._S.T @ self._S
        if not np.all(np.isfinite(P)):
            raise ValueError(f"S is too large for a dense covariance: SᵀS overflows float64 (max |S| = "
                             f"{np.max(np.abs(self._S)):.3g}); use sqrt_cov and the square-root operations")
        return P

    @property
    def size(self) -> int:
        """n, the dimension."""
        return int(self._mu.size)

    def __repr__(self) -> str:
        return f"Gaussian(size={self.size})"

    def marginal(self, idx: ArrayLike) -> Gaussian:
        """Marginal of the components ``idx`` (any order, non-contiguous allowed): QR of S[:, idx]."""
        idx = index_list(idx, self.size, "idx", integral_floats=True)
        return Gaussian(self._mu[idx], square_r_factor(self._S[:, idx]))

    def conditional(self, idx_a: ArrayLike, idx_b: ArrayLike, x_b: ArrayLike) -> Gaussian:
        """p(x_A | x_B = x_b) by QR of [S[:, B], S[:, A]] (Lab 5 eqs 23–26); A and B disjoint, B without repeats."""
        idx_a = index_list(idx_a, self.size, "idx_a", integral_floats=True)
        idx_b = index_list(idx_b, self.size, "idx_b", integral_floats=True, distinct=True)
        if np.intersect1d(idx_a, idx_b).size:
            raise ValueError("idx_a and idx_b must be disjoint")
        x_b = finite_vector(x_b, "x_b", idx_b.size)
        nb = idx_b.size
        R = square_r_factor(np.hstack([self._S[:, idx_b], self._S[:, idx_a]]))
        R1, R2, R3 = R[:nb, :nb], R[:nb, nb:], R[nb:, nb:]
        if np.any(np.diag(R1) == 0):
            raise ValueError("the marginal of idx_b is singular; cannot condition on x_b")
        z = linalg.solve_triangular(R1, x_b - self._mu[idx_b], trans="T", lower=False)
        return Gaussian(self._mu[idx_a] + R2.T @ z, R3)

    def transform(self, h: Callable, noise: Gaussian | None = None) -> Gaussian:
        """First-order (affine) transform through y = h(x): ``h(x)`` returns ``(y, J)`` with J = ∂h/∂x.

        S_y = top m rows of R in QR([S Jᵀ; S_R]); ``noise`` (optional) is a zero-mean Gaussian of size
        m = len(y), added as independent additive noise.
        """
        if not callable(h):
            raise ValueError(f"h must be callable returning (y, J), got {type(h).__name__}")
        out = h(self._mu.copy())
        if not isinstance(out, tuple) or len(out) != 2:
            raise ValueError("h must return a tuple (y, J)")
        y = finite_vector(out[0], "h(x)[0] (y)")
        J = float_array(out[1], "h(x)[1] (the Jacobian J)")
        if J.shape != (y.size, self.size):
            raise ValueError(f"h(x)[1] (the Jacobian J) must have shape ({y.size}, {self.size}), got {J.shape}")
        if not np.all(np.isfinite(J)):
            raise ValueError("h(x)[1] (the Jacobian J) must be finite")
        A = self._S @ J.T
        if noise is not None:
            if not isinstance(noise, Gaussian):
                raise ValueError(f"noise must be a Gaussian or None, got {type(noise).__name__}")
            if noise.size != y.size:
                raise ValueError(f"noise must have size {y.size} (the size of h(x)), got {noise.size}")
            if np.any(noise._mu != 0):
                raise ValueError("noise must have zero mean")
            A = np.vstack([A, noise._S])
        return Gaussian(y, square_r_factor(A))

    def _whiten(self, X: ArrayLike, name: str) -> np.ndarray:
        """w with Sᵀ w = X − μ, for X of shape (n,) or (n, m)."""
        X = float_array(X, name)
        if X.ndim not in (1, 2) or X.shape[0] != self.size:
            raise ValueError(f"{name} must have shape ({self.size},) or ({self.size}, m), got {X.shape}")
        if not np.all(np.isfinite(X)):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
        if np.any(np.diag(self._S) == 0):
            raise ValueError("S is singular (zero on its diagonal); this operation needs an invertible S")
        D = X - (self._mu if X.ndim == 1 else self._mu[:, None])
        return linalg.solve_triangular(self._S, D, trans="T", lower=False, check_finite=False)

    def sq_mahalanobis(self, X: ArrayLike) -> float | np.ndarray:
        """(x − μ)ᵀ P⁻¹ (x − μ) = wᵀw with Sᵀ w = x − μ. X (n,) → float; X (n, m) columns → (m,)."""
        w = self._whiten(X, "X")
        out = np.sum(w * w, axis=0)
        return float(out) if out.ndim == 0 else out

    def log_pdf(self, x: ArrayLike) -> float:
        """log N(x; μ, P) = −½ wᵀw − (n/2) log 2π − Σ log|S_ii| with Sᵀ w = x − μ, for x of shape (n,)."""
        if np.ndim(float_array(x, "x")) != 1:
            raise ValueError(f"x must have shape ({self.size},), got {np.shape(x)}")
        w = self._whiten(x, "x")
        return float(-0.5 * (w @ w) - 0.5 * self.size * np.log(2.0 * np.pi) - np.sum(np.log(np.abs(np.diag(self._S)))))

    def is_within_confidence_region(self, x: ArrayLike, n_sigma: float = 3.0) -> bool | np.ndarray:
        """wᵀw ≤ χ²_n(c), c = 2Φ(n_σ) − 1 (Lab 7 eqs 19–24; note ≤). x (n,) → bool; (n, m) → bool (m,)."""
        threshold = chi2inv(confidence_level(n_sigma), self.size)
        d2 = self.sq_mahalanobis(x)
        return bool(d2 <= threshold) if np.ndim(d2) == 0 else d2 <= threshold

    def confidence_ellipse(self, n_sigma: float = 3.0, n_samples: int = 100) -> np.ndarray:
        """Boundary of the n_σ confidence region of a 2-D Gaussian, shape (2, n_samples), closed curve.

        t = linspace(0, 2π, n_samples) (both ends), w = r [cos t; sin t], r = sqrt(χ²_2(c)), X = μ + Sᵀ w.
        """
        if self.size != 2:
            raise ValueError(f"confidence_ellipse needs a 2-D Gaussian, this one has size {self.size}")
        n_samples = integer(n_samples, "n_samples", minimum=2)
        r = np.sqrt(chi2inv(confidence_level(n_sigma), 2))
        t = np.linspace(0.0, 2.0 * np.pi, n_samples)
        return self._mu[:, None] + self._S.T @ (r * np.vstack([np.cos(t), np.sin(t)]))

    def simulate(self, rng: np.random.Generator, n_draws: int | None = None) -> np.ndarray:
        """Draw x = μ + Sᵀ w, w ~ N(0, I) from ``rng``: shape (n,) for ``n_draws`` None, else (n, n_draws)."""
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if n_draws is None:
            return self._mu + self._S.T @ rng.standard_normal(self.size)
        n_draws = integer(n_draws, "n_draws", minimum=1)
        return self._mu[:, None] + self._S.T @ rng.standard_normal((self.size, n_draws))
