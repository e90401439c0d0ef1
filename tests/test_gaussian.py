import numpy as np
import pytest
import scipy.stats
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers.gaussian import Gaussian, chi2inv, confidence_level, normcdf

PROPS = settings(max_examples=40, deadline=None, derandomize=True)


def random_upper(rng, n, negative=True):
    S = np.triu(rng.normal(size=(n, n)))
    d = rng.uniform(0.5, 2.0, n) * (rng.choice([-1, 1], n) if negative else 1)
    S[np.diag_indices(n)] = d
    return S


# ---------------------------------------------------------------------------- published test vectors
def test_log_pdf_published_value_negative_diagonal():
    S = np.array([[-1.0, -4.0, -6.0], [0.0, -2.0, -5.0], [0.0, 0.0, -3.0]])
    g = Gaussian([2.0, 4.0, 6.0], S)
    assert g.log_pdf([1.0, 2.0, 3.0]) == pytest.approx(-5.7707972911, abs=1e-10)


@pytest.mark.parametrize("a", [1e-4, 1e4])
def test_log_pdf_scaled_identity(a):
    n = 100
    g = Gaussian(np.zeros(n), a * np.eye(n))
    expected = -n * np.log(a) - n / 2 * np.log(2 * np.pi)
    assert g.log_pdf(np.zeros(n)) == pytest.approx(expected, rel=1e-12)


def test_log_pdf_huge_scale_stays_finite():
    n = 100
    g = Gaussian(np.zeros(n), 1e300 * np.eye(n))
    value = g.log_pdf(np.ones(n))
    assert value == pytest.approx(-n * np.log(1e300) - n / 2 * np.log(2 * np.pi), rel=1e-12)


@pytest.mark.parametrize("p, nu, expected", [
    (0.5, 1, 0.454936423119573), (0.5, 2, 1.386294361119890),
    (0.5, 3, 2.365973884375338), (0.75, 3, 4.108344935632316)])
def test_chi2inv_published(p, nu, expected):
    assert chi2inv(p, nu) == pytest.approx(expected, rel=1e-13)
    assert chi2inv(p, nu) == pytest.approx(scipy.stats.chi2.ppf(p, nu), rel=1e-13)


@pytest.mark.parametrize("w, expected", [(0.0, 0.5), (1.0, 0.841344746068543), (2.0, 0.977249868051821)])
def test_normcdf_published(w, expected):
    assert normcdf(w) == pytest.approx(expected, rel=1e-14)


def test_confidence_level_three_sigma():
    assert confidence_level(3.0) == pytest.approx(0.9973002039367398, rel=1e-15)


@pytest.mark.parametrize("nu, expected", [
    (1, 9.0), (2, 11.829158081900795), (3, 14.156413609126675), (4, 16.251340813956187),
    (6, 20.06208616571403), (8, 23.574591022671044), (10, 26.901119405801232), (12, 30.097266729568556),
    (14, 33.19540931314273), (16, 36.21637614028137), (18, 39.17450942666591)])
def test_chi2_threshold_table(nu, expected):
    assert chi2inv(confidence_level(3.0), nu) == pytest.approx(expected, rel=1e-12)


def test_confidence_ellipse_published():
    S = np.array([[1.0, 0.3], [0.0, 0.1]])
    mu = np.array([2.0, -1.0])
    g = Gaussian(mu, S)
    X = g.confidence_ellipse()
    assert X.shape == (2, 100)
    np.testing.assert_allclose(X[:, 0], X[:, -1], atol=1e-12)  # closed curve
    r = np.linalg.norm(np.linalg.solve(S.T, X - mu[:, None]), axis=0)
    np.testing.assert_allclose(r, 3.43935431177144, rtol=1e-12)
    assert not np.any(g.is_within_confidence_region(X, n_sigma=2.9))
    assert np.all(g.is_within_confidence_region(X, n_sigma=3.1))
    # the same, one point at a time (scalar API)
    assert all(g.is_within_confidence_region(X[:, k], 3.1) for k in range(0, 100, 9))
    assert not any(g.is_within_confidence_region(X[:, k], 2.9) for k in range(0, 100, 9))


