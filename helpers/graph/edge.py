"""Edges of the graph: the per-object API over one vectorised model function per edge class.

An edge class declares

    vertex_types          tuple, one vertex class per slot (isinstance check; subclasses are accepted)
    measurement_dimension m
    parameters            dict name -> default (array-like; its shape is the per-edge shape), e.g. {"dt": 0.1}
    evaluate(states, z, params, jacobians=True) -> (e, [J_0, J_1, ...])      a staticmethod

``states`` = list of (E, d_k) arrays (the estimates of slot k for E edges), ``z`` (E, m), ``params``
{name: (E, *shape)}; e (E, m) and, when ``jacobians`` is true, J_k = ∂e/∂(vertex k) of shape (E, m, d_k) with
respect to the vertex's coordinates (else ``None``). Convention: e = h(x) − z, χ² = eᵀ Ω e. The per-object
``error()`` / ``jacobians()`` / ``chi2()`` call the same ``evaluate`` with E = 1.
"""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ..validation import float_array
from .errors import GraphError, NonFiniteError
from .vertex import BaseVertex, as_rows

__all__ = ["BaseEdge", "check_information", "information_from_covariance", "check_parameters", "batch_matrix",
           "check_model_output", "edge_label"]

_CACHE = {}   # validated single matrices by value: loaders and simulators repeat the same few


def _cached(key: tuple, value: tuple | np.ndarray) -> tuple | np.ndarray:
    if len(_CACHE) > 4096:
        _CACHE.clear()
    _CACHE[key] = value
    return value


def check_information(info: ArrayLike, m: int, name: str = "information", count: int | None = None) -> tuple:
    """Validate information matrices Ω: finite, symmetric, positive definite. Returns (Ω, W) with Ω = WᵀW.

    ``count`` None: one (m, m) matrix (read-only results, cached by value). ``count`` = E: an (E, m, m) stack, or
    one (m, m) matrix for all E (checked once, broadcast). ValueError naming ``name`` (and the bad index).
    """
    arr = float_array(info, name)
    if arr.ndim == 0 and m == 1:
        arr = arr.reshape(1, 1)
    if arr.shape == (m, m):
        key = ("information", arr.tobytes())
        single = _CACHE.get(key) or _cached(key, _check_stack(arr[None], name, True))
        return single if count is None else tuple(np.broadcast_to(a, (count, m, m)) for a in single)
    if count is None or arr.shape != (count, m, m):
        want = f"({m}, {m})" + ("" if count is None else f" or ({count}, {m}, {m})")
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    return _check_stack(arr, name, False)


def _check_stack(arr: np.ndarray, name: str, single: bool) -> tuple:
    """(Ω, W) of a stack (E, m, m) of information matrices (squeezed to (m, m) when ``single``)."""
    at = (lambda mask: "") if single else (lambda mask: f"[{int(np.argmax(mask))}]")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}{at(~np.isfinite(arr).all(axis=(1, 2)))} must be finite (no NaN or inf)")
    scale = np.maximum(1.0, np.abs(arr).max(axis=(1, 2)))
    asym = np.abs(arr - arr.transpose(0, 2, 1)).max(axis=(1, 2)) > 1e-9 * scale
    if asym.any():
        raise ValueError(f"{name}{at(asym)} must be symmetric")
    arr = 0.5 * (arr + arr.transpose(0, 2, 1))
    try:
        w = np.linalg.cholesky(arr).transpose(0, 2, 1).copy()    # Ω = L Lᵀ, W = Lᵀ
    except np.linalg.LinAlgError:
        bad = np.linalg.eigvalsh(arr).min(axis=1) <= 0
        raise ValueError(f"{name}{at(bad)} must be positive definite (all eigenvalues > 0)") from None
    if not single:
        return arr, w
    arr, w = arr[0], w[0]
    arr.flags.writeable = w.flags.writeable = False
    return arr, w


def information_from_covariance(cov: ArrayLike, name: str = "covariance") -> np.ndarray:
    """Ω = Σ⁻¹ for a symmetric positive-definite covariance Σ (symmetrised, read-only, cached by value)."""
    arr = float_array(cov, name)
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix, got shape {arr.shape}")
    key = ("covariance", arr.tobytes())
    if key in _CACHE:
        return _CACHE[key]
    check_information(arr, arr.shape[0], name)                  # the same checks on Σ: finite, symmetric, SPD
    info = np.linalg.inv(arr)
    if not np.isfinite(info).all():
        raise ValueError(f"{name} is too close to singular: its inverse (the information matrix) is not finite")
    info = 0.5 * (info + info.T)
    info.flags.writeable = False
    return _cached(key, info)


