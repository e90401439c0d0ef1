"""SparseOptimizer: the graph (vertices and edges: ``elements``) and its optimiser.

One linearisation, for the free state X (the estimates of the vertices that are not fixed, stacked: ``layout``),
per edge class, for all its E edges at once:

    e, J_k = evaluate(x_slots, z, params)              e (E, m), J_k (E, m, d_k) = ∂e/∂(vertex in slot k)
    r = W e,  A_k = W J_k                              whitened with W, Ω = WᵀW
    χ² += Σ rᵀr,   b[slot k] += A_kᵀ r,   H[slot k, slot l] += A_kᵀ A_l

then the step solves H dX = b (Gauss–Newton) or (H + μI) dX = b (Levenberg–Marquardt) and moves X ← X ⊞ (−dX), each
vertex class by its own ⊞. H is sparse and symmetric positive definite at a well-posed graph; qdldl factorises it
as Pᵀ H P = (I + L) D (I + L)ᵀ (AMD ordering; the symbolic analysis is made once per layout).

Gauss–Newton: dX = H⁻¹ b, step X ⊞ (−α dX) with α halved while χ² rises (down to 1e−10); stops when ‖b‖∞ < 1e−12 or
the decrease of χ² is below ``gn_tolerance`` (1e−5, absolute).

Levenberg–Marquardt as the coursework (Lourakis's SBA, Fig. 2), τ = 1e−3, ε₁ = ε₂ = ε₃ = 1e−12:
    R0 = χ²(X), (H, b) at X; stop if ‖b‖∞ < ε₁;  μ = τ·max diag H, ν = 2
    per iteration, until a step is accepted (or a stop):
        dX = (H + μI)⁻¹ b; stop if ‖dX‖ < ε₂ (‖X‖ + ε₂)
        X' = X ⊞ (−dX), R1 = χ²(X'), ρ = (R0 − R1) / (dXᵀ(μ dX + b))
        ρ > 0: accept X'; (H, b) at X'; stop if ‖b‖∞ < ε₁; μ ← μ·max(1/3, 1 − (2ρ − 1)³), ν = 2
        else:  μ ← μ ν, ν ← 2ν
    stop if √R0 < ε₃

``optimize`` is a transaction: whatever escapes it (an error in an edge model, a non-finite χ², an interrupt) first
puts the last accepted X back into the vertices. ``compute_marginals`` gives blocks of H⁻¹ (``marginals``).
"""
from __future__ import annotations

import time
from collections.abc import Iterator

import numpy as np
import qdldl
import scipy.sparse as sp

from ..validation import boolean, integer, nonnegative_number, one_of, positive_number
from .edge import check_model_output
from .elements import GraphElements, nonfinite_error, total_chi2
from .errors import GraphError, NonFiniteError
from .layout import Layout, add_normal_equations, build_layout
from .marginals import marginal_blocks

__all__ = ["SparseOptimizer"]

TAU = 1e-3                # LM's initial damping μ = τ·max diag H
GN_TOLERANCE = 1e-5       # Gauss–Newton stops when χ² decreases by less (absolute)
_SMALL = 1e-12            # ε₁ = ε₂ = ε₃ of LM; Gauss–Newton's gradient test
_MIN_STEP = 1e-10         # Gauss–Newton gives up when α has been halved below this


