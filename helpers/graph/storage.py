"""Growable array storage of a graph's vertices and edges (what ``SparseOptimizer`` keeps between builds).

Every vertex added to a graph gets a *handle* (its creation number, never reused). Its estimate lives in one flat
float array at ``offset[handle]``; its dimension, class code, fixed and alive flags are arrays over handles
(``VertexStore``). Edges live in one ``EdgeStore`` per edge class: the vertex handles of every slot (E, slots),
the measurements (E, m), the whitening matrices W (E, m, m) with Ω = WᵀW, the per-edge parameters, an alive flag
and the graph-wide insertion number of every edge.

All arrays are ``GrowableArray``: capacity doubles when full, so adding one element is O(1) amortised. Removing an
element only clears its alive flag; the rows stay (handles and edge rows are never renumbered).
"""

import numpy as np

__all__ = ["GrowableArray", "VertexStore", "EdgeStore"]


class GrowableArray:
    """A numpy array that grows at its end (capacity doubling).

    ``values`` is the filled part (a view), ``buffer`` the whole allocated array (index it with handles/rows that
    are known to be filled), ``size`` the number of filled rows. Each row has the shape ``row_shape``.
    """

    def __init__(self, row_shape=(), dtype=float, fill=0):
        self.row_shape = tuple(row_shape)
        self.fill = fill
        self.buffer = np.full((16,) + self.row_shape, fill, dtype=dtype)
        self.size = 0

    def _reserve(self, extra):
        need = self.size + extra
        if need > len(self.buffer):
            capacity = max(need, 2 * len(self.buffer))
            bigger = np.full((capacity,) + self.row_shape, self.fill, dtype=self.buffer.dtype)
            bigger[: self.size] = self.buffer[: self.size]
            self.buffer = bigger

    def append(self, value):
        """Add one row (of shape ``row_shape``); returns its index."""
        if self.row_shape:  # a shorter row or a scalar would broadcast silently (scalar rows: numpy checks)
            if isinstance(value, np.ndarray):
                shape = value.shape
            elif isinstance(value, (list, tuple)) and len(self.row_shape) == 1:
                shape = (len(value),)  # deeper nesting cannot be assigned to a 1-D row: numpy raises
            else:
                shape = np.shape(value)
            if shape != self.row_shape:
                raise ValueError(f"append: a row must have shape {self.row_shape}, got {shape}")
        self._reserve(1)
        self.buffer[self.size] = value
        self.size += 1
        return self.size - 1

    def extend(self, values):
        """Add len(values) rows (shape (count, *row_shape)); returns the index of the first."""
        values = np.asarray(values)
        if values.shape[1:] != self.row_shape or values.ndim != 1 + len(self.row_shape):
            raise ValueError(f"extend: rows must have shape (count, *{self.row_shape}), got {values.shape}")
        count = len(values)
        self._reserve(count)
        self.buffer[self.size: self.size + count] = values
        self.size += count
        return self.size - count

    @property
    def values(self):
        return self.buffer[: self.size]


