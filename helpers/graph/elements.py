"""Adding, removing and finding the vertices and edges of a graph (the part of ``SparseOptimizer`` that owns
the storage), and the hooks through which vertex and edge objects read and write their values in it.

An element that joins a graph keeps a reference to it (``_graph``) and its place in the storage (a vertex its
handle ``_h``, an edge its row ``_row``). From then on the graph's storage is the one copy of its values: the
element's getters and setters call the graph back through the hooks at the end of ``GraphElements``. Every change
of the structure (elements, connections, fixed flags) marks the built structure stale; every change of a value
calls ``_values_changed`` (the optimiser drops its cached H and b there), and an edited edge's class joins
``_dirty_edge_classes`` (the optimiser re-gathers those classes' values before it next linearises).

Every method validates its arguments before it changes anything, so a rejected call leaves the graph as it was.
"""

import numpy as np

from ..validation import integer
from .edge import BaseEdge, check_information_batch, check_model_output, edge_label
from .errors import GraphError, NonFiniteError
from .storage import EdgeStore, VertexStore
from .vertex import BaseVertex

__all__ = ["GraphElements", "total_chi2", "nonfinite_error"]


class GraphElements:
    """Storage and element bookkeeping of a graph (``SparseOptimizer`` adds structure, optimisation, marginals).

    ``_structure_stale`` is True whenever the elements changed since the last ``initialize_optimization``, and
    ``_rebuild_needed`` when the change was more than additions of vertices and edges;
    ``_hessian_index`` (per vertex handle: first row in the free state vector, −1 when fixed) is that build's.
    """

    def __init__(self):
        self._vertex_store = VertexStore()
        self._edge_stores = {}  # edge class -> EdgeStore, in order of first use
        self._edge_sequence = 0
        self._n_edges = 0
        self._n_vertices = 0
        self._structure_stale = True
        self._rebuild_needed = True     # something other than additions changed since the last build
        self._hessian_index = np.zeros(0, dtype=np.int64)
        self._dirty_edge_classes = set()  # edge classes whose values were edited since the last build/refresh
        self._edit_count = 0            # structural changes and edge-value edits so far (growth is not counted)

    def _values_changed(self):
        """An estimate, measurement, information or parameter changed (subclasses drop cached linearisations)."""

    def _structure_changed(self):
        """Elements removed, a vertex fixed or freed, an edge's vertex replaced: the next build starts afresh."""
        self._edit_count += 1
        self._structure_stale = True
        self._rebuild_needed = True

    def _structure_grown(self):
        """Vertices or edges added: the next build may extend the last one (``structure.extend_structure``)."""
        self._structure_stale = True

    def _edge_store(self, cls):
        store = self._edge_stores.get(cls)
        if store is None:
            store = EdgeStore(cls)
            self._edge_stores[cls] = store
        return store

    # ======================================================================================== adding
    def add_vertex(self, vertex):
        """Add a vertex (its (class, id) must be new in this graph). Returns True."""
        if not isinstance(vertex, BaseVertex):
            raise GraphError(f"add_vertex: expected a vertex, got {type(vertex).__name__}")
        if vertex._graph is self:
            raise GraphError(f"add_vertex: {type(vertex).__name__} id {vertex.id} is already in this graph")
        if vertex._graph is not None:
            raise GraphError(f"add_vertex: {type(vertex).__name__} id {vertex.id} belongs to another graph")
        cls = type(vertex)
        if (cls, vertex.id) in self._vertex_store.by_key:
            raise GraphError(f"add_vertex: duplicate vertex id {vertex.id} for class {cls.__name__}")
        vertex._h = self._vertex_store.append(vertex)
        vertex._graph = self
        self._n_vertices += 1
        self._structure_grown()
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
        row = self._edge_store(cls).append(edge, self._edge_sequence)
        self._edge_sequence += 1
        edge._graph = self
        edge._row = row
        for v in edge._vertices:
            v._edges[edge] = None
        self._n_edges += 1
        self._structure_grown()
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
        if not edge_class.vertex_types or not edge_class.measurement_dimension:
            raise GraphError(f"add_edges: {edge_class.__name__} declares no vertex_types / measurement_dimension")
        try:
            rows = [tuple(r) for r in vertices]
        except TypeError:
            raise ValueError(f"add_edges: vertices must be a list of rows (tuples) of "
                             f"{len(edge_class.vertex_types)} vertices, got {vertices!r}") from None
        count = len(rows)
        if count == 0:
            return []
        self._check_edge_rows(edge_class, rows)
        z, info, w, pvals = _bulk_edge_values(edge_class, count, measurements, information, params)
        store = self._edge_store(edge_class)
        handles = np.array([[v._h for v in r] for r in rows], dtype=np.int64)
        row0 = store.extend(handles, z, w, pvals, self._edge_sequence)
        self._edge_sequence += count
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
        store.objects.extend(out)
        self._n_edges += count
        self._structure_grown()
        return out

    def _check_edge_rows(self, edge_class, rows):
        """Every row of ``add_edges`` has one vertex of the right class, in this graph, per slot."""
        nv = len(edge_class.vertex_types)
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

    # ======================================================================================== removing
    def _detach_edge(self, edge):
        self._edge_stores[type(edge)].mark_removed(edge)
        edge._graph = None
        edge._row = -1
        self._n_edges -= 1
        self._structure_changed()

    def remove_edge(self, edge):
        """Remove an edge; every vertex left with no edge is removed from the graph too (coursework semantics).

        Returns the list of vertices removed as a consequence.
        """
        if not isinstance(edge, BaseEdge):
            raise GraphError(f"remove_edge: expected an edge, got {type(edge).__name__}")
        if edge._graph is not self:
            raise GraphError(f"remove_edge: this {type(edge).__name__} is not in this graph (already removed, "
                             "never added, or in another graph)")
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
        if not isinstance(vertex, BaseVertex):
            raise GraphError(f"remove_vertex: expected a vertex, got {type(vertex).__name__}")
        if vertex._graph is not self:
            raise GraphError(f"remove_vertex: {type(vertex).__name__} id {vertex.id} is not in this graph (already "
                             "removed, never added, or in another graph)")
        for e in list(vertex._edges):
            self._detach_edge(e)
            for v in e._vertices:
                v._edges.pop(e, None)
        self._drop_vertex(vertex)
        return True

    def _drop_vertex(self, v):
        h = v._h
        v._est = self._vertex_store.estimate(h).copy()
        self._vertex_store.mark_removed(v)
        if h < len(self._hessian_index):
            self._hessian_index[h] = -1
        v._graph = None
        v._h = -1
        self._n_vertices -= 1
        self._structure_changed()

    # ======================================================================================== queries
    def vertex(self, id, cls=None):
        """The vertex with this id (and class, when ids repeat across classes), or None."""
        id = integer(id, "vertex: id")
        if cls is not None and not (isinstance(cls, type) and issubclass(cls, BaseVertex)):
            raise ValueError(f"vertex: cls must be a vertex class or None, got {cls!r}")
        by_key = self._vertex_store.by_key
        if cls is not None:
            return by_key.get((cls, id))
        hits = [v for (c, i), v in by_key.items() if i == id]
        if len(hits) > 1:
            raise GraphError(f"vertex({id}): several classes use this id; pass cls")
        return hits[0] if hits else None

    def _own_vertices(self, vertices, what):
        """``vertices`` (None: all) as a list, each a vertex of this graph; ValueError / GraphError otherwise."""
        if vertices is None:
            return self.vertices()
        if isinstance(vertices, (BaseVertex, str)) or not hasattr(vertices, "__iter__"):
            raise ValueError(f"{what}: vertices must be a list of vertices of this graph (or None for all), "
                             f"got {vertices!r}")
        vertices = list(vertices)
        for v in vertices:
            if not isinstance(v, BaseVertex):
                raise GraphError(f"{what}: expected vertices of this graph, got {v!r}")
            if v._graph is not self:
                raise GraphError(f"{what}: {v!r} is not in this graph")
        return vertices

    def vertices(self):
        """All vertices, in the order they were added."""
        return [v for v in self._vertex_store.objects if v is not None]

    def edges(self):
        """All edges, in the order they were added."""
        pairs = []
        for store in self._edge_stores.values():
            alive = store.alive_rows()
            pairs.extend(zip(store.sequence.values[alive].tolist(), (store.objects[i] for i in alive)))
        pairs.sort(key=lambda p: p[0])
        return [e for _, e in pairs]

    def number_of_vertices(self):
        return self._n_vertices

    def number_of_edges(self):
        return self._n_edges

    # ======================================================================================== element hooks
    # Called by BaseVertex / BaseEdge objects that are in this graph (``element._graph is self``).
    def _read_vertex_estimate(self, handle):
        """The stored estimate of a vertex (a view; the vertex returns a copy)."""
        return self._vertex_store.estimate(handle)

    def _write_vertex_estimate(self, handle, x):
        self._vertex_store.write_estimate(handle, x)
        self._values_changed()

    def _write_vertex_fixed(self, handle, flag):
        self._vertex_store.fixed.buffer[handle] = flag
        self._structure_changed()

    def _vertex_hessian_start(self, handle):
        """First row of the vertex in the free state vector X, or None (fixed, or structure not built/stale)."""
        if self._structure_stale or handle >= len(self._hessian_index) or self._hessian_index[handle] < 0:
            return None
        return int(self._hessian_index[handle])

    def _write_edge_values(self, edge):
        """The edge's measurement, information or a parameter changed: copy them into its store row."""
        self._edge_stores[type(edge)].write_values(edge)
        self._dirty_edge_classes.add(type(edge))
        self._edit_count += 1
        self._values_changed()

    def _replace_edge_vertex(self, edge, k, old, new):
        """Slot ``k`` of ``edge`` now holds ``new`` instead of ``old``."""
        if new is None or new._graph is not self:
            raise GraphError(f"set_vertex: the new vertex of slot {k} must be in the edge's graph")
        if old is not None:
            old._edges.pop(edge, None)
        new._edges[edge] = None
        self._edge_stores[type(edge)].handles.buffer[edge._row, k] = new._h
        self._structure_changed()

    # The names vertex.py and edge.py call (kept so those modules need not change together with this one).
    _vertex_estimate = _read_vertex_estimate
    _set_vertex_estimate = _write_vertex_estimate
    _set_vertex_fixed = _write_vertex_fixed
    _vertex_hessian_index = _vertex_hessian_start
    _edge_store_row = _write_edge_values
    _edge_set_vertex = _replace_edge_vertex


