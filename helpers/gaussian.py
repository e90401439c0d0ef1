"""The square-root Gaussian N(μ, P) with P = SᵀS and S upper-triangular (course Labs 5, 7, 8).

Why square roots: every operation below is a triangular solve or a QR decomposition, so covariances
stay symmetric positive semi-definite by construction and conditioning is the square root of that of P.
Diagonal entries of S may be negative (QR does not normalise signs); only |S_ii| enters determinants.

Operations (n = size, idx an index list):

- marginal(idx):   QR of S[:, idx] = Q R, new S = top |idx| rows of R (zero-padded if S has fewer rows);
                   then RᵀR = S[:, idx]ᵀ S[:, idx] = P[idx, idx].
- conditional(A, B, x_B):  QR of [S[:, B], S[:, A]] = Q [[R1, R2], [0, R3]];
                   μ_{A|B} = μ_A + R2ᵀ R1⁻ᵀ (x_B − μ_B),  S_{A|B} = R3.
- transform(h):    y = h(μ), C = ∂h/∂x(μ);  QR of [S Cᵀ; S_R] (noise N(0, S_RᵀS_R) optional);
                   S_y = top m rows of R, so P_y = C P Cᵀ + S_RᵀS_R.
- log_pdf(x):      −½ wᵀw − (n/2) log 2π − Σ log|S_ii|  with  Sᵀ w = x − μ;
                   gradient −P⁻¹(x − μ) = −S⁻¹ w,  Hessian −P⁻¹ = −S⁻¹ S⁻ᵀ.
- confidence region (Lab 7 eqs 19–24): c = 2Φ(n_σ) − 1;  x is inside iff wᵀw ≤ χ²_n(c).

Singular square roots (a zero on the diagonal of S, e.g. a state block with no uncertainty) are allowed
at construction and in marginal / transform / simulate / confidence_ellipse. Methods that must
solve with S (log_pdf, sq_mahalanobis, is_within_confidence_region, conditional's R1) raise ValueError
when the triangular factor they solve with has a zero diagonal entry.
"""
from __future__ import annotations

import functools
import math
import numbers

import numpy as np
from scipy import linalg, special

from .validation import boolean, broadcastable, check_symmetric, finite_vector, float_array, index_list

__all__ = ["Gaussian", "chi2inv", "chi2_interval", "normcdf", "confidence_level", "square_r_factor"]


# ----------------------------------------------------------------------------------------------------
# χ² quantiles and the normal CDF (from scipy, never hand tables)
# ----------------------------------------------------------------------------------------------------
def chi2inv(p, nu):
    """Inverse CDF of the χ² distribution with ``nu`` degrees of freedom: 2·gammaincinv(ν/2, p).

    Equals ``scipy.stats.chi2.ppf(p, nu)``. ``p`` must lie in [0, 1), ``nu`` must be positive.
    Scalars give a float; arrays broadcast.
    """
    if (type(p) is float or isinstance(p, numbers.Real)) and (type(nu) in (int, float) or isinstance(nu, numbers.Real)):
        return _chi2inv_scalar(float(p), float(nu))    # the association gates ask for a few values very often
    return _chi2inv_array(p, nu)


@functools.lru_cache(maxsize=256)
def _chi2inv_scalar(p: float, nu: float) -> float:
    return _chi2inv_array(p, nu)


def _chi2inv_array(p, nu):
    p_arr = float_array(p, "p")
    nu_arr = float_array(nu, "nu")
    if not np.all(np.isfinite(p_arr)) or np.any(p_arr < 0) or np.any(p_arr >= 1):
        raise ValueError(f"p must lie in [0, 1), got {p!r}")
    if not np.all(np.isfinite(nu_arr)) or np.any(nu_arr <= 0):
        raise ValueError(f"nu must be positive and finite, got {nu!r}")
    broadcastable(p=p_arr, nu=nu_arr)
    out = 2.0 * special.gammaincinv(nu_arr / 2.0, p_arr)
    return float(out) if out.ndim == 0 else out


