"""Sparse linear algebra of the optimiser: the Hessian pattern and its LDLᵀ factorisation (qdldl); the batched
per-edge products (JᵀJ, Jᵀe, W J) the linearisation uses are in ``batched``.

Pattern. Every edge contributes the blocks H_kl = J_kᵀ Ω J_l (k ≤ l) between its free vertices. The upper
triangle (row ≤ col) of all contributions, plus the full diagonal (LM damping adds μ there), is computed once per
structure change from the edge → vertex index arrays (``csc_unique``: the distinct (row, col) entries in CSC order
and, for every contribution, the position of its value in the CSC data array; equal to ``np.unique`` on the keys
(col << 32) | row, from two counting-sort passes; ``block_pattern`` builds the same arrays from the distinct vertex
pairs instead, the fast path ``build_structure`` uses). Every iteration only adds the new values into those
positions (``batched.scatter_jtj``; the reference ``linearise_reference`` does it with ``np.bincount``).

Factorisation. LDLᵀ by the maintained library qdldl (chosen by measurement: qdldl 87 ms / 58 ms
refactor on W10000 against cholespy 139 ms and splu 133 ms). ``qdldl.Solver`` is built once per pattern: it computes
the AMD fill-reducing ordering P and the symbolic analysis (elimination tree, column counts of L); every later
matrix with the same pattern goes through ``Solver.update`` (numeric factorisation only) and ``Solver.solve``.
The solver is built at the first factorisation with a new pattern, from that matrix itself (its construction
also factorises it). qdldl's constructor refuses a zero pivot, which ``Solver.update`` reports in D instead, so
when the first matrix is not quasi-definite the solver is built from a diagonally dominant matrix with H's pattern
and then updated with it.
qdldl factorises quasi-definite matrices without complaint, so positive definiteness is checked on D.

CHOLMOD. When cvxopt is installed and the pattern is large and its factor has dense enough columns
(``cholmod_backend``: CHOLMOD's supernodal rule on the column counts of L under an AMD ordering), the iterations
factorise with CHOLMOD's supernodal Cholesky instead (≈ 0.5× qdldl's time on W10000; qdldl stays faster on
sparser graphs), and qdldl's solver is not built unless asked for. CHOLMOD refuses a matrix that is not positive
definite (``ok`` False, as qdldl's pivot check). qdldl stays the solver the marginals and ``hessian_factors``
read: ``LDLSolver.qdldl`` builds it or brings its factor up to date with the last factorised matrix when CHOLMOD
did the factorisation.

Marginals (the sparse inverse on the pattern of qdldl's L) are in ``marginals``.
"""

import numpy as np
import qdldl
import scipy.sparse as sp
from numba import njit

from ...graph.errors import GraphError
from . import cholmod_backend

__all__ = ["HessianPattern", "LDLSolver", "csc_unique"]


@njit(cache=True)
def _counting_order(keys, n, order_in):
    """order_in stably reordered by keys[order_in] (each in [0, n)): one counting-sort pass."""
    start = np.zeros(n + 1, dtype=np.int64)
    for i in range(keys.size):
        start[keys[i] + 1] += 1
    for j in range(n):
        start[j + 1] += start[j]
    out = np.empty(order_in.size, dtype=np.int64)
    for t in range(order_in.size):
        i = order_in[t]
        out[start[keys[i]]] = i
        start[keys[i]] += 1
    return out


@njit(cache=True)
def csc_unique(n, rows, cols):
    """The distinct entries (rows[i], cols[i]), both in [0, n), in CSC order (column, then row, ascending):
    (indices: their rows, indptr, inverse: position of each input entry among them). The same arrays as
    ``np.unique((cols << 32) | rows, return_inverse=True)`` gives, from two counting-sort passes (by row, then
    stably by column) instead of a comparison sort of all keys."""
    N = rows.size
    order = _counting_order(cols, n, _counting_order(rows, n, np.arange(N)))
    inverse = np.empty(N, dtype=np.int64)
    indices = np.empty(N, dtype=np.int64)
    indptr = np.zeros(n + 1, dtype=np.int64)
    u = 0
    prev_r, prev_c = -1, -1
    for t in range(N):
        i = order[t]
        if rows[i] != prev_r or cols[i] != prev_c:
            prev_r, prev_c = rows[i], cols[i]
            indices[u] = prev_r
            indptr[prev_c + 1] += 1
            u += 1
        inverse[i] = u - 1
    for j in range(n):
        indptr[j + 1] += indptr[j]
    return indices[:u].copy(), indptr, inverse