class SparseOptimizer(GraphElements):
    """The graph (``add_vertex``, ``add_edge``, ``add_edges``, ``remove_edge``, ``remove_vertex``, ``vertex(id,
    cls)``, ``vertices()``, ``edges()``: ``GraphElements``) and its optimiser: ``initialize_optimization()``,
    ``optimize``, ``chi2()``, ``hessian()``, ``gradient()``, ``compute_marginals``, ``statistics`` (one dict per
    iteration), ``iterations``, ``chi2_history``, ``dimension`` (the size of X), ``factor`` (the qdldl solver)."""

    #: the names ``optimize`` accepts as ``algorithm``
    ALGORITHMS = ("lm", "gn")

    def __init__(self, verbose: bool = False) -> None:
        super().__init__()
        self.verbose = boolean(verbose, "SparseOptimizer(verbose)")
        self._layout = None
        self._system = None       # (χ², H data, b) at the current estimates, or None
        self.factor = None        # qdldl.Solver of the last factorisation (of this layout's pattern)
        self.statistics = []

    def _values_changed(self) -> None:
        self._system = None

    @property
    def dimension(self) -> int:
        return 0 if self._layout is None else self._layout.dimension

    @property
    def iterations(self) -> int:
        return len(self.statistics)

    @property
    def chi2_history(self) -> list:
        return [s["chi2"] for s in self.statistics]

    # ================================================================================ structure
    def initialize_optimization(self) -> bool:
        """Lay out X, every edge's place in H and b, and H's pattern (``layout``); GaugeFreedomError when a
        component of free vertices is not anchored. Needed again after any element is added or removed or a vertex
        is fixed or freed."""
        layout = build_layout(self._vertex_store, self._edge_stores)
        self._layout, self._hessian_index, self._system, self.factor = layout, layout.hessian_index, None, None
        self._structure_stale = self._rebuild_needed = False
        self._dirty_edge_classes.clear()
        return True

    def _require_layout(self, what: str) -> Layout:
        if self._layout is None:
            raise GraphError(f"{what}: the structure has not been built; call initialize_optimization() first")
        if self._structure_stale:
            raise GraphError(f"{what}: the graph's structure changed since initialize_optimization() (an element "
                             "added or removed, or a vertex fixed or freed); call initialize_optimization() again")
        return self._layout

    # ================================================================================ the free state X
    def _get_x(self) -> np.ndarray:
        estimates = self._vertex_store.estimates.buffer
        x = np.empty(self._layout.dimension)
        for g in self._layout.groups:
            x[g.hessian_rows] = estimates[g.state_index]
        return x

    def _set_x(self, x: np.ndarray) -> None:
        estimates = self._vertex_store.estimates.buffer
        for g in self._layout.groups:
            estimates[g.state_index] = x[g.hessian_rows]
        self._system = None

    def _retract(self, dx: np.ndarray) -> None:
        """X ← X ⊞ (−dx), each vertex class by its own ⊞."""
        estimates = self._vertex_store.estimates.buffer
        for g in self._layout.groups:
            moved = g.cls.oplus_batch(estimates[g.state_index], -dx[g.hessian_rows])
            _check_oplus_output(g, moved, self._vertex_store.objects)
            estimates[g.state_index] = moved
        self._system = None

    # ================================================================================ linearisation
    def _edge_terms(self, layout: Layout, jacobians: bool) -> Iterator[tuple]:
        """Per edge class: (its layout, W (E, m, m), e (E, m), J = [J_0 J_1 …] (E, m, D) or None)."""
        estimates = self._vertex_store.estimates.buffer
        for edges in layout.edges:
            store, rows = edges.store, edges.rows
            states = [estimates[index] for index in edges.state_index]
            params = {name: column.values[rows] for name, column in store.params.items()}
            e, jac = store.cls.evaluate(states, store.measurements.values[rows], params, jacobians=jacobians)
            check_model_output(store.cls, e, jac, len(rows), jacobians)
            yield edges, store.whitening.values[rows], e, (None if jac is None else np.concatenate(jac, axis=2))

    def _chi2_at_x(self, what: str) -> float:
        value = sum(_chi2_terms(w, e).sum() for _, w, e, _ in self._edge_terms(self._layout, False))
        if not np.isfinite(value):
            raise nonfinite_error(what, self._nonfinite_edges(False))
        return value

    def _linearise(self, what: str) -> tuple:
        """(χ², H's upper-triangle CSC data, b) at the current estimates (cached until a value changes)."""
        if self._system is not None:
            return self._system
        layout = self._layout
        chi2, b, data = 0.0, np.zeros(layout.dimension), np.zeros(layout.nnz)
        for edges, w, e, jac in self._edge_terms(layout, True):       # χ² += rᵀr, b += Aᵀr, H += AᵀA
            chi2 += add_normal_equations(np.ascontiguousarray(w), np.ascontiguousarray(e), jac, edges.x_rows,
                                         edges.h_index, data, b)
        if not (np.isfinite(chi2) and np.isfinite(b).all() and np.isfinite(data).all()):
            raise nonfinite_error(what, self._nonfinite_edges(True))
        self._system = (chi2, data, b)
        return self._system

    def _nonfinite_edges(self, jacobians: bool) -> list:
        bad = []
        for edges, w, e, jac in self._edge_terms(self._layout, jacobians):
            with np.errstate(over="ignore", invalid="ignore"):
                mask = ~np.isfinite(_chi2_terms(w, e))                       # the edge's χ² term
                if jac is not None:
                    mask |= ~np.isfinite(w @ jac).all(axis=(1, 2))
            bad += [edges.store.objects[row] for row in edges.rows[mask]]
        return bad

    # ================================================================================ the linear solve
    def _factorise(self, data: np.ndarray, definite: bool = False) -> bool:
        """LDLᵀ of the matrix with upper-triangle CSC ``data``; True when it is positive definite (every pivot of D
        positive; not checked when the caller knows it, ``definite``: the check copies the whole factor)."""
        layout = self._layout
        if self.factor is None:
            self._upper = sp.csc_matrix((data.copy(), layout.indices, layout.indptr), shape=(layout.dimension,) * 2)
            try:
                self.factor = qdldl.Solver(self._upper, upper=True)  # AMD ordering, symbolic and numeric LDLᵀ
                return definite or _positive_pivots(self.factor)
            except RuntimeError:                                     # a zero pivot: start from a definite matrix
                self._upper.data[:] = 0.0
                self._upper.data[layout.diagonal] = 1.0
                self.factor = qdldl.Solver(self._upper, upper=True)
        self._upper.data[:] = data
        self.factor.update(self._upper, upper=True)                 # numeric LDLᵀ only: same pattern
        return definite or _positive_pivots(self.factor)

    def _solve(self, data: np.ndarray, b: np.ndarray, mu: float = 0.0) -> np.ndarray:
        """dX = (H + μI)⁻¹ b; NaN when H + μI is not positive definite. H = Σ AᵀA is positive semi-definite, so
        with μ well above round-off (1e−9 of H's largest diagonal entry) H + μI is positive definite: unchecked."""
        diagonal = self._layout.diagonal
        definite = mu > 1e-9 * float(np.max(data[diagonal]))
        if mu:
            data = data.copy()
            data[diagonal] += mu
        if not self._factorise(data, definite):
            return np.full(len(b), np.nan)
        dx = self.factor.solve(b)
        return dx if np.all(np.isfinite(dx)) else np.full(len(b), np.nan)

    # ================================================================================ optimisation
    def optimize(self, max_iterations: int = 100, algorithm: str = "lm", tau: float | None = None,
                 gn_tolerance: float | None = None) -> float:
        """Optimise the free vertices with ``algorithm`` "lm" (Levenberg–Marquardt; ``tau`` sets its initial
        damping, default 1e−3) or "gn" (Gauss–Newton; ``gn_tolerance`` its stopping decrease, default 1e−5); returns
        the final χ². ``statistics`` then holds one dict per iteration (iteration, chi2, mu, rejected, time).

        NonFiniteError (naming the edges) when χ², H or b is not finite at the start or at a tried step; on any
        exception or interrupt the vertices hold the last accepted state."""
        max_iterations = integer(max_iterations, "max_iterations", minimum=0)
        one_of(algorithm, "algorithm", self.ALGORITHMS)
        if tau is not None and algorithm != "lm":
            raise ValueError(f"tau sets the initial damping of algorithm='lm' only (got algorithm={algorithm!r})")
        if gn_tolerance is not None and algorithm != "gn":
            raise ValueError(f"gn_tolerance applies to algorithm='gn' only (got algorithm={algorithm!r})")
        tau = TAU if tau is None else positive_number(tau, "tau")
        gn_tolerance = GN_TOLERANCE if gn_tolerance is None else nonnegative_number(gn_tolerance, "gn_tolerance")
        self._require_layout("optimize")
        self.statistics = []
        if self._layout.dimension == 0:
            return self.chi2()
        self._x, self._t0 = self._get_x(), time.perf_counter()
        try:
            self._chi2 = self._linearise("optimize: at the initial estimates")[0]
            if algorithm == "gn":
                self._gauss_newton(max_iterations, gn_tolerance)
            else:
                self._levenberg_marquardt(max_iterations, tau)
        finally:
            self._reject()                                # the accepted X (also after an error or interrupt)
        return self._chi2

    # The trial protocol of both algorithms (g2o's push / pop): X is the accepted state, χ² its value.
    def _try_step(self, dx: np.ndarray) -> float:
        """Move to X ⊞ (−dx); returns χ² there (X is kept until ``_accept``)."""
        self._retract(dx)
        return self._chi2_at_x("optimize: at a trial step")

    def _accept(self, chi2: float) -> None:
        """Keep the tried state: it becomes X."""
        self._x, self._chi2 = self._get_x(), chi2

    def _reject(self) -> None:
        """Go back to X."""
        self._set_x(self._x)

    def _gauss_newton(self, max_iterations: int, tolerance: float) -> None:
        for k in range(1, max_iterations + 1):
            _, data, b = self._linearise("optimize: at an accepted step")
            if np.max(np.abs(b)) < _SMALL:
                return
            dx = self._solve(data, b)                     # H dX = b
            if not np.all(np.isfinite(dx)):
                raise GraphError("optimize (Gauss–Newton): the Hessian is singular; use algorithm='lm'")
            alpha = 1.0
            while (r1 := self._try_step(alpha * dx)) > self._chi2:   # halve the step while χ² rises
                self._reject()
                alpha *= 0.5
                if alpha < _MIN_STEP:
                    self._record(k, 0.0, 1)
                    return
            decrease = self._chi2 - r1
            self._accept(r1)
            self._record(k, 0.0, 0)
            if decrease < tolerance:
                return

    def _levenberg_marquardt(self, max_iterations: int, tau: float) -> None:
        _, data, b = self._linearise("optimize: at the initial estimates")
        if np.max(np.abs(b)) < _SMALL:
            return
        mu, nu = tau * float(np.max(data[self._layout.diagonal])), 2.0
        for k in range(1, max_iterations + 1):
            rejected, stop = 0, False
            while True:                                   # damped steps until one is accepted
                dx = self._solve(data, b, mu)             # (H + μI) dX = b
                if not np.all(np.isfinite(dx)) or _norm(dx) < _SMALL * (_norm(self._x) + _SMALL):
                    stop = True
                    break
                r0, r1 = self._chi2, self._try_step(dx)
                denominator = float(np.multiply(dx, mu * dx + b).sum())
                rho = (r0 - r1) / denominator if denominator > 0 else -1.0   # the gain ratio
                if rho > 0:                               # accept X', then μ follows ρ
                    self._accept(r1)
                    _, data, b = self._linearise("optimize: at an accepted step")
                    stop = np.max(np.abs(b)) < _SMALL
                    mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                    nu = 2.0
                    break
                self._reject()                            # back to X, more damping
                rejected += 1
                mu, nu = mu * nu, 2.0 * nu
                if not np.isfinite(mu):
                    stop = True
                    break
            self._record(k, mu, rejected)
            if stop or np.sqrt(self._chi2) < _SMALL:
                return

    def _record(self, k: int, mu: float, rejected: int) -> None:
        entry = {"iteration": k, "chi2": self._chi2, "mu": mu, "rejected": rejected,
                 "time": time.perf_counter() - self._t0}
        self.statistics.append(entry)
        if self.verbose:
            print(f"Iteration = {k:03d}; Residual = {self._chi2:6.3f}; Time = {entry['time']:3.3f}")

    # ================================================================================ results
    def chi2(self) -> float:
        """χ² = Σ eᵀΩe over all edges at the current estimates (needs no structure)."""
        return total_chi2(self._vertex_store, self._edge_stores)

    def hessian(self) -> sp.csc_matrix:
        """H = Σ JᵀΩJ at the current estimates (symmetric scipy CSC, n×n, free vertices only)."""
        layout = self._require_layout("hessian")
        upper = sp.csc_matrix((self._linearise("hessian")[1], layout.indices, layout.indptr),
                              shape=(layout.dimension,) * 2)
        return (upper + sp.triu(upper, k=1).T).tocsc()

    def gradient(self) -> np.ndarray:
        """b = Σ JᵀΩe at the current estimates."""
        self._require_layout("gradient")
        return self._linearise("gradient")[2].copy()

    def compute_marginals(self, vertices: list | None = None) -> dict:
        """{vertex: covariance block} of H⁻¹ at the current estimates for ``vertices`` (default: all); a fixed
        vertex gets a zero block. GraphError when H is not positive definite (no covariance exists)."""
        vertices = self._own_vertices(vertices, "compute_marginals")
        self._require_layout("compute_marginals")
        data = self._linearise("compute_marginals")[1]
        if any(self._hessian_index[v._h] >= 0 for v in vertices) and not self._factorise(data):
            raise GraphError("compute_marginals: H is not positive definite at this state (unobservable "
                             "directions?), so no covariance exists")
        return marginal_blocks(vertices, self._hessian_index, self.factor)


