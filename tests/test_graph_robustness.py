"""helpers.graph on bad input: every public method of SparseOptimizer, the vertex / edge base classes, the
parameter classes and the module-level helpers rejects it with an error naming the argument, and a rejected call
leaves the graph as it was. (Non-finite values, edits after initialisation and interrupted optimisation are in
``test_graph_transactions.py``.)"""

import numpy as np
import pytest

from helpers.advanced.fast_graph import GaussNewtonParams, GTSAMLevenbergMarquardtParams, LevenbergMarquardtParams
from helpers.advanced.fast_graph.linear import HessianPattern, LDLSolver
from helpers.graph import (BaseEdge, BaseVertex, EdgeHeadingPrior, EdgePositionPrior, EdgeRangeBearing, EdgeSE2,
                           GaugeFreedomError, GraphError, SparseOptimizer, VertexPointXY, VertexSE2,
                           batch_matrix, check_information, information_from_covariance, wrap_angle,
                           wrap_angle_mod)

NAN, INF = float("nan"), float("inf")


class NonNegativeRange(EdgeRangeBearing):
    """A user edge class whose ``check_measurements`` hook rejects a negative range."""

    @classmethod
    def check_measurements(cls, z, name):
        if np.any(z[:, 0] < 0):
            raise ValueError(f"{name}: range must be ≥ 0")


class Ctx:
    """A small initialised graph (fixed pose 0, pose 1, point 0; odometry, two range-bearing edges, a GPS edge) and
    some loose elements: ``spare`` (a pose not in the graph), ``other`` (a second graph with a pose and an edge)."""

    def __init__(self):
        g = SparseOptimizer()
        self.a, self.b = VertexSE2(0, [0.0, 0.0, 0.0], fixed=True), VertexSE2(1, [1.1, 0.1, 0.05])
        self.p = VertexPointXY(0, [2.0, 1.0])
        for v in (self.a, self.b, self.p):
            g.add_vertex(v)
        self.odo = EdgeSE2([self.a, self.b], measurement=[1.0, 0.0, 0.0], information=np.diag([100.0, 100.0, 400.0]))
        self.rb = [EdgeRangeBearing([v, self.p], measurement=[2.2, 0.45]) for v in (self.a, self.b)]
        self.gps = EdgePositionPrior([self.b], measurement=[1.0, 0.0], lever_arm=[0.1, 0.0])
        for e in [self.odo, *self.rb, self.gps]:
            g.add_edge(e)
        g.initialize_optimization()
        self.g = g
        self.spare = VertexSE2(7, [3.0, 0.0, 0.0])
        self.other = SparseOptimizer()
        self.oa, self.ob = VertexSE2(0, fixed=True), VertexSE2(1, [1.0, 0.0, 0.0])
        self.other.add_vertex(self.oa)
        self.other.add_vertex(self.ob)
        self.oedge = EdgeSE2([self.oa, self.ob], measurement=[1.0, 0.0, 0.0])
        self.other.add_edge(self.oedge)

    def snapshot(self):
        g = self.g
        return (g.number_of_vertices(), g.number_of_edges(), g._structure_stale,
                [(type(v).__name__, v.id, v.estimate.tolist(), v.fixed) for v in g.vertices()],
                [(e.measurement.tolist(), e.information.tolist()) for e in g.edges()])


def rows2(c):
    """Two range-bearing rows (pose a / pose b → point) for ``add_edges``."""
    return [(c.a, c.p), (c.b, c.p)]


def _edge_class(**attrs):
    return type("UserEdge", (BaseEdge,), attrs)


def _vertex_class(dimension):
    class UserVertex(BaseVertex):
        pass
    UserVertex.dimension = dimension
    return UserVertex(0)


def _pattern():
    return HessianPattern(2, np.array([0]), np.array([1]), np.array([True]))


