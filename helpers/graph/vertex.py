"""Vertices of the graph: the per-object API and the vectorised ⊞ (oplus) of each vertex class.

A vertex class declares

    dimension : int                       size of the state vector (and of the update)
    oplus_batch(x, dx) -> x ⊞ dx          staticmethod on arrays of shape (V, dimension)

``oplus_batch`` is the only implementation of the class's ⊞; the per-object ``oplus`` and the optimiser both
call it. Ids are allocated per class from 0 at construction unless given explicitly.

While a vertex belongs to a ``SparseOptimizer`` its estimate lives in the optimiser's flat state array (so the
optimiser can gather and update all vertices at once); ``estimate`` / ``set_estimate`` read and write it there.
"""


import numpy as np

from ..validation import boolean
from .angles import wrap_angle

__all__ = ["BaseVertex", "VertexSE2", "VertexPointXY"]


def _as_vector(value, size, name):
    """Validate and flatten a vector argument of length ``size`` (accepts (size,), (size, 1) or a scalar if size 1)."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric vector of length {size}, got {value!r}") from None
    if arr.ndim == 0 and size == 1:
        arr = arr.reshape(1)
    if arr.shape not in ((size,), (size, 1), (1, size)):
        raise ValueError(f"{name} must have {size} elements (shape ({size},) or ({size}, 1)), got shape {arr.shape}")
    arr = arr.reshape(size)
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite (no NaN or inf), got {arr}")
    return arr


class BaseVertex:
    """A state block of the graph. Subclasses set ``dimension`` and (optionally) override ``oplus_batch``.

    Attributes/methods: ``id``, ``dimension``, ``estimate`` (copy), ``set_estimate(x)``, ``oplus(dx)``,
    ``fixed`` / ``set_fixed(flag)``, ``edges()`` (in attachment order), ``number_of_edges()``,
    ``hessian_index`` (first row of this vertex in the free state vector X, or None when fixed / not built /
    removed from its graph), ``graph``.
    """

    dimension = 0
    _counters = {}

    def __init__(self, id=None, estimate=None, fixed=False):
        cls = type(self)
        dim = cls.dimension
        if isinstance(dim, bool) or not isinstance(dim, (int, np.integer)) or dim <= 0:
            raise TypeError(f"{cls.__name__} must define a positive int class attribute 'dimension', got {dim!r}")
        counter = BaseVertex._counters.setdefault(cls, [0])
        if id is None:
            id = counter[0]
        elif not isinstance(id, (int, np.integer)) or isinstance(id, bool):
            raise ValueError(f"vertex id must be an int, got {id!r}")
        id = int(id)
        counter[0] = max(counter[0], id + 1)
        self._id = id
        self._graph = None
        self._h = -1  # handle inside the graph
        self._est = np.zeros(cls.dimension)
        self._fixed = boolean(fixed, f"{cls.__name__}(fixed)")
        self._edges = {}  # insertion-ordered set of attached edges
        self._hidx = None
        if estimate is not None:
            self.set_estimate(estimate)

    # ----- vectorised model -------------------------------------------------------------------------
    @staticmethod
    def oplus_batch(x, dx):
        """x ⊞ dx for arrays (V, d) → (V, d). Default: vector addition."""
        return x + dx

    #: For a ⊞ that is not (locally) plain addition: staticmethod x (V, d) → M (V, d, d) = ∂(x ⊞ δ)/∂δ at δ = 0.
    #: Edges give Jacobians with respect to the estimate's coordinates; the optimiser multiplies them by M.
    oplus_jacobian_batch = None

    # ----- per-object API ---------------------------------------------------------------------------
    @property
    def id(self):
        return self._id

    @property
    def graph(self):
        return self._graph

    @property
    def estimate(self):
        if self._graph is not None:
            return self._graph._vertex_estimate(self._h).copy()
        return self._est.copy()

    def set_estimate(self, value):
        x = _as_vector(value, type(self).dimension, f"{type(self).__name__}.set_estimate(estimate)")
        if self._graph is not None:
            self._graph._set_vertex_estimate(self._h, x)
        else:
            self._est = x

    def set_to_origin(self):
        self.set_estimate(np.zeros(type(self).dimension))

    def oplus(self, update):
        """x ← x ⊞ update (through the class's vectorised ``oplus_batch``)."""
        d = type(self).dimension
        dx = _as_vector(update, d, f"{type(self).__name__}.oplus(update)")
        self.set_estimate(type(self).oplus_batch(self.estimate[None, :], dx[None, :])[0])

    @property
    def fixed(self):
        return self._fixed

    def set_fixed(self, flag=True):
        """Fix (or free) the vertex. In a graph this changes the structure: call ``initialize_optimization()``
        again before the next ``optimize`` (which otherwise raises GraphError)."""
        flag = boolean(flag, f"{type(self).__name__}.set_fixed(flag)")
        if flag != self._fixed:
            self._fixed = flag
            if self._graph is not None:
                self._graph._set_vertex_fixed(self._h, flag)

    def edges(self):
        return list(self._edges)

    def number_of_edges(self):
        return len(self._edges)

    @property
    def hessian_index(self):
        if self._graph is None:
            return None
        return self._graph._vertex_hessian_index(self._h)

    def __repr__(self):
        state = "fixed" if self._fixed else "free"
        return f"{type(self).__name__}(id={self._id}, estimate={np.round(self.estimate, 6).tolist()}, {state})"


class VertexSE2(BaseVertex):
    """Planar pose x = [x, y, ψ]; x ⊞ δ = [x + δx, y + δy, wrap(ψ + δψ)] (ψ in [−π, π))."""

    dimension = 3

    @staticmethod
    def oplus_batch(x, dx):
        out = x + dx
        out[:, 2] = wrap_angle(out[:, 2])
        return out


class VertexPointXY(BaseVertex):
    """Planar point m = [x, y]; additive ⊞."""

    dimension = 2


def _reset_counters():  # used by tests only
    BaseVertex._counters.clear()
