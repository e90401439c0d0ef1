"""What guards the front-end's state: its inputs checked before anything changes, and a failed scan undone.

Checks (ValueError naming the argument and what was expected):

- ``check_graph_and_model``: the graph is a ``FastOptimizer``, the model a ``RangeBearingModel``;
- ``check_pose_vertex`` (``start``): a vertex of the model's pose class in that graph;
- ``check_pose_edge`` (``add_pose``): a binary edge of that graph from the current pose to a new pose vertex;
- ``check_scan`` (``process_scan``): the observations Z — finite, (d, m), and each column a measurement the
  model's edge class accepts (a range ≥ 0: ``check_measurements``) —, their noise covariance R (finite, symmetric,
  positive definite) and the edges' information Ω ((d, d) or one per observation; finite, symmetric, positive
  definite as ``add_edges`` requires). Nothing of a scan is processed before all of this passes, so
  a bad scan cannot fail later, half-way, inside the graph.

``ScanUndo``: what a scan may change — the scan counter and observation log, the tracks it can touch (the
candidates and the tentative landmarks, every one of which is in the window), the window, the statistics, the pool
of left-out observations, the merge records and the landmark vertices it adds to the graph — recorded before the
scan and put back if anything raises before its edges are in the graph (the last step that can fail:
``add_edges`` checks everything before it adds anything). The record is cheap: references to the window's
arrays (a scan replaces them, it never writes into them), copies of small dicts and lists, the fields of the few
tracks involved, and the lengths of their lists (a scan only appends to a track's lists or replaces them, so
the lists the fields refer to are cut back to those lengths).
"""
from __future__ import annotations

import numpy as np

from ...graph import BaseEdge, BaseVertex, check_information
from ...validation import float_array
from ..fast_graph import FastOptimizer
from .models import RangeBearingModel

__all__ = ["check_graph_and_model", "check_pose_vertex", "check_pose_edge", "check_scan", "ScanUndo"]


def _kind(value) -> str:
    return type(value).__name__


def check_graph_and_model(graph, model) -> None:
    """ValueError unless ``graph`` is a ``FastOptimizer`` and ``model`` a ``RangeBearingModel``."""
    if not isinstance(graph, FastOptimizer):
        raise ValueError(f"graph must be a FastOptimizer (the graph the SLAM system builds), got {_kind(graph)}")
    if not isinstance(model, RangeBearingModel):
        raise ValueError(f"model must be a RangeBearingModel (online_slam.models), got {_kind(model)}")


def check_pose_vertex(vertex, graph, model, name: str = "pose_vertex") -> None:
    """ValueError naming ``name`` unless ``vertex`` is a vertex of the model's pose class in ``graph``."""
    cls = model.edge_class.vertex_types[0]
    if not isinstance(vertex, cls):
        raise ValueError(f"{name} must be a {cls.__name__} (the pose vertex the observations are made from), got "
                         f"{_kind(vertex)}")
    if vertex.graph is not graph:
        raise ValueError(f"{name} must be a vertex of the front-end's graph (add it to the graph first)")


def check_pose_edge(edge, pose, graph, model) -> None:
    """ValueError naming ``edge`` unless it is a binary edge from the current pose ``pose`` to a new pose vertex
    of the model's pose class in ``graph`` (an odometry edge: ``add_pose``)."""
    if pose is None:
        raise ValueError("add_pose: call start(first_pose) first")
    expected = "a binary odometry edge (a BaseEdge from the current pose to the new one)"
    if not isinstance(edge, BaseEdge):
        raise ValueError(f"edge must be {expected}, got {_kind(edge)}")
    ends = edge.vertices()
    if len(ends) != 2:
        raise ValueError(f"edge must be {expected}, got {_kind(edge)}, an edge with {len(ends)} vertices")
    if ends[0] is not pose:
        raise ValueError(f"edge must be {expected}: its first vertex is not the current pose")
    if ends[1] is pose or not isinstance(ends[1], BaseVertex):
        raise ValueError(f"edge must be {expected}: its second vertex must be a new pose vertex")
    check_pose_vertex(ends[1], graph, model, "edge.vertex(1)")
    if edge.graph is not graph:
        raise ValueError("edge must be an edge of the front-end's graph (add it to the graph first)")


