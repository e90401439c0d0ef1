"""``DriveBotSLAMSystem``: builds the coursework's factor graph from the event stream; ``SLAMOptions``: its options.

Per batch (one simulator tick), in queue order: if initialised and the event is ≥ 1 ms after the current time,
predict to it (one new vehicle vertex with the *previously stored* odometry over [t_{k−1}, t_k]); then dispatch:
INITIAL_CONDITION creates vertex 0 (fixed when det P0 < 1e−6), ODOMETRY stores u and Ω = R⁻¹ (also before
initialisation), COMPASS, GPS and LANDMARK add edges to the current vertex once initialised. ``step_number``
counts the batches. An event earlier than the current time, a second INITIAL_CONDITION, an event of a disabled
sensor or a prediction before any odometry raises ValueError (events check themselves when built).

Each edge's Ω is the inverse of its event's covariance. ``remove_edge`` deletes every vertex left without edges
(Q3): the histories report such vehicle vertices through an ``in_graph`` mask (NaN state and covariance).
"""
from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from ..graph import (BaseEdge, EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2Prior, SparseOptimizer,
                     information_from_covariance)
from ..validation import boolean, function, integer, one_of
from .config import SimulatorConfiguration
from .edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex, predict
from .events import Event, EventType

__all__ = ["DriveBotSLAMSystem", "SLAMOptions", "MERGE_TIME"]

#: Events closer than this (s) share one vehicle vertex, so a simulator tick must be at least twice as long.
MERGE_TIME = 1e-3
#: The observation sensors' event types and their configuration flags.
_SENSOR_FLAGS = {EventType.COMPASS: "enable_compass", EventType.GPS: "enable_gps", EventType.LANDMARK: "enable_laser"}


@dataclass(frozen=True)
class SLAMOptions:
    """The options of a ``DriveBotSLAMSystem``, checked once when built (ValueError naming the option). Frozen: a
    changed option is a new object, e.g. ``dataclasses.replace(options, optimization_period=5)``."""

    optimization_period: int | None = None    # optimise every this many steps; None or inf: only at the end
    compass_edge: str = "fixed"               # "fixed" (EdgeHeadingPrior) or "buggy" (the edge the coursework provides)
    remove_prediction_edges: bool = False     # Q3a: remove the kinematics edges before every optimisation …
    keep_first_prediction_edge: bool = False  # … all but the first
    pre_optimization_hook: Callable[[DriveBotSLAMSystem], object] | None = None   # e.g. a Q3b pruning heuristic
    optimization_algorithm: str = "lm"        # "lm" (Levenberg–Marquardt) or "gn"; one of graph_class.ALGORITHMS

    def __post_init__(self):
        period = None if self.optimization_period == math.inf else self.optimization_period
        object.__setattr__(self, "optimization_period",
                           integer(period, "optimization_period (a number of steps, None or inf)", minimum=1,
                                   allow_none=True))
        one_of(self.compass_edge, "compass_edge", ("fixed", "buggy"))
        boolean(self.remove_prediction_edges, "remove_prediction_edges")
        boolean(self.keep_first_prediction_edge, "keep_first_prediction_edge")
        function(self.pre_optimization_hook, "pre_optimization_hook", allow_none=True)



