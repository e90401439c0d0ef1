"""FastOptimizer: the course's graph (``helpers.graph``: the same vertices, edges and element storage) with a
faster engine underneath.

The class is a thin front over modules with one job each:

    storage      growable arrays: vertex estimates/flags by handle, one edge store per edge class
    elements     ``GraphElements`` (the base class): add/remove/find vertices and edges, and the hooks through
                 which vertex and edge objects read and write their values in the storage
    structure    ``initialize_optimization``: Hessian indices of the free vertices, per edge class gather arrays,
                 the Hessian pattern (laid out from the vertex blocks: ``block_pattern``), the gauge check
    linearise    evaluate every edge class, whiten, assemble χ², H and b; ``FreeState`` (X as algorithms see it)
    algorithms   Gauss–Newton, the coursework's LM, GTSAM's LM schedule, with their parameters dataclasses
    algorithms_default  the default of ``optimize``: LM with GTSAM's λ schedule, SE(2) poses moved along arcs,
                 a window stopping rule (``DefaultParams``)
    batched      the per-edge products (W J M, Jᵀ J and Jᵀ e added into H and b), compiled
    linear       the Hessian pattern and the LDLᵀ solver (qdldl; CHOLMOD via cvxopt where it pays)
    marginals    blocks of H⁻¹ by the Takahashi recursion on the LDLᵀ factor

The vertices always hold the accepted state when ``optimize`` returns, and also when it raises (any exception or
interrupt restores the last accepted state first: ``algorithms.Algorithm.run``). Editing an edge's measurement,
information or parameters after ``initialize_optimization`` needs no rebuild: the edited edge classes are
re-gathered before the next linearisation. Adding/removing elements or fixing/freeing a vertex changes the
structure: ``optimize`` then asks for ``initialize_optimization()`` again.
"""

import time

import numpy as np
import scipy.sparse as sp

from ...graph.elements import GraphElements
from ...graph.errors import GraphError
from ...graph.marginals import marginal_blocks
from ...validation import boolean, integer
from .algorithms import GaussNewtonParams, GTSAMLevenbergMarquardtParams, LevenbergMarquardtParams
from .algorithms_default import DefaultParams, select_algorithm
from .linear import LDLSolver
from .linearise import FreeState, total_chi2
from .structure import build_structure, extend_structure, refresh_edge_values

__all__ = ["FastOptimizer", "DefaultParams", "LevenbergMarquardtParams", "GaussNewtonParams",
           "GTSAMLevenbergMarquardtParams"]

TAU = LevenbergMarquardtParams.tau  # LM's default τ (``optimize(tau=None)`` uses it)


