"""Growable array storage of a graph's vertices and edges (what ``SparseOptimizer`` keeps between builds).

Every vertex added to a graph gets a *handle* (its creation number, never reused); its estimate lives in one flat
float array at ``offset[handle]`` (``VertexStore``). Edges live in one ``EdgeStore`` per edge class, one row per
edge. Removing an element only clears its alive flag and forgets its object; rows are never renumbered.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

if TYPE_CHECKING:
    from .edge import BaseEdge
    from .vertex import BaseVertex

__all__ = ["GrowableArray", "VertexStore", "EdgeStore"]


class GrowableArray:
    """A numpy array that grows at its end, doubling its capacity when full: ``values`` is the filled part (a view),
    ``buffer`` the whole allocated array, ``size`` the number of filled rows, each of shape ``row_shape``."""

    def __init__(self, row_shape: tuple = (), dtype: type = float, fill: float = 0) -> None:
        self.row_shape = tuple(row_shape)
        self.fill = fill
        self.buffer = np.full((16,) + self.row_shape, fill, dtype=dtype)
        self.size = 0

    def extend(self, values: ArrayLike) -> int:
        """Add len(values) rows (shape (count, *row_shape)); returns the index of the first."""
        values = np.asarray(values)
        count, need = len(values), self.size + len(values)
        if need > len(self.buffer):
            bigger = np.full((max(need, 2 * len(self.buffer)),) + self.row_shape, self.fill, dtype=self.buffer.dtype)
            bigger[:self.size] = self.buffer[:self.size]
            self.buffer = bigger
        self.buffer[self.size:need] = values
        self.size = need
        return need - count

    def append(self, value: ArrayLike) -> int:
        """Add one row; returns its index."""
        return self.extend(np.asarray(value, dtype=self.buffer.dtype)[None])

    @property
    def values(self) -> np.ndarray:
        return self.buffer[:self.size]


class VertexStore:
    """The vertices of one graph, by handle: ``estimates`` (flat), ``offset``, ``dimension``, ``class_code``,
    ``fixed``, ``alive`` (arrays over handles), ``objects[h]`` (None once removed), ``by_key`` {(class, id): vertex}
    of the live vertices, ``classes[code]`` the vertex class of a class code."""

    def __init__(self) -> None:
        self.estimates = GrowableArray((), float, 0.0)
        self.offset = GrowableArray((), np.int64, -1)
        self.dimension = GrowableArray((), np.int64, 0)
        self.class_code = GrowableArray((), np.int64, -1)
        self.fixed = GrowableArray((), bool, False)
        self.alive = GrowableArray((), bool, False)
        self.objects = []
        self.by_key = {}
        self.classes = []

    @property
    def count(self) -> int:
        """Number of handles ever given out (live and removed)."""
        return self.offset.size

    def append(self, vertex: BaseVertex) -> int:
        """Store a new vertex (estimate, flags); returns its handle."""
        cls = type(vertex)
        if cls not in self.classes:
            self.classes.append(cls)
        handle = self.offset.append(self.estimates.extend(vertex._est))
        self.dimension.append(cls.dimension)
        self.class_code.append(self.classes.index(cls))
        self.fixed.append(vertex._fixed)
        self.alive.append(True)
        self.objects.append(vertex)
        self.by_key[(cls, vertex.id)] = vertex
        return handle

    def estimate(self, handle: int) -> np.ndarray:
        """The stored estimate of ``handle`` (a view into ``estimates``)."""
        start = self.offset.buffer[handle]
        return self.estimates.buffer[start:start + self.dimension.buffer[handle]]

    def write_estimate(self, handle: int, x: np.ndarray) -> None:
        self.estimate(handle)[:] = x

    def mark_removed(self, vertex: BaseVertex) -> None:
        self.alive.buffer[vertex._h] = False
        self.objects[vertex._h] = None
        del self.by_key[(type(vertex), vertex.id)]

    def state_indices(self, handles: np.ndarray, dimension: int) -> np.ndarray:
        """(len(handles), dimension) positions in ``estimates`` of the coordinates of ``handles``."""
        return self.offset.buffer[handles][:, None] + np.arange(dimension)


class EdgeStore:
    """The edges of one edge class, by row: ``handles`` (E, slots), ``measurements`` (E, m), ``whitening``
    (E, m, m), ``params`` {name: (E, *shape)}, ``alive`` (E,), ``objects[row]`` the edge object (None once
    removed)."""

    def __init__(self, cls: type) -> None:
        self.cls = cls
        self.slots = len(cls.vertex_types)
        self.measurement_dimension = m = cls.measurement_dimension
        self.slot_dimensions = [t.dimension for t in cls.vertex_types]
        self.handles = GrowableArray((self.slots,), np.int64, -1)
        self.measurements = GrowableArray((m,))
        self.whitening = GrowableArray((m, m))
        self.alive = GrowableArray((), bool, False)
        self.params = {name: GrowableArray(default.shape) for name, default in cls._param_defaults.items()}
        self.objects = []

    def extend(self, handles: np.ndarray, measurements: np.ndarray, whitening: np.ndarray, params: dict,
               objects: list) -> int:
        """Store E edges given as arrays and their objects; returns the first row."""
        count = len(handles)
        row0 = self.handles.extend(handles)
        self.measurements.extend(measurements)
        self.whitening.extend(whitening)
        self.alive.extend(np.ones(count, dtype=bool))
        for name, column in self.params.items():
            column.extend(params[name])
        self.objects.extend(objects)
        return row0

    def write_values(self, edge: BaseEdge) -> None:
        """Copy the edge object's measurement, whitening and parameters into its row."""
        self.measurements.buffer[edge._row] = edge._z
        self.whitening.buffer[edge._row] = edge._w
        for name, column in self.params.items():
            column.buffer[edge._row] = edge._params[name]

    def mark_removed(self, edge: BaseEdge) -> None:
        self.alive.buffer[edge._row] = False
        self.objects[edge._row] = None

    def alive_rows(self) -> np.ndarray:
        return np.nonzero(self.alive.values)[0]