def check_parameters(cls: type, params: dict, count: int, where: str) -> dict:
    """{name: (count, *shape) float array} of every parameter of edge class ``cls``: the value in ``params`` (one
    for all edges or one per edge) or the class default. ValueError naming ``where`` and the parameter."""
    unknown = sorted(set(params) - set(cls._param_defaults))
    if unknown:
        raise ValueError(f"{where}: {cls.__name__} has no parameter {unknown[0]!r} (has {sorted(cls._param_defaults)})")
    out = {}
    for name, default in cls._param_defaults.items():
        value = float_array(params.get(name, default), f"{where}: parameter {name}")
        if value.size == default.size and (count == 1 or value.shape == default.shape):
            value = value.reshape(default.shape)
        if value.shape == default.shape:
            value = np.broadcast_to(value, (count,) + default.shape)
        if value.shape != (count,) + default.shape:
            raise ValueError(f"{where}: parameter {name} must have shape {default.shape}, got {value.shape}")
        if not np.isfinite(value).all():
            raise ValueError(f"{where}: parameter {name} must be finite, got {value}")
        out[name] = np.array(value)
    return out


def batch_matrix(rows: list) -> np.ndarray:
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


def edge_label(edge: BaseEdge) -> str:
    """``EdgeRangeBearing(VertexSE2 4, VertexPointXY 7)``: the edge's class and its vertices, for messages."""
    names = ", ".join("unset" if v is None else f"{type(v).__name__} {v.id}" for v in edge._vertices)
    return f"{type(edge).__name__}({names})"


def check_model_output(cls: type, e: np.ndarray, jac: list | None, count: int, jacobians: bool) -> None:
    """GraphError unless ``cls.evaluate`` returned e (count, m) and, when ``jacobians``, one J_k (count, m, d_k)
    per slot (shapes only)."""
    m = cls.measurement_dimension
    if np.shape(e) != (count, m):
        raise GraphError(f"{cls.__name__}.evaluate returned an error of shape {np.shape(e)} for {count} edge(s); "
                         f"expected ({count}, {m}) (one row per edge)")
    if not jacobians:
        return
    want = [(count, m, t.dimension) for t in cls.vertex_types]
    got = None if jac is None else [np.shape(j) for j in jac]
    if got != want:
        raise GraphError(f"{cls.__name__}.evaluate(jacobians=True) returned Jacobians of shapes {got}; "
                         f"expected {want} (one per vertex slot)")


def _check_edge_class(cls: type) -> None:
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
    if "evaluate" in cls.__dict__ and not isinstance(cls.__dict__["evaluate"], staticmethod):
        raise TypeError(f"{cls.__name__}.evaluate must be a @staticmethod: it receives (states, z, params, "
                        "jacobians) for all edges of the class, not self")


