"""The optional CHOLMOD backend of ``LDLSolver``: supernodal Cholesky factorisation through ``cvxopt.cholmod``.

Why. On Hessians whose factor has dense columns (many loop closures: W10000) CHOLMOD's supernodal LLᵀ, which
works on dense blocks with BLAS, refactorises in about 0.6× qdldl's time; on the sparser graphs (W20000, Victoria
Park, the DriveBot maps) qdldl's simplicial LDLᵀ is faster (1.2–2×) — ``benchmarks/factorisation.py``,
``benchmarks/RESULTS.md``. ``prefers_cholmod`` decides per pattern from the column counts of L under an AMD ordering
with CHOLMOD's own rule for supernodal against simplicial: supernodal pays when the factorisation's flops per non-zero
of L reach ``SUPERNODAL_SWITCH`` (CHOLMOD's default ``supernodal_switch``, 40; the measured crossover lies at
≈ 30), and the factorisation is not tiny (``MIN_FLOPS``).

Availability. cvxopt is an optional dependency (environment markers in environment.txt): it has wheels for
Windows, Linux and macOS arm64 up to CPython 3.12, none for macOS arm64 + CPython 3.13, where ``AVAILABLE`` is
False and everything runs on qdldl.

Ordering and decision. For a large pattern (at least ``AUTO_MIN_NNZ`` stored entries) ``LDLSolver`` decides
before building any factor: ``amd_ordering`` (AMD through cvxopt, on the cvxopt matrix CHOLMOD needs anyway) and
``column_counts`` (the elimination tree and the column counts of L under that ordering) give the flops for
``prefers_cholmod``. Below that size, qdldl factorises without a decision: a refactorisation takes a few
milliseconds at most there, and the decision (a cvxopt matrix and an ordering: 45–65 % of the time qdldl takes to
build its solver, measured on Victoria Park, W10000, W20000 and the DriveBot map q2_e) would cost more than the
supernodal factorisation can save in an online run that builds many such patterns.

Use. ``CholmodFactor(pattern, perm)`` builds the cvxopt matrix with H's pattern (or takes the one the decision
built) and CHOLMOD's symbolic analysis with the given fill-reducing permutation once per pattern; ``factor(data)``
refactorises numerically (False when CHOLMOD finds the matrix not positive definite:
it raises ArithmeticError), ``solve(rhs)`` returns H⁻¹ rhs. CHOLMOD's options live in a module-level dict of
cvxopt that every call reads; the calls here set their own options and restore the caller's afterwards.
"""

import numpy as np
from numba import njit

try:
    import cvxopt
    from cvxopt import amd as _amd
    from cvxopt import cholmod as _cholmod
except ImportError:  # optional: no wheel on macOS arm64 + CPython 3.13
    cvxopt = None
    _amd = _cholmod = None

__all__ = ["AVAILABLE", "SUPERNODAL_SWITCH", "MIN_FLOPS", "AUTO_MIN_NNZ", "factor_statistics", "prefers_cholmod",
           "pattern_matrix", "amd_ordering", "column_counts", "CholmodFactor"]

#: True when cvxopt (and with it CHOLMOD) can be imported
AVAILABLE = _cholmod is not None
#: flops / nnz(L) from which the supernodal factorisation is used (CHOLMOD's default supernodal_switch)
SUPERNODAL_SWITCH = 40.0
#: smaller factorisations stay on qdldl (the cost of the calls dominates there)
MIN_FLOPS = 1e6
#: patterns with fewer stored entries (upper triangle) stay on qdldl without a decision
AUTO_MIN_NNZ = 100_000
#: the options of every CHOLMOD call made here: supernodal LLᵀ, the given ordering only, postordered
_OPTIONS = {"supernodal": 2, "nmethods": 1, "postorder": True}


def factor_statistics(column_counts):
    """(nnz(L), flops) of a Cholesky factorisation from the non-zeros per column of L (diagonal included):
    flops = Σ c_j² (the multiply–adds of the left-looking update, up to a constant)."""
    c = np.asarray(column_counts, dtype=float)
    return float(c.sum()), float(np.dot(c, c))


def prefers_cholmod(column_counts):
    """Whether CHOLMOD's supernodal factorisation is expected to beat qdldl for a factor with these column
    counts (module docstring); False when cvxopt is not installed."""
    if not AVAILABLE:
        return False
    nnz, flops = factor_statistics(column_counts)
    return flops >= MIN_FLOPS and flops >= SUPERNODAL_SWITCH * nnz


def _require_cvxopt():
    if not AVAILABLE:
        raise ImportError("the CHOLMOD backend needs cvxopt, which is not installed")


def _permutation(perm, n, where):
    """``perm`` as int64 after checking that it is a permutation of range(n) (ValueError naming ``where``)."""
    perm = np.asarray(perm)
    if perm.shape != (n,) or (perm.size and not np.issubdtype(perm.dtype, np.integer)) \
            or not np.array_equal(np.sort(perm), np.arange(n)):
        raise ValueError(f"{where}: perm must be a permutation of range({n}), got shape {perm.shape}, "
                         f"dtype {perm.dtype}")
    return np.ascontiguousarray(perm, dtype=np.int64)


def amd_ordering(matrix):
    """AMD fill-reducing permutation (int64, position → row) of the upper-triangle cvxopt matrix ``matrix``
    (square ``spmatrix``, e.g. ``pattern_matrix``)."""
    _require_cvxopt()
    if not isinstance(matrix, cvxopt.spmatrix) or matrix.size[0] != matrix.size[1]:
        raise ValueError(f"amd_ordering: matrix must be a square cvxopt spmatrix, got {type(matrix).__name__}")
    return np.asarray(_amd.order(matrix, uplo="U"), dtype=np.int64).reshape(-1)


