"""Edges of the graph: the per-object API over one vectorised model function per edge class.

An edge class declares

    vertex_types          tuple, one vertex class per slot (isinstance check; subclasses are accepted)
    measurement_dimension m
    parameters            dict name -> default (array-like; its shape is the per-edge shape), e.g. {"dt": 0.1}

and its model in one of two ways:

    evaluate(states, z, params, jacobians=True) -> (e, [J_0, J_1, ...])      (staticmethod; analytic Jacobians)
    error_batch(states, z, params) -> e                                        (staticmethod; error only)

``states`` = list of (E, d_k) arrays (the estimates of slot k for E edges), ``z`` (E, m), ``params``
{name: (E, *shape)}; e (E, m) and, when ``jacobians`` is true, J_k = ∂e/∂(vertex k) of shape (E, m, d_k) with
respect to the vertex's coordinates (= its ⊞ update for additive ⊞; else ``None``). A class that gives only
``error_batch`` inherits ``BaseEdge.evaluate``, which takes the Jacobians by central differences through each
slot's ⊞ (``numeric_jacobians``): right but slower, and a good check of analytic ones.
Convention: e = h(x) − z, χ² = eᵀ Ω e, and the optimiser steps X ⊞ (−dX) with dX = H⁻¹ b.
The per-object ``error()`` / ``chi2()`` call the same ``evaluate`` with E = 1.

``batch_matrix`` writes an (E, r, c) stack of Jacobians row by row, the way the equations read.
"""

import numpy as np

from .angles import wrap_angle
from .errors import GraphError, NonFiniteError
from .vertex import BaseVertex, _as_vector

__all__ = ["BaseEdge", "check_information", "information_from_covariance", "batch_matrix", "numeric_jacobians",
           "check_model_output", "edge_label"]


#: validated information matrices (and inverted covariances), keyed by kind and value; bounded
_INFO_CACHE = {}


def _cache_put(key, value):
    if len(_INFO_CACHE) > 4096:
        _INFO_CACHE.clear()
    _INFO_CACHE[key] = value
    return value


