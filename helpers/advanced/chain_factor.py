"""The square-root information factor of a trajectory-and-map graph, eliminated pose by pose and kept between updates.

Variables: the chain x_0 … x_{N−1} (poses, p coordinates each) and the map m (D coordinates, every landmark). Each
edge touches at most x_k and x_{k+1} and any map coordinates, so the Gauss–Newton system H δ = −g is a sum of *slot*
terms: slot k holds the edges whose first pose is x_k, summed into A_k = Σ J̃ᵀJ̃ and a_k = Σ J̃ᵀẽ over the local
variables (x_k, x_{k+1}, m) (the map-only edges form the map slot, A_m and a_m over m).

Elimination order x_0, x_1, …, x_{N−1}, then m. The frontier F_k is the information on (x_k, m) that the poses
before x_k leave behind (F_0 = 0, f_0 = 0). Eliminating x_k:

    M = F_k ⊕ A_k over (x_k, x_{k+1}, m),   r = f_k ⊕ (−a_k)
    R_kk = chol(M_kk)ᵀ (upper triangular),   [R_k,k+1  R_k,m] = R_kk⁻ᵀ M_k,(k+1,m),   y_k = R_kk⁻ᵀ r_k
    F_{k+1} = M_(k+1,m) − R_k,(k+1,m)ᵀ R_k,(k+1,m),   f_{k+1} = r_(k+1,m) − R_k,(k+1,m)ᵀ y_k

and after x_{N−1}: R_mm = chol(F_N + A_m)ᵀ, y_m = R_mm⁻ᵀ (f_N − a_m). The rows form R with RᵀR = H and Rᵀy = −g,
so the back-substitution R δ = y gives the Gauss–Newton step:

    δ_m = R_mm⁻¹ y_m,    δ_k = R_kk⁻¹ (y_k − R_k,k+1 δ_{k+1} − R_k,m δ_m)   for k = N−1 … 0

(one banded triangular solve of the poses, LAPACK ``dtbtrs``, after R_k,m δ_m for all k at once). Every F_k is kept,
so a change to the slots k ≥ k₀ is absorbed by eliminating again from x_{k₀} only. Memory: N (p + D)² floats for
the frontiers and N (2p + D)² for the slots, so the map should be tens of landmarks, not thousands.
"""

import numpy as np
from scipy.linalg import solve_triangular
from scipy.linalg.lapack import dtbtrs

from ..graph.errors import GraphError
from .chain_kernel import eliminate_chain, solve_chain

__all__ = ["ChainFactor", "NotPositiveDefiniteError", "add_slot_terms_reference"]


class NotPositiveDefiniteError(GraphError):
    """A pivot block of the elimination is not positive definite: the variable is not constrained by its edges.
    ``variable`` is ("chain", index of the pose) or ("map", the failing map column); ``vertex`` is the vertex
    object when the caller knows it (``IncrementalSmoother`` does), else None."""

    def __init__(self, message, variable, vertex=None):
        super().__init__(message)
        self.variable = variable
        self.vertex = vertex


