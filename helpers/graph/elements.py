"""Adding, removing and finding the vertices and edges of a graph (the part of ``SparseOptimizer`` that owns the
storage), and the hooks through which vertex and edge objects read and write their values in it.

An element that joins a graph keeps a reference to it (``_graph``) and its place in the storage (a vertex its
handle ``_h``, an edge its row ``_row``); from then on the storage holds its values and the element's getters and
setters call the hooks at the end of ``GraphElements``. A change of the structure (elements, fixed flags) marks
the built structure stale; a change of a value calls ``_values_changed`` (the optimiser drops its cached H and b).
Every method validates its arguments before it changes anything, so a rejected call leaves the graph as it was.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..validation import integer
from .edge import BaseEdge, check_information, check_model_output, check_parameters, edge_label
from .errors import GraphError, NonFiniteError
from .storage import EdgeStore, VertexStore
from .vertex import BaseVertex, as_rows

__all__ = ["GraphElements", "total_chi2", "nonfinite_error"]


class GraphElements:
    """Storage and element bookkeeping of a graph (``SparseOptimizer`` adds the optimisation).

    Since the last ``initialize_optimization`` (whose ``_hessian_index`` gives each vertex handle its first row in
    X, −1 when fixed): ``_structure_stale`` the elements changed, ``_rebuild_needed`` by more than additions,
    ``_dirty_edge_classes`` these edge classes' values were edited. ``_edit_count`` counts changes and edits.
    """

    def __init__(self) -> None:
        self._vertex_store = VertexStore()
        self._edge_stores = {}          # edge class -> EdgeStore, in order of first use
        self._edges = {}                # every edge, in the order added
        self._structure_stale = True
        self._rebuild_needed = True
        self._hessian_index = np.zeros(0, dtype=np.int64)
        self._dirty_edge_classes = set()
        self._edit_count = 0

    def _values_changed(self) -> None:
        """An estimate, measurement, information or parameter changed (subclasses drop cached linearisations)."""

    def _structure_changed(self, grown_only: bool = False) -> None:
        self._structure_stale = True
        if not grown_only:
            self._edit_count += 1
            self._rebuild_needed = True

    def _store_edges(self, cls: type, handles: np.ndarray, z: np.ndarray, w: np.ndarray, params: dict,
                     edges: list) -> None:
        """Add edges of class ``cls`` to its store and attach them to their vertices."""
        store = self._edge_stores.get(cls) or self._edge_stores.setdefault(cls, EdgeStore(cls))
        row0 = store.extend(handles, z, w, params, edges)
        for t, e in enumerate(edges):
            e._graph, e._row = self, row0 + t
            self._edges[e] = None
            for v in e._vertices:
                v._edges[e] = None
        self._structure_changed(grown_only=True)

    # ======================================================================================== adding
    def add_vertex(self, vertex: BaseVertex) -> bool:
        """Add a vertex (its (class, id) must be new in this graph). Returns True."""
        if not isinstance(vertex, BaseVertex):
            raise GraphError(f"add_vertex: expected a vertex, got {type(vertex).__name__}")
        if vertex._graph is not None:
            where = "is already in this graph" if vertex._graph is self else "belongs to another graph"
            raise GraphError(f"add_vertex: {type(vertex).__name__} id {vertex.id} {where}")
        if (type(vertex), vertex.id) in self._vertex_store.by_key:
            raise GraphError(f"add_vertex: duplicate vertex id {vertex.id} for class {type(vertex).__name__}")
        vertex._h = self._vertex_store.append(vertex)
        vertex._graph = self
        self._structure_changed(grown_only=True)
        return True

    def add_edge(self, edge: BaseEdge) -> bool:
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
                raise GraphError(f"add_edge: {cls.__name__} slot {k}: unknown vertex {type(v).__name__} id {v.id} "
                                 "(add it to this graph first)")
        params = {name: value[None] for name, value in edge._params.items()}
        self._store_edges(cls, np.array([[v._h for v in edge._vertices]]), edge._z[None], edge._w[None], params,
                          [edge])
        return True

    def add_edges(self, edge_class: type, vertices: list, measurements: ArrayLike, information: ArrayLike | None = None,
                  **params: ArrayLike) -> list:
        """Add E edges of one class at once (validated as arrays); returns the new edge objects, as if added one
        by one. ``vertices``: E rows of one vertex per slot, already in this graph; ``measurements`` (E, m);
        ``information`` (E, m, m) or one (m, m) for all (default I); ``params``: name -> (E, *shape) or one value.
        """
        if not (isinstance(edge_class, type) and issubclass(edge_class, BaseEdge)) or not edge_class.vertex_types:
            raise GraphError(f"add_edges: edge_class must be a concrete BaseEdge subclass, got {edge_class!r}")
        try:
            rows = [tuple(r) for r in vertices]
        except TypeError:
            raise ValueError(f"add_edges: vertices must be a list of rows (tuples) of "
                             f"{len(edge_class.vertex_types)} vertices, got {vertices!r}") from None
        count, m = len(rows), edge_class.measurement_dimension
        if count == 0:
            return []
        self._check_edge_rows(edge_class, rows)
        z = as_rows(measurements, count, m, "add_edges: measurements")
        edge_class.check_measurements(z, "add_edges: measurements")
        info, w = check_information(np.eye(m) if information is None else information, m, "add_edges: information",
                                    count)
        pvals = check_parameters(edge_class, params, count, "add_edges")
        edges = []
        for t, r in enumerate(rows):
            e = edge_class.__new__(edge_class)
            e._vertices, e._z, e._info, e._w = list(r), z[t], info[t], w[t]
            e._params = {name: pvals[name][t] for name in pvals}
            edges.append(e)
        self._store_edges(edge_class, np.array([[v._h for v in r] for r in rows], dtype=np.int64), z, w, pvals, edges)
        return edges

    def _check_edge_rows(self, edge_class: type, rows: list) -> None:
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
            if len({id(v) for v in r}) != nv:
                raise GraphError(f"add_edges: row {t} uses the same vertex in two slots")

    # ======================================================================================== removing
    def remove_edge(self, edge: BaseEdge) -> list:
        """Remove an edge; every vertex left with no edge is removed from the graph too (coursework semantics).
        Returns the vertices removed as a consequence."""
        if not isinstance(edge, BaseEdge):
            raise GraphError(f"remove_edge: expected an edge, got {type(edge).__name__}")
        if edge._graph is not self:
            raise GraphError(f"remove_edge: this {type(edge).__name__} is not in this graph (already removed, "
                             "never added, or in another graph)")
        self._detach_edge(edge)
        orphans = [v for v in edge._vertices if not v._edges and v._graph is self]
        for v in orphans:
            self._drop_vertex(v)
        return orphans

    def remove_vertex(self, vertex: BaseVertex) -> bool:
        """Remove a vertex and every edge attached to it (other vertices stay, even if left without edges)."""
        if not isinstance(vertex, BaseVertex):
            raise GraphError(f"remove_vertex: expected a vertex, got {type(vertex).__name__}")
        if vertex._graph is not self:
            raise GraphError(f"remove_vertex: {type(vertex).__name__} id {vertex.id} is not in this graph (already "
                             "removed, never added, or in another graph)")
        for e in list(vertex._edges):
            self._detach_edge(e)
        self._drop_vertex(vertex)
        return True

    def _detach_edge(self, edge: BaseEdge) -> None:
        self._edge_stores[type(edge)].mark_removed(edge)
        for v in edge._vertices:
            v._edges.pop(edge, None)
        del self._edges[edge]
        edge._graph, edge._row = None, -1
        self._structure_changed()

    def _drop_vertex(self, v: BaseVertex) -> None:
        v._est = self._vertex_store.estimate(v._h).copy()
        self._vertex_store.mark_removed(v)
        if v._h < len(self._hessian_index):
            self._hessian_index[v._h] = -1
        v._graph, v._h = None, -1
        self._structure_changed()

    # ======================================================================================== queries
    def vertex(self, id: int, cls: type | None = None) -> BaseVertex | None:
        """The vertex with this id (and class, when ids repeat across classes), or None."""
        id = integer(id, "vertex: id")
        if cls is not None and not (isinstance(cls, type) and issubclass(cls, BaseVertex)):
            raise ValueError(f"vertex: cls must be a vertex class or None, got {cls!r}")
        if cls is not None:
            return self._vertex_store.by_key.get((cls, id))
        hits = [v for (_, i), v in self._vertex_store.by_key.items() if i == id]
        if len(hits) > 1:
            raise GraphError(f"vertex({id}): several classes use this id; pass cls")
        return hits[0] if hits else None

    def _own_vertices(self, vertices: list | None, what: str) -> list:
        """``vertices`` (None: all) as a list, each a vertex of this graph; ValueError / GraphError otherwise."""
        if vertices is None:
            return self.vertices()
        if isinstance(vertices, (BaseVertex, str)) or not hasattr(vertices, "__iter__"):
            raise ValueError(f"{what}: vertices must be a list of vertices of this graph (or None for all), "
                             f"got {vertices!r}")
        vertices = list(vertices)
        for v in vertices:
            if not isinstance(v, BaseVertex) or v._graph is not self:
                raise GraphError(f"{what}: {v!r} is not in this graph")
        return vertices

    def vertices(self) -> list:
        """All vertices, in the order they were added."""
        return [v for v in self._vertex_store.objects if v is not None]

    def edges(self) -> list:
        """All edges, in the order they were added."""
        return list(self._edges)

    def number_of_vertices(self) -> int:
        return len(self._vertex_store.by_key)

    def number_of_edges(self) -> int:
        return len(self._edges)

    # ======================================================================================== element hooks
    def _read_vertex_estimate(self, handle: int) -> np.ndarray:
        return self._vertex_store.estimate(handle)

    def _write_vertex_estimate(self, handle: int, x: np.ndarray) -> None:
        self._vertex_store.write_estimate(handle, x)
        self._values_changed()

    def _write_vertex_fixed(self, handle: int, flag: bool) -> None:
        self._vertex_store.fixed.buffer[handle] = flag
        self._structure_changed()

    def _vertex_hessian_start(self, handle: int) -> int | None:
        """First row of the vertex in X, or None (fixed, or the structure not built or stale)."""
        if self._structure_stale or handle >= len(self._hessian_index) or self._hessian_index[handle] < 0:
            return None
        return int(self._hessian_index[handle])

    def _write_edge_values(self, edge: BaseEdge) -> None:
        self._edge_stores[type(edge)].write_values(edge)
        self._dirty_edge_classes.add(type(edge))
        self._edit_count += 1
        self._values_changed()


def total_chi2(vertex_store: VertexStore, edge_stores: dict) -> float:
    """χ² = Σ eᵀΩe over the live edges at the stored estimates (no layout needed); NonFiniteError naming the edges
    whose term is NaN or inf."""
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