def normcdf(w):
    """Standard normal CDF Φ(w) = ½ erfc(−w/√2). Scalars give a float; arrays broadcast."""
    w_arr = float_array(w, "w")
    if np.any(np.isnan(w_arr)):
        raise ValueError(f"w must not be NaN, got {w!r}")
    out = special.ndtr(w_arr)
    return float(out) if out.ndim == 0 else out


def chi2_interval(dof, probability: float = 0.99) -> tuple[float, float]:
    """(lo, hi) with P(lo ≤ χ²_dof ≤ hi) = probability, equal tails: the (1 ∓ p)/2 quantiles of χ²_dof.

    The acceptance interval of a consistent graph's χ² (dof = measurement dimensions − free state dimensions).
    Unlike the Gaussian approximation dof ± k√(2 dof) it never goes negative and has the right skew.
    """
    if isinstance(dof, bool) or not isinstance(dof, numbers.Integral) or dof < 1:
        raise ValueError(f"dof must be a positive integer, got {dof!r}")
    if isinstance(probability, bool) or not isinstance(probability, numbers.Real) or not 0 < probability < 1:
        raise ValueError(f"probability must lie in (0, 1), got {probability!r}")
    tail = 0.5 * (1.0 - float(probability))
    return chi2inv(tail, int(dof)), chi2inv(1.0 - tail, int(dof))


def confidence_level(n_sigma) -> float:
    """c = 2Φ(n_σ) − 1, the probability mass within ±n_σ of a 1-D Gaussian (0.9973002039367398 for 3)."""
    _check_n_sigma(n_sigma)
    return _confidence_level(float(n_sigma))


@functools.lru_cache(maxsize=64)
def _confidence_level(n_sigma: float) -> float:
    return 2.0 * normcdf(n_sigma) - 1.0           # the gates ask for the same few levels very often


def _check_n_sigma(n_sigma):
    if type(n_sigma) is float and 0.0 < n_sigma < math.inf:
        return                                          # the common case, without the ABC checks below
    if isinstance(n_sigma, bool) or not isinstance(n_sigma, numbers.Real) or not np.isfinite(n_sigma) \
            or n_sigma <= 0:
        raise ValueError(f"n_sigma must be a positive finite number, got {n_sigma!r}")


# ----------------------------------------------------------------------------------------------------
# validation helpers
# ----------------------------------------------------------------------------------------------------
def _as_upper(S, name, n=None):
    S = np.array(float_array(S, name))  # copy: a Gaussian owns its square root
    if S.ndim != 2 or S.shape[0] != S.shape[1]:
        raise ValueError(f"{name} must be a square 2-D array, got shape {S.shape}")
    if n is not None and S.shape[0] != n:
        raise ValueError(f"{name} must have shape ({n}, {n}), got {S.shape}")
    if not np.all(np.isfinite(S)):
        raise ValueError(f"{name} must be finite (no NaN/inf)")
    lower = np.tril(S, -1)
    scale = np.max(np.abs(S)) if S.size else 0.0
    if np.any(np.abs(lower) > 1e-12 * scale):
        raise ValueError(f"{name} must be upper-triangular (non-zero entries below the diagonal)")
    return np.triu(S)


def square_r_factor(A) -> np.ndarray:
    """The k × k upper-triangular R with AᵀA = RᵀR for A of shape (r, k): the top k rows of A's QR factor,
    zero-padded when r < k (r = 0 gives zeros). The one QR step behind marginal, conditional and transform.
    ``A`` must be a finite 2-D array (ValueError naming ``A`` otherwise)."""
    A = float_array(A, "A")
    if A.ndim != 2:
        raise ValueError(f"A must be a 2-D array (r, k), got shape {A.shape}")
    if not np.all(np.isfinite(A)):
        raise ValueError("A must be finite (no NaN/inf)")
    k = A.shape[1]
    out = np.zeros((k, k))
    if A.shape[0] == 0:
        return out
    R = np.triu(np.linalg.qr(A, mode="r"))
    rows = min(R.shape[0], k)
    out[:rows] = R[:rows]
    return out