class BaseEdge:
    """A measurement z of ``len(vertex_types)`` vertices (unary, binary or more) with information Ω.

    Per-object API: ``vertex(k)``, ``vertices()``, ``measurement`` / ``set_measurement(z)``, ``information`` /
    ``set_information(Ω)``, ``parameter(name)`` / ``set_parameter(name, value)`` (also an attribute: ``edge.dt``),
    ``error()``, ``jacobians()``, ``chi2()``, ``graph``. Vertices are given at construction.
    """

    vertex_types = ()
    measurement_dimension = 0
    parameters = {}
    _param_defaults = {}

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        _check_edge_class(cls)
        cls._param_defaults = {}
        for name, default in cls.parameters.items():
            if not isinstance(name, str) or not name.isidentifier() or hasattr(BaseEdge, name):
                raise TypeError(f"{cls.__name__}.parameters: {name!r} cannot be a parameter name (an identifier "
                                "that is not a BaseEdge attribute)")
            try:
                value = np.array(default, dtype=float)
            except (TypeError, ValueError):
                raise TypeError(f"{cls.__name__}.parameters[{name!r}] must be numeric, got {default!r}") from None
            if not np.isfinite(value).all():
                raise TypeError(f"{cls.__name__}.parameters[{name!r}] must be finite, got {default!r}")
            cls._param_defaults[name] = value
            setattr(cls, name, property(lambda self, n=name: self.parameter(n),
                                        lambda self, value, n=name: self.set_parameter(n, value)))

    def __init__(self, vertices: list | None = None, measurement: ArrayLike | None = None,
                 information: ArrayLike | None = None, **params: ArrayLike) -> None:
        cls = type(self)
        n = len(cls.vertex_types)
        if n == 0:
            raise TypeError(f"{cls.__name__} must define vertex_types and a positive measurement_dimension")
        vertices = [None] * n if vertices is None else vertices
        if isinstance(vertices, BaseVertex) or not hasattr(vertices, "__len__") or len(vertices) != n:
            raise ValueError(f"{cls.__name__}: vertices must be a list of {n} vertices, got {vertices!r}")
        for k, (v, want) in enumerate(zip(vertices, cls.vertex_types)):
            if v is not None and not isinstance(v, want):
                raise ValueError(f"{cls.__name__}: slot {k} needs a {want.__name__}, got {type(v).__name__}")
        given = [id(v) for v in vertices if v is not None]
        if len(set(given)) < len(given):
            raise ValueError(f"{cls.__name__}: the same vertex cannot occupy two slots")
        m = cls.measurement_dimension
        self._graph, self._row, self._vertices = None, -1, list(vertices)
        self._z = np.zeros(m)
        self._info, self._w = check_information(np.eye(m), m)
        self._params = {k: v[0] for k, v in check_parameters(cls, params, 1, cls.__name__).items()}
        if measurement is not None:
            self.set_measurement(measurement)
        if information is not None:
            self.set_information(information)

    @staticmethod
    def evaluate(states: list, z: np.ndarray, params: dict, jacobians: bool = True) -> tuple:
        """e (E, m) = h(x) − z for E edges and, when ``jacobians``, [J_k (E, m, d_k)]; else (e, None)."""
        raise NotImplementedError("an edge class must define evaluate(states, z, params, jacobians=True)")

    @classmethod
    def check_measurements(cls, z: np.ndarray, name: str) -> None:
        """Hook: ValueError (naming ``name``) if a row of the finite (E, m) ``z`` is physically impossible for this
        class. Called by ``set_measurement`` and ``add_edges`` before anything is stored; the default accepts all."""

    # ----- vertices, values ---------------------------------------------------------------------------
    def vertex(self, k: int) -> BaseVertex | None:
        """The vertex in slot k (None while the slot is empty)."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or not 0 <= k < len(self._vertices):
            raise ValueError(f"{type(self).__name__}.vertex: slot k must be in 0..{len(self._vertices) - 1}, "
                             f"got {k!r}")
        return self._vertices[k]

    def vertices(self) -> list:
        return list(self._vertices)

    @property
    def graph(self) -> object | None:
        """The graph (a ``SparseOptimizer``) this element is in, or None."""
        return self._graph

    @property
    def measurement(self) -> np.ndarray:
        return self._z.copy()

    def set_measurement(self, z: ArrayLike) -> None:
        cls = type(self)
        name = f"{cls.__name__}.set_measurement(z)"
        z = as_rows(z, 1, cls.measurement_dimension, name)
        cls.check_measurements(z, name)
        self._z = z[0]
        self._stored()

    @property
    def information(self) -> np.ndarray:
        return self._info.copy()

    def set_information(self, info: ArrayLike) -> None:
        cls = type(self)
        self._info, self._w = check_information(info, cls.measurement_dimension,
                                                f"{cls.__name__}.set_information(information)")
        self._stored()

    def parameter(self, name: str) -> float | np.ndarray:
        if name not in self._params:
            raise ValueError(f"{type(self).__name__} has no parameter {name!r} (has {sorted(self._params)})")
        value = self._params[name]
        return float(value) if value.ndim == 0 else value.copy()

    def set_parameter(self, name: str, value: ArrayLike) -> None:
        cls = type(self)
        self._params[name] = check_parameters(cls, {name: value}, 1, cls.__name__)[name][0]
        self._stored()

    def _stored(self) -> None:
        if self._graph is not None:
            self._graph._write_edge_values(self)

    # ----- evaluation (through the vectorised model) ----------------------------------------------------
    def _evaluate(self, jacobians: bool) -> tuple:
        cls = type(self)
        for k, v in enumerate(self._vertices):
            if v is None:
                raise GraphError(f"{cls.__name__}: vertex slot {k} is not set")
        params = {k: v[None, ...] for k, v in self._params.items()}
        e, jac = cls.evaluate([v.estimate[None, :] for v in self._vertices], self._z[None, :], params, jacobians)
        check_model_output(cls, e, jac, 1, jacobians)
        if not np.isfinite(e).all() or (jacobians and not all(np.isfinite(j).all() for j in jac)):
            raise NonFiniteError(f"{edge_label(self)}: the error or a Jacobian is not finite (NaN or inf) at the "
                                 "current estimates (a degenerate configuration or an overflowing estimate?)", [self])
        return e, jac

    def error(self) -> np.ndarray:
        """e = h(x) − z for the current vertex estimates, shape (m,)."""
        return self._evaluate(False)[0][0].copy()

    def jacobians(self) -> list:
        """[J_k = ∂e/∂(vertex k)], each (m, d_k)."""
        return [j[0].copy() for j in self._evaluate(True)[1]]

    def chi2(self) -> float:
        """eᵀ Ω e."""
        e = self.error()
        value = float(e @ self._info @ e)
        if not np.isfinite(value):
            raise NonFiniteError(f"{edge_label(self)}: χ² = eᵀΩe overflows (e = {e}) at the current estimates", [self])
        return value

    def __repr__(self) -> str:
        ids = [None if v is None else v.id for v in self._vertices]
        return f"{type(self).__name__}(vertices={ids}, z={np.round(self._z, 6).tolist()})"
