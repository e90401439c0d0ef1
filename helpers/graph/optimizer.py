"""SparseOptimizer: the coursework's g2o-style graph with a vectorised, sparse engine underneath.

Storage. Every vertex added to the graph gets a handle h (creation order); its estimate lives in one flat float
array at offset off[h]; fixed/alive flags, class codes and Hessian indices are numpy arrays over handles. Edges
live in one store per edge class: vertex handles (E, nv), measurements (E, m), whitening matrices W (E, m, m)
with Ω = WᵀW, and per-edge parameters — all amortised (capacity doubling), so adding an element is O(1).

Structure (``initialize_optimization``, once per structure change, vectorised over edges): the free vertices
are stacked in creation order into X (Hessian indices); for every edge class the gather indices of its slots and
the upper-triangle Hessian contributions are computed; ``HessianPattern`` maps contributions to CSC data.
Gauge check: every connected component of free vertices must touch a fixed vertex or a unary edge.

Iteration (no Python loop over edges): per edge class, gather the slot states, call the class's ``evaluate``,
whiten (ẽ = W e, J̃_k = W J_k), form χ² = Σ‖ẽ‖², b_k = J̃_kᵀ ẽ, H_kl = J̃_kᵀ J̃_l, scatter with ``np.bincount``,
factorise with qdldl (``Solver.update``: its AMD ordering and symbolic analysis are reused), solve
dX = (H + μI)⁻¹ b and step X ⊞ (−dX) per vertex class.

Levenberg–Marquardt exactly as the coursework (Lourakis, SBA Fig. 2), τ = 1e−3, ε1 = ε2 = ε3 = 1e−12, ε4 = 0:
    R0 = χ²(X), (H, b) at X; stop if ‖b‖∞ < ε1;  μ = τ·max diag H, ν = 2
    per outer iteration, until a step is accepted (or stop):
        dX = (H + μI)⁻¹ b; stop if ‖dX‖ < ε2 (‖X‖ + ε2)
        X' = X ⊞ (−dX), R1 = χ²(X'), ρ = (R0 − R1) / (dXᵀ(μ dX + b))
        ρ > 0: stop if √R0 − √R1 < ε4 √R0; accept; (H, b) at X; stop if ‖b‖∞ < ε1; μ ← μ·max(1/3, 1 − (2ρ − 1)³), ν = 2
        else:  μ ← μ ν, ν ← 2ν
    stop if √R0 < ε3
Gauss–Newton: dX = H⁻¹ b, step X ⊞ (−α dX) with α halved while χ² rises (down to 1e−10); stop when the decrease
is below ``gn_tolerance`` (1e−5, absolute).
The vertices always hold the accepted state when ``optimize`` returns.
"""

import time

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .edge import BaseEdge, check_information_batch
from .errors import GaugeFreedomError, GraphError
from .linear import (HessianPattern, LDLSolver, batched_jte, batched_jtj, batched_matmul,
                     sparse_inverse_on_pattern)
from .vertex import BaseVertex

__all__ = ["SparseOptimizer"]

TAU = 1e-3
EPS1 = EPS2 = EPS3 = 1e-12
EPS4 = 0.0


def _dot(a, b):
    """aᵀb without BLAS: on a loaded machine a threaded BLAS ddot can stall for milliseconds per call."""
    return float(np.multiply(a, b).sum())


class _Grow:
    """Amortised growable numpy array (capacity doubling)."""

    def __init__(self, tail=(), dtype=float, fill=0):
        self.tail = tuple(tail)
        self.fill = fill
        self.a = np.full((16,) + self.tail, fill, dtype=dtype)
        self.n = 0

    def _reserve(self, extra):
        need = self.n + extra
        if need > len(self.a):
            cap = max(need, 2 * len(self.a))
            b = np.full((cap,) + self.tail, self.fill, dtype=self.a.dtype)
            b[: self.n] = self.a[: self.n]
            self.a = b

    def append(self, value):
        self._reserve(1)
        self.a[self.n] = value
        self.n += 1
        return self.n - 1

    def extend(self, values):
        values = np.asarray(values)
        k = len(values)
        self._reserve(k)
        self.a[self.n: self.n + k] = values
        self.n += k
        return self.n - k

    @property
    def v(self):
        return self.a[: self.n]


class _EdgeStore:
    def __init__(self, cls):
        self.cls = cls
        self.nv = len(cls.vertex_types)
        self.m = int(cls.measurement_dimension)
        self.dims = [int(t.dimension) for t in cls.vertex_types]
        self.vh = _Grow((self.nv,), np.int64, -1)
        self.z = _Grow((self.m,))
        self.w = _Grow((self.m, self.m))
        self.alive = _Grow((), bool, False)
        self.seq = _Grow((), np.int64, -1)
        self.params = {k: _Grow(v.shape) for k, v in cls._param_defaults.items()}
        self.obj = []