def column_counts(pattern, perm):
    """Non-zeros per column of L (diagonal included) for the factorisation of P H Pᵀ, H with the ``HessianPattern``
    ``pattern``, ``perm[k]`` its row at position k (``_column_counts``); ValueError unless ``perm`` is a
    permutation of range(n)."""
    perm = _permutation(perm, pattern.n, "column_counts")
    return _column_counts(pattern.n, pattern.indptr, pattern.indices, perm)


@njit(cache=True)
def _column_counts(n, indptr, indices, perm):
    """Non-zeros per column of L (diagonal included) for the factorisation of P H Pᵀ, H given by the CSC pattern
    of its upper triangle, ``perm[k]`` the row of H at position k. Row k of L is the union of the elimination-tree
    paths from the rows r < k of column k of P H Pᵀ up to k (the row subtree); walking them, with a mark per node
    so that each is counted once per row, finds the parent of every node and counts each column."""
    pinv = np.empty(n, dtype=np.int64)
    for k in range(n):
        pinv[perm[k]] = k
    start = np.zeros(n + 1, dtype=np.int64)                 # the permuted upper triangle, columns as lists
    for j in range(n):
        for q in range(indptr[j], indptr[j + 1]):
            a, b = pinv[indices[q]], pinv[j]
            if a != b:
                start[max(a, b) + 1] += 1
    for k in range(n):
        start[k + 1] += start[k]
    fill = start[:-1].copy()
    rows = np.empty(start[n], dtype=np.int64)
    for j in range(n):
        for q in range(indptr[j], indptr[j + 1]):
            a, b = pinv[indices[q]], pinv[j]
            if a != b:
                rows[fill[max(a, b)]] = min(a, b)
                fill[max(a, b)] += 1
    parent = np.full(n, -1, dtype=np.int64)
    mark = np.full(n, -1, dtype=np.int64)
    counts = np.ones(n, dtype=np.int64)
    for k in range(n):
        mark[k] = k
        for q in range(start[k], start[k + 1]):
            i = rows[q]
            while mark[i] != k:
                if parent[i] == -1:
                    parent[i] = k
                counts[i] += 1
                mark[i] = k
                i = parent[i]
    return counts


def _call(function, *args, **kwargs):
    """Call a cvxopt.cholmod function with this module's options (the caller's options are restored after)."""
    saved = dict(_cholmod.options)
    _cholmod.options.clear()
    _cholmod.options.update(_OPTIONS)
    try:
        return function(*args, **kwargs)
    finally:
        _cholmod.options.clear()
        _cholmod.options.update(saved)


def pattern_matrix(pattern, values=1.0):
    """The upper triangle of H as a cvxopt ``spmatrix`` on ``pattern`` (CSC values ``values``, or one scalar).
    cvxopt orders the entries by column, then row: the pattern's own CSC order, so the value buffers line up."""
    _require_cvxopt()
    cols = np.repeat(np.arange(pattern.n, dtype=np.int64), np.diff(pattern.indptr))
    if not np.isscalar(values):
        values = cvxopt.matrix(np.ascontiguousarray(values, dtype=float))
    return cvxopt.spmatrix(values, cvxopt.matrix(pattern.indices.astype(np.int64), tc="i"),
                           cvxopt.matrix(cols, tc="i"), (pattern.n, pattern.n))


class CholmodFactor:
    """CHOLMOD's factorisation of matrices with one ``HessianPattern`` (upper triangle, CSC) and one ordering."""

    def __init__(self, pattern, perm, matrix=None):
        _require_cvxopt()
        n = pattern.n
        perm = _permutation(perm, n, "CholmodFactor")
        self._values = cvxopt.matrix(np.zeros(pattern.nnz))
        self._matrix = pattern_matrix(pattern) if matrix is None else matrix
        self._view = np.asarray(self._values).reshape(-1)   # writable view of the value buffer
        self._rhs = cvxopt.matrix(np.zeros(n))
        self._rhs_view = np.asarray(self._rhs).reshape(-1)
        self._factor = _call(_cholmod.symbolic, self._matrix, p=cvxopt.matrix(perm, tc="i"), uplo="U")
        self.n = n
        self.ok = False

    @property
    def values(self):
        """The upper-triangle CSC values of the last factorised matrix (a view: read only)."""
        out = self._view.view()
        out.flags.writeable = False
        return out

    def factor(self, data, check_pivots=True):
        """Numeric factorisation of the matrix with CSC values ``data``; returns (and keeps in ``ok``) whether
        it is positive definite.

        CHOLMOD raises ArithmeticError at a pivot ≤ 0; ``check_pivots`` also requires every diagonal entry of L
        to be finite and > 0 (the supernodal factorisation lets a NaN or inf pass, as qdldl does; the caller's
        check on qdldl's D catches it there)."""
        self._view[:] = data
        self._matrix.V = self._values
        try:
            _call(_cholmod.numeric, self._matrix, self._factor)
        except ArithmeticError:  # CHOLMOD_NOT_POSDEF
            self.ok = False
            return self.ok
        self.ok = True
        if check_pivots:
            diag = np.asarray(_call(_cholmod.diag, self._factor)).reshape(-1)
            self.ok = bool(np.all(np.isfinite(diag)) and np.all(diag > 0.0))
        return self.ok

    def solve(self, rhs):
        """H⁻¹ rhs with the last positive definite factorisation."""
        if not self.ok:
            raise ArithmeticError("CholmodFactor.solve: the last factorisation failed (not positive definite)")
        self._rhs_view[:] = rhs
        _call(_cholmod.solve, self._factor, self._rhs)
        return self._rhs_view.copy()