class HessianPattern:
    """CSC pattern of the upper triangle of H (original ordering, full diagonal always present) and the scatter map.

    ``rows``/``cols``: free indices of every contribution (row ≤ col), ``valid`` False for contributions that touch
    a fixed vertex (they go to a dummy bin that is dropped).
    """

    def __init__(self, n, rows, cols, valid):
        self.n = n = int(n)
        valid = np.asarray(valid, dtype=bool)
        rows = np.asarray(rows, dtype=np.int64)[valid]
        cols = np.asarray(cols, dtype=np.int64)[valid]
        diag = np.arange(n, dtype=np.int64)
        r = np.concatenate([rows, diag])
        c = np.concatenate([cols, diag])
        indices, indptr, inverse = csc_unique(n, r, c)
        nvalid = len(rows)
        self.nnz = len(indices)
        self.keys = (np.repeat(diag, np.diff(indptr)) << 32) | indices   # (col << 32) | row, ascending
        self.scatter = np.full(len(valid), self.nnz, dtype=np.int32)     # int32: nnz < 2³¹ (as indptr)
        self.scatter[valid] = inverse[:nvalid]
        self.indices = indices.astype(np.int32)
        self.indptr = indptr.astype(np.int32)
        # diag_pos[i]: CSC position of H[i, i]
        self.diag_pos = inverse[nvalid:].astype(np.int64)

    def extended(self, n, rows, cols, valid):
        """The pattern after free rows ``self.n … n−1`` and contributions ``rows``/``cols``/``valid`` (as in
        the constructor) were added: returns (pattern, scatter of the new contributions), or None when a valid new
        contribution joins two old rows in an entry the old pattern lacks (a new edge between old vertices that
        were not coupled), which the append-only extension cannot place. Contributions between old rows that the
        pattern has (a landmark's diagonal block, seen again from a new pose) keep their positions; every other
        entry lies in a new column, so the old CSC positions do not move: the new data array is the old one
        followed by the new columns, and equals, position for position, the pattern the constructor would build
        from all contributions."""
        n = int(n)
        valid = np.asarray(valid, dtype=bool)
        rows = np.asarray(rows, dtype=np.int64)[valid]
        cols = np.asarray(cols, dtype=np.int64)[valid]
        if n < self.n:
            return None
        old = cols < self.n
        known = (cols[old] << 32) | rows[old]
        at = np.searchsorted(self.keys, known)
        if at.size and (int(at.max()) >= self.nnz or np.any(self.keys[at] != known)):
            return None
        fresh = np.arange(self.n, n, dtype=np.int64)
        key = (np.concatenate([cols[~old], fresh]) << 32) | np.concatenate([rows[~old], fresh])
        uniq, inverse = np.unique(key, return_inverse=True)
        new = HessianPattern.__new__(HessianPattern)
        new.n, new.nnz = n, self.nnz + len(uniq)
        new.keys = np.concatenate([self.keys, uniq])
        new.indices = np.concatenate([self.indices, (uniq & 0xFFFFFFFF).astype(np.int32)])
        counts = np.bincount((uniq >> 32) - self.n, minlength=n - self.n)
        new.indptr = np.concatenate([self.indptr, self.indptr[-1] + np.cumsum(counts)]).astype(np.int32)
        n_new = int(np.count_nonzero(~old))
        new.diag_pos = np.concatenate([self.diag_pos, self.nnz + inverse[n_new:]]).astype(np.int64)
        new.scatter = None                       # composed by the caller (structure.extend_structure)
        placed = np.empty(len(rows), dtype=np.int64)
        placed[old] = at
        placed[~old] = self.nnz + inverse[:n_new]
        scatter = np.full(len(valid), new.nnz, dtype=np.int32)
        scatter[valid] = placed
        return new, scatter

    def assemble(self, values):
        """CSC data of the upper triangle of H from the contribution values (same order as rows/cols)."""
        return np.bincount(self.scatter, weights=values, minlength=self.nnz + 1)[: self.nnz]

    def upper(self, data):
        """The upper triangle of H as a scipy CSC matrix sharing this pattern (explicit zeros kept)."""
        return sp.csc_matrix((np.ascontiguousarray(data, dtype=float), self.indices, self.indptr),
                             shape=(self.n, self.n))

    def full_matrix(self, data):
        """Symmetric scipy CSC H (both triangles)."""
        u = self.upper(data)
        return (u + sp.triu(u, k=1, format="csc").T).tocsc()

    def surrogate(self):
        """CSC data of a diagonally dominant (hence positive definite) matrix with this pattern."""
        data = np.full(self.nnz, -1.0)
        colidx = np.repeat(np.arange(self.n), np.diff(self.indptr))
        off = self.indices != colidx
        deg = np.bincount(self.indices[off], minlength=self.n) + np.bincount(colidx[off], minlength=self.n)
        data[self.diag_pos] = deg + 1.0
        return data