class _ClassBlock:
    """Per edge class, the structure arrays of one build."""

    __slots__ = ("store", "rows", "sidx", "shid", "vh", "z", "w", "wt", "params", "diag_w", "n")


class SparseOptimizer:
    """The graph: vertices, edges, and the optimiser (see the module docstring).

    Public: ``add_vertex``, ``add_edge``, ``remove_edge``, ``remove_vertex``, ``vertex(id, cls)``, ``vertices()``,
    ``edges()``, ``initialize_optimization()``, ``optimize(max_iterations=50, algorithm="lm")``, ``chi2()``,
    ``hessian()``, ``compute_marginals(vertices=None)``, ``statistics``, ``iterations``, ``chi2_history``,
    ``dimension`` (size of the free state), ``verbose``.
    """

    def __init__(self, verbose=False):
        self.verbose = bool(verbose)
        self._vobj = []
        self._vx = _Grow((), float, 0.0)
        self._voff = _Grow((), np.int64, -1)
        self._vdim = _Grow((), np.int64, 0)
        self._vcls = _Grow((), np.int64, -1)
        self._vfixed = _Grow((), bool, False)
        self._valive = _Grow((), bool, False)
        self._vkey = {}
        self._class_codes = {}
        self._classes = []
        self._stores = {}
        self._edge_seq = 0
        self._n_edges = 0
        self._n_vertices = 0
        self._dirty = True
        self._struct = None
        self._hidx = np.zeros(0, dtype=np.int64)
        self._solver = LDLSolver()
        self._hb = None  # (data, b, chi2) at the current state
        self.statistics = []

    # ======================================================================================== elements
    def add_vertex(self, vertex):
        """Add a vertex (its (class, id) must be new in this graph). Returns True."""
        if not isinstance(vertex, BaseVertex):
            raise GraphError(f"add_vertex: expected a vertex, got {type(vertex).__name__}")
        if vertex._graph is self:
            raise GraphError(f"add_vertex: {type(vertex).__name__} id {vertex.id} is already in this graph")
        if vertex._graph is not None:
            raise GraphError(f"add_vertex: {type(vertex).__name__} id {vertex.id} belongs to another graph")
        cls = type(vertex)
        key = (cls, vertex.id)
        if key in self._vkey:
            raise GraphError(f"add_vertex: duplicate vertex id {vertex.id} for class {cls.__name__}")
        code = self._class_codes.get(cls)
        if code is None:
            code = len(self._classes)
            self._class_codes[cls] = code
            self._classes.append(cls)
        d = int(cls.dimension)
        est = vertex._est
        off = self._vx.extend(est)
        h = self._voff.append(off)
        self._vdim.append(d)
        self._vcls.append(code)
        self._vfixed.append(vertex._fixed)
        self._valive.append(True)
        self._vobj.append(vertex)
        self._vkey[key] = vertex
        vertex._graph = self
        vertex._h = h
        self._n_vertices += 1
        self._dirty = True
        return True

    def add_edge(self, edge):
        """Add an edge whose vertices are all set and already in this graph. Returns True."""
        if not isinstance(edge, BaseEdge):
            raise GraphError(f"add_edge: expected an edge, got {type(edge).__name__}")
        cls = type(edge)
        if edge._graph is not None:
            raise GraphError(f"add_edge: this {cls.__name__} is already in a graph")
        for k, v in enumerate(edge._vertices):
            if v is None:
                raise GraphError(f"add_edge: {cls.__name__} vertex slot {k} is not set")
            if v._graph is not self:
                raise GraphError(
                    f"add_edge: {cls.__name__} slot {k}: unknown vertex {type(v).__name__} id {v.id} "
                    "(add it to this graph first)")
            if int(type(v).dimension) != int(cls.vertex_types[k].dimension):
                raise GraphError(f"add_edge: {cls.__name__} slot {k}: vertex dimension mismatch")
        store = self._stores.get(cls)
        if store is None:
            store = _EdgeStore(cls)
            self._stores[cls] = store
        row = store.vh.append([v._h for v in edge._vertices])
        store.z.append(edge._z)
        store.w.append(edge._w)
        store.alive.append(True)
        store.seq.append(self._edge_seq)
        for name, g in store.params.items():
            g.append(edge._params[name])
        store.obj.append(edge)
        self._edge_seq += 1
        edge._graph = self
        edge._row = row
        for v in edge._vertices:
            v._edges[edge] = None
        self._n_edges += 1
        self._dirty = True
        return True

    def add_edges(self, edge_class, vertices, measurements, information=None, **params):
        """Add many edges of one class at once (fast path for loaders); returns the new edge objects.

        ``vertices``: E rows of ``len(edge_class.vertex_types)`` vertices already in this graph;
        ``measurements`` (E, m); ``information`` (E, m, m) or one (m, m) for all (default I);
        ``params``: name -> (E, *shape) or one value for all. Validation is vectorised; the result is identical
        to adding the edges one by one, in order.
        """
        if not (isinstance(edge_class, type) and issubclass(edge_class, BaseEdge)):
            raise GraphError(f"add_edges: edge_class must be a BaseEdge subclass, got {edge_class!r}")
        nv = len(edge_class.vertex_types)
        m = int(edge_class.measurement_dimension)
        rows = [tuple(r) for r in vertices]
        E = len(rows)
        if E == 0:
            return []
        for t, r in enumerate(rows):
            if len(r) != nv:
                raise GraphError(f"add_edges: row {t} has {len(r)} vertices, {edge_class.__name__} needs {nv}")
            for k, v in enumerate(r):
                if not isinstance(v, edge_class.vertex_types[k]):
                    raise GraphError(f"add_edges: row {t} slot {k} needs a {edge_class.vertex_types[k].__name__}, "
                                     f"got {type(v).__name__}")
                if v._graph is not self:
                    raise GraphError(f"add_edges: row {t} slot {k}: unknown vertex {type(v).__name__} id {v.id}")
            if nv > 1 and len({id(v) for v in r}) != nv:
                raise GraphError(f"add_edges: row {t} uses the same vertex in two slots")
        z = np.array(measurements, dtype=float).reshape(E, -1) if np.size(measurements) == E * m else None
        if z is None:
            raise ValueError(f"add_edges: measurements must have shape ({E}, {m}), got {np.shape(measurements)}")
        if not np.isfinite(z).all():
            raise ValueError("add_edges: measurements must be finite")
        if information is None:
            information = np.eye(m)
        info = np.asarray(information, dtype=float)
        if info.ndim == 2:
            info = np.broadcast_to(info, (E, m, m))
        info, w = check_information_batch(info, m, "add_edges: information")
        pvals = {}
        for name, default in edge_class._param_defaults.items():
            val = np.asarray(params.pop(name, default), dtype=float)
            if val.shape == default.shape:
                val = np.broadcast_to(val, (E,) + default.shape)
            if val.shape != (E,) + default.shape or not np.isfinite(val).all():
                raise ValueError(f"add_edges: parameter {name} must be finite with shape {(E,) + default.shape}")
            pvals[name] = np.array(val)
        if params:
            raise ValueError(f"add_edges: {edge_class.__name__} has no parameter(s) {sorted(params)}")
        store = self._stores.get(edge_class)
        if store is None:
            store = _EdgeStore(edge_class)
            self._stores[edge_class] = store
        handles = np.array([[v._h for v in r] for r in rows], dtype=np.int64)
        row0 = store.vh.extend(handles)
        store.z.extend(z)
        store.w.extend(w)
        store.alive.extend(np.ones(E, dtype=bool))
        store.seq.extend(self._edge_seq + np.arange(E))
        for name, g in store.params.items():
            g.extend(pvals[name])
        self._edge_seq += E
        out = []
        new = edge_class.__new__
        for t, r in enumerate(rows):
            e = new(edge_class)
            e._graph = self
            e._row = row0 + t
            e._vertices = list(r)
            e._z = z[t]
            e._info = info[t]
            e._w = w[t]
            e._params = {name: pvals[name][t] for name in pvals}
            for v in r:
                v._edges[e] = None
            out.append(e)
        store.obj.extend(out)
        self._n_edges += E
        self._dirty = True
        return out

    def _detach_edge(self, edge):
        store = self._stores[type(edge)]
        store.alive.a[edge._row] = False
        store.obj[edge._row] = None
        edge._graph = None
        edge._row = -1
        self._n_edges -= 1
        self._dirty = True

    def remove_edge(self, edge):
        """Remove an edge; every vertex left with no edge is removed from the graph too (coursework semantics).

        Returns the list of vertices removed as a consequence.
        """
        if not isinstance(edge, BaseEdge) or edge._graph is not self:
            raise GraphError(f"remove_edge: this {type(edge).__name__} is not in this graph")
        self._detach_edge(edge)
        orphans = []
        for v in edge._vertices:
            v._edges.pop(edge, None)
            if not v._edges and v._graph is self:
                self._drop_vertex(v)
                orphans.append(v)
        return orphans

    def remove_vertex(self, vertex):
        """Remove a vertex and every edge attached to it (other vertices stay, even if left without edges)."""
        if not isinstance(vertex, BaseVertex) or vertex._graph is not self:
            raise GraphError(f"remove_vertex: {type(vertex).__name__} is not in this graph")
        for e in list(vertex._edges):
            self._detach_edge(e)
            for v in e._vertices:
                v._edges.pop(e, None)
        self._drop_vertex(vertex)
        return True

    def _drop_vertex(self, v):
        h = v._h
        v._est = self._vertex_estimate(h).copy()
        self._valive.a[h] = False
        self._vobj[h] = None
        del self._vkey[(type(v), v.id)]
        if h < len(self._hidx):
            self._hidx[h] = -1
        v._graph = None
        v._h = -1
        self._n_vertices -= 1
        self._dirty = True

    def vertex(self, id, cls=None):
        """The vertex with this id (and class, when ids repeat across classes), or None."""
        if cls is not None:
            return self._vkey.get((cls, id))
        hits = [v for (c, i), v in self._vkey.items() if i == id]
        if len(hits) > 1:
            raise GraphError(f"vertex({id}): several classes use this id; pass cls")
        return hits[0] if hits else None

    def vertices(self):
        """All vertices, in the order they were added."""
        return [v for v in self._vobj if v is not None]

    def edges(self):
        """All edges, in the order they were added."""
        pairs = []
        for store in self._stores.values():
            alive = np.nonzero(store.alive.v)[0]
            pairs.extend(zip(store.seq.v[alive].tolist(), (store.obj[i] for i in alive)))
        pairs.sort(key=lambda p: p[0])
        return [e for _, e in pairs]

    def number_of_vertices(self):
        return self._n_vertices

    def number_of_edges(self):
        return self._n_edges

    # ----- hooks used by the element objects -------------------------------------------------------------
    def _vertex_estimate(self, h):
        off = self._voff.a[h]
        return self._vx.a[off: off + self._vdim.a[h]]

    def _set_vertex_estimate(self, h, x):
        off = self._voff.a[h]
        self._vx.a[off: off + len(x)] = x
        self._hb = None

    def _set_vertex_fixed(self, h, flag):
        self._vfixed.a[h] = flag
        self._dirty = True

    def _vertex_hessian_index(self, h):
        if self._dirty or h >= len(self._hidx) or self._hidx[h] < 0:
            return None
        return int(self._hidx[h])

    def _edge_store_row(self, edge):
        store = self._stores[type(edge)]
        r = edge._row
        store.z.a[r] = edge._z
        store.w.a[r] = edge._w
        for name, g in store.params.items():
            g.a[r] = edge._params[name]
        self._hb = None

    def _edge_set_vertex(self, edge, k, old, new):
        if new is None or new._graph is not self:
            raise GraphError(f"set_vertex: the new vertex of slot {k} must be in the edge's graph")
        if old is not None:
            old._edges.pop(edge, None)
        new._edges[edge] = None
        self._stores[type(edge)].vh.a[edge._row, k] = new._h
        self._dirty = True

    # ======================================================================================== structure
    @property
    def dimension(self):
        """Size n of the free state vector X (valid after initialize_optimization)."""
        return 0 if self._struct is None else self._struct["n"]

    def initialize_optimization(self):
        """Build the structure: Hessian indices of the free vertices, edge gather arrays, the H pattern.

        Raises GaugeFreedomError if a component of free vertices is not anchored.
        """
        nh = self._voff.n
        alive = self._valive.v
        free = alive & ~self._vfixed.v
        dims = self._vdim.v
        off = self._voff.v
        hidx = np.full(nh, -1, dtype=np.int64)
        fdims = dims[free]
        starts = np.cumsum(fdims) - fdims
        hidx[free] = starts
        n = int(fdims.sum())
        free_h = np.nonzero(free)[0]
        # flat offsets of X in hidx order, and the oplus groups per vertex class
        groups = []
        codes = self._vcls.v[free_h]
        for code in np.unique(codes):
            hs = free_h[codes == code]
            cls = self._classes[code]
            d = int(cls.dimension)
            ar = np.arange(d)
            groups.append((cls, off[hs][:, None] + ar, hidx[hs][:, None] + ar, hs))
        manifold = any(cls.oplus_jacobian_batch is not None for cls, *_ in groups)
        free_off = np.zeros(n, dtype=np.int64)
        for _, vi, hi, _ in groups:
            free_off[hi.ravel()] = vi.ravel()

        blocks = []
        rows_all, cols_all, valid_all, brow_all = [], [], [], []
        comp_a, comp_b, anchored_h = [], [], []
        for store in self._stores.values():
            rows = np.nonzero(store.alive.v)[0]
            if len(rows) == 0:
                continue
            blk = _ClassBlock()
            blk.store = store
            blk.rows = rows
            blk.n = len(rows)
            vh = store.vh.v[rows]
            blk.sidx = [off[vh[:, k]][:, None] + np.arange(d) for k, d in enumerate(store.dims)]
            blk.shid = [hidx[vh[:, k]] for k in range(store.nv)]
            blk.vh = vh
            blk.z = store.z.v[rows].copy()
            w = store.w.v[rows].copy()
            blk.w = w
            offdiag = w.copy()
            ar = np.arange(store.m)
            offdiag[:, ar, ar] = 0.0
            blk.diag_w = not np.any(offdiag)
            blk.wt = np.ascontiguousarray(w.transpose(0, 2, 1))
            if blk.diag_w:
                blk.w = w[:, ar, ar].copy()
            blk.params = {k: g.v[rows].copy() for k, g in store.params.items()}
            blocks.append(blk)
            for k in range(store.nv):
                dk = store.dims[k]
                hk = blk.shid[k]
                for l in range(k, store.nv):
                    dl = store.dims[l]
                    hl = blk.shid[l]
                    if k == l:
                        a, b = np.triu_indices(dk)
                    else:
                        a, b = np.divmod(np.arange(dk * dl), dl)
                    r = hk[:, None] + a
                    c = hl[:, None] + b
                    rows_all.append(np.minimum(r, c).ravel())
                    cols_all.append(np.maximum(r, c).ravel())
                    ok = (hk >= 0) & (hl >= 0)
                    valid_all.append(np.repeat(ok, len(a)))
                brow = hk[:, None] + np.arange(dk)
                brow_all.append(np.where(hk[:, None] >= 0, brow, n).ravel())
            # gauge bookkeeping: connections between free vertices, anchors
            fh = [vh[:, k] for k in range(store.nv)]
            isfree = [blk.shid[k] >= 0 for k in range(store.nv)]
            anyfixed = np.zeros(len(rows), dtype=bool)
            for k in range(store.nv):
                anyfixed |= ~isfree[k]
            for k in range(store.nv):
                for l in range(k + 1, store.nv):
                    both = isfree[k] & isfree[l]
                    comp_a.append(fh[k][both])
                    comp_b.append(fh[l][both])
                if store.nv == 1:
                    anchored_h.append(fh[k][isfree[k]])
                else:
                    anchored_h.append(fh[k][isfree[k] & anyfixed])

        self._check_gauge(free_h, hidx, comp_a, comp_b, anchored_h)

        if rows_all:
            rows_c = np.concatenate(rows_all)
            cols_c = np.concatenate(cols_all)
            valid_c = np.concatenate(valid_all)
            brow_c = np.concatenate(brow_all)
        else:
            rows_c = cols_c = brow_c = np.zeros(0, dtype=np.int64)
            valid_c = np.zeros(0, dtype=bool)
        pattern = HessianPattern(n, rows_c, cols_c, valid_c)
        self._solver.analyse(pattern)
        self._hidx = hidx
        self._struct = {"n": n, "groups": groups, "manifold": manifold, "nh": nh, "free_off": free_off, "blocks": blocks,
                        "pattern": pattern, "brow": brow_c}
        self._hb = None
        self._dirty = False
        return True

    def _check_gauge(self, free_h, hidx, comp_a, comp_b, anchored_h):
        nf = len(free_h)
        if nf == 0:
            return
        rank = np.full(len(hidx), -1, dtype=np.int64)
        rank[free_h] = np.arange(nf)
        a = rank[np.concatenate(comp_a)] if comp_a else np.zeros(0, dtype=np.int64)
        b = rank[np.concatenate(comp_b)] if comp_b else np.zeros(0, dtype=np.int64)
        adj = sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(nf, nf))
        ncomp, labels = connected_components(adj, directed=False)
        anchored = np.zeros(ncomp, dtype=bool)
        if anchored_h:
            anc = rank[np.concatenate(anchored_h)]
            anchored[labels[anc]] = True
        if anchored.all():
            return
        bad = np.nonzero(~anchored)[0]
        comps = []
        for c in bad[:5]:
            members = free_h[labels == c]
            comps.append([self._vobj[h] for h in members])
        first = comps[0]
        names = ", ".join(f"{type(v).__name__} {v.id}" for v in first[:8])
        more = "" if len(first) <= 8 else f", … ({len(first)} vertices)"
        raise GaugeFreedomError(
            f"{len(bad)} connected component(s) of free vertices have no fixed vertex and no unary (prior) edge, "
            f"so their position is undetermined (gauge freedom); first component: {len(first)} vertices "
            f"[{names}{more}]. Fix a vertex (set_fixed(True)) or add a prior edge.", comps)

    def _require_structure(self, what):
        if self._dirty or self._struct is None:
            raise GraphError(f"{what}: the graph changed since initialize_optimization(); call it first")

    # ======================================================================================== evaluation
    def _eval_blocks(self, jacobians):
        """Per class: whitened errors and (optionally) Jacobians at the current estimates."""
        vx = self._vx.a
        out = []
        mjac = self._oplus_jacobians() if (jacobians and self._struct["manifold"]) else None
        for blk in self._struct["blocks"]:
            states = [vx[s] for s in blk.sidx]
            e, jac = blk.store.cls.evaluate(states, blk.z, blk.params, jacobians=jacobians)
            if mjac is not None:
                jac = [batched_matmul(np.ascontiguousarray(j), mjac[j.shape[2]][blk.vh[:, k]]) if j.shape[2] in mjac
                       else j for k, j in enumerate(jac)]
            if blk.diag_w:
                ew = blk.w * e
                jw = None if jac is None else [blk.w[:, :, None] * j for j in jac]
            else:
                ew = batched_jte(blk.wt, np.ascontiguousarray(e))
                jw = None if jac is None else [batched_matmul(blk.w, np.ascontiguousarray(j)) for j in jac]
            out.append((blk, ew, jw))
        return out

    def _oplus_jacobians(self):
        """Per dimension d: (handles, d, d) array of ∂(x ⊞ δ)/∂δ (identity for additive vertex classes)."""
        vx = self._vx.a
        out = {}
        for cls, vi, _, hs in self._struct["groups"]:
            if cls.oplus_jacobian_batch is None:
                continue
            d = vi.shape[1]
            if d not in out:
                out[d] = np.broadcast_to(np.eye(d), (self._struct["nh"], d, d)).copy()
            out[d][hs] = cls.oplus_jacobian_batch(vx[vi])
        return out

    def _chi2_current(self):
        total = 0.0
        for _, ew, _ in self._eval_blocks(False):
            total += float(np.einsum("ei,ei->", ew, ew))
        return total

    def _compute_hb(self):
        st = self._struct
        n = st["n"]
        hvals, bvals = [], []
        chi2 = 0.0
        for blk, ew, jw in self._eval_blocks(True):
            chi2 += float(np.einsum("ei,ei->", ew, ew))
            nv = blk.store.nv
            jw = [np.ascontiguousarray(j) for j in jw]
            for k in range(nv):
                jk = jw[k]
                for l in range(k, nv):
                    hvals.append(batched_jtj(jk, jw[l], k == l).ravel())
                bvals.append(batched_jte(jk, ew).ravel())
        if n == 0:
            self._hb = (np.zeros(0), np.zeros(0), chi2)
            return self._hb
        pattern = st["pattern"]
        data = pattern.assemble(np.concatenate(hvals) if hvals else np.zeros(0))
        b = np.bincount(st["brow"], weights=np.concatenate(bvals) if bvals else None, minlength=n + 1)[:n]
        self._hb = (data, b, chi2)
        return self._hb

    def chi2(self):
        """χ² = Σ eᵀΩe over all edges at the current estimates (no structure needed)."""
        vx = self._vx.a
        off = self._voff.a
        total = 0.0
        for store in self._stores.values():
            rows = np.nonzero(store.alive.v)[0]
            if len(rows) == 0:
                continue
            vh = store.vh.v[rows]
            states = [vx[off[vh[:, k]][:, None] + np.arange(d)] for k, d in enumerate(store.dims)]
            params = {k: g.v[rows] for k, g in store.params.items()}
            e, _ = store.cls.evaluate(states, store.z.v[rows], params, jacobians=False)
            ew = np.einsum("eij,ej->ei", store.w.v[rows], e)
            total += float(np.einsum("ei,ei->", ew, ew))
        return total

    # ======================================================================================== state moves
    def _get_x(self):
        return self._vx.a[self._struct["free_off"]].copy()

    def _set_x(self, x):
        self._vx.a[self._struct["free_off"]] = x
        self._hb = None

    def _oplus_minus(self, dx):
        vx = self._vx.a
        for cls, vi, hi, _ in self._struct["groups"]:
            vx[vi] = cls.oplus_batch(vx[vi], -dx[hi])
        self._hb = None

    # ======================================================================================== optimise
    def optimize(self, max_iterations=50, algorithm="lm", tau=TAU, gn_tolerance=1e-5):
        """Run LM (default, the coursework's) or Gauss–Newton ("gn"); returns the final χ².

        ``tau`` sets LM's initial damping μ = τ·max(diag H) (coursework: 1e−3; a smaller τ starts closer to
        Gauss–Newton, which pays off on large pose graphs far from their optimum).
        ``statistics`` then holds one dict per outer iteration (chi2, mu, rejected steps, time).
        """
        if not np.isscalar(tau) or not np.isfinite(tau) or tau <= 0:
            raise ValueError(f"tau must be a positive number, got {tau!r}")
        if not isinstance(max_iterations, (int, np.integer)) or isinstance(max_iterations, bool) \
                or max_iterations < 0:
            raise ValueError(f"max_iterations must be a non-negative int, got {max_iterations!r}")
        if algorithm not in ("lm", "gn", "lm-gtsam"):
            raise ValueError(f"algorithm must be 'lm', 'gn' or 'lm-gtsam', got {algorithm!r}")
        self._require_structure("optimize")
        self.statistics = []
        if self._struct["n"] == 0:
            return self.chi2()
        if algorithm == "lm":
            return self._optimize_lm(int(max_iterations), float(tau))
        if algorithm == "lm-gtsam":
            return self._optimize_lm_gtsam(int(max_iterations))
        return self._optimize_gn(int(max_iterations), float(gn_tolerance))

    def _record(self, k, chi2, mu, rejected, t0):
        entry = {"iteration": k, "chi2": chi2, "mu": mu, "rejected": rejected, "time": time.perf_counter() - t0}
        self.statistics.append(entry)
        if self.verbose:
            print(f"Iteration = {k:03d}; Residual = {chi2:6.3f}; Time = {entry['time']:3.3f}")

    def _optimize_lm(self, kmax, tau):
        t0 = time.perf_counter()
        st = self._struct
        pattern = st["pattern"]
        data, b, r0 = self._compute_hb()
        if not np.isfinite(r0):
            raise GraphError("optimize: χ² is not finite at the initial estimates")
        x = self._get_x()
        if np.max(np.abs(b)) < EPS1:
            return r0
        mu = tau * float(np.max(data[pattern.diag_pos]))
        nu = 2.0
        k = 1
        stop = False
        while not stop and k <= kmax:
            rejected = 0
            while True:
                damped = data.copy()
                damped[pattern.diag_pos] += mu
                dx = self._solver.factor(pattern, damped, damping=mu).solve(b)
                if not np.all(np.isfinite(dx)):
                    stop = True
                    break
                if np.sqrt(_dot(dx, dx)) < EPS2 * (np.sqrt(_dot(x, x)) + EPS2):
                    stop = True
                    break
                self._oplus_minus(dx)
                r1 = self._chi2_current()
                denom = _dot(dx, mu * dx + b)
                rho = (r0 - r1) / denom if np.isfinite(r1) and denom > 0 else -1.0
                if rho > 0:
                    if np.sqrt(r0) - np.sqrt(r1) < EPS4 * np.sqrt(r0):
                        stop = True
                    x = self._get_x()
                    r0 = r1
                    data, b, _ = self._compute_hb()
                    if np.max(np.abs(b)) < EPS1:
                        stop = True
                    mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                    nu = 2.0
                    break
                self._set_x(x)
                rejected += 1
                mu *= nu
                nu *= 2.0
                if not np.isfinite(mu):
                    stop = True
                    break
            self._record(k, r0, mu, rejected, t0)
            if np.sqrt(r0) < EPS3:
                stop = True
            k += 1
        self._set_x(x)  # the vertices hold the accepted state
        self._hb = (data, b, r0)
        return r0

    def _optimize_lm_gtsam(self, kmax, lam0=1e-5, factor=10.0, lam_max=1e5, min_fidelity=1e-3, rel_tol=1e-5,
                           abs_tol=1e-5):
        """GTSAM's LevenbergMarquardtOptimizer with its default parameters: λ₀ = 1e−5 (absolute), λI damping,
        accept when (actual / linearised decrease) > 1e−3 then λ /= 10, else λ *= 10 (stop above 1e5); stop when
        the decrease is below 1e−5 relative or absolute (on GTSAM's ½χ² scale)."""
        t0 = time.perf_counter()
        pattern = self._struct["pattern"]
        data, b, r0 = self._compute_hb()
        x = self._get_x()
        lam = lam0
        for k in range(1, kmax + 1):
            rejected = 0
            accepted = False
            while lam < lam_max:
                damped = data.copy()
                damped[pattern.diag_pos] += lam
                dx = self._solver.factor(pattern, damped, damping=lam).solve(b)
                if np.all(np.isfinite(dx)):
                    # linearised decrease 2bᵀdx − dxᵀH dx, with (H + λI) dx = b:  = bᵀdx + λ‖dx‖²
                    lin = _dot(b, dx) + lam * _dot(dx, dx)
                    self._oplus_minus(dx)
                    r1 = self._chi2_current()
                    if lin >= 0 and np.isfinite(r1) and (r0 - r1) / max(lin, 1e-300) > min_fidelity:
                        accepted = True
                        break
                    self._set_x(x)
                rejected += 1
                lam *= factor
            if not accepted:
                self._record(k, r0, lam, rejected, t0)
                break
            decrease = r0 - r1
            x = self._get_x()
            r0 = r1
            lam /= factor
            data, b, _ = self._compute_hb()
            self._record(k, r0, lam, rejected, t0)
            if decrease < rel_tol * r0 or 0.5 * decrease < abs_tol:
                break
        self._set_x(x)
        self._hb = (data, b, r0)
        return r0

    def _optimize_gn(self, kmax, tol):
        t0 = time.perf_counter()
        pattern = self._struct["pattern"]
        data, b, r0 = self._compute_hb()
        x = self._get_x()
        for k in range(1, kmax + 1):
            if np.max(np.abs(b)) < EPS1:
                break
            dx = self._solver.factor(pattern, data).solve(b)
            if not np.all(np.isfinite(dx)):
                raise GraphError("optimize (Gauss–Newton): the Hessian is singular; use algorithm='lm'")
            alpha = 1.0
            while True:
                self._oplus_minus(alpha * dx)
                r1 = self._chi2_current()
                if np.isfinite(r1) and r1 <= r0:
                    break
                self._set_x(x)
                alpha *= 0.5
                if alpha < 1e-10:
                    break
            if alpha < 1e-10:
                self._record(k, r0, 0.0, 1, t0)
                break
            decrease = r0 - r1
            x = self._get_x()
            r0 = r1
            data, b, _ = self._compute_hb()
            self._record(k, r0, 0.0, 0, t0)
            if decrease < tol:
                break
        self._set_x(x)
        self._hb = (data, b, r0)
        return r0

    @property
    def iterations(self):
        return len(self.statistics)

    @property
    def chi2_history(self):
        return [s["chi2"] for s in self.statistics]

    # ======================================================================================== H, marginals
    def _current_hb(self):
        self._require_structure("hessian")
        if self._hb is None:
            self._compute_hb()
        return self._hb

    def hessian(self):
        """The undamped H = Σ JᵀΩJ at the current state (symmetric scipy CSC, n×n, free vertices only)."""
        data, _, _ = self._current_hb()
        if self._struct["n"] == 0:
            return sp.csc_matrix((0, 0))
        return self._struct["pattern"].full_matrix(data)

    def gradient(self):
        """b = Σ JᵀΩe at the current state."""
        return self._current_hb()[1].copy()

    def compute_marginals(self, vertices=None):
        """Covariance blocks (H⁻¹ at the current state, undamped) for the given vertices (default: all).

        Returns {vertex: (d, d) array}: the covariance of the vertex's ⊞ update δ (for additive vertices, of its
        coordinates; for VertexSE2Exp, body-frame — map with M = oplus_jacobian_batch: M Σ Mᵀ). Fixed vertices get a
        zero block. Uses the sparse inverse on the pattern of
        the LDLᵀ factor (Takahashi recursion), never a dense inverse.
        """
        if vertices is None:
            vertices = self.vertices()
        vertices = list(vertices)
        for v in vertices:
            if not isinstance(v, BaseVertex) or v._graph is not self:
                raise GraphError(f"compute_marginals: {v!r} is not in this graph")
        data, _, _ = self._current_hb()
        out = {}
        free = [v for v in vertices if self._hidx[v._h] >= 0]
        for v in vertices:
            if self._hidx[v._h] < 0:
                out[v] = np.zeros((type(v).dimension, type(v).dimension))
        if not free:
            return out
        if not np.all(np.isfinite(data)):
            raise GraphError("compute_marginals: the Hessian is not finite")
        if not self._solver.factor(self._struct["pattern"], data).ok:
            raise GraphError("compute_marginals: H is not positive definite at this state (unobservable "
                             "directions?), so no covariance exists")
        dims = np.array([type(v).dimension for v in free])
        starts = self._hidx[np.array([v._h for v in free])]
        groups, rows, cols = [], [], []
        for d in np.unique(dims):
            sel = np.nonzero(dims == d)[0]
            a, b = np.divmod(np.arange(d * d), d)
            rows.append((starts[sel][:, None] + a).ravel())
            cols.append((starts[sel][:, None] + b).ravel())
            groups.append((int(d), sel))
        vals = sparse_inverse_on_pattern(self._solver, np.concatenate(rows), np.concatenate(cols))
        result = {}
        pos = 0
        for d, sel in groups:
            block = vals[pos: pos + len(sel) * d * d].reshape(len(sel), d, d)
            pos += len(sel) * d * d
            for i, s in enumerate(sel):
                result[free[s]] = block[i]
        for v in vertices:
            if v not in out:
                out[v] = result[v]
        # keep the caller's order
        return {v: out[v] for v in vertices}
