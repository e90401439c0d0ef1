"""``IncrementalSmoother``: re-optimise a growing trajectory-and-map graph after every addition, keeping its factor.

Every free vertex of ``chain_class`` (the poses) is a chain variable, in creation order; every other free vertex is
a map variable. Each edge may touch two chain variables only if they are consecutive, x_k and x_{k+1}, and any map
variables (odometry, pose priors, pose–landmark observations, landmark priors). ``chain_factor`` explains the
elimination along the chain that this shape allows.

Each variable j has a linearisation point θ̄_j, and its estimate is θ̄_j ⊞ δ_j. Every edge is linearised at the θ̄
of its vertices, and δ solves the Gauss–Newton system of all edges there: H δ = −g, H = Σ J̃ᵀJ̃, g = Σ J̃ᵀẽ, with
ẽ = W e and J̃_k = W J_k M_k (Ω = WᵀW, M_k = ∂(x ⊞ δ)/∂δ). ``update()`` does one such solve after the graph grew:

1. new vertices start with θ̄ at the estimate they were given; new edges are linearised there;
2. every ``relinearize_skip``-th update, a variable whose δ exceeds ``relinearize_threshold`` (largest absolute
   coordinate) is relinearised, θ̄_j ← θ̄_j ⊞ δ_j, and so are its edges (iSAM2's fluid relinearisation: Kaess et
   al., "iSAM2: Incremental smoothing and mapping using the Bayes tree", IJRR 2012; threshold 0 and skip 1
   relinearise everything that moved, which makes each update a Gauss–Newton iteration);
3. the slots whose terms changed are summed again and the factor is eliminated again from the first of them (only
   the last poses, unless an old pose or a landmark was relinearised);
4. δ by back-substitution; with ``max_solves`` > 1, while some δ is over the threshold, those variables are
   relinearised and δ is solved again (Gauss–Newton iterations: what a first update from dead reckoning needs);
5. every vertex gets θ̄ ⊞ δ; χ² is evaluated there and returned.

So after every update δ is exactly the batch solution of the system linearised at θ̄ (the tests compare it with
the graph's own Hessian); what is approximate, as in iSAM2, is only that θ̄ is not re-centred on every variable at
every step.

Anything but growth since the last update (a vertex removed, fixed or freed, an edge removed or its values edited,
an estimate changed by someone else) makes the next update start afresh from the current estimates: nothing is
ignored. A failed update (``NonFiniteError``, ``NotPositiveDefiniteError``) leaves the vertices as they were, and
the next update starts afresh.
"""

import numpy as np

from ..graph.edge import check_model_output
from ..graph.elements import nonfinite_error, total_chi2
from ..graph.errors import GraphError
from ..graph.storage import GrowableArray
from ..graph.vertex import BaseVertex
from ..validation import integer, nonnegative_number
from .chain_factor import ChainFactor, NotPositiveDefiniteError
from .chain_kernel import add_slot_terms

__all__ = ["IncrementalSmoother", "NotPositiveDefiniteError"]

_IGNORED, _MAP_SLOT = -2, -1   # slot codes of an edge on fixed vertices only / on map variables only