class LDLSolver:
    """LDLᵀ of H through ``qdldl.Solver``: the first ``factor`` after ``analyse`` builds the solver (AMD ordering,
    symbolic analysis and the factorisation of that matrix), every later matrix with that pattern only goes through
    ``update`` (numeric refactorisation; LM only changes the diagonal).

    ``backend``: "auto" (default) — CHOLMOD for the patterns where it pays (module docstring), qdldl otherwise;
    "qdldl" or "cholmod" force one (cholmod needs cvxopt). A change applies from the next ``analyse``;
    ``active_backend`` is the one the current pattern uses. In "auto" the solver keeps its last decision for later
    patterns whose size stays within a factor 2 of the pattern it decided on (an online run's patterns grow a few
    entries at a time; each decision costs an ordering)."""

    BACKENDS = ("auto", "qdldl", "cholmod")

    def __init__(self, backend="auto"):
        self.pattern = None
        self._prepared = False      # the backend of the current pattern is chosen and its solver built
        self._qdldl = None
        self._cholmod = None
        self._qdldl_stale = False   # CHOLMOD factorised a matrix that qdldl has not seen
        self._upper = None          # the pattern's upper triangle for qdldl (values replaced per matrix)
        self._trusted = False       # the last matrix was declared positive definite by its damping
        self._decision = None       # "auto": (nnz of the pattern decided on, whether CHOLMOD was chosen)
        self.ok = False
        self.factorisations = 0     # calls of ``factor``: tells a caller whether the factorisation it made is current
        self.backend = backend

    @property
    def backend(self):
        return self._backend

    @backend.setter
    def backend(self, value):
        if value not in self.BACKENDS:
            raise ValueError(f"LDLSolver.backend must be one of {self.BACKENDS}, got {value!r}")
        if value == "cholmod" and not cholmod_backend.AVAILABLE:
            raise GraphError("LDLSolver.backend 'cholmod' needs cvxopt, which is not installed")
        self._backend = value
        self._decision = None

    @property
    def active_backend(self):
        """"cholmod" or "qdldl": the backend of the current pattern (None before ``analyse``)."""
        if self.pattern is None:
            return None
        if not self._prepared and self.pattern.n:
            self._prepare(None)
        return "cholmod" if self._cholmod is not None else "qdldl"

    @property
    def qdldl(self):
        """The ``qdldl.Solver`` of the current pattern holding the factor of the last factorised matrix (None when
        the pattern is empty). When CHOLMOD factorised that matrix, qdldl's solver is built (once per pattern) or
        refactorised here first, and its pivot check then also applies to ``ok``."""
        if self.pattern is None or not self.pattern.n:
            return None
        if not self._prepared:
            self._prepare(None)
        if self._qdldl is None:         # a CHOLMOD pattern: qdldl's solver only on demand
            self._qdldl = self._stand_in_solver()
        if self._qdldl_stale:
            self._qdldl_stale = False
            self._qdldl.update(self.pattern.upper(self._cholmod.values), upper=True)
            if self.ok and not self._trusted:
                self.ok = self._pivots_positive()
        return self._qdldl

    def analyse(self, pattern):
        """Take ``pattern`` as the pattern of the next matrices (once per structure change); the backend, its
        ordering and symbolic analysis are settled at the first ``factor`` (``_prepare``)."""
        self.pattern = pattern
        self.ok = False
        self._prepared = False
        self._cholmod = None
        self._qdldl = None
        self._qdldl_stale = False
        self._upper = None
        return self

    def _upper_of(self, data):
        """The upper triangle with values ``data`` as a scipy matrix for qdldl: one matrix per pattern whose values
        are replaced (scipy's constructor checks cost more than qdldl's refactorisation of a small graph)."""
        data = np.ascontiguousarray(data, dtype=float)
        if self._upper is None:             # built at the first use (a CHOLMOD pattern may never need it)
            self._upper = self.pattern.upper(data)
        self._upper.data = data
        return self._upper

    def _stand_in_solver(self):
        """qdldl's solver for the current pattern, built from a diagonally dominant matrix with that pattern."""
        return qdldl.Solver(self.pattern.upper(self.pattern.surrogate()), upper=True)

    def _choose_cholmod(self):
        """(ordering, cvxopt matrix) when the current pattern is to be factorised by CHOLMOD, else None: forced by
        ``backend``, or in "auto" for a pattern of at least ``AUTO_MIN_NNZ`` entries by CHOLMOD's rule on the column
        counts of L under an AMD ordering (``cholmod_backend``) — or by the last decision, for a size within a
        factor 2 of the pattern it was made on."""
        pattern, reuse = self.pattern, False
        if self._backend == "qdldl" or not cholmod_backend.AVAILABLE:
            return None
        if self._backend == "auto":
            if pattern.nnz < cholmod_backend.AUTO_MIN_NNZ:
                return None
            reuse = self._decision is not None and self._decision[0] / 2 <= pattern.nnz <= 2 * self._decision[0]
            if reuse and not self._decision[1]:
                return None
        matrix = cholmod_backend.pattern_matrix(pattern)
        perm = cholmod_backend.amd_ordering(matrix)
        if self._backend == "auto" and not reuse:
            counts = cholmod_backend.column_counts(pattern, perm)
            self._decision = (pattern.nnz, cholmod_backend.prefers_cholmod(counts))
            if not self._decision[1]:
                return None
        return perm, matrix

    def _prepare(self, data):
        """The backend of the current pattern and its solver: CHOLMOD's symbolic analysis (``_choose_cholmod``),
        or qdldl's solver (AMD ordering, symbolic analysis and a factorisation). qdldl factorises ``data`` when
        that is quasi-definite (returns True), else (or when ``data`` is None) a diagonally dominant matrix with the
        pattern."""
        pattern, factored = self.pattern, False
        chosen = self._choose_cholmod()
        self._prepared = True
        if chosen is not None:
            self._cholmod = cholmod_backend.CholmodFactor(pattern, *chosen)
            return False
        if data is not None:
            try:
                self._qdldl = qdldl.Solver(self._upper_of(data), upper=True)
                factored = True
            except RuntimeError:        # a zero pivot: qdldl's constructor refuses what update() accepts
                pass
        if not factored:
            self._qdldl = self._stand_in_solver()
        return factored

    def _pivots_positive(self):
        d = self._qdldl.factors()[1]
        return bool(np.all(d > 0.0) and np.all(np.isfinite(d)))

    def factor(self, pattern, data, damping=0.0):
        """Factorise the matrix with upper-triangle CSC ``data`` on ``pattern``; ``ok`` says whether it is
        positive definite (every pivot d_i > 0).

        ``damping`` = μ declares the matrix to be H + μI with H = Σ JᵀΩJ positive semi-definite. When μ is
        well above round-off (μ > 1e−9·max diag) the matrix is positive definite by construction (its smallest
        eigenvalue is ≥ μ), so qdldl's pivot check — which copies the whole factor out of qdldl — is skipped; a
        numerical breakdown would still show up as a non-finite solution, which the callers test. CHOLMOD checks
        every pivot itself (a failure gives ``ok`` False, hence a NaN solution, in either case)."""
        if self.pattern is not pattern:
            self.analyse(pattern)
        if np.shape(data) != (pattern.nnz,):
            raise ValueError(f"factor: data must hold the {pattern.nnz} CSC values of the pattern, got shape "
                             f"{np.shape(data)}")
        self.factorisations += 1
        if pattern.n == 0:
            self.ok = True
            return self
        self._trusted = damping > 1e-9 * float(np.max(np.abs(data[pattern.diag_pos])))
        factored = not self._prepared and self._prepare(data)
        if self._cholmod is not None:
            self.ok = self._cholmod.factor(data, check_pivots=not self._trusted)
            self._qdldl_stale = True
            return self
        if not factored:
            self._qdldl.update(self._upper_of(data), upper=True)
        self.ok = True if self._trusted else self._pivots_positive()
        return self

    def solve(self, rhs):
        """x = H⁻¹ rhs; NaN everywhere if H was not positive definite."""
        if self.pattern is None:
            raise GraphError("solve: nothing has been factorised yet (call factor first)")
        if np.shape(rhs) != (self.pattern.n,):
            raise ValueError(f"solve: rhs must have shape ({self.pattern.n},), got {np.shape(rhs)}")
        if self.pattern.n == 0:
            return np.zeros(0)
        if not self.ok:
            return np.full(self.pattern.n, np.nan)
        rhs = np.ascontiguousarray(rhs, dtype=float)
        if self._cholmod is not None:
            return self._cholmod.solve(rhs)
        return np.asarray(self._qdldl.solve(rhs), dtype=float)