class FastOptimizer(GraphElements):
    """The graph: vertices, edges, and the optimiser (see the module docstring).

    Public: ``add_vertex``, ``add_edge``, ``add_edges``, ``remove_edge``, ``remove_vertex``, ``vertex(id, cls)``,
    ``vertices()``, ``edges()``, ``initialize_optimization()``, ``optimize(max_iterations=100, algorithm="default")``,
    ``chi2()``, ``hessian()``, ``gradient()``, ``compute_marginals(vertices=None)``, ``statistics``,
    ``iterations``, ``chi2_history``, ``dimension`` (size of the free state), ``linear_solver``, ``verbose``.
    """

    #: the names ``optimize`` accepts as ``algorithm`` (or a parameters object)
    ALGORITHMS = ("default", "lm", "gn", "lm-gtsam")

    def __init__(self, verbose=False):
        super().__init__()
        self.verbose = boolean(verbose, "SparseOptimizer(verbose)")
        self._structure = None
        self._solver = LDLSolver()
        self._linear_system = None  # LinearSystem (H data, b, χ²) at the current state, or None
        self._factored = None       # (LinearSystem, solver count) of the last undamped factorisation of hessian_factors
        self.statistics = []

    def _values_changed(self):
        self._linear_system = None

    @property
    def linear_solver(self):
        """The ``LDLSolver`` of the last factorisation (``linear_solver.qdldl.factors()`` gives L, D, P)."""
        return self._solver

    # ======================================================================================== structure
    @property
    def dimension(self):
        """Size n of the free state vector X (valid after initialize_optimization)."""
        return 0 if self._structure is None else self._structure.dimension

    def initialize_optimization(self):
        """Build the structure: Hessian indices of the free vertices, edge gather arrays, the H pattern.

        When vertices and edges were only added since the last build, the structure is extended instead of
        rebuilt (``structure.extend_structure``; the same arrays either way). The solver's ordering and symbolic
        analysis are redone for every new pattern, at its first factorisation (qdldl chooses its own ordering).

        Raises GaugeFreedomError if a component of free vertices is not anchored.
        """
        structure = None
        if self._structure is not None and not self._rebuild_needed:
            structure = extend_structure(self._structure, self._vertex_store, self._edge_stores,
                                         self._dirty_edge_classes)
        if structure is None:
            structure = build_structure(self._vertex_store, self._edge_stores)
        self._solver.analyse(structure.pattern)
        self._hessian_index = structure.hessian_index
        self._structure = structure
        self._linear_system = None
        self._structure_stale = False
        self._rebuild_needed = False
        self._dirty_edge_classes.clear()
        return True

    def _require_structure(self, what):
        """Raise GraphError unless the structure is built and current; re-gather edited edge values."""
        if self._structure is None:
            raise GraphError(f"{what}: the structure has not been built; call initialize_optimization() first")
        if self._structure_stale:
            raise GraphError(f"{what}: the graph's structure changed since initialize_optimization() (an element "
                             "added or removed, or a vertex fixed or freed); call initialize_optimization() again")
        if self._dirty_edge_classes:
            refresh_edge_values(self._structure, self._vertex_store, self._dirty_edge_classes)
            self._dirty_edge_classes.clear()

    def _free_state(self):
        return FreeState(self._structure, self._vertex_store.estimates, self._solver, self._vertex_store.objects)

    def chi2(self):
        """χ² = Σ eᵀΩe over all edges at the current estimates (no structure needed)."""
        return total_chi2(self._vertex_store, self._edge_stores)

    # ======================================================================================== optimise
    def optimize(self, max_iterations=100, algorithm="default", tau=None, gn_tolerance=None):
        """Optimise the free vertices; returns the final χ².

        ``algorithm``: "default" — a Levenberg–Marquardt that converges from far away (GTSAM's λ schedule, SE(2) poses
        moved along arcs, stops only when χ² fell by less than 1e−9·χ² over 5 accepted iterations; module
        ``algorithms_default``); "lm" — the coursework's LM (what the DriveBot system runs); "gn" — Gauss–Newton;
        "lm-gtsam" — GTSAM's LM with its own stopping rules.
        ``tau`` sets the coursework LM's initial damping μ = τ·max(diag H) (default 1e−3) and needs algorithm="lm";
        ``gn_tolerance`` Gauss–Newton's stopping decrease (default 1e−5) and needs algorithm="gn". ``algorithm`` may
        also be a parameters object (``DefaultParams``, ``LevenbergMarquardtParams``, ``GaussNewtonParams``,
        ``GTSAMLevenbergMarquardtParams``), which then sets every parameter.
        ``statistics`` then holds one dict per outer iteration (chi2, mu, rejected steps, time).
        A linearisation already made at the current estimates (``hessian``, ``gradient``, ``hessian_factors``) is
        used as the first one, and after ``hessian_factors`` the first undamped solve (Gauss–Newton's) reuses its
        factorisation when the solver has factorised nothing since: the same numbers, without repeating the work.

        Raises NonFiniteError (naming the edges) when χ², H or b is not finite at the start or at a tried step;
        on any exception or interrupt the vertices hold the last accepted state.
        """
        max_iterations = integer(max_iterations, "max_iterations", minimum=0)
        method = select_algorithm(algorithm, tau=tau, gn_tolerance=gn_tolerance)
        self._require_structure("optimize")
        self.statistics = []
        if self._structure.dimension == 0:
            return self.chi2()
        t0 = time.perf_counter()
        start = None
        if self._linear_system is not None:       # linearised at this state already (e.g. by hessian_factors)
            factored = (self._factored is not None and self._factored[0] is self._linear_system
                        and self._factored[1] == self._solver.factorisations and self._solver.ok)
            start = (self._linear_system, factored)
        self._linear_system = None  # stays None if the run raises (H is then recomputed when asked for)
        chi2, self._linear_system = method.run(self._free_state(), max_iterations,
                                               lambda *row: self._record(*row, t0), start=start)
        return chi2

    def _record(self, k, chi2, mu, rejected, t0):
        entry = {"iteration": k, "chi2": chi2, "mu": mu, "rejected": rejected, "time": time.perf_counter() - t0}
        self.statistics.append(entry)
        if self.verbose:
            print(f"Iteration = {k:03d}; Residual = {chi2:6.3f}; Time = {entry['time']:3.3f}")

    @property
    def iterations(self):
        return len(self.statistics)

    @property
    def chi2_history(self):
        return [s["chi2"] for s in self.statistics]

    # ======================================================================================== H, marginals
    def _current_linear_system(self, what="hessian"):
        self._require_structure(what)
        if self._linear_system is None:
            self._linear_system = self._free_state().linearise(what)
        return self._linear_system

    def hessian(self):
        """The undamped H = Σ JᵀΩJ at the current state (symmetric scipy CSC, n×n, free vertices only)."""
        data = self._current_linear_system("hessian").hessian_data
        if self._structure.dimension == 0:
            return sp.csc_matrix((0, 0))
        return self._structure.pattern.full_matrix(data)

    def gradient(self):
        """b = Σ JᵀΩe at the current state."""
        return self._current_linear_system("gradient").gradient.copy()

    def hessian_factors(self):
        """(L, d, perm) of the undamped H = Σ JᵀΩJ at the current state, Pᵀ H P = (I + L) D (I + L)ᵀ with
        P[perm[j], j] = 1 and L strictly lower (scipy CSC); None when H is not positive definite or the graph has
        no free vertex. The graph's own solver refactorises H numerically (the ordering and symbolic analysis of
        the current pattern are reused) and the factor is copied out, so later changes do not affect it.
        Selected columns of H⁻¹ then cost one forward and one backward sweep each."""
        system = self._current_linear_system("hessian_factors")
        if self._structure.dimension == 0:
            return None
        self._solver.factor(self._solver.pattern, system.hessian_data)
        if not self._solver.ok:
            return None
        self._factored = (system, self._solver.factorisations)   # an optimize() from here reuses it
        lower, d, perm = self._solver.qdldl.factors()
        return sp.csc_matrix(lower), np.asarray(d, dtype=float), np.asarray(perm, dtype=np.int64)

    def compute_marginals(self, vertices=None):
        """Covariance blocks (H⁻¹ at the current state, undamped) for the given vertices (default: all).

        Returns {vertex: (d, d) array}: the covariance of the vertex's ⊞ update δ (for additive vertices, of its
        coordinates; for VertexSE2Exp, body-frame — map with M = oplus_jacobian_batch: M Σ Mᵀ). Fixed vertices get a
        zero block. Uses the sparse inverse on the pattern of
        the LDLᵀ factor (Takahashi recursion), never a dense inverse.
        """
        vertices = self._own_vertices(vertices, "compute_marginals")
        data = self._current_linear_system("compute_marginals").hessian_data
        if any(self._hessian_index[v._h] >= 0 for v in vertices):
            if not np.all(np.isfinite(data)):
                raise GraphError("compute_marginals: the Hessian is not finite")
            if not self._solver.factor(self._structure.pattern, data).ok:
                raise GraphError("compute_marginals: H is not positive definite at this state (unobservable "
                                 "directions?), so no covariance exists")
        return marginal_blocks(vertices, self._hessian_index, self._solver.qdldl)