# (prepare or None, action, expected exception, regex that the message must match: it names the argument)
CASES = {
    # ------------------------------------------------------------------ SparseOptimizer()
    "optimizer-verbose-str": (None, lambda c: SparseOptimizer(verbose="no"), ValueError, "verbose"),
    "optimizer-verbose-none": (None, lambda c: SparseOptimizer(verbose=None), ValueError, "verbose"),
    "optimizer-verbose-2": (None, lambda c: SparseOptimizer(verbose=2), ValueError, "verbose"),
    "optimizer-verbose-1": (None, lambda c: SparseOptimizer(verbose=1), ValueError, "verbose"),
    # ------------------------------------------------------------------ add_vertex
    "add_vertex-none": (None, lambda c: c.g.add_vertex(None), GraphError, "add_vertex: expected a vertex"),
    "add_vertex-str": (None, lambda c: c.g.add_vertex("v"), GraphError, "add_vertex: expected a vertex"),
    "add_vertex-class": (None, lambda c: c.g.add_vertex(VertexSE2), GraphError, "add_vertex: expected a vertex"),
    "add_vertex-edge": (None, lambda c: c.g.add_vertex(c.odo), GraphError, "add_vertex: expected a vertex"),
    "add_vertex-twice": (None, lambda c: c.g.add_vertex(c.b), GraphError, "already in this graph"),
    "add_vertex-duplicate-id": (None, lambda c: c.g.add_vertex(VertexSE2(1)), GraphError, "duplicate vertex id 1"),
    "add_vertex-other-graph": (None, lambda c: c.g.add_vertex(c.ob), GraphError, "belongs to another graph"),
    # ------------------------------------------------------------------ add_edge
    "add_edge-none": (None, lambda c: c.g.add_edge(None), GraphError, "add_edge: expected an edge"),
    "add_edge-vertex": (None, lambda c: c.g.add_edge(c.spare), GraphError, "add_edge: expected an edge"),
    "add_edge-unset-slot": (None, lambda c: c.g.add_edge(EdgeSE2(measurement=[1, 0, 0])), GraphError,
                            "slot 0 is not set"),
    "add_edge-unknown-vertex": (None, lambda c: c.g.add_edge(EdgeSE2([c.a, c.spare])), GraphError, "unknown vertex"),
    "add_edge-twice": (None, lambda c: c.g.add_edge(c.odo), GraphError, "already in a graph"),
    "add_edge-other-graph": (None, lambda c: c.g.add_edge(c.oedge), GraphError, "already in a graph"),
    "add_edge-removed-vertex": (lambda c: c.g.remove_vertex(c.p),
                                lambda c: c.g.add_edge(EdgeRangeBearing([c.a, c.p])), GraphError, "unknown vertex"),
    # ------------------------------------------------------------------ add_edges
    "add_edges-class-instance": (None, lambda c: c.g.add_edges(c.odo, [(c.a, c.b)], [[1, 0, 0]]), GraphError,
                                 "edge_class"),
    "add_edges-class-str": (None, lambda c: c.g.add_edges("EdgeSE2", [(c.a, c.b)], [[1, 0, 0]]), GraphError,
                            "edge_class"),
    "add_edges-vertex-class": (None, lambda c: c.g.add_edges(VertexSE2, [(c.a, c.b)], [[1, 0, 0]]), GraphError,
                               "edge_class"),
    "add_edges-abstract-class": (None, lambda c: c.g.add_edges(BaseEdge, [(c.a, c.b)], [[1, 0, 0]]), GraphError,
                                 "concrete BaseEdge subclass"),
    "add_edges-vertices-int": (None, lambda c: c.g.add_edges(EdgeSE2, 5, [[1, 0, 0]]), ValueError, "vertices"),
    "add_edges-rows-are-vertices": (None, lambda c: c.g.add_edges(EdgeSE2, [c.a, c.b], [[1, 0, 0]] * 2),
                                    ValueError, "vertices must be a list of rows"),
    "add_edges-row-length": (None, lambda c: c.g.add_edges(EdgeSE2, [(c.a,)], [[1, 0, 0]]), GraphError,
                             "row 0 has 1 vertices"),
    "add_edges-row-class": (None, lambda c: c.g.add_edges(EdgeSE2, [(c.a, c.p)], [[1, 0, 0]]), GraphError,
                            "row 0 slot 1 needs a VertexSE2"),
    "add_edges-row-unknown": (None, lambda c: c.g.add_edges(EdgeSE2, [(c.a, c.spare)], [[1, 0, 0]]), GraphError,
                              "row 0 slot 1: unknown vertex"),
    "add_edges-row-same-vertex": (None, lambda c: c.g.add_edges(EdgeSE2, [(c.b, c.b)], [[1, 0, 0]]), GraphError,
                                  "same vertex"),
    "add_edges-z-wide": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 3))), ValueError,
                         r"measurements must have shape \(2, 2\)"),
    "add_edges-z-transposed": (None, lambda c: c.g.add_edges(EdgeSE2, [(c.a, c.b), (c.a, c.b)], np.ones((3, 2))),
                               ValueError, r"measurements must have shape \(2, 3\)"),
    "add_edges-z-flat": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones(4)), ValueError,
                         r"measurements must have shape \(2, 2\)"),
    "add_edges-z-none": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), None), ValueError,
                         "measurements must be an array of real numbers"),
    "add_edges-z-nan": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), [[1, 0], [NAN, 0]]), ValueError,
                        "measurements must be finite"),
    "add_edges-z-inf": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), [[1, 0], [1, INF]]), ValueError,
                        "measurements must be finite"),
    "add_edges-z-str": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), [["a", 0], [1, 0]]), ValueError,
                        "measurements must be an array of real numbers"),
    "add_edges-z-hook": (None, lambda c: c.g.add_edges(NonNegativeRange, rows2(c), [[1, 0], [-1, 0]]), ValueError,
                         "add_edges: measurements: range must be ≥ 0"),
    "add_edges-info-count": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 2)),
                                                           np.stack([np.eye(2)] * 3)), ValueError,
                             r"information must have shape \(2, 2\) or \(2, 2, 2\)"),
    "add_edges-info-size": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 2)), np.eye(3)),
                            ValueError, "information must have shape"),
    "add_edges-info-asym": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 2)),
                                                          [[1, 0.5], [0, 1]]), ValueError, "information.*symmetric"),
    "add_edges-info-not-pd": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 2)),
                                                            np.diag([1, -1])), ValueError,
                              "information.*positive definite"),
    "add_edges-info-nan": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 2)),
                                                         np.diag([1, NAN])), ValueError, "information.*finite"),
    "add_edges-info-str": (None, lambda c: c.g.add_edges(EdgeRangeBearing, rows2(c), np.ones((2, 2)), "eye"),
                           ValueError, "information must be an array of real numbers"),
    "add_edges-param-unknown": (None, lambda c: c.g.add_edges(EdgeSE2, [(c.a, c.b)], [[1, 0, 0]], dt=0.1),
                                ValueError, "no parameter"),
    "add_edges-param-shape": (None, lambda c: c.g.add_edges(EdgePositionPrior, [(c.b,)], [[1, 0]],
                                                            lever_arm=[1, 2, 3]), ValueError, "parameter lever_arm"),
    "add_edges-param-nan": (None, lambda c: c.g.add_edges(EdgePositionPrior, [(c.b,)], [[1, 0]],
                                                          lever_arm=[1, NAN]), ValueError, "parameter lever_arm"),
    "add_edges-param-str": (None, lambda c: c.g.add_edges(EdgeHeadingPrior, [(c.b,)], [0.1], offset="x"),
                            ValueError, "parameter offset must be an array of real numbers"),
    # ------------------------------------------------------------------ remove_edge / remove_vertex
    "remove_edge-twice": (lambda c: c.g.remove_edge(c.gps), lambda c: c.g.remove_edge(c.gps), GraphError,
                          "remove_edge: this EdgePositionPrior is not in this graph"),
    "remove_edge-other-graph": (None, lambda c: c.g.remove_edge(c.oedge), GraphError, "not in this graph"),
    "remove_edge-never-added": (None, lambda c: c.g.remove_edge(EdgeSE2()), GraphError, "not in this graph"),
    "remove_edge-vertex": (None, lambda c: c.g.remove_edge(c.b), GraphError, "remove_edge: expected an edge"),
    "remove_edge-none": (None, lambda c: c.g.remove_edge(None), GraphError, "remove_edge: expected an edge"),
    "remove_vertex-twice": (lambda c: c.g.remove_vertex(c.p), lambda c: c.g.remove_vertex(c.p), GraphError,
                            "remove_vertex: VertexPointXY id 0 is not in this graph"),
    "remove_vertex-never-added": (None, lambda c: c.g.remove_vertex(c.spare), GraphError, "not in this graph"),
    "remove_vertex-other-graph": (None, lambda c: c.g.remove_vertex(c.ob), GraphError, "not in this graph"),
    "remove_vertex-edge": (None, lambda c: c.g.remove_vertex(c.odo), GraphError, "remove_vertex: expected a vertex"),
    # ------------------------------------------------------------------ vertex(id, cls)
    "vertex-id-str": (None, lambda c: c.g.vertex("1"), ValueError, "id must be an integer"),
    "vertex-id-list": (None, lambda c: c.g.vertex([1], VertexSE2), ValueError, "id must be an integer"),
    "vertex-id-float": (None, lambda c: c.g.vertex(1.0), ValueError, "id must be an integer"),
    "vertex-id-bool": (None, lambda c: c.g.vertex(True), ValueError, "id must be an integer"),
    "vertex-cls-str": (None, lambda c: c.g.vertex(1, "VertexSE2"), ValueError, "cls must be a vertex class"),
    "vertex-cls-edge": (None, lambda c: c.g.vertex(1, EdgeSE2), ValueError, "cls must be a vertex class"),
    "vertex-ambiguous": (None, lambda c: c.g.vertex(0), GraphError, "several classes use this id; pass cls"),
    # ------------------------------------------------------------------ initialize_optimization
    "initialize-gauge": (lambda c: (c.g.remove_edge(c.gps), c.a.set_fixed(False)),
                         lambda c: c.g.initialize_optimization(),
                         GaugeFreedomError, "gauge freedom"),
    # ------------------------------------------------------------------ optimize
    "optimize-iterations-negative": (None, lambda c: c.g.optimize(-1), ValueError, "max_iterations"),
    "optimize-iterations-float": (None, lambda c: c.g.optimize(1.5), ValueError, "max_iterations"),
    "optimize-iterations-str": (None, lambda c: c.g.optimize("10"), ValueError, "max_iterations"),
    "optimize-iterations-bool": (None, lambda c: c.g.optimize(True), ValueError, "max_iterations"),
    "optimize-iterations-none": (None, lambda c: c.g.optimize(None), ValueError, "max_iterations"),
    "optimize-iterations-npfloat": (None, lambda c: c.g.optimize(np.float64(3.0)), ValueError, "max_iterations"),
    "optimize-algorithm-name": (None, lambda c: c.g.optimize(5, algorithm="newton"), ValueError, "algorithm"),
    "optimize-algorithm-int": (None, lambda c: c.g.optimize(5, algorithm=42), ValueError, "algorithm"),
    "optimize-algorithm-none": (None, lambda c: c.g.optimize(5, algorithm=None), ValueError, "algorithm"),
    "optimize-algorithm-class": (None, lambda c: c.g.optimize(5, algorithm=LevenbergMarquardtParams), ValueError,
                                 "algorithm"),
    "optimize-algorithm-array": (None, lambda c: c.g.optimize(5, algorithm=np.array([1, 2])), ValueError,
                                 "algorithm"),
    "optimize-tau-zero": (None, lambda c: c.g.optimize(5, tau=0.0), ValueError, "tau"),
    "optimize-tau-negative": (None, lambda c: c.g.optimize(5, tau=-1e-3), ValueError, "tau"),
    "optimize-tau-nan": (None, lambda c: c.g.optimize(5, tau=NAN), ValueError, "tau"),
    "optimize-tau-inf": (None, lambda c: c.g.optimize(5, tau=INF), ValueError, "tau"),
    "optimize-tau-str": (None, lambda c: c.g.optimize(5, tau="1e-3"), ValueError, "tau"),
    "optimize-tau-bool": (None, lambda c: c.g.optimize(5, tau=True), ValueError, "tau"),
    "optimize-tau-with-gn": (None, lambda c: c.g.optimize(5, algorithm="gn", tau=1e-5), ValueError,
                             "tau sets the initial damping of algorithm='lm' only"),
    "optimize-params-object": (None, lambda c: c.g.optimize(5, algorithm=LevenbergMarquardtParams()), ValueError,
                               "algorithm must be one of 'lm', 'gn'"),
    "optimize-gn_tolerance-negative": (None, lambda c: c.g.optimize(5, algorithm="gn", gn_tolerance=-1.0),
                                       ValueError, "gn_tolerance"),
    "optimize-gn_tolerance-nan": (None, lambda c: c.g.optimize(5, algorithm="gn", gn_tolerance=NAN), ValueError,
                                  "gn_tolerance"),
    "optimize-gn_tolerance-str": (None, lambda c: c.g.optimize(5, algorithm="gn", gn_tolerance="1e-3"), ValueError,
                                  "gn_tolerance"),
    "optimize-gn_tolerance-bool": (None, lambda c: c.g.optimize(5, algorithm="gn", gn_tolerance=True), ValueError,
                                   "gn_tolerance"),
    "optimize-gn_tolerance-with-lm": (None, lambda c: c.g.optimize(5, gn_tolerance=1e-3), ValueError,
                                      "gn_tolerance applies to algorithm='gn' only"),
    "optimize-not-initialised": (None, lambda c: c.other.optimize(5), GraphError,
                                 "optimize: the structure has not been built; call initialize_optimization"),
    "optimize-after-add_vertex": (lambda c: c.g.add_vertex(c.spare), lambda c: c.g.optimize(5), GraphError,
                                  "structure changed.*call initialize_optimization"),
    "optimize-after-remove_edge": (lambda c: c.g.remove_edge(c.gps), lambda c: c.g.optimize(5), GraphError,
                                   "structure changed.*call initialize_optimization"),
    "optimize-after-set_fixed": (lambda c: c.b.set_fixed(True), lambda c: c.g.optimize(5), GraphError,
                                 "a vertex fixed or freed.*call initialize_optimization"),
    # ------------------------------------------------------------------ hessian / gradient / compute_marginals
    "hessian-not-initialised": (None, lambda c: c.other.hessian(), GraphError,
                                "hessian: .*call initialize_optimization"),
    "gradient-not-initialised": (None, lambda c: c.other.gradient(), GraphError,
                                 "gradient: .*call initialize_optimization"),
    "marginals-not-initialised": (None, lambda c: c.other.compute_marginals(), GraphError,
                                  "compute_marginals: .*call initialize_optimization"),
    "marginals-stale": (lambda c: c.b.set_fixed(True), lambda c: c.g.compute_marginals([c.p]), GraphError,
                        "compute_marginals: .*initialize_optimization"),
    "marginals-single-vertex": (None, lambda c: c.g.compute_marginals(c.b), ValueError,
                                "vertices must be a list of vertices"),
    "marginals-int": (None, lambda c: c.g.compute_marginals(3), ValueError, "vertices must be a list"),
    "marginals-str": (None, lambda c: c.g.compute_marginals("b"), ValueError, "vertices must be a list"),
    "marginals-list-of-str": (None, lambda c: c.g.compute_marginals(["b"]), GraphError, "not in this graph"),
    "marginals-other-graph": (None, lambda c: c.g.compute_marginals([c.ob]), GraphError, "not in this graph"),
    "marginals-never-added": (None, lambda c: c.g.compute_marginals([c.spare]), GraphError, "not in this graph"),
    # ------------------------------------------------------------------ parameter classes
    "lm-tau-zero": (None, lambda c: LevenbergMarquardtParams(tau=0.0), ValueError, "tau"),
    "lm-tau-nan": (None, lambda c: LevenbergMarquardtParams(tau=NAN), ValueError, "tau"),
    "lm-tau-none": (None, lambda c: LevenbergMarquardtParams(tau=None), ValueError, "tau"),
    "lm-gradient-negative": (None, lambda c: LevenbergMarquardtParams(gradient_tolerance=-1.0), ValueError,
                             "gradient_tolerance"),
    "lm-step-inf": (None, lambda c: LevenbergMarquardtParams(step_tolerance=INF), ValueError, "step_tolerance"),
    "lm-chi2-str": (None, lambda c: LevenbergMarquardtParams(chi2_tolerance="0"), ValueError, "chi2_tolerance"),
    "lm-relative-bool": (None, lambda c: LevenbergMarquardtParams(relative_decrease_tolerance=True), ValueError,
                         "relative_decrease_tolerance"),
    "lm-unknown-field": (None, lambda c: LevenbergMarquardtParams(mu=1.0), TypeError, "mu"),
    "gn-tolerance-negative": (None, lambda c: GaussNewtonParams(tolerance=-1e-5), ValueError, "tolerance"),
    "gn-tolerance-nan": (None, lambda c: GaussNewtonParams(tolerance=NAN), ValueError, "tolerance"),
    "gn-min-step-zero": (None, lambda c: GaussNewtonParams(min_step_fraction=0.0), ValueError, "min_step_fraction"),
    "gn-min-step-above-one": (None, lambda c: GaussNewtonParams(min_step_fraction=2.0), ValueError,
                              "min_step_fraction must be ≤ 1"),
    "gn-gradient-str": (None, lambda c: GaussNewtonParams(gradient_tolerance="x"), ValueError, "gradient_tolerance"),
    "gtsam-lambda-zero": (None, lambda c: GTSAMLevenbergMarquardtParams(initial_lambda=0.0), ValueError,
                          "initial_lambda"),
    "gtsam-factor-one": (None, lambda c: GTSAMLevenbergMarquardtParams(lambda_factor=1.0), ValueError,
                         "lambda_factor"),
    "gtsam-factor-half": (None, lambda c: GTSAMLevenbergMarquardtParams(lambda_factor=0.5), ValueError,
                          "lambda_factor"),
    "gtsam-max-below-initial": (None, lambda c: GTSAMLevenbergMarquardtParams(max_lambda=1e-6), ValueError,
                                "max_lambda must be > initial_lambda"),
    "gtsam-fidelity-negative": (None, lambda c: GTSAMLevenbergMarquardtParams(min_model_fidelity=-0.1), ValueError,
                                "min_model_fidelity"),
    "gtsam-relative-nan": (None, lambda c: GTSAMLevenbergMarquardtParams(relative_tolerance=NAN), ValueError,
                           "relative_tolerance"),
    "gtsam-absolute-inf": (None, lambda c: GTSAMLevenbergMarquardtParams(absolute_tolerance=INF), ValueError,
                           "absolute_tolerance"),
    # ------------------------------------------------------------------ vertices
    "vertex-init-id-float": (None, lambda c: VertexSE2(1.5), ValueError, "vertex id must be an int"),
    "vertex-init-id-str": (None, lambda c: VertexSE2("a"), ValueError, "vertex id must be an int"),
    "vertex-init-id-bool": (None, lambda c: VertexSE2(True), ValueError, "vertex id must be an int"),
    "vertex-init-estimate-short": (None, lambda c: VertexSE2(3, [1, 2]), ValueError, "set_estimate.*3 elements"),
    "vertex-init-estimate-nan": (None, lambda c: VertexSE2(3, [0, NAN, 0]), ValueError, "set_estimate.*finite"),
    "vertex-init-estimate-str": (None, lambda c: VertexSE2(3, "abc"), ValueError, "set_estimate"),
    "vertex-init-fixed-str": (None, lambda c: VertexSE2(3, fixed="yes"), ValueError, r"VertexSE2\(fixed\)"),
    "vertex-init-fixed-none": (None, lambda c: VertexSE2(3, fixed=None), ValueError, r"VertexSE2\(fixed\)"),
    "vertex-init-fixed-int": (None, lambda c: VertexSE2(3, fixed=1), ValueError, r"VertexSE2\(fixed\)"),
    "vertex-set_estimate-long": (None, lambda c: c.b.set_estimate([1, 2, 3, 4]), ValueError, "set_estimate"),
    "vertex-set_estimate-inf": (None, lambda c: c.b.set_estimate([INF, 0, 0]), ValueError, "set_estimate.*finite"),
    "vertex-set_estimate-none": (None, lambda c: c.b.set_estimate(None), ValueError, "set_estimate"),
    "vertex-set_fixed-str": (None, lambda c: c.b.set_fixed("no"), ValueError, "set_fixed"),
    "vertex-set_fixed-none": (None, lambda c: c.b.set_fixed(None), ValueError, "set_fixed"),
    "vertex-set_fixed-half": (None, lambda c: c.b.set_fixed(0.5), ValueError, "set_fixed"),
    "vertex-oplus-shape": (None, lambda c: c.b.oplus([1, 2]), ValueError, "oplus"),
    "vertex-oplus-nan": (None, lambda c: c.b.oplus([0, 0, NAN]), ValueError, "oplus"),
    "vertex-class-dimension-zero": (None, lambda c: _vertex_class(0), TypeError, "dimension"),
    "vertex-class-dimension-str": (None, lambda c: _vertex_class("3"), TypeError, "dimension"),
    "vertex-class-dimension-float": (None, lambda c: _vertex_class(2.0), TypeError, "dimension"),
    # ------------------------------------------------------------------ edges
    "edge-init-single-vertex": (None, lambda c: EdgeSE2(c.a), ValueError, "vertices must be a list of 2"),
    "edge-init-one-vertex": (None, lambda c: EdgeSE2([c.a]), ValueError, "vertices must be a list of 2"),
    "edge-init-int": (None, lambda c: EdgeSE2(5), ValueError, "vertices must be a list of 2"),
    "edge-init-unknown-param": (None, lambda c: EdgeSE2(dt=0.1), ValueError, "no parameter 'dt'"),
    "edge-vertex-bool": (None, lambda c: c.odo.vertex(True), ValueError, "slot k"),
    "edge-vertex-2": (None, lambda c: c.odo.vertex(2), ValueError, "slot k"),
    "edge-vertex-negative": (None, lambda c: c.odo.vertex(-1), ValueError, "slot k"),
    "edge-vertex-float": (None, lambda c: c.odo.vertex(1.0), ValueError, "slot k"),
    "edge-init-class": (None, lambda c: EdgeRangeBearing([c.a, c.b]), ValueError, "slot 1 needs a VertexPointXY"),
    "edge-init-str": (None, lambda c: EdgeSE2([c.a, "a"]), ValueError, "slot 1 needs a VertexSE2"),
    "edge-init-two-slots": (None, lambda c: EdgeSE2([c.a, c.a]), ValueError, "two slots"),
    "edge-set_measurement-size": (None, lambda c: c.odo.set_measurement([1, 2]), ValueError,
                                  r"set_measurement\(z\).*3 elements"),
    "edge-set_measurement-nan": (None, lambda c: c.odo.set_measurement([1, NAN, 0]), ValueError,
                                 r"set_measurement\(z\).*finite"),
    "edge-set_measurement-str": (None, lambda c: c.odo.set_measurement("abc"), ValueError, r"set_measurement\(z\)"),
    "edge-set_measurement-none": (None, lambda c: c.odo.set_measurement(None), ValueError, r"set_measurement\(z\)"),
    "edge-set_measurement-hook": (None, lambda c: NonNegativeRange(measurement=[-1.0, 0.0]), ValueError,
                                  r"NonNegativeRange.set_measurement\(z\): range must be ≥ 0"),
    "edge-set_information-asym": (None, lambda c: c.rb[0].set_information([[1, 0.5], [0.4, 1]]), ValueError,
                                  "information.*symmetric"),
    "edge-set_information-not-pd": (None, lambda c: c.rb[0].set_information(np.diag([1, -1])), ValueError,
                                    "information.*positive definite"),
    "edge-set_information-zero": (None, lambda c: c.rb[0].set_information(np.zeros((2, 2))), ValueError,
                                  "information.*positive definite"),
    "edge-set_information-nan": (None, lambda c: c.rb[0].set_information(np.diag([1, NAN])), ValueError,
                                 "information.*finite"),
    "edge-set_information-shape": (None, lambda c: c.rb[0].set_information(np.eye(3)), ValueError,
                                   r"information.*shape \(2, 2\)"),
    "edge-set_information-str": (None, lambda c: c.rb[0].set_information("eye"), ValueError, "information"),
    "edge-set_parameter-unknown": (None, lambda c: c.gps.set_parameter("dt", 0.1), ValueError, "no parameter 'dt'"),
    "edge-set_parameter-shape": (None, lambda c: c.gps.set_parameter("lever_arm", [1, 2, 3]), ValueError,
                                 "lever_arm must have shape"),
    "edge-set_parameter-nan": (None, lambda c: c.gps.set_parameter("lever_arm", [1, NAN]), ValueError,
                               "lever_arm must be finite"),
    "edge-set_parameter-str": (None, lambda c: c.gps.set_parameter("lever_arm", "far"), ValueError,
                               "lever_arm must be an array of real numbers"),
    "edge-attribute-nan": (None, lambda c: setattr(c.gps, "lever_arm", [NAN, 0]), ValueError,
                           "lever_arm must be finite"),
    "edge-parameter-unknown": (None, lambda c: c.gps.parameter("dt"), ValueError, "no parameter 'dt'"),
    "edge-error-unset-slot": (None, lambda c: EdgeSE2([c.a, None]).error(), GraphError, "slot 1 is not set"),
    "edge-class-vertex-types-str": (None, lambda c: _edge_class(vertex_types=("VertexSE2",), measurement_dimension=3),
                                    TypeError, "vertex_types must be a tuple of vertex classes"),
    "edge-class-vertex-types-edge": (None, lambda c: _edge_class(vertex_types=(EdgeSE2,), measurement_dimension=3),
                                     TypeError, "vertex_types"),
    "edge-class-dimension-str": (None, lambda c: _edge_class(vertex_types=(VertexSE2,), measurement_dimension="3"),
                                 TypeError, "measurement_dimension"),
    "edge-class-dimension-zero": (None, lambda c: _edge_class(vertex_types=(VertexSE2,), measurement_dimension=0),
                                  TypeError, "measurement_dimension"),
    "edge-class-parameters-list": (None, lambda c: _edge_class(vertex_types=(VertexSE2,), measurement_dimension=1,
                                                               parameters=["dt"]), TypeError,
                                   "parameters must be a dict"),
    "edge-class-parameter-str": (None, lambda c: _edge_class(vertex_types=(VertexSE2,), measurement_dimension=1,
                                                             parameters={"dt": "fast"}), TypeError,
                                 r"parameters\['dt'\] must be numeric"),
    "edge-class-parameter-nan": (None, lambda c: _edge_class(vertex_types=(VertexSE2,), measurement_dimension=1,
                                                             parameters={"dt": NAN}), TypeError,
                                 r"parameters\['dt'\] must be finite"),
    "edge-class-parameter-shadows": (None, lambda c: _edge_class(vertex_types=(VertexSE2,), measurement_dimension=1,
                                                                 parameters={"measurement": 0.0}), TypeError,
                                     "'measurement' cannot be a parameter name"),
    # ------------------------------------------------------------------ module-level helpers
    "check_information-str": (None, lambda c: check_information("eye", 2), ValueError, "information"),
    "check_information-shape": (None, lambda c: check_information(np.eye(3), 2), ValueError, "information"),
    "check_information-not-pd": (None, lambda c: check_information(-np.eye(2), 2), ValueError,
                                 "information.*positive definite"),
    "covariance-not-square": (None, lambda c: information_from_covariance(np.ones((2, 3))), ValueError, "covariance"),
    "covariance-not-pd": (None, lambda c: information_from_covariance(np.diag([1.0, 0.0])), ValueError, "covariance"),
    "covariance-str": (None, lambda c: information_from_covariance("I"), ValueError, "covariance"),
    "batch_matrix-int": (None, lambda c: batch_matrix(5), ValueError, "rows"),
    "batch_matrix-ragged": (None, lambda c: batch_matrix([[1, 2], [3]]), ValueError, "rows"),
    "batch_matrix-str-entry": (None, lambda c: batch_matrix([[1, "x"]]), ValueError, r"rows\[0\]\[1\]"),
    "wrap_angle-str": (None, lambda c: wrap_angle("north"), ValueError, "theta"),
    "wrap_angle_mod-str": (None, lambda c: wrap_angle_mod(["a"]), ValueError, "theta"),
    "ldl-solve-before-factor": (None, lambda c: LDLSolver().solve(np.ones(2)), GraphError, "factor first"),
    "ldl-solve-rhs": (None, lambda c: LDLSolver().factor(_pattern(), np.array([2.0, 1.0, 2.0])).solve(np.ones(3)),
                      ValueError, "rhs"),
    "ldl-factor-data": (None, lambda c: LDLSolver().factor(_pattern(), np.ones(2)), ValueError, "factor: data"),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_names_the_argument_and_changes_nothing(case):
    prepare, action, error, match = CASES[case]
    ctx = Ctx()
    if prepare is not None:
        prepare(ctx)
    before = ctx.snapshot()
    with pytest.raises(error, match=match):
        action(ctx)
    assert ctx.snapshot() == before