def test_confidence_region_is_inclusive():
    g = Gaussian([0.0], [[1.0]])
    # a point exactly on the boundary needs fl(x·x) == χ²_1(c) to the last bit, and only about half of all doubles
    # are the square of a double: n_σ is stepped from 2 until the threshold is one, rather than trusting one value
    # of the quantile (whose last bit may differ between scipy builds and CPUs)
    for n_sigma in 2.0 + 1e-6 * np.arange(64):
        threshold = chi2inv(confidence_level(float(n_sigma)), 1)  # ≈ 4
        x = np.sqrt(threshold)
        if x * x == threshold:
            break
    assert x * x == threshold
    assert g.is_within_confidence_region([x], n_sigma=float(n_sigma)) is True  # wᵀw == χ²_1(c): inside (<=)
    assert g.is_within_confidence_region([x * (1 + 1e-12)], n_sigma=float(n_sigma)) is False


# ---------------------------------------------------------------------------- marginal / conditional
def test_marginal_any_order_and_padding():
    rng = np.random.default_rng(0)
    S = random_upper(rng, 5)
    g = Gaussian(rng.normal(size=5), S)
    idx = [4, 1, 3]
    m = g.marginal(idx)
    np.testing.assert_allclose(m.cov, g.cov[np.ix_(idx, idx)], atol=1e-12)
    np.testing.assert_allclose(m.mean, g.mean[idx])
    assert np.allclose(np.tril(m.sqrt_cov, -1), 0)
    # more columns than rows: S (2x2) marginal with a repeated index → padding
    g2 = Gaussian([1.0, 2.0], [[1.0, 0.5], [0.0, 2.0]])
    m2 = g2.marginal([0, 1, 0])
    assert m2.sqrt_cov.shape == (3, 3)
    np.testing.assert_allclose(m2.cov, g2.cov[np.ix_([0, 1, 0], [0, 1, 0])], atol=1e-12)


def test_conditional_matches_dense_formula():
    rng = np.random.default_rng(5)
    g = Gaussian(rng.normal(size=6), random_upper(rng, 6))
    A, B = [0, 4, 2], [5, 1]
    xb = rng.normal(size=2)
    c = g.conditional(A, B, xb)
    P, mu = g.cov, g.mean
    Pab, Pbb = P[np.ix_(A, B)], P[np.ix_(B, B)]
    np.testing.assert_allclose(c.mean, mu[A] + Pab @ np.linalg.solve(Pbb, xb - mu[B]), atol=1e-10)
    np.testing.assert_allclose(c.cov, P[np.ix_(A, A)] - Pab @ np.linalg.solve(Pbb, Pab.T), atol=1e-10)


def test_constructors():
    a = Gaussian.from_cov([1.0, 2.0], [[4.0, 1.0], [1.0, 3.0]])
    np.testing.assert_allclose(a.cov, [[4.0, 1.0], [1.0, 3.0]], atol=1e-14)
    b = Gaussian.from_sqrt_cov([[2.0]])
    np.testing.assert_array_equal(b.mean, [0.0])
    assert b.cov[0, 0] == 4.0


# ---------------------------------------------------------------------------- transform
def test_transform_with_noise_dense_formula():
    rng = np.random.default_rng(7)
    g = Gaussian(rng.normal(size=4), random_upper(rng, 4))
    C = rng.normal(size=(3, 4))
    SR = random_upper(rng, 3)
    y = g.transform(lambda x: (np.sin(x[:3]) + x[3], C), noise=Gaussian.from_sqrt_cov(SR))
    np.testing.assert_allclose(y.mean, np.sin(g.mean[:3]) + g.mean[3])
    np.testing.assert_allclose(y.cov, C @ g.cov @ C.T + SR.T @ SR, atol=1e-10)


def test_log_pdf_equals_scipy():
    rng = np.random.default_rng(11)
    g = Gaussian(rng.normal(size=4), random_upper(rng, 4))
    x = rng.normal(size=4)
    assert g.log_pdf(x) == pytest.approx(scipy.stats.multivariate_normal(g.mean, g.cov).logpdf(x), rel=1e-10)


def test_sq_mahalanobis_vectorised():
    rng = np.random.default_rng(3)
    g = Gaussian(rng.normal(size=3), random_upper(rng, 3))
    X = rng.normal(size=(3, 7))
    d2 = g.sq_mahalanobis(X)
    assert d2.shape == (7,)
    D = X - g.mean[:, None]
    np.testing.assert_allclose(d2, np.einsum("im,ij,jm->m", D, np.linalg.inv(g.cov), D), rtol=1e-10)
    assert isinstance(g.sq_mahalanobis(X[:, 0]), float)