def _bulk_edge_values(edge_class, count, measurements, information, params):
    """Validated arrays of ``add_edges``: measurements (E, m), information and whitening (E, m, m), and the
    per-edge parameters {name: (E, *shape)}. Raises ValueError naming the bad argument."""
    m = int(edge_class.measurement_dimension)
    z = _numeric(measurements, "measurements")
    if z.shape == (count,) and m == 1 or z.shape == (m,) and count == 1:
        z = z.reshape(count, m)
    if z.shape != (count, m):
        raise ValueError(f"add_edges: measurements must have shape ({count}, {m}), got {z.shape}")
    if not np.isfinite(z).all():
        raise ValueError("add_edges: measurements must be finite")
    edge_class.check_measurements(z, "add_edges: measurements")
    if information is None:
        information = np.eye(m)
    info = _numeric(information, "information")
    if info.shape == (m, m):
        info = np.broadcast_to(info, (count, m, m))
    if info.shape != (count, m, m):
        raise ValueError(f"add_edges: information must have shape ({m}, {m}) or ({count}, {m}, {m}), got {info.shape}")
    info, w = check_information_batch(info, m, "add_edges: information")
    params = dict(params)
    pvals = {}
    for name, default in edge_class._param_defaults.items():
        val = _numeric(params.pop(name, default), f"parameter {name}")
        if val.shape == default.shape:
            val = np.broadcast_to(val, (count,) + default.shape)
        if val.shape != (count,) + default.shape or not np.isfinite(val).all():
            raise ValueError(f"add_edges: parameter {name} must be finite with shape {(count,) + default.shape}")
        pvals[name] = np.array(val)
    if params:
        raise ValueError(f"add_edges: {edge_class.__name__} has no parameter(s) {sorted(params)}")
    return z, info, w, pvals