class ChainFactor:
    """Slot terms, frontiers and factor rows of N poses (dimension p) and a D-dimensional map (module docstring).

    ``A``/``a`` are the slot terms over (x_k, x_{k+1}, m) and ``Am``/``am`` the map slot; callers fill them through
    ``reserve``. ``eliminate(k0)`` redoes the rows from x_{k0}; ``solve()`` returns (δ_chain (N, p), δ_m (D,)).
    """

    def __init__(self, p):
        self.p = int(p)
        self.N = 0
        self.D = 0
        self._alloc(16, 8)

    def _alloc(self, ncap, dcap):
        p = self.p
        self.ncap, self.dcap = ncap, dcap
        s = 2 * p + dcap
        self.A = np.zeros((ncap, s, s))
        self.a = np.zeros((ncap, s))
        self.Am = np.zeros((dcap, dcap))
        self.am = np.zeros(dcap)
        self.F = np.zeros((ncap + 1, p + dcap, p + dcap))
        self.f = np.zeros((ncap + 1, p + dcap))
        self.Rkk = np.zeros((ncap, p, p))
        self.Rk1 = np.zeros((ncap, p, p))
        self.RkM = np.zeros((ncap, p, dcap))
        self.y = np.zeros((ncap, p))
        self.Rmm = np.zeros((dcap, dcap))
        self.ym = np.zeros(dcap)

    def reserve(self, n, d):
        """Make room for n poses and a d-dimensional map (zero slot terms for the new ones); sets N and D."""
        if n > self.ncap or d > self.dcap:
            old = {k: getattr(self, k) for k in ("A", "a", "Am", "am", "F", "f", "Rkk", "Rk1", "RkM", "y",
                                             "Rmm", "ym")}
            self._alloc(max(n, 2 * self.ncap) if n > self.ncap else self.ncap,
                        max(d, 2 * self.dcap) if d > self.dcap else self.dcap)
            for name, value in old.items():   # every layout keeps its offsets (the map columns start at 2p in A)
                getattr(self, name)[tuple(slice(0, m) for m in value.shape)] = value
        self.N, self.D = n, d

    def eliminate(self, k0):
        """Recompute the factor rows of x_{k0} … x_{N−1} and of the map from the frontier F_{k0} (compiled:
        ``chain_kernel.eliminate_chain``, the same arithmetic as ``eliminate_reference``)."""
        failed = eliminate_chain(self.A, self.a, self.F, self.f, self.Am, self.am, self.Rkk, self.Rk1, self.RkM,
                                 self.y, self.Rmm, self.ym, int(k0), self.N, self.p, self.D)
        if failed >= 0:
            raise _not_positive_definite(("chain", int(failed)) if failed < self.N else ("map", int(failed - self.N)))

    def eliminate_reference(self, k0):
        """``eliminate`` in plain numpy, statement by statement as in the module docstring."""
        p, D, N = self.p, self.D, self.N
        s = 2 * p + D
        loc = np.r_[0:p, 2 * p:s]        # (x_k, m) inside (x_k, x_{k+1}, m)
        for k in range(k0, N):
            M = self.A[k, :s, :s].copy()
            r = -self.a[k, :s]
            M[np.ix_(loc, loc)] += self.F[k, :p + D, :p + D]
            r[loc] += self.f[k, :p + D]
            L = self._pivot(M[:p, :p], ("chain", k))
            W = solve_triangular(L, M[:p, p:], lower=True)
            yk = solve_triangular(L, r[:p], lower=True)
            self.Rkk[k], self.Rk1[k], self.RkM[k, :, :D], self.y[k] = L.T, W[:, :p], W[:, p:], yk
            self.F[k + 1, :p + D, :p + D] = M[p:, p:] - W.T @ W       # over (x_{k+1}, m)
            self.f[k + 1, :p + D] = r[p:] - W.T @ yk
        Fm = self.F[N, p:p + D, p:p + D] + self.Am[:D, :D]             # x_N does not exist: keep the map part
        L = self._pivot(Fm, ("map", None)) if D else np.zeros((0, 0))
        self.Rmm[:D, :D] = L.T
        self.ym[:D] = solve_triangular(L, self.f[N, p:p + D] - self.am[:D], lower=True)

    @staticmethod
    def _pivot(block, variable):
        try:
            return np.linalg.cholesky(block)
        except np.linalg.LinAlgError:
            raise _not_positive_definite(variable) from None

    def solve(self):
        """Back-substitution R δ = y: (δ_chain (N, p), δ_m (D,)) (compiled: ``chain_kernel.solve_chain``)."""
        return solve_chain(self.Rkk, self.Rk1, self.RkM, self.y, self.Rmm, self.ym, self.N, self.p, self.D)

    def solve_reference(self):
        """``solve`` with numpy and LAPACK: δ_m by one triangular solve, the poses by one banded one (dtbtrs)."""
        p, D, N = self.p, self.D, self.N
        dm = solve_triangular(self.Rmm[:D, :D], self.ym[:D]) if D else np.zeros(0)
        rhs = self.y[:N] - np.einsum("kij,j->ki", self.RkM[:N, :, :D], dm)
        if N == 0:
            return np.zeros((0, p)), dm
        kd = 2 * p - 1
        ab = np.zeros((kd + 1, N * p))
        rows, cols, vals = _band_entries(self.Rkk[:N], self.Rk1[:N])
        ab[kd + rows - cols, cols] = vals
        x, info = dtbtrs(ab, rhs.reshape(-1, 1), uplo="U")
        if info != 0:
            raise NotPositiveDefiniteError(f"the factor's pivot {info} is zero", ("chain", (info - 1) // p))
        return x.reshape(N, p), dm


def _not_positive_definite(variable):
    kind, index = variable
    what = f"pose {index} of the chain" if kind == "chain" else "the map" + ("" if index is None else
                                                                             f" (column {index})")
    return NotPositiveDefiniteError(f"the information on {what} is not positive definite after eliminating the "
                                    "variables before it: its edges do not constrain it (a gauge freedom or a "
                                    "degenerate measurement)", variable)


def _band_entries(Rkk, Rk1):
    """(rows, cols, values) of the block-bidiagonal upper factor of the chain (Rkk upper, Rk1 full)."""
    N, p, _ = Rkk.shape
    i, j = np.triu_indices(p)
    k = np.arange(N)[:, None]
    r0 = (k * p + i).ravel()
    c0 = (k * p + j).ravel()
    v0 = Rkk[:, i, j].ravel()
    ii, jj = np.indices((p, p))
    k1 = np.arange(N - 1)[:, None]
    r1 = (k1 * p + ii.ravel()).ravel()
    c1 = ((k1 + 1) * p + jj.ravel()).ravel()
    v1 = Rk1[:N - 1].reshape(-1)
    return np.r_[r0, r1], np.r_[c0, c1], np.r_[v0, v1]


def add_slot_terms_reference(factor, slots, ew, J, starts, dims):
    """``chain_kernel.add_slot_terms`` in numpy: each edge's whitened Jacobians placed at their local columns
    (a dense J_loc over (x_k, x_{k+1}, m)), then A_k += J_locᵀ J_loc and a_k += J_locᵀ ẽ (the map slot, −1,
    into Am, am over the map columns)."""
    p, D = factor.p, factor.D
    s = 2 * p + D
    J_loc = np.zeros((len(ew), ew.shape[1], s))
    offsets = np.r_[0, np.cumsum(dims)]
    for e in range(len(ew)):
        for u, d in enumerate(dims):
            if starts[e, u] >= 0:
                J_loc[e, :, starts[e, u]:starts[e, u] + d] = J[e, :, offsets[u]:offsets[u] + d]
    H = np.einsum("emi,emj->eij", J_loc, J_loc)
    b = np.einsum("emi,em->ei", J_loc, ew)
    chain = slots >= 0
    np.add.at(factor.A[:, :s, :s], slots[chain], H[chain])
    np.add.at(factor.a[:, :s], slots[chain], b[chain])
    factor.Am[:D, :D] += H[~chain][:, 2 * p:, 2 * p:].sum(axis=0)
    factor.am[:D] += b[~chain][:, 2 * p:].sum(axis=0)