def test_simulate_is_seeded_and_has_right_moments():
    g = Gaussian([1.0, -2.0], [[2.0, 0.5], [0.0, -0.3]])
    a = g.simulate(np.random.default_rng(4))
    b = g.simulate(np.random.default_rng(4))
    np.testing.assert_array_equal(a, b)
    X = g.simulate(np.random.default_rng(5), n_draws=20000)
    np.testing.assert_allclose(X.mean(axis=1), g.mean, atol=0.05)
    np.testing.assert_allclose(np.cov(X), g.cov, atol=0.08)


# ---------------------------------------------------------------------------- property tests
@st.composite
def gaussians(draw, max_n=6):
    n = draw(st.integers(1, max_n))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    return Gaussian(rng.normal(size=n), random_upper(rng, n)), rng


@PROPS
@given(gaussians(), st.data())
def test_property_marginal_matches_dense(gr, data):
    g, rng = gr
    idx = data.draw(st.lists(st.integers(0, g.size - 1), min_size=1, max_size=g.size, unique=True))
    m = g.marginal(idx)
    np.testing.assert_allclose(m.cov, g.cov[np.ix_(idx, idx)], rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(m.mean, g.mean[idx])
    np.testing.assert_array_equal(np.tril(m.sqrt_cov, -1), 0)


@PROPS
@given(gaussians(), st.integers(1, 7), st.booleans())
def test_property_transform_matches_dense(gr, m, with_noise):
    g, rng = gr
    C = rng.normal(size=(m, g.size))
    b = rng.normal(size=m)
    noise = Gaussian.from_sqrt_cov(random_upper(rng, m)) if with_noise else None
    y = g.transform(lambda x: (C @ x + b, C), noise=noise)
    P = C @ g.cov @ C.T + (noise.cov if with_noise else 0)
    np.testing.assert_allclose(y.mean, C @ g.mean + b, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(y.cov, P, rtol=1e-9, atol=1e-9)
    np.testing.assert_array_equal(np.tril(y.sqrt_cov, -1), 0)


# ---------------------------------------------------------------------------- bad inputs
def test_constructor_bad_inputs():
    with pytest.raises(ValueError, match="mu"):
        Gaussian(np.zeros((2, 1)), np.eye(2))
    with pytest.raises(ValueError, match="mu"):
        Gaussian([np.nan, 0.0], np.eye(2))
    with pytest.raises(ValueError, match="mu"):
        Gaussian([], np.zeros((0, 0)))
    with pytest.raises(ValueError, match="S must have shape"):
        Gaussian([0.0, 0.0], np.eye(3))
    with pytest.raises(ValueError, match="S must be a square"):
        Gaussian([0.0, 0.0], np.ones((2, 3)))
    with pytest.raises(ValueError, match="S must be finite"):
        Gaussian([0.0, 0.0], [[1.0, np.inf], [0.0, 1.0]])
    with pytest.raises(ValueError, match="S must be upper-triangular"):
        Gaussian([0.0, 0.0], [[1.0, 0.0], [0.5, 1.0]])
    with pytest.raises(ValueError, match="P must be positive definite"):
        Gaussian.from_cov([0.0, 0.0], [[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(ValueError, match="P must be symmetric"):
        Gaussian.from_cov([0.0, 0.0], [[1.0, 0.5], [0.0, 1.0]])
    with pytest.raises(ValueError, match="P must have shape"):
        Gaussian.from_cov([0.0, 0.0], np.eye(3))


def test_singular_S_is_accepted_but_solves_raise():
    g = Gaussian([0.0, 0.0], [[1.0, 0.0], [0.0, 0.0]])
    assert g.marginal([0]).cov[0, 0] == 1.0  # structural operations work
    for call in (lambda: g.log_pdf([0.0, 0.0]), lambda: g.sq_mahalanobis([0.0, 0.0]),
                 lambda: g.is_within_confidence_region([0.0, 0.0])):
        with pytest.raises(ValueError, match="S is singular"):
            call()
    with pytest.raises(ValueError, match="idx_b"):
        g.conditional([0], [1], [0.0])


def test_method_bad_inputs():
    g = Gaussian([0.0, 1.0, 2.0], np.eye(3))
    with pytest.raises(ValueError, match="idx has an index out of range"):
        g.marginal([0, 3])
    with pytest.raises(ValueError, match="idx has an index out of range"):
        g.marginal([-1])
    with pytest.raises(ValueError, match="idx must be a non-empty"):
        g.marginal([])
    with pytest.raises(ValueError, match="idx must contain integer"):
        g.marginal([0.5])
    with pytest.raises(ValueError, match="disjoint"):
        g.conditional([0, 1], [1], [0.0])
    with pytest.raises(ValueError, match="x_b must have shape"):
        g.conditional([0], [1, 2], [0.0])
    with pytest.raises(ValueError, match="idx_a has an index out of range"):
        g.conditional([5], [1], [0.0])
    with pytest.raises(ValueError, match="x must have shape"):
        g.log_pdf([0.0, 1.0])
    with pytest.raises(ValueError, match="x must be finite"):
        g.log_pdf([0.0, np.nan, 1.0])
    with pytest.raises(ValueError, match="X must have shape"):
        g.sq_mahalanobis(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="n_sigma"):
        g.is_within_confidence_region([0.0, 1.0, 2.0], n_sigma=-1.0)
    with pytest.raises(ValueError, match="2-D Gaussian"):
        g.confidence_ellipse()
    with pytest.raises(ValueError, match="n_samples"):
        g.marginal([0, 1]).confidence_ellipse(n_samples=1)
    with pytest.raises(ValueError, match="rng"):
        g.simulate(42)
    with pytest.raises(ValueError, match="n_draws"):
        g.simulate(np.random.default_rng(0), n_draws=0)


def test_transform_bad_inputs():
    g = Gaussian([0.0, 1.0], np.eye(2))
    with pytest.raises(ValueError, match="h must be callable"):
        g.transform(np.eye(2))
    with pytest.raises(ValueError, match="h must return a tuple"):
        g.transform(lambda x: x)
    with pytest.raises(ValueError, match="Jacobian J\\) must have shape"):
        g.transform(lambda x: (x, np.eye(3)))
    with pytest.raises(ValueError, match="Jacobian J\\) must be finite"):
        g.transform(lambda x: (x, np.full((2, 2), np.nan)))
    with pytest.raises(ValueError, match=r"h\(x\)\[0\]"):
        g.transform(lambda x: (x * np.nan, np.eye(2)))
    with pytest.raises(ValueError, match="noise must have size"):
        g.transform(lambda x: (x, np.eye(2)), noise=Gaussian.from_sqrt_cov(np.eye(3)))
    with pytest.raises(ValueError, match="noise must have zero mean"):
        g.transform(lambda x: (x, np.eye(2)), noise=Gaussian([1.0, 0.0], np.eye(2)))
    with pytest.raises(ValueError, match="noise must be a Gaussian"):
        g.transform(lambda x: (x, np.eye(2)), noise=np.eye(2))


@pytest.mark.parametrize("p", [-0.1, 1.0, 1.5, np.nan])
def test_chi2inv_bad_p(p):
    with pytest.raises(ValueError, match="p must lie in"):
        chi2inv(p, 2)


def test_chi2inv_bad_nu_and_normcdf_nan():
    with pytest.raises(ValueError, match="nu must be positive"):
        chi2inv(0.5, 0)
    with pytest.raises(ValueError, match="w must not be NaN"):
        normcdf(np.nan)
    assert chi2inv(0.0, 3) == 0.0
    np.testing.assert_allclose(chi2inv(np.array([0.5, 0.75]), 3), [2.365973884375338, 4.108344935632316])


def test_chi2inv_scalar_cache_equals_array_path():
    """Scalars go through a cache; the value is bit-for-bit the array path's, and bad scalars still raise
    (a failed call is not cached)."""
    for p, nu in [(0.95, 2), (0.9973002039367398, 6.0), (np.float64(0.5), np.int64(3)), (0.0, 1)]:
        first, again = chi2inv(p, nu), chi2inv(p, nu)
        assert isinstance(first, float) and first == again
        assert first == float(chi2inv(np.array([p]), np.array([nu]))[0])
    for _ in range(2):
        with pytest.raises(ValueError, match="p must lie"):
            chi2inv(1.0, 2)
        with pytest.raises(ValueError, match="nu must be positive"):
            chi2inv(0.5, -1.0)