def _check_noise(R, d):
    """R as a finite symmetric positive-definite (d, d) float array, and its inverse."""
    R = float_array(R, "R")
    if R.shape != (d, d) or not np.all(np.isfinite(R)) or not np.allclose(R, R.T):
        raise ValueError(f"R must be a finite symmetric ({d}, {d}) covariance, got shape {R.shape}")
    if np.any(np.linalg.eigvalsh(R) <= 0):
        raise ValueError("R must be positive definite")
    return np.linalg.inv(R)


def _check_observations(model, Z):
    """Z as a finite (d, m) float array whose columns the model's edge class accepts as measurements."""
    d = model.dimension
    Z = float_array(Z, "Z")
    if Z.ndim != 2 or Z.shape[0] != d:
        raise ValueError(f"Z must be a ({d}, m) array of observations (one per column), got shape {Z.shape}")
    if not np.isfinite(Z).all():
        bad = np.flatnonzero(~np.isfinite(Z).all(axis=0))
        raise ValueError(f"Z must be finite (no NaN/inf); bad columns: {bad.tolist()}")
    if Z.shape[1]:
        try:
            model.edge_class.check_measurements(Z.T, "Z")
        except ValueError:                  # name the column (the edge class counts the rows of Zᵀ)
            for j in range(Z.shape[1]):
                model.edge_class.check_measurements(Z[None, :, j], f"Z[:, {j}]")
            raise
    return Z


def check_scan(model, Z, R, information, noise_cache: dict):
    """(Z, R, information (m, d, d), noise cache) for ``process_scan``, everything checked (module docstring).
    ``noise_cache`` maps the bytes of an accepted R to R⁻¹ (the sensor's R rarely changes: checked once); the
    cache to keep is returned, not stored, so that a refused scan changes nothing."""
    d = model.dimension
    Z = _check_observations(model, Z)
    R = float_array(R, "R")
    key = R.tobytes() if R.shape == (d, d) else None
    if key is None or key not in noise_cache:
        noise_cache = {key: _check_noise(R, d)}
    if information is None:
        information = noise_cache[key]
    else:
        information = float_array(information, "information")
        if information.shape == (d, d):
            check_information(information, d, "information")          # cached by value: cheap per scan
        elif information.shape == (Z.shape[1], d, d):
            check_information(information, d, "information", count=Z.shape[1])
    if information.shape == (d, d):
        full = np.empty((Z.shape[1], d, d))
        full[:] = information
        information = full
    if information.shape != (Z.shape[1], d, d):
        raise ValueError(f"information must be ({d}, {d}) or ({Z.shape[1]}, {d}, {d}), got {information.shape}")
    return Z, R, information, noise_cache


class ScanUndo:
    """The front-end's state before a scan, and ``restore()`` to put it back (module docstring). ``cands``: the
    scan's candidate tracks; ``vertices``: the landmark vertices the scan has added to the graph (``_confirm``)."""

    def __init__(self, fe, cands):
        self.fe = fe
        self.scan_count = fe.scan_count
        self.n_log = len(fe.observation_log["key"])
        self.n_tracks = len(fe.tracks)
        touched = {id(t): t for t in cands}
        touched.update((id(fe.tracks[k]), fe.tracks[k]) for k in fe.window.keys)
        self.tracks = [(t, t.__dict__.copy(), len(t.pending), len(t.observations)) for t in touched.values()]
        w = fe.window
        self.window = (w.A, w.P, dict(w.rows), dict(w.means), list(w._order))
        self.stats = dict(fe.stats)
        self.n_orphans = len(fe.orphans)
        self.n_unverified = len(fe._unverified)
        self.merge_scans = dict(fe.merge_scans)
        self.vertices = []

    def restore(self) -> None:
        fe = self.fe
        for v in self.vertices:
            if v.graph is fe.graph:
                fe.graph.remove_vertex(v)       # no edge yet: the scan's edges are added last
        fe.scan_count = self.scan_count
        for log in fe.observation_log.values():
            del log[self.n_log:]
        del fe.tracks[self.n_tracks:]
        for t, fields, n_pending, n_observations in self.tracks:
            t.__dict__.update(fields)           # the track's own list objects, cut back to their lengths
            del t.pending[n_pending:]
            del t.observations[n_observations:]
        w = fe.window
        w.A, w.P, w.rows, w.means, w._order = self.window
        fe.stats.clear()
        fe.stats.update(self.stats)
        del fe.orphans[self.n_orphans:]
        del fe._unverified[self.n_unverified:]
        fe.merge_scans.clear()
        fe.merge_scans.update(self.merge_scans)