class DriveBotSLAMSystem:
    """The coursework's SLAM system on ``graph_class`` (module docstring). ``config``: the sensors that may send
    events and the compass offset / GPS lever arm; ``options``: a SLAMOptions (default: all defaults)."""

    graph_class = SparseOptimizer

    def __init__(self, config: SimulatorConfiguration | None = None, options: SLAMOptions | None = None):
        config = SimulatorConfiguration() if config is None else config
        options = SLAMOptions() if options is None else options
        if not isinstance(config, SimulatorConfiguration):
            raise ValueError(f"config must be a SimulatorConfiguration, got {type(config).__name__}")
        if not isinstance(options, SLAMOptions):
            raise ValueError(f"options must be a SLAMOptions, got {type(options).__name__}")
        if config.dt < 2 * MERGE_TIME:
            raise ValueError(f"config.dt must be at least {2 * MERGE_TIME:g} s: events less than {MERGE_TIME:g} s "
                             f"apart share one vehicle vertex, got dt = {config.dt!r}")
        one_of(options.optimization_algorithm, "optimization_algorithm", self.graph_class.ALGORITHMS)
        if options.remove_prediction_edges and not any(getattr(config, f) for f in _SENSOR_FLAGS.values()):
            raise ValueError("remove_prediction_edges=True needs an observation sensor (enable_compass, enable_gps or "
                             "enable_laser): with odometry only the prediction edges are the whole graph")
        self.config = config
        self.options = options
        self.graph = self.graph_class()
        self.vehicle_vertices: list[VehicleVertex] = []
        self.process_model_edges: list[VehicleKinematicsEdge] = []
        self.landmark_vertices: dict[int, LandmarkVertex] = {}
        self.current_vehicle_vertex: VehicleVertex | None = None
        self.initialised = False
        self.current_time = 0.0
        self.step_number = 0
        self._u = np.zeros(3)
        self._u_info = None
        self._removal_done_upto = 0  # process_model_edges[:k] have already been through removal
        self._built = False          # structure current for the graph as it is now

    # ================================================================================= event processing
    def process_events(self, events: Iterable[Event]) -> None:
        """Process one batch (one simulator tick) of events in order (module docstring); then step_number += 1.
        A batch that breaks the order rules raises ValueError before anything changes."""
        if isinstance(events, Event) or not isinstance(events, Iterable):
            raise ValueError(f"events must be a batch (a list) of Event, got {type(events).__name__}")
        events = list(events)
        self._check_order(events)
        for event in events:
            if self.initialised:
                dt = event.time - self.current_time
                if dt >= MERGE_TIME:
                    self._predict_to_time(event.time, dt)
                    self.current_time = event.time
            t = event.type
            if t is EventType.INITIAL_CONDITION:
                self._handle_initial_condition(event)
            elif t is EventType.VEHICLE_ODOMETRY:
                self._u = event.data.copy()
                self._u_info = information_from_covariance(event.covariance, "odometry covariance")
            elif self.initialised and t is EventType.COMPASS:
                self._handle_compass(event)
            elif self.initialised and t is EventType.GPS:
                self._handle_gps(event)
            elif self.initialised and t is EventType.LANDMARK:
                self._handle_landmarks(event)
        self.step_number += 1

    def _check_order(self, events):
        # The batch's rules, checked before any event is applied: time order, one INITIAL_CONDITION, only the
        # sensors the configuration enables, odometry before the first prediction, positive-definite covariances.
        now, initialised, odometry = self.current_time, self.initialised, self._u_info is not None
        for event in events:
            if not isinstance(event, Event):
                raise ValueError(f"events must hold Event objects, got {type(event).__name__}")
            t = event.type
            if initialised and event.time - now <= -MERGE_TIME:
                raise ValueError(f"events must come in time order: a {t.name} event at t = {event.time:.4f} is "
                                 f"earlier than the current time {now:.4f}")
            if initialised and event.time - now >= MERGE_TIME and not odometry:
                raise ValueError("prediction needs an odometry event first (none received)")
            odometry = odometry or t is EventType.VEHICLE_ODOMETRY
            if t is EventType.VEHICLE_ODOMETRY:
                information_from_covariance(event.covariance, "odometry covariance")
            if t is EventType.INITIAL_CONDITION and np.linalg.det(event.covariance) >= 1e-6:
                information_from_covariance(event.covariance, "initial covariance")
            if t in _SENSOR_FLAGS and not getattr(self.config, _SENSOR_FLAGS[t]):
                raise ValueError(f"received a {t.name} event at t = {event.time:.3f} but the configuration has "
                                 f"{_SENSOR_FLAGS[t]} = False")
            if t is EventType.INITIAL_CONDITION and initialised:
                raise ValueError("received a second INITIAL_CONDITION event")
            if initialised and event.time - now >= MERGE_TIME or t is EventType.INITIAL_CONDITION:
                now, initialised = event.time, True

    def _handle_initial_condition(self, event):
        v = VehicleVertex(event.time, id=0, estimate=event.data)
        self.graph.add_vertex(v)
        if np.linalg.det(event.covariance) < 1e-6:
            v.set_fixed(True)
        else:  # never in DriveBot (P0 = 0): a unary prior with Ω = P0⁻¹
            information = information_from_covariance(event.covariance, "initial covariance")
            self.graph.add_edge(EdgeSE2Prior([v], measurement=event.data, information=information))
        self.vehicle_vertices.append(v)
        self.current_vehicle_vertex = v
        self.current_time = event.time
        self.initialised = True
        self._built = False

    def _predict_to_time(self, time, dt):
        """Q1b: the prediction step from the current vehicle vertex over ``dt`` = ΔT_k seconds to ``time`` (one call
        per tick: module docstring). Adds one VehicleVertex at ``time`` (id = its index in ``vehicle_vertices``),
        initialised by the process model with the stored odometry ``self._u``, and one VehicleKinematicsEdge from
        the current vertex to it (measurement ``self._u``, information ``self._u_info``, parameter ``dt``); appends
        them to ``vehicle_vertices`` and ``process_model_edges``, makes the new vertex ``current_vehicle_vertex``
        and sets ``self._built = False`` (the graph changed). A current vertex that has left the graph (Q3a) is
        added back to it first."""
        # Q1b: the prediction step. Each tick adds one new vehicle vertex, initialised by the process model
        # x_{k+1} = x_k + ΔT M(ψ_k) u (ψ wrapped), and one VehicleKinematicsEdge from the previous vertex with the
        # stored odometry u as its measurement, Ω = R_odo⁻¹ and the tick length ΔT as its parameter.
        prev = self.current_vehicle_vertex
        if prev.graph is not self.graph:
            # Q3a: the current vertex lost its only edge at the last optimisation and was deleted; the new
            # prediction edge reconnects it, so it re-enters the graph with its last estimate.
            self.graph.add_vertex(prev)
        est = predict(prev.estimate, self._u, dt)        # x + ΔT M(ψ) u, ψ wrapped (edges.predict)
        v = VehicleVertex(time, id=len(self.vehicle_vertices), estimate=est)
        self.graph.add_vertex(v)
        e = VehicleKinematicsEdge([prev, v], measurement=self._u, information=self._u_info, dt=dt)
        self.graph.add_edge(e)
        self.vehicle_vertices.append(v)
        self.process_model_edges.append(e)
        self.current_vehicle_vertex = v
        self._built = False

    def _handle_compass(self, event):
        # Q1c: one unary compass edge on the current vehicle vertex (appendix A.3); options.compass_edge picks the
        # edge the coursework provides ("buggy") or the student's EdgeHeadingPrior ("fixed", the default).
        edge_class = BuggyCompassEdge if self.options.compass_edge == "buggy" else EdgeHeadingPrior
        info = information_from_covariance(event.covariance, "compass covariance")
        e = edge_class([self.current_vehicle_vertex], measurement=event.data, information=info,
                       offset=self.config.compass_angular_offset)
        self.graph.add_edge(e)
        self._built = False

    def _handle_gps(self, event):
        """Q1d: the GPS ``event`` (data z (2,), covariance R_GPS) becomes one EdgePositionPrior on the current
        vehicle vertex, with information R_GPS⁻¹ and the lever arm ``self.config.gps_position_offset``; sets
        ``self._built = False`` (the graph changed)."""
        # Q1d: the GPS is a 2-D observation of the antenna, e = [x, y] + R(ψ) l − z with the lever arm l: one
        # unary EdgePositionPrior on the current vehicle vertex, Ω = R_GPS⁻¹.
        e = EdgePositionPrior([self.current_vehicle_vertex], measurement=event.data,
                              information=information_from_covariance(event.covariance, "GPS covariance"),
                              lever_arm=self.config.gps_position_offset)
        self.graph.add_edge(e)
        self._built = False

    def _handle_landmarks(self, event):
        """Q2b: the observations of one LANDMARK ``event`` join the graph (coursework appendix A.5).

        ``event.data`` (2, n): column l = [z_r, z_β] of the landmark ``event.landmark_ids[l]``; ``event.covariance``
        R (2 × 2) for every column. For each column, in order: a landmark id not yet in ``self.landmark_vertices``
        gets a ``LandmarkVertex(landmark_id, id=landmark_id)``, added to ``self.graph`` and to
        ``self.landmark_vertices``, whose estimate is the position that the observation model maps to this
        measurement from the pose of ``self.current_vehicle_vertex``; a landmark already known keeps its vertex
        and estimate. Then one ``EdgeRangeBearing`` joins [current vehicle vertex, landmark vertex] (in that
        order), with measurement [z_r, z_β] and information R⁻¹ (``information_from_covariance``). Finally
        ``self._built = False`` (the graph changed).
        """
        # Q2b: SLAM. A landmark seen for the first time gets a vertex, initialised by inverting the observation
        # model; every observation adds a range-bearing edge between the current vehicle vertex and its landmark,
        # e = [‖m − p‖ − z_r, wrap(atan2(m_y − y, m_x − x) − ψ − z_β)], Ω = R_laser⁻¹.
        info = information_from_covariance(event.covariance, "laser covariance")
        vehicle = self.current_vehicle_vertex
        x = vehicle.estimate
        z = event.data
        rows = []
        for l, lid in enumerate(event.landmark_ids.tolist()):  # a handful of columns per scan
            lm = self.landmark_vertices.get(lid)
            if lm is None:  # first sighting: inverse observation m = p + z_r [cos(z_β + ψ), sin(z_β + ψ)]
                ang = z[1, l] + x[2]
                lm = LandmarkVertex(lid, id=lid, estimate=x[:2] + z[0, l] * np.array([math.cos(ang), math.sin(ang)]))
                self.graph.add_vertex(lm)
                self.landmark_vertices[lid] = lm
            rows.append((vehicle, lm))
        # all range-bearing edges of the scan in one call (same result as adding them one by one, in order)
        self.graph.add_edges(EdgeRangeBearing, rows, z.T, info)
        self._built = False

    # ================================================================================= optimisation
    def recommend_optimization(self) -> bool:
        """True when step_number is a multiple of the optimisation period (never when the period is None)."""
        period = self.options.optimization_period
        return period is not None and self.step_number % period == 0

    def _delete_prediction_edges(self):
        """Q3a: remove the vehicle prediction edges from the graph (``optimize`` calls it when
        ``options.remove_prediction_edges``).

        ``self.process_model_edges`` lists every VehicleKinematicsEdge the system has made, in order. Remove from
        ``self.graph`` (``graph.remove_edge``) those made since the previous call: all of them, or, when
        ``self.options.keep_first_prediction_edge``, all but the very first one (``process_model_edges[0]``), which
        stays. ``self._removal_done_upto`` (0 before the first call) is there to remember how far the list has been
        handled. An edge already removed is not removed again (``remove_edge`` raises GraphError for it); the graph
        deletes every vertex left without edges; landmark edges and estimates are left alone. Finally
        ``self._built = False`` (the graph changed).
        """
        # Q3a: only edges added since the last call are visited; with keep_first_prediction_edge the very first
        # kinematics edge stays, which keeps the graph connected to the fixed first vertex.
        start = self._removal_done_upto
        if start == 0 and self.options.keep_first_prediction_edge:
            start = 1
        for e in self.process_model_edges[start:]:
            if e.graph is self.graph:
                self.graph.remove_edge(e)
        self._removal_done_upto = len(self.process_model_edges)
        self._built = False

    def ensure_structure(self) -> None:
        """Build the optimiser structure if the graph changed since the last build."""
        if not self._built:
            self.graph.initialize_optimization()
            self._built = True

    def optimize(self, max_iterations: int = 50) -> float:
        """Hook, prediction-edge removal (if requested), structure build, ``optimization_algorithm``; returns χ².

        Raises helpers.graph.GaugeFreedomError when nothing anchors the graph's gauge (its Hessian is singular).
        """
        if self.options.pre_optimization_hook is not None:  # Q3b: a pruning heuristic edits the graph here
            self._built = False        # (the structure is rebuilt even if the hook raises part-way)
            self.options.pre_optimization_hook(self)
        if self.options.remove_prediction_edges:  # Q3a: delete the prediction edges before optimising
            self._delete_prediction_edges()
        return self._solve(max_iterations)

    def _solve(self, max_iterations: int) -> float:
        """Build the structure if the graph changed and run ``optimization_algorithm``; returns χ²."""
        self.ensure_structure()
        return float(self.graph.optimize(max_iterations, algorithm=self.options.optimization_algorithm))

    def chi2(self) -> float:
        """χ² of the graph at the current estimates."""
        self.ensure_structure()
        return float(self.graph.chi2())

    # ================================================================================= estimates
    def platform_estimate(self) -> tuple[np.ndarray, np.ndarray]:
        """(x (3,), P (3×3)) of the current vehicle vertex (P from the marginal of the current H; NaN when the
        vertex has left the graph)."""
        v = self.current_vehicle_vertex
        if v is None:
            raise ValueError("platform_estimate: the system has not been initialised")
        if v.graph is None:
            return v.estimate, np.full((3, 3), np.nan)
        self.ensure_structure()
        return v.estimate, self.graph.compute_marginals([v])[v]

    def platform_estimate_history(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(T (N,), X (3×N), P (3×N covariance diagonals), in_graph (N,) bool) from one marginal computation.

        Vertices removed from the graph (Q3a/Q3b) have in_graph False and NaN in X and P; the fixed first
        vertex has P = 0.
        """
        vv = self.vehicle_vertices
        T = np.array([v.time for v in vv])
        in_graph = np.array([v.graph is self.graph for v in vv], dtype=bool)
        X = np.full((3, len(vv)), np.nan)
        P = np.full((3, len(vv)), np.nan)
        live = [v for v, g in zip(vv, in_graph) if g]
        if live:
            self.ensure_structure()
            marg = self.graph.compute_marginals(live)
            X[:, in_graph] = np.array([v.estimate for v in live]).T
            P[:, in_graph] = np.array([np.diag(marg[v]) for v in live]).T
        return T, X, P, in_graph

    def landmark_estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x 2×L, P 2×2×L, ids (L,)) in ascending landmark id order (landmarks still in the graph)."""
        ids = sorted(i for i, v in self.landmark_vertices.items() if v.graph is self.graph)
        x = np.zeros((2, len(ids)))
        P = np.zeros((2, 2, len(ids)))
        if ids:
            self.ensure_structure()
            verts = [self.landmark_vertices[i] for i in ids]
            marg = self.graph.compute_marginals(verts)
            for k, v in enumerate(verts):
                x[:, k] = v.estimate
                P[:, :, k] = marg[v]
        return x, P, np.array(ids, dtype=np.int64)

    def edge_residuals(self, edge_class: type[BaseEdge]) -> tuple[np.ndarray, np.ndarray]:
        """(times (E,), errors (E, m)) of every edge of ``edge_class`` in the graph, evaluated in one call of the
        class's vectorised model at the current estimates; times are those of each edge's first vertex."""
        if not (isinstance(edge_class, type) and issubclass(edge_class, BaseEdge)):
            raise ValueError(f"edge_class must be an edge class (a BaseEdge subclass), got {edge_class!r}")
        edges = [e for e in self.graph.edges() if type(e) is edge_class]
        if not edges:
            return np.zeros(0), np.zeros((0, edge_class.measurement_dimension))
        states = [np.array([e.vertex(k).estimate for e in edges]) for k in range(len(edge_class.vertex_types))]
        z = np.array([e.measurement for e in edges])
        params = {name: np.array([e.parameter(name) for e in edges]) for name in (edge_class.parameters or {})}
        err, _ = edge_class.evaluate(states, z, params, jacobians=False)
        return np.array([getattr(e.vertex(0), "time", np.nan) for e in edges]), err

    # ================================================================================= statistics
    def graph_statistics(self) -> dict:
        """Q2c: statistics of the graph as it is now, read from the graph itself (``self.graph.vertices()`` and
        ``.edges()`` and each element's class; the system's own lists may hold vertices the graph has deleted).
        Returns a dict; it changes nothing::

            vehicle_vertices           int: VehicleVertex objects in the graph
            landmark_vertices          int: LandmarkVertex objects in the graph
            edges_by_type              {class name: int}: the edges by their exact class, type(edge).__name__
                                       (a subclass such as BuggyCompassEdge counts under its own name)
            landmark_edges             int: the EdgeRangeBearing edges (the landmark observations)
            observations_per_step      float: landmark_edges / vehicle_vertices (0.0 without vehicle vertices)
            observations_per_landmark  float: landmark_edges / landmark_vertices (0.0 without landmarks)
            measurement_dimensions     int: the sum of the edges' measurement_dimension
            free_state_dimensions      int: the sum of the dimension of the vertices that are not fixed
            dof                        int: measurement_dimensions − free_state_dimensions
        """
        # Q2c: everything is read from the graph: vertices and edges counted by their class (the Python
        # counterpart of MATLAB's isa), measurement dimensions per edge type, free state dimensions.
        verts = self.graph.vertices()
        n_vehicle = sum(isinstance(v, VehicleVertex) for v in verts)
        n_landmark = sum(isinstance(v, LandmarkVertex) for v in verts)
        free_dims = sum(type(v).dimension for v in verts if not v.fixed)
        by_class = Counter(type(e) for e in self.graph.edges())
        by_type = {cls.__name__: n for cls, n in by_class.items()}
        meas = sum(cls.measurement_dimension * n for cls, n in by_class.items())  # each class knows its m
        n_obs = by_type.get("EdgeRangeBearing", 0)
        return {
            "vehicle_vertices": n_vehicle,
            "landmark_vertices": n_landmark,
            "edges_by_type": dict(sorted(by_type.items())),
            "landmark_edges": n_obs,
            "observations_per_step": n_obs / n_vehicle if n_vehicle else 0.0,
            "observations_per_landmark": n_obs / n_landmark if n_landmark else 0.0,
            "measurement_dimensions": meas,
            "free_state_dimensions": free_dims,
            "dof": meas - free_dims,
        }