class VertexStore:
    """The vertices of one graph, by handle.

    ``estimates`` flat float array of all estimates (a vertex's coordinates at ``offset[h]`` … ``+ dimension[h]``);
    ``offset``, ``dimension``, ``class_code``, ``fixed``, ``alive`` arrays over handles; ``objects[h]`` the vertex
    object (None once removed); ``by_key`` {(class, id): vertex} of the live vertices; ``classes[code]`` the vertex
    class of a class code.
    """

    def __init__(self):
        self.estimates = GrowableArray((), float, 0.0)
        self.offset = GrowableArray((), np.int64, -1)
        self.dimension = GrowableArray((), np.int64, 0)
        self.class_code = GrowableArray((), np.int64, -1)
        self.fixed = GrowableArray((), bool, False)
        self.alive = GrowableArray((), bool, False)
        self.objects = []
        self.by_key = {}
        self.classes = []
        self._codes = {}

    @property
    def count(self):
        """Number of handles ever given out (live and removed)."""
        return self.offset.size

    def code_of(self, cls):
        """The class code of vertex class ``cls`` (a new code the first time a class is seen)."""
        code = self._codes.get(cls)
        if code is None:
            code = len(self.classes)
            self._codes[cls] = code
            self.classes.append(cls)
        return code

    def append(self, vertex):
        """Store a new vertex (estimate, flags); returns its handle."""
        cls = type(vertex)
        code = self.code_of(cls)
        offset = self.estimates.extend(vertex._est)
        handle = self.offset.append(offset)
        self.dimension.append(int(cls.dimension))
        self.class_code.append(code)
        self.fixed.append(vertex._fixed)
        self.alive.append(True)
        self.objects.append(vertex)
        self.by_key[(cls, vertex.id)] = vertex
        return handle

    def estimate(self, handle):
        """The stored estimate of ``handle`` (a view into ``estimates``)."""
        start = self.offset.buffer[handle]
        return self.estimates.buffer[start: start + self.dimension.buffer[handle]]

    def write_estimate(self, handle, x):
        start = self.offset.buffer[handle]
        self.estimates.buffer[start: start + len(x)] = x

    def mark_removed(self, vertex):
        """Clear the alive flag of the vertex's handle and forget the object (its row stays)."""
        handle = vertex._h
        self.alive.buffer[handle] = False
        self.objects[handle] = None
        del self.by_key[(type(vertex), vertex.id)]

    def state_indices(self, handles, dimension):
        """(len(handles), dimension) positions in ``estimates`` of the coordinates of ``handles``."""
        return self.offset.buffer[handles][:, None] + np.arange(dimension)


class EdgeStore:
    """The edges of one edge class, by row.

    ``handles`` (E, slots) vertex handles, ``measurements`` (E, m), ``whitening`` (E, m, m) W with Ω = WᵀW,
    ``params`` {name: (E, *shape)}, ``alive`` (E,), ``sequence`` (E,) graph-wide insertion number (for
    ``edges()`` in insertion order), ``objects[row]`` the edge object (None once removed).
    """

    def __init__(self, cls):
        self.cls = cls
        self.slots = len(cls.vertex_types)
        self.measurement_dimension = int(cls.measurement_dimension)
        self.slot_dimensions = [int(t.dimension) for t in cls.vertex_types]
        m = self.measurement_dimension
        self.handles = GrowableArray((self.slots,), np.int64, -1)
        self.measurements = GrowableArray((m,))
        self.whitening = GrowableArray((m, m))
        self.alive = GrowableArray((), bool, False)
        self.sequence = GrowableArray((), np.int64, -1)
        self.params = {name: GrowableArray(default.shape) for name, default in cls._param_defaults.items()}
        self.objects = []

    def append(self, edge, sequence):
        """Store one edge object's values; returns its row."""
        row = self.handles.append([v._h for v in edge._vertices])
        self.measurements.append(edge._z)
        self.whitening.append(edge._w)
        self.alive.append(True)
        self.sequence.append(sequence)
        for name, column in self.params.items():
            column.append(edge._params[name])
        self.objects.append(edge)
        return row

    def extend(self, handles, measurements, whitening, params, first_sequence):
        """Store E edges given as arrays (objects are attached afterwards with ``objects.extend``); returns the
        first row."""
        count = len(handles)
        row0 = self.handles.extend(handles)
        self.measurements.extend(measurements)
        self.whitening.extend(whitening)
        self.alive.extend(np.ones(count, dtype=bool))
        self.sequence.extend(first_sequence + np.arange(count))
        for name, column in self.params.items():
            column.extend(params[name])
        return row0

    def write_values(self, edge):
        """Copy the edge object's measurement, whitening and parameters into its row."""
        row = edge._row
        self.measurements.buffer[row] = edge._z
        self.whitening.buffer[row] = edge._w
        for name, column in self.params.items():
            column.buffer[row] = edge._params[name]

    def mark_removed(self, edge):
        self.alive.buffer[edge._row] = False
        self.objects[edge._row] = None

    def alive_rows(self):
        return np.nonzero(self.alive.values)[0]