def _chi2_terms(w: np.ndarray, e: np.ndarray) -> np.ndarray:
    """eᵀΩe = |W e|² of every edge: (E,)."""
    r = (w @ e[:, :, None])[:, :, 0]
    return np.multiply(r, r).sum(axis=1)


def _positive_pivots(factor) -> bool:
    d = factor.factors()[1]
    return bool(np.all(d > 0.0) and np.all(np.isfinite(d)))


def _norm(v: np.ndarray) -> float:
    return float(np.sqrt(np.multiply(v, v).sum()))


def _check_oplus_output(group, moved: np.ndarray, objects: list) -> None:
    """``oplus_batch`` of a vertex class must return finite (V, d) estimates (else GraphError / NonFiniteError)."""
    if np.shape(moved) != group.state_index.shape:
        raise GraphError(f"{group.cls.__name__}.oplus_batch returned shape {np.shape(moved)}; expected "
                         f"{group.state_index.shape} (one row per vertex)")
    if not np.isfinite(moved).all():
        ids = [objects[h].id for h in group.handles[~np.isfinite(moved).all(axis=1)][:5]]
        raise NonFiniteError(f"{group.cls.__name__}.oplus_batch returned non-finite estimates for vertex ids {ids}"
                             " (a non-finite or overflowing step)")