# ----------------------------------------------------------------------------------------------------
class Gaussian:
    """N(μ, SᵀS) with S upper-triangular.

    Parameters
    ----------
    mu : array (n,), finite
    S  : array (n, n), finite, upper-triangular (entries below the diagonal must be 0 up to 1e-12·max|S|;
         they are then set exactly to 0). A zero diagonal (singular S) is accepted here; see the module
         docstring for which methods then raise.
    """

    __slots__ = ("_mu", "_S")

    def __init__(self, mu, S):
        mu = finite_vector(float_array(mu, "mu"), "mu")
        if mu.size == 0:
            raise ValueError("mu must have at least one element")
        self._mu = mu.copy()
        self._S = _as_upper(S, "S", mu.size)

    # -- constructors ----------------------------------------------------------------------------------
    @classmethod
    def from_sqrt_cov(cls, S) -> Gaussian:
        """Zero-mean Gaussian N(0, SᵀS) (used for additive noise)."""
        S = float_array(S, "S")
        if S.ndim != 2:
            raise ValueError(f"S must be a square 2-D array, got shape {S.shape}")
        return cls(np.zeros(S.shape[0]), S)

    @classmethod
    def from_cov(cls, mu, P) -> Gaussian:
        """N(μ, P) from a dense covariance: S = Lᵀ with P = L Lᵀ (Cholesky). P must be symmetric PD."""
        mu = finite_vector(float_array(mu, "mu"), "mu")
        if mu.size == 0:
            raise ValueError("mu must have at least one element")
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
        g = object.__new__(cls)           # μ and Lᵀ are already checked: skip the constructor's checks
        g._mu, g._S = mu.copy(), np.triu(L.T)
        return g

    # -- accessors -------------------------------------------------------------------------------------
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
        """P = SᵀS, shape (n, n). ValueError when an entry of P overflows float64 (|S| near 1e154 or more):
        the square-root operations still work then, the dense covariance cannot be formed."""
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

    # -- structural operations -------------------------------------------------------------------------
    def marginal(self, idx) -> Gaussian:
        """Marginal of the components ``idx`` (any order, non-contiguous allowed): QR of S[:, idx]."""
        idx = index_list(idx, self.size, "idx", integral_floats=True)
        return Gaussian(self._mu[idx], square_r_factor(self._S[:, idx]))

    def conditional(self, idx_a, idx_b, x_b) -> Gaussian:
        """p(x_A | x_B = x_b) by QR of [S[:, B], S[:, A]] (Lab 5 eqs 23–26). A and B must be disjoint, and B
        must not repeat an index (conditioning on x_i twice is ill-posed)."""
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

    def transform(self, h, noise: Gaussian | None = None) -> Gaussian:
        """First-order (affine) transform through y = h(x): ``h(x)`` returns ``(y, J)`` with J = ∂h/∂x.

        S_y = top m rows of R in QR([S Jᵀ; S_R]); ``noise`` (optional) must be a zero-mean Gaussian of
        size m = len(y), added as independent additive noise.
        """
        if not callable(h):
            raise ValueError(f"h must be callable returning (y, J), got {type(h).__name__}")
        out = h(self._mu.copy())
        if not isinstance(out, tuple) or len(out) != 2:
            raise ValueError("h must return a tuple (y, J)")
        y = finite_vector(float_array(out[0], "h(x)[0] (y)"), "h(x)[0] (y)")
        m = y.size
        J = float_array(out[1], "h(x)[1] (the Jacobian J)")
        if J.shape != (m, self.size):
            raise ValueError(f"h(x)[1] (the Jacobian J) must have shape ({m}, {self.size}), got {J.shape}")
        if not np.all(np.isfinite(J)):
            raise ValueError("h(x)[1] (the Jacobian J) must be finite")
        A = self._S @ J.T
        if noise is not None:
            if not isinstance(noise, Gaussian):
                raise ValueError(f"noise must be a Gaussian or None, got {type(noise).__name__}")
            if noise.size != m:
                raise ValueError(f"noise must have size {m} (the size of h(x)), got {noise.size}")
            if np.any(noise._mu != 0):
                raise ValueError("noise must have zero mean")
            A = np.vstack([A, noise._S])
        return Gaussian(y, square_r_factor(A))

    # -- densities ---------------------------------------------------------------------------------------
    def _check_nonsingular(self):
        if np.any(np.diag(self._S) == 0):
            raise ValueError("S is singular (zero on its diagonal); this operation needs an invertible S")

    def _whiten(self, X, name="x"):
        """w with Sᵀ w = X − μ, for X of shape (n,) or (n, m)."""
        X = float_array(X, name)
        if X.ndim not in (1, 2) or X.shape[0] != self.size:
            raise ValueError(f"{name} must have shape ({self.size},) or ({self.size}, m), got {X.shape}")
        if not np.all(np.isfinite(X)):
            raise ValueError(f"{name} must be finite (no NaN/inf)")
        self._check_nonsingular()
        D = X - (self._mu if X.ndim == 1 else self._mu[:, None])
        return linalg.solve_triangular(self._S, D, trans="T", lower=False, check_finite=False)

    def sq_mahalanobis(self, X):
        """(x − μ)ᵀ P⁻¹ (x − μ) = wᵀw with Sᵀ w = x − μ. X (n,) → float; X (n, m) columns → (m,)."""
        w = self._whiten(X, "X")
        out = np.sum(w * w, axis=0)
        return float(out) if out.ndim == 0 else out

    def log_pdf(self, x, return_grad: bool = False, return_hess: bool = False):
        """log N(x; μ, P) = −½ wᵀw − (n/2) log 2π − Σ log|S_ii| with Sᵀ w = x − μ.

        Returns the value (float), or ``(value, grad)``, ``(value, hess)`` or ``(value, grad, hess)`` with
        grad = −P⁻¹(x − μ) (shape (n,)) and hess = −P⁻¹ (shape (n, n)).
        """
        return_grad, return_hess = boolean(return_grad, "return_grad"), boolean(return_hess, "return_hess")
        x = float_array(x, "x")
        if x.ndim != 1:
            raise ValueError(f"x must have shape ({self.size},), got {x.shape}")
        w = self._whiten(x, "x")
        n = self.size
        value = float(-0.5 * (w @ w) - 0.5 * n * np.log(2.0 * np.pi) - np.sum(np.log(np.abs(np.diag(self._S)))))
        out = [value]
        if return_grad:
            out.append(-linalg.solve_triangular(self._S, w, lower=False, check_finite=False))
        if return_hess:
            Sinv = linalg.solve_triangular(self._S, np.eye(n), lower=False, check_finite=False)
            out.append(-(Sinv @ Sinv.T))
        return value if len(out) == 1 else tuple(out)

    def is_within_confidence_region(self, x, n_sigma: float = 3.0):
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
        if isinstance(n_samples, bool) or not isinstance(n_samples, numbers.Integral) or n_samples < 2:
            raise ValueError(f"n_samples must be an integer >= 2, got {n_samples!r}")
        r = np.sqrt(chi2inv(confidence_level(n_sigma), 2))
        t = np.linspace(0.0, 2.0 * np.pi, int(n_samples))
        W = r * np.vstack([np.cos(t), np.sin(t)])
        return self._mu[:, None] + self._S.T @ W

    def simulate(self, rng, n_draws: int | None = None) -> np.ndarray:
        """Draw x = μ + Sᵀ w, w ~ N(0, I) from the numpy Generator ``rng``.

        n_draws None → shape (n,); an integer k → shape (n, k) (one draw per column).
        """
        if not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        if n_draws is None:
            return self._mu + self._S.T @ rng.standard_normal(self.size)
        if isinstance(n_draws, bool) or not isinstance(n_draws, numbers.Integral) or n_draws < 1:
            raise ValueError(f"n_draws must be a positive integer or None, got {n_draws!r}")
        return self._mu[:, None] + self._S.T @ rng.standard_normal((self.size, int(n_draws)))
