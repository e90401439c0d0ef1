"""The shared argument checks (helpers.validation), the timing helpers (helpers.timing) and the one QR step."""
import numpy as np
import pytest

from helpers.gaussian import Gaussian, square_r_factor
from helpers.timing import best_of, timed
from helpers.validation import (check_symmetric, feature_columns, finite_number, finite_vector, int_array, integer,
                                positive_number)


def test_integer_bounds_and_none():
    assert integer(3, "k") == 3 and isinstance(integer(np.int64(3), "k"), int)
    assert integer(0, "i", minimum=0, below=2) == 0
    assert integer(None, "max_nodes", minimum=1, allow_none=True) is None
    with pytest.raises(ValueError, match=r"i must be an integer in \[0, 2\), got 2"):
        integer(2, "i", minimum=0, below=2)
    with pytest.raises(ValueError, match="k must be an integer ≥ 1 or None"):
        integer(0, "k", minimum=1, allow_none=True)
    with pytest.raises(ValueError, match="k must be an integer"):
        integer(True, "k")
    with pytest.raises(ValueError, match="k must be an integer"):
        integer(None, "k")


def test_numbers_and_arrays():
    assert finite_number(-2, "sU") == -2.0 and positive_number(0.5, "dt") == 0.5
    for bad in (np.nan, np.inf, "1", True):
        with pytest.raises(ValueError, match="sU must be a finite number"):
            finite_number(bad, "sU")
    assert int_array([1, 2], "ids").dtype == np.int64
    np.testing.assert_array_equal(finite_vector([1, 2], "mu", 2), [1.0, 2.0])
    with pytest.raises(ValueError, match=r"mu must have shape \(3,\)"):
        finite_vector([1, 2], "mu", 3)
    with pytest.raises(ValueError, match="mu must be a 1-D array"):
        finite_vector(np.zeros((2, 2)), "mu")
    with pytest.raises(ValueError, match="mu must be finite"):
        finite_vector([1, np.nan], "mu")


def test_feature_columns():
    assert feature_columns(np.zeros((2, 0))).shape == (2, 0)
    with pytest.raises(ValueError, match=r"Y must have shape \(2, m\) with m >= 1"):
        feature_columns(np.zeros((2, 0)), allow_empty=False)
    with pytest.raises(ValueError, match="Z must have shape"):
        feature_columns(np.zeros((3, 4)), "Z")
    with pytest.raises(ValueError, match="Y must be finite"):
        feature_columns([[0.0], [np.inf]])


def test_check_symmetric_accepts_round_off_and_names_the_argument():
    P = np.array([[2.0, 1.0], [1.0 + 1e-14, 3.0]])
    check_symmetric(P, "P")
    check_symmetric(np.zeros((0, 0)), "P")
    with pytest.raises(ValueError, match="Q must be symmetric"):
        check_symmetric(np.array([[2.0, 1.0], [1.1, 3.0]]), "Q")


def test_timed_and_best_of():
    calls = []
    result, seconds = timed(lambda x: calls.append(x) or x + 1, 1)
    assert result == 2 and seconds >= 0
    result, best = best_of(3, lambda: calls.append(0) or len(calls))
    assert result == 4 and len(calls) == 4 and best >= 0
    with pytest.raises(ValueError, match="repeats"):
        best_of(0, print)
    with pytest.raises(ValueError, match="fn must be callable"):
        best_of(2, None)


def test_square_r_factor_matches_covariance_and_pads():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(5, 3))
    R = square_r_factor(A)
    assert R.shape == (3, 3) and np.allclose(np.tril(R, -1), 0)
    np.testing.assert_allclose(R.T @ R, A.T @ A, atol=1e-12)
    short = square_r_factor(A[:2])                      # fewer rows than columns: zero-padded
    assert short.shape == (3, 3) and np.all(short[2] == 0)
    np.testing.assert_allclose(short.T @ short, A[:2].T @ A[:2], atol=1e-12)
    assert np.all(square_r_factor(np.zeros((0, 2))) == 0)
    g = Gaussian(np.zeros(3), np.triu(rng.normal(size=(3, 3))))
    np.testing.assert_allclose(g.marginal([2, 0]).cov, g.cov[np.ix_([2, 0], [2, 0])], atol=1e-12)


def test_index_list():
    from helpers.validation import index_list

    np.testing.assert_array_equal(index_list(2, 3, "idx"), [2])
    np.testing.assert_array_equal(index_list([2.0, 0.0], 3, "idx", integral_floats=True), [2, 0])
    with pytest.raises(ValueError, match="idx must contain integer indices"):
        index_list([2.0], 3, "idx")
    with pytest.raises(ValueError, match=r"j has a landmark index out of range \[0, 3\)"):
        index_list([3], 3, "j", kind="landmark ")
    with pytest.raises(ValueError, match="idx has an index out of range"):
        index_list([-1], 3, "idx")
    with pytest.raises(ValueError, match="non-empty 1-D list of indices"):
        index_list([], 3, "idx")