def check_information(info, m, name="information"):
    """Validate an m×m information matrix: finite, symmetric, positive definite. Returns (Ω, W) with Ω = WᵀW.

    Results are cached by value (datasets repeat the same few matrices), so validating is cheap.
    """
    try:
        arr = np.array(info, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric {m}x{m} matrix, got {info!r}") from None
    if arr.ndim == 0 and m == 1:
        arr = arr.reshape(1, 1)
    if arr.shape != (m, m):
        raise ValueError(f"{name} must have shape ({m}, {m}), got {arr.shape}")
    key = ("information", arr.tobytes())
    hit = _INFO_CACHE.get(key)
    if hit is not None:
        return hit
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    scale = max(1.0, float(np.abs(arr).max()))
    if float(np.abs(arr - arr.T).max()) > 1e-9 * scale:
        raise ValueError(f"{name} must be symmetric, got {arr.tolist()}")
    arr = 0.5 * (arr + arr.T)
    try:
        lower = np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        raise ValueError(f"{name} must be positive definite (all eigenvalues > 0), got {arr.tolist()}") from None
    if not np.all(np.diag(lower) > 0.0):
        raise ValueError(f"{name} must be positive definite (all eigenvalues > 0)")
    out = (arr, lower.T.copy())
    out[0].flags.writeable = False
    out[1].flags.writeable = False
    return _cache_put(key, out)


def information_from_covariance(cov, name="covariance"):
    """Ω = Σ⁻¹ for a symmetric positive-definite covariance Σ (the exact inverse, symmetrised), read-only.

    Cached by value with :func:`check_information`'s cache: a simulator repeats the same few covariances.
    """
    try:
        arr = np.array(cov, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a numeric square matrix, got {cov!r}") from None
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix, got shape {arr.shape}")
    key = ("covariance", arr.tobytes(), arr.shape[0])
    hit = _INFO_CACHE.get(key)
    if hit is not None:
        return hit
    sym, _ = check_information(arr, arr.shape[0], name)      # the same checks: finite, symmetric, SPD
    info = np.linalg.inv(arr)
    if not np.all(np.isfinite(info)):
        raise ValueError(f"{name} is too close to singular: its inverse (the information matrix) is not finite")
    info = 0.5 * (info + info.T)
    info.flags.writeable = False
    return _cache_put(key, info)


def check_information_batch(info, m, name="information"):
    """Vectorised check of (E, m, m) information matrices. Returns (Ω, W) stacks with Ω_e = W_eᵀ W_e."""
    try:
        arr = np.asarray(info, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numeric (E, {m}, {m}) matrices, got {type(info).__name__}") from None
    if arr.ndim != 3 or arr.shape[1:] != (m, m):
        raise ValueError(f"{name} must have shape (E, {m}, {m}), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite (no NaN or inf)")
    scale = np.maximum(1.0, np.abs(arr).max(axis=(1, 2)))
    asym = np.abs(arr - arr.transpose(0, 2, 1)).max(axis=(1, 2)) > 1e-9 * scale
    if asym.any():
        raise ValueError(f"{name}[{int(np.argmax(asym))}] must be symmetric")
    arr = 0.5 * (arr + arr.transpose(0, 2, 1))
    try:
        lower = np.linalg.cholesky(arr)
    except np.linalg.LinAlgError:
        eig = np.linalg.eigvalsh(arr).min(axis=1)
        raise ValueError(f"{name}[{int(np.argmin(eig))}] must be positive definite (all eigenvalues > 0)") from None
    d = np.diagonal(lower, axis1=1, axis2=2)
    if not (d > 0).all():
        raise ValueError(f"{name}[{int(np.argmin(d.min(axis=1)))}] must be positive definite")
    return arr, lower.transpose(0, 2, 1).copy()


def batch_matrix(rows):
    """(E, r, c) array from a matrix written row by row whose entries are (E,) arrays or scalars.

    ``batch_matrix([[c, -s], [s, c]])`` stacks the rotations R(ψ) of E angles (c, s of shape (E,)).
    """
    if not isinstance(rows, (list, tuple)) or not rows or not all(isinstance(row, (list, tuple)) for row in rows) \
            or any(len(row) != len(rows[0]) for row in rows) or len(rows[0]) == 0:
        raise ValueError(f"rows must be a non-empty list of equally long rows, got {rows!r}")
    out = np.empty(np.broadcast_shapes(*(np.shape(v) for row in rows for v in row)) + (len(rows), len(rows[0])))
    for i, row in enumerate(rows):
        for j, value in enumerate(row):
            try:
                out[..., i, j] = value
            except (TypeError, ValueError):
                raise ValueError(f"rows[{i}][{j}] must be a number or an (E,) numeric array, got {value!r}") from None
    return out


def edge_label(edge):
    """``EdgeRangeBearing(VertexSE2 4, VertexPointXY 7)``: the edge's class and its vertices, for messages."""
    names = ", ".join("unset" if v is None else f"{type(v).__name__} {v.id}" for v in edge._vertices)
    return f"{type(edge).__name__}({names})"


def check_model_output(cls, e, jac, count, jacobians):
    """Raise GraphError unless ``cls.evaluate`` returned e of shape (count, m) and, when ``jacobians``, one
    Jacobian (count, m, d_k) per slot (shapes only: O(1))."""
    m = int(cls.measurement_dimension)
    if np.shape(e) != (count, m):
        raise GraphError(f"{cls.__name__}.evaluate returned an error of shape {np.shape(e)} for {count} edge(s); "
                         f"expected ({count}, {m}) (one row per edge)")
    if not jacobians:
        return
    dims = [int(t.dimension) for t in cls.vertex_types]
    if jac is None or len(jac) != len(dims):
        got = "None" if jac is None else f"{len(jac)} Jacobian(s)"
        raise GraphError(f"{cls.__name__}.evaluate(jacobians=True) returned {got}; expected a list of {len(dims)} "
                         f"(one per vertex slot)")
    for k, (j, d) in enumerate(zip(jac, dims)):
        if np.shape(j) != (count, m, d):
            raise GraphError(f"{cls.__name__}.evaluate returned a Jacobian of shape {np.shape(j)} for slot {k}; "
                             f"expected ({count}, {m}, {d})")


def _check_edge_class(cls):
    """Class-level declarations of an edge class (TypeError naming the attribute); empty ones mark an abstract class."""
    types = cls.vertex_types
    if not isinstance(types, (tuple, list)) or not all(isinstance(t, type) and issubclass(t, BaseVertex)
                                                        for t in types):
        raise TypeError(f"{cls.__name__}.vertex_types must be a tuple of vertex classes, got {types!r}")
    m = cls.measurement_dimension
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 0 or (types and m == 0):
        raise TypeError(f"{cls.__name__}.measurement_dimension must be a positive int, got {m!r}")
    if not isinstance(cls.parameters, dict):
        raise TypeError(f"{cls.__name__}.parameters must be a dict name -> default value, got {cls.parameters!r}")
    for name in ("evaluate", "error_batch"):          # called on the class with the batch, never on an edge
        member = cls.__dict__.get(name)
        if member is not None and not isinstance(member, (staticmethod, classmethod)):
            raise TypeError(f"{cls.__name__}.{name} must be a @staticmethod: it receives (states, z, params"
                            f"{', jacobians' if name == 'evaluate' else ''}) for all edges of the class, not self")


def numeric_jacobians(cls, states, z, params, step=None):
    """[J_k (E, m, d_k)] of ``cls.error_batch`` by central differences, (e(x ⊞ hε_a) − e(x ⊞ −hε_a)) / 2h.

    Slot k steps through ``cls.vertex_types[k].oplus_batch`` when that ⊞ is additive to first order (no
    ``oplus_jacobian_batch``), else through plain addition: J is with respect to the coordinates either way.
    The difference of the errors is wrapped into [−π, π), so an angular component that crosses the ±π cut
    between the two evaluations does not jump by 2π (assumes |J|·2h < π).
    """
    h = float(cls.numeric_step if step is None else step)
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"step must be a positive finite number, got {step!r}")
    jac = []
    for k, x in enumerate(states):
        vtype = cls.vertex_types[k]
        oplus = vtype.oplus_batch if vtype.oplus_jacobian_batch is None else np.add
        cols = []
        for a in range(x.shape[1]):
            dx = np.zeros(x.shape)
            dx[:, a] = h
            plus, minus = list(states), list(states)
            plus[k], minus[k] = oplus(x, dx), oplus(x, -dx)
            diff = cls.error_batch(plus, z, params) - cls.error_batch(minus, z, params)
            cols.append(wrap_angle(diff) / (2.0 * h))
        jac.append(np.stack(cols, axis=-1))
    return jac


class _ParameterProperty:
    def __init__(self, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        return obj.parameter(self.name)

    def __set__(self, obj, value):
        obj.set_parameter(self.name, value)


class BaseEdge:
    """A measurement between ``len(vertex_types)`` vertices (unary, binary or more).

    Per-object API: ``set_vertex(k, v)``, ``vertex(k)``, ``vertices()``, ``set_measurement(z)``,
    ``set_information(Ω)``, ``measurement``, ``information``, per-edge parameters (constructor keywords, attribute
    access and ``set_parameter``), ``error()``, ``jacobians()``, ``chi2()``, ``graph``.
    """

    vertex_types = ()
    measurement_dimension = 0
    parameters = {}

    _param_defaults = {}

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        _check_edge_class(cls)
        defaults = {}
        for name, default in dict(cls.parameters).items():
            if not isinstance(name, str) or not name.isidentifier() or hasattr(BaseEdge, name):
                raise TypeError(f"{cls.__name__}.parameters: {name!r} cannot be a parameter name (an identifier "
                                "that is not a BaseEdge attribute)")
            try:
                defaults[name] = np.array(default, dtype=float)
            except (TypeError, ValueError):
                raise TypeError(f"{cls.__name__}.parameters[{name!r}] must be numeric, got {default!r}") from None
            if not np.all(np.isfinite(defaults[name])):
                raise TypeError(f"{cls.__name__}.parameters[{name!r}] must be finite, got {default!r}")
            setattr(cls, name, _ParameterProperty(name))
        cls._param_defaults = defaults

    def __init__(self, vertices=None, measurement=None, information=None, **params):
        cls = type(self)
        m = int(cls.measurement_dimension)
        if m <= 0 or len(cls.vertex_types) == 0:
            raise TypeError(f"{cls.__name__} must define vertex_types and a positive measurement_dimension")
        self._graph = None
        self._row = -1
        self._vertices = [None] * len(cls.vertex_types)
        self._z = np.zeros(m)
        self._info, self._w = check_information(np.eye(m), m)
        self._params = {k: v.copy() for k, v in cls._param_defaults.items()}
        for name, value in params.items():
            self.set_parameter(name, value)
        if vertices is not None:
            if isinstance(vertices, BaseVertex) or not hasattr(vertices, "__len__") \
                    or len(vertices) != len(cls.vertex_types):
                got = f"{len(vertices)}" if hasattr(vertices, "__len__") else repr(vertices)
                raise ValueError(f"{cls.__name__}: vertices must be a list of {len(cls.vertex_types)} vertices, "
                                 f"got {got}")
            for k, v in enumerate(vertices):
                self.set_vertex(k, v)
        if measurement is not None:
            self.set_measurement(measurement)
        if information is not None:
            self.set_information(information)

    # ----- vectorised model (override evaluate, or only error_batch) ---------------------------------------
    #: step h of the central differences in the default ``evaluate``
    numeric_step = 1e-6

    @staticmethod
    def error_batch(states, z, params):
        """e (E, m) = h(x) − z for E edges. Define it (and not ``evaluate``) to get numeric Jacobians."""
        raise NotImplementedError

    @classmethod
    def evaluate(cls, states, z, params, jacobians=True):
        """Default model: e from ``error_batch``; J_k by central differences through slot k's ⊞."""
        if cls.error_batch is BaseEdge.error_batch:
            raise NotImplementedError(f"{cls.__name__} must define evaluate(states, z, params, jacobians) "
                                      "or error_batch(states, z, params)")
        e = cls.error_batch(states, z, params)
        return e, (numeric_jacobians(cls, states, z, params) if jacobians else None)

    # ----- vertices ------------------------------------------------------------------------------------
    def _slot(self, k, method):
        """k as a slot index of this edge class (ValueError naming ``method`` otherwise)."""
        n = len(self._vertices)
        if type(k) is int and 0 <= k < n:
            return k
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k < n:
            raise ValueError(f"{type(self).__name__}.{method}: slot k must be in 0..{n - 1}, got {k!r}")
        return int(k)

    def set_vertex(self, k, vertex):
        cls = type(self)
        k = self._slot(k, "set_vertex")
        if vertex is not None:
            if not isinstance(vertex, BaseVertex):
                raise ValueError(f"{cls.__name__}.set_vertex: expected a vertex, got {type(vertex).__name__}")
            want = cls.vertex_types[k]
            if not isinstance(vertex, want):
                raise ValueError(
                    f"{cls.__name__}.set_vertex: slot {k} needs a {want.__name__}, got {type(vertex).__name__}")
            if any(v is vertex for j, v in enumerate(self._vertices) if j != k):
                raise ValueError(f"{cls.__name__}.set_vertex: the same vertex cannot occupy two slots")
        old = self._vertices[k]
        if self._graph is not None:
            self._graph._edge_set_vertex(self, k, old, vertex)
        self._vertices[k] = vertex

    def vertex(self, k):
        """The vertex in slot k (None while the slot is empty)."""
        return self._vertices[self._slot(k, "vertex")]

    def vertices(self):
        return list(self._vertices)

    @property
    def graph(self):
        return self._graph

    # ----- measurement, information, parameters ---------------------------------------------------------
    @property
    def measurement(self):
        return self._z.copy()

    @classmethod
    def check_measurements(cls, z, name):
        """Hook: raise ValueError (naming ``name``) if a row of ``z`` is physically impossible for this class.

        ``z`` is an (E, m) float array already checked for shape and finiteness. Called by ``set_measurement``
        (with a (1, m) view, before anything is stored) and by ``SparseOptimizer.add_edges``; the default accepts
        every finite value."""

    def set_measurement(self, z):
        cls = type(self)
        name = f"{cls.__name__}.set_measurement(z)"
        z = _as_vector(z, cls.measurement_dimension, name)
        cls.check_measurements(z[None, :], name)
        self._z = z
        if self._graph is not None:
            self._graph._edge_store_row(self)

    @property
    def information(self):
        return self._info.copy()

    def set_information(self, info):
        cls = type(self)
        self._info, self._w = check_information(info, cls.measurement_dimension,
                                                f"{cls.__name__}.set_information(information)")
        if self._graph is not None:
            self._graph._edge_store_row(self)

    def parameter(self, name):
        if name not in self._params:
            raise ValueError(f"{type(self).__name__} has no parameter {name!r} (has {sorted(self._params)})")
        value = self._params[name]
        return float(value) if value.ndim == 0 else value.copy()

    def set_parameter(self, name, value):
        cls = type(self)
        if name not in cls._param_defaults:
            raise ValueError(f"{cls.__name__} has no parameter {name!r} (has {sorted(cls._param_defaults)})")
        shape = cls._param_defaults[name].shape
        try:
            arr = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{cls.__name__} parameter {name} must be numeric, got {value!r}") from None
        if arr.size == int(np.prod(shape)) and arr.shape != shape:
            arr = arr.reshape(shape)
        if arr.shape != shape:
            raise ValueError(f"{cls.__name__} parameter {name} must have shape {shape}, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{cls.__name__} parameter {name} must be finite, got {arr}")
        self._params[name] = arr
        if self._graph is not None:
            self._graph._edge_store_row(self)

    # ----- evaluation (through the vectorised model) ----------------------------------------------------
    def _states(self):
        cls = type(self)
        for k, v in enumerate(self._vertices):
            if v is None:
                raise GraphError(f"{cls.__name__}: vertex slot {k} is not set")
        return [v.estimate[None, :] for v in self._vertices]

    def _eval(self, jacobians):
        cls = type(self)
        params = {k: v[None, ...] for k, v in self._params.items()}
        e, jac = cls.evaluate(self._states(), self._z[None, :], params, jacobians=jacobians)
        check_model_output(cls, e, jac, 1, jacobians)
        if not np.all(np.isfinite(e)) or (jacobians and not all(np.all(np.isfinite(j)) for j in jac)):
            raise NonFiniteError(f"{edge_label(self)}: the error or a Jacobian is not finite (NaN or inf) at the "
                                 "current estimates (a degenerate configuration or an overflowing estimate?)", [self])
        return e, jac

    def error(self):
        """e = h(x) − z for the current vertex estimates, shape (m,)."""
        e, _ = self._eval(False)
        return e[0].copy()

    def jacobians(self):
        """[J_k = ∂e/∂(vertex k)], each (m, d_k)."""
        _, jac = self._eval(True)
        return [j[0].copy() for j in jac]

    def chi2(self):
        """eᵀ Ω e."""
        e = self.error()
        value = float(e @ self._info @ e)
        if not np.isfinite(value):
            raise NonFiniteError(f"{edge_label(self)}: χ² = eᵀΩe overflows (e = {e}) at the current estimates", [self])
        return value

    def __repr__(self):
        ids = [None if v is None else v.id for v in self._vertices]
        return f"{type(self).__name__}(vertices={ids}, z={np.round(self._z, 6).tolist()})"