# ---------------------------------------------------------------------------------------------------- valid edges
def test_edge_cases_that_are_valid_give_the_documented_result():
    ctx = Ctx()
    marg = ctx.g.compute_marginals([ctx.a, ctx.p, ctx.p])             # fixed vertex, duplicate: zero block, one key
    assert list(marg) == [ctx.a, ctx.p] and not marg[ctx.a].any()
    assert ctx.g.compute_marginals([]) == {}
    assert ctx.g.vertex(np.int64(1), VertexSE2) is ctx.b and ctx.g.vertex(5) is None
    # optimize's χ² (the structure's blocks) and chi2() (the edge stores) are two summation paths: equal to round-off
    assert ctx.g.optimize(np.int64(0)) == pytest.approx(ctx.g.chi2(), rel=1e-12) and ctx.g.iterations == 0
    empty = SparseOptimizer()
    empty.initialize_optimization()
    assert (empty.optimize(5), empty.compute_marginals(), empty.hessian().shape) == (0.0, {}, (0, 0))
    ctx.g.remove_vertex(ctx.p)                                         # a removed vertex can join a graph again
    ctx.g.add_vertex(ctx.p)
    assert ctx.p.graph is ctx.g and ctx.p.hessian_index is None
    g = SparseOptimizer(verbose=np.bool_(False))
    g.add_vertex(VertexSE2(0, fixed=np.bool_(True)))
    z = g.add_edges(EdgeHeadingPrior, [(g.vertex(0),)], [0.25])        # m = 1: (E,) measurements are accepted
    assert z[0].measurement.tolist() == [0.25] and g.vertex(0).fixed is True


def test_singular_hessian_gauss_newton_names_it_lm_proceeds_marginals_refuse():
    """A pose held only by a GPS prior: its heading is unobservable, so H is singular (not a non-finite value)."""
    g = SparseOptimizer()
    v = VertexSE2(0, [1.0, 2.0, 0.3])
    g.add_vertex(v)
    g.add_edge(EdgePositionPrior([v], measurement=[1.5, 2.5]))
    g.initialize_optimization()
    with pytest.raises(GraphError, match="Gauss–Newton.*singular.*algorithm='lm'"):
        g.optimize(5, algorithm="gn")
    assert v.estimate.tolist() == [1.0, 2.0, 0.3]
    assert g.optimize(20) == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(GraphError, match="compute_marginals: H is not positive definite"):
        g.compute_marginals([v])
