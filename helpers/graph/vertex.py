"""Vertices of the graph: the per-object API and the vectorised ⊞ (oplus) of each vertex class.

A vertex class declares ``dimension`` (size of the state and of the update) and, if ⊞ is not plain addition, the
staticmethod ``oplus_batch(x, dx)`` on arrays (V, dimension); the per-object ``oplus`` and the optimiser both call
it. Ids are allocated per class from 0 unless given. While a vertex belongs to a ``SparseOptimizer`` its estimate
lives in the optimiser's flat state array (so the optimiser can gather and update all vertices at once).
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..validation import boolean, float_array
from .angles import wrap_angle

__all__ = ["BaseVertex", "VertexSE2", "VertexPointXY", "as_rows"]


def as_rows(value: ArrayLike, count: int, size: int, name: str) -> np.ndarray:
    """``value`` as a finite (count, size) float array; ValueError naming ``name`` otherwise. One row may also be
    given as (size,), (size, 1) or a scalar (size 1), and one column (size 1) as (count,)."""
    arr = float_array(value, name)
    if arr.shape != (count, size) and arr.ndim <= 2 and arr.size == count * size and (count == 1 or size == 1):
        arr = arr.reshape(count, size)
    if arr.shape != (count, size):
        want = f"{size} elements" if count == 1 else f"shape ({count}, {size})"
        raise ValueError(f"{name} must have {want}, got shape {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite (no NaN or inf), got {arr}")
    return arr.copy()


class BaseVertex:
    """A state block of the graph: ``id``, ``dimension``, ``estimate`` (a copy) / ``set_estimate(x)``,
    ``oplus(dx)``, ``fixed`` / ``set_fixed(flag)``, ``edges()`` (in attachment order), ``number_of_edges()``,
    ``hessian_index`` (first row of this vertex in the free state vector X; None when fixed, not built or removed),
    ``graph``."""

    dimension = 0
    #: For a ⊞ that is not (locally) plain addition: staticmethod x (V, d) → M (V, d, d) = ∂(x ⊞ δ)/∂δ at δ = 0
    #: (used by the advanced optimiser only).
    oplus_jacobian_batch = None
    _counters = {}

    def __init__(self, id: int | None = None, estimate: ArrayLike | None = None, fixed: bool = False) -> None:
        cls = type(self)
        dim = cls.dimension
        if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim <= 0:
            raise TypeError(f"{cls.__name__} must define a positive int class attribute 'dimension', got {dim!r}")
        counter = BaseVertex._counters.setdefault(cls, [0])
        if id is None:
            id = counter[0]
        elif not isinstance(id, (int, np.integer)) or isinstance(id, bool):
            raise ValueError(f"vertex id must be an int, got {id!r}")
        counter[0] = max(counter[0], int(id) + 1)
        self._id = int(id)
        self._graph = None
        self._h = -1                  # handle inside the graph
        self._est = np.zeros(dim)
        self._fixed = boolean(fixed, f"{cls.__name__}(fixed)")
        self._edges = {}              # insertion-ordered set of attached edges
        if estimate is not None:
            self.set_estimate(estimate)

    @staticmethod
    def oplus_batch(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
        """x ⊞ dx for arrays (V, d) → (V, d). Default: vector addition."""
        return x + dx

    @property
    def id(self) -> int:
        return self._id

    @property
    def graph(self) -> object | None:
        """The graph (a ``SparseOptimizer``) this element is in, or None."""
        return self._graph

    @property
    def estimate(self) -> np.ndarray:
        if self._graph is not None:
            return self._graph._read_vertex_estimate(self._h).copy()
        return self._est.copy()

    def set_estimate(self, value: ArrayLike) -> None:
        x = as_rows(value, 1, type(self).dimension, f"{type(self).__name__}.set_estimate(estimate)")[0]
        if self._graph is not None:
            self._graph._write_vertex_estimate(self._h, x)
        else:
            self._est = x

    def oplus(self, update: ArrayLike) -> None:
        """x ← x ⊞ update (through the class's vectorised ``oplus_batch``)."""
        dx = as_rows(update, 1, type(self).dimension, f"{type(self).__name__}.oplus(update)")
        self.set_estimate(type(self).oplus_batch(self.estimate[None, :], dx)[0])

    @property
    def fixed(self) -> bool:
        return self._fixed

    def set_fixed(self, flag: bool = True) -> None:
        """Fix (or free) the vertex. In a graph this changes the structure: call ``initialize_optimization()``
        again before the next ``optimize`` (which otherwise raises GraphError)."""
        flag = boolean(flag, f"{type(self).__name__}.set_fixed(flag)")
        if flag != self._fixed:
            self._fixed = flag
            if self._graph is not None:
                self._graph._write_vertex_fixed(self._h, flag)

    def edges(self) -> list:
        return list(self._edges)

    def number_of_edges(self) -> int:
        return len(self._edges)

    @property
    def hessian_index(self) -> int | None:
        return None if self._graph is None else self._graph._vertex_hessian_start(self._h)

    def __repr__(self) -> str:
        state = "fixed" if self._fixed else "free"
        return f"{type(self).__name__}(id={self._id}, estimate={np.round(self.estimate, 6).tolist()}, {state})"


class VertexSE2(BaseVertex):
    """Planar pose x = [x, y, ψ]; x ⊞ δ = [x + δx, y + δy, wrap(ψ + δψ)] (ψ in [−π, π))."""

    dimension = 3

    @staticmethod
    def oplus_batch(x: np.ndarray, dx: np.ndarray) -> np.ndarray:
        out = x + dx
        out[:, 2] = wrap_angle(out[:, 2])
        return out


class VertexPointXY(BaseVertex):
    """Planar point m = [x, y]; additive ⊞."""

    dimension = 2