def _numeric(value, name):
    """``value`` as a float array; ValueError naming ``name`` when it is not numeric."""
    try:
        return np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"add_edges: {name} must be numeric, got {value!r}") from None


def total_chi2(vertex_store, edge_stores) -> float:
    """χ² = Σ eᵀΩe over the live edges of ``edge_stores`` at the stored estimates (no layout needed);
    NonFiniteError naming the edges whose term is NaN or inf."""
    total, bad = 0.0, []
    estimates = vertex_store.estimates.buffer
    for store in edge_stores.values():
        rows = store.alive_rows()
        if len(rows) == 0:
            continue
        handles = store.handles.values[rows]
        states = [estimates[vertex_store.state_indices(handles[:, k], d)] for k, d in enumerate(store.slot_dimensions)]
        params = {name: column.values[rows] for name, column in store.params.items()}
        e, _ = store.cls.evaluate(states, store.measurements.values[rows], params, jacobians=False)
        check_model_output(store.cls, e, None, len(rows), False)
        r = np.einsum("eij,ej->ei", store.whitening.values[rows], e)
        terms = np.einsum("ei,ei->e", r, r)
        total += float(terms.sum())
        bad += [store.objects[row] for row in rows[~np.isfinite(terms)]]
    if not np.isfinite(total):
        raise nonfinite_error("chi2", bad)
    return total


def nonfinite_error(what: str, edges: list) -> NonFiniteError:
    """The NonFiniteError for ``what`` (e.g. "optimize: at the initial estimates") naming up to 5 of ``edges``."""
    if not edges:
        return NonFiniteError(f"{what}: χ², H or b is not finite although every edge's term is: the sum "
                              "overflowed (check the scale of the estimates and information matrices)")
    names = "; ".join(edge_label(e) for e in edges[:5]) + ("" if len(edges) <= 5 else f"; … ({len(edges)} edges)")
    return NonFiniteError(f"{what}: {len(edges)} edge(s) have a non-finite (NaN or inf) error, χ² term or "
                          f"Jacobian: {names}. Look for a degenerate configuration (e.g. a landmark exactly at a "
                          "pose), an overflowing estimate, or a model that returns NaN.", edges)