class IncrementalSmoother:
    """Incremental Gauss–Newton smoothing of ``graph`` (a ``SparseOptimizer``) whose poses are ``chain_class``.

    ``update(max_solves=1)`` → χ² after the solve(s). Read-only after an update: ``delta`` (the last δ: chain
    (N, p), map (D,); ``delta_of(vertex)``), ``last`` {"eliminated": poses eliminated again, "relinearised":
    variables, "solves", "restarted": bool}, ``restarts`` (updates that started afresh).
    """

    def __init__(self, graph, chain_class, relinearize_threshold=0.1, relinearize_skip=10):
        if not hasattr(graph, "_vertex_store") or not hasattr(graph, "_edge_stores"):
            raise ValueError(f"IncrementalSmoother: graph must be a SparseOptimizer, got {graph!r}")
        if not (isinstance(chain_class, type) and issubclass(chain_class, BaseVertex)):
            raise ValueError(f"IncrementalSmoother: chain_class must be a vertex class, got {chain_class!r}")
        self.graph = graph
        self.chain_class = chain_class
        self.relinearize_threshold = nonnegative_number(relinearize_threshold, "relinearize_threshold")
        self.relinearize_skip = integer(relinearize_skip, "relinearize_skip", minimum=1)
        self.restarts = -1          # the first update "restarts" from nothing
        self.last = {}
        self._reset()

    def delta_of(self, vertex):
        """δ of ``vertex`` from the last update (zeros for a fixed vertex; its estimate is θ̄ ⊞ δ)."""
        h = self._handle(vertex)
        c, col = self._chain_of.buffer[h], self._map_of.buffer[h]
        if c >= 0:
            return self.delta[0][c].copy()
        if col >= 0:
            return self.delta[1][col:col + type(vertex).dimension].copy()
        return np.zeros(type(vertex).dimension)

    def linearisation_point(self, vertex):
        """θ̄ of ``vertex``: where its edges were last linearised."""
        vs = self.graph._vertex_store
        h = self._handle(vertex)
        return self._lin[vs.offset.buffer[h]:vs.offset.buffer[h] + vs.dimension.buffer[h]].copy()

    def _handle(self, vertex):
        if not isinstance(vertex, BaseVertex) or vertex.graph is not self.graph:
            raise ValueError(f"vertex must be a vertex of the smoother's graph, got {vertex!r}")
        if self.delta is None or vertex._h >= self._vertices_done:
            raise ValueError(f"{vertex!r} was added after the last update(); call update() first")
        return vertex._h

    # ----------------------------------------------------------------------------------------- bookkeeping
    def _reset(self):
        p = self.chain_class.dimension
        self.factor = ChainFactor(p)
        self._vertices_done = 0                       # handles seen
        self._chain_of = GrowableArray((), np.int64, -1)   # per handle: chain index, or −1
        self._map_of = GrowableArray((), np.int64, -1)     # per handle: first map column, or −1
        self._chain_pos = GrowableArray((p,), np.int64)    # per chain index: positions in the estimate array
        self._chain_handles = []
        self._map_handles = []
        self._map_dims = []
        self._rows_done = {}                          # edge store → rows seen
        self._slot = {}                               # edge store → GrowableArray of slot codes per row
        self._slot_rows = {}                          # slot code → [(edge store, row), …]
        self._chi2_pos = {}                           # edge store → per vertex slot, GrowableArray of positions
        self._lin = np.zeros(0)                       # θ̄, laid out as the graph's estimate array
        self._written = np.zeros(0)                   # the estimate array as the last update left it
        self._edits = self.graph._edit_count
        self._updates = 0
        self.delta = None
        self.restarts += 1

    def _changed_since_last_update(self):
        est = self.graph._vertex_store.estimates.values
        return (self.graph._edit_count != self._edits
                or not np.array_equal(est[:len(self._written)], self._written))

    def _add_vertices(self):
        vs = self.graph._vertex_store
        est = vs.estimates.values
        if len(self._lin) < len(est):
            self._lin = np.r_[self._lin, est[len(self._lin):]]
        for h in range(self._vertices_done, vs.count):
            chain = mapcol = -1
            if vs.alive.buffer[h] and not vs.fixed.buffer[h]:
                cls, d = vs.classes[vs.class_code.buffer[h]], int(vs.dimension.buffer[h])
                if cls is self.chain_class:
                    chain = self._chain_pos.append(vs.offset.buffer[h] + np.arange(d))
                    self._chain_handles.append(h)
                else:
                    mapcol = sum(self._map_dims)
                    self._map_handles.append(h)
                    self._map_dims.append(d)
            self._chain_of.append(chain)
            self._map_of.append(mapcol)
        self._vertices_done = vs.count
        self.factor.reserve(self._chain_pos.size, sum(self._map_dims))

    def _add_edges(self):
        """Slot codes of the new edges; returns the set of slots they change."""
        dirty = set()
        for store in self.graph._edge_stores.values():
            done = self._rows_done.get(store, 0)
            codes = self._slot.setdefault(store, GrowableArray((), np.int64, _IGNORED))
            for row in range(done, store.alive.size):
                code = self._slot_of(store, row) if store.alive.buffer[row] else _IGNORED
                codes.append(code)
                if code != _IGNORED:
                    dirty.add(code)
                    self._slot_rows.setdefault(code, []).append((store, row))
            self._rows_done[store] = store.alive.size
        return dirty

    def _slot_of(self, store, row):
        handles = store.handles.buffer[row]
        chain = [c for c in self._chain_of.buffer[handles] if c >= 0]
        free_map = any(self._map_of.buffer[h] >= 0 for h in handles)
        if chain and max(chain) - min(chain) > 1:
            raise GraphError(f"IncrementalSmoother: {store.objects[row]!r} joins poses {min(chain)} and {max(chain)} "
                             "of the chain; an edge may join consecutive poses only")
        if chain:
            return min(chain)
        return _MAP_SLOT if free_map else _IGNORED

    # ----------------------------------------------------------------------------------------- the update
    def update(self, max_solves=1):
        """One incremental Gauss–Newton solve (module docstring), then, while solves remain of ``max_solves`` and
        some variable's δ is over the threshold, relinearise those variables and solve again (Gauss–Newton
        iterations, for a graph far from its linearisation points, such as a first update from dead reckoning).
        Returns χ² at the new estimates; ``last["solves"]`` counts the solves."""
        max_solves = integer(max_solves, "max_solves", minimum=1)
        restarted = self._changed_since_last_update()
        if restarted:
            self._reset()
        try:
            return self._update(restarted, max_solves)
        except BaseException:
            self._reset()          # the vertices were not written; start afresh next time
            raise

    def _update(self, restarted, max_solves):
        self._add_vertices()
        dirty = self._add_edges()
        relinearised = eliminated = solves = 0
        if self.delta is not None and self._updates % self.relinearize_skip == 0:
            relinearised = self._relinearise(dirty)
        self._updates += 1
        f = self.factor
        n_old, d_old = (0, 0) if self.delta is None else (len(self.delta[0]), len(self.delta[1]))
        if n_old < f.N:     # new poses are eliminated even without edges (then NotPositiveDefiniteError names them)
            dirty.add(n_old)
        if d_old < f.D:
            dirty.add(_MAP_SLOT)
        while dirty:
            self._sum_slots(sorted(dirty))
            chain_slots = [s for s in dirty if s >= 0]
            k0 = min(chain_slots) if chain_slots else f.N
            self._eliminate(k0)
            self.delta = f.solve()
            eliminated += f.N - k0
            solves += 1
            dirty = set()
            if solves < max_solves and self._any_over_threshold():
                relinearised += self._relinearise(dirty)
        if self.delta is None:
            self.delta = (np.zeros((0, f.p)), np.zeros(0))
        self._write_estimates()
        self.last = {"eliminated": eliminated, "relinearised": relinearised, "solves": solves,
                     "restarted": restarted}
        return self._chi2()

    def _eliminate(self, k0):
        """``factor.eliminate(k0)``; a pivot that is not positive definite is reported with its vertex."""
        try:
            self.factor.eliminate(k0)
        except NotPositiveDefiniteError as err:
            kind, index = err.variable
            if kind == "chain":
                h = self._chain_handles[index]
            else:
                starts = self._map_starts()
                h = self._map_handles[int(np.searchsorted(starts, index, side="right")) - 1]
            vertex = self.graph._vertex_store.objects[h]
            raise NotPositiveDefiniteError(f"IncrementalSmoother.update: {vertex!r} is not constrained by its edges "
                                           "(its information is not positive definite after eliminating the poses "
                                           "before it: a gauge freedom or a degenerate measurement)",
                                           err.variable, vertex) from None

    def _chi2(self):
        """χ² = Σ eᵀΩe of every live edge at the estimates (``linearise.total_chi2``'s sum, with the positions of
        each edge's vertices kept between updates instead of gathered again)."""
        vs = self.graph._vertex_store
        est = vs.estimates.buffer
        total = 0.0
        for store in self.graph._edge_stores.values():
            n = store.alive.size
            if n == 0:
                continue
            cached = self._chi2_pos.setdefault(store, [GrowableArray((d,), np.int64) for d in store.slot_dimensions])
            new = store.handles.values[cached[0].size:n]
            for k, (positions, d) in enumerate(zip(cached, store.slot_dimensions)):
                positions.extend(vs.state_indices(new[:, k], d))
            live = store.alive.values
            rows = slice(None) if live.all() else np.flatnonzero(live)
            states = [est[positions.values[rows]] for positions in cached]
            params = {name: column.values[rows] for name, column in store.params.items()}
            e, _ = store.cls.evaluate(states, store.measurements.values[rows], params, jacobians=False)
            check_model_output(store.cls, e, None, len(states[0]), False)
            ew = np.einsum("eij,ej->ei", store.whitening.values[rows], e)
            total += float(np.einsum("ei,ei->", ew, ew))
        if not np.isfinite(total):
            return total_chi2(vs, self.graph._edge_stores)    # names the edges (NonFiniteError)
        return total

    def _map_starts(self):
        """First map column of every map vertex, and the map's dimension last."""
        return np.cumsum([0] + self._map_dims)

    def _any_over_threshold(self):
        dc, dm = self.delta
        return max(np.abs(dc).max(initial=0.0), np.abs(dm).max(initial=0.0)) > self.relinearize_threshold

    def _relinearise(self, dirty):
        """θ̄_j ← θ̄_j ⊞ δ_j for every variable whose δ is over the threshold; adds the slots of their edges to
        ``dirty``; returns how many variables moved."""
        dc, dm = self.delta
        thr = self.relinearize_threshold
        moved = np.flatnonzero(np.max(np.abs(dc), axis=1, initial=0.0) > thr) if len(dc) else np.zeros(0, int)
        if len(moved):
            pos = self._chain_pos.values[moved]
            self._lin[pos] = self.chain_class.oplus_batch(self._lin[pos], dc[moved])
            dirty.update(moved.tolist())
            dirty.update((moved[moved > 0] - 1).tolist())
        handles = []
        vs = self.graph._vertex_store
        starts = self._map_starts()
        known = int(np.searchsorted(starts, len(dm), side="right")) - 1      # landmarks new this update: no δ
        if known > 0:
            over = np.flatnonzero(np.maximum.reduceat(np.abs(dm), starts[:known]) > thr)
            for j in over.tolist():
                h, d, c = self._map_handles[j], self._map_dims[j], int(starts[j])
                cls = vs.classes[vs.class_code.buffer[h]]
                pos = vs.state_indices(np.array([h]), d)
                self._lin[pos] = cls.oplus_batch(self._lin[pos], dm[None, c:c + d])
                handles.append(h)
        if handles:
            for store, codes in self._slot.items():
                rows = np.flatnonzero(np.isin(store.handles.values[:codes.size], handles).any(axis=1))
                dirty.update(int(s) for s in np.unique(codes.values[rows]) if s != _IGNORED)
        return len(moved) + len(handles)

    def _sum_slots(self, slots):
        """A_k, a_k of every slot in ``slots`` (and of the map slot, −1, if listed) summed again from its edges."""
        f = self.factor
        chain = np.array([s for s in slots if s >= 0], dtype=np.int64)
        f.A[chain] = 0.0
        f.a[chain] = 0.0
        if _MAP_SLOT in slots:
            f.Am[:] = 0.0
            f.am[:] = 0.0
        by_store = {}
        for slot in slots:
            for store, row in self._slot_rows.get(slot, ()):
                by_store.setdefault(store, []).append(row)
        for store, rows in by_store.items():
            rows = np.array(rows, dtype=np.int64)
            self._add_terms(store, rows, self._slot[store].values[rows])

    def _add_terms(self, store, rows, slots):
        """Linearise ``rows`` of ``store`` at θ̄ and add J̃ᵀJ̃, J̃ᵀẽ into their slots (local layout (x_k, x_{k+1}, m);
        ``chain_kernel.add_slot_terms`` adds them, ``slot_terms_reference`` is the same sum in numpy)."""
        vs = self.graph._vertex_store
        handles = store.handles.values[rows]
        states = [self._lin[vs.state_indices(handles[:, k], d)] for k, d in enumerate(store.slot_dimensions)]
        params = {name: column.values[rows] for name, column in store.params.items()}
        e, jac = store.cls.evaluate(states, store.measurements.values[rows], params, jacobians=True)
        check_model_output(store.cls, e, jac, len(rows), True)
        jac = [j if t.oplus_jacobian_batch is None else j @ t.oplus_jacobian_batch(x)
               for j, t, x in zip(jac, store.cls.vertex_types, states)]
        w = store.whitening.values[rows]
        ew = np.einsum("eij,ej->ei", w, e)
        J = w @ np.concatenate(jac, axis=2)
        bad = ~(np.isfinite(ew).all(axis=1) & np.isfinite(J).all(axis=(1, 2)))
        if bad.any():
            raise nonfinite_error("IncrementalSmoother.update: at the linearisation points",
                                  [store.objects[r] for r in rows[bad]])
        p = self.factor.p
        chain, mapcol = self._chain_of.buffer[handles], self._map_of.buffer[handles]
        starts = np.where(chain >= 0, (chain - slots[:, None]) * p, np.where(mapcol >= 0, 2 * p + mapcol, -1))
        f = self.factor
        add_slot_terms(f.A, f.a, f.Am, f.am, slots, ew, J, starts, np.array(store.slot_dimensions), p)

    def _write_estimates(self):
        """Every free vertex ← θ̄ ⊞ δ (written straight into the graph's estimate array)."""
        vs = self.graph._vertex_store
        est = vs.estimates.values
        dc, dm = self.delta
        pos = self._chain_pos.values
        est[pos] = self.chain_class.oplus_batch(self._lin[pos], dc)
        by_class = {}
        for h in self._map_handles:
            by_class.setdefault(vs.class_code.buffer[h], []).append(h)
        for code, handles in by_class.items():
            cls, handles = vs.classes[code], np.array(handles)
            d = int(cls.dimension)
            pos = vs.state_indices(handles, d)
            cols = self._map_of.buffer[handles][:, None] + np.arange(d)
            est[pos] = cls.oplus_batch(self._lin[pos], dm[cols])
        self._written = est.copy()
        self.graph._values_changed()
