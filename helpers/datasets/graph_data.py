"""The parsed dataset (``GraphData``), its initial values, and the optimiser built from it."""
from __future__ import annotations

import os

import numpy as np

from ..graph import EdgeRangeBearing, EdgeSE2, EdgeSE2PointXY, SparseOptimizer, VertexPointXY, VertexSE2, wrap_angle
from ..graph.elements import GraphElements
from ..validation import boolean
from .records import DatasetFormatError

__all__ = ["GraphData", "build_optimizer", "pose_arrays", "merge_in_file_order", "initial_values"]

_KINDS = {"se2": "relative-pose", "rb": "range-bearing", "xy": "point"}


class GraphData:
    """Parsed dataset: poses {id: [x, y, θ]}, points {id: [x, y]}, fixed ids, and edge lists.

    ``edges`` is a list of (kind, i, j, z, information) with kind "se2" (pose–pose), "rb" (pose → point,
    z = (range, bearing)) or "xy" (pose → point, Cartesian in the pose frame), in file order; ``edge_lines``
    holds the 1-based line of each edge in the file (the readers fill it; error messages use it).
    """

    def __init__(self, source: str | os.PathLike) -> None:
        self.source = str(source)
        self.poses = {}
        self.points = {}
        self.fixed = []
        self.edges = []
        self.edge_lines = []

    def __repr__(self) -> str:
        kinds = {}
        for e in self.edges:
            kinds[e[0]] = kinds.get(e[0], 0) + 1
        return f"GraphData({self.source!r}, poses={len(self.poses)}, points={len(self.points)}, edges={kinds})"


def merge_in_file_order(data: GraphData, parts: list[tuple]) -> None:
    """Append the edges of ``parts`` [(line numbers, kind, ij, z, info), …] to ``data`` in file order."""
    if not parts:
        return
    lines = np.concatenate([p[0] for p in parts])
    order = np.argsort(lines, kind="stable")
    flat = []
    for ln, kind, ij, z, info in parts:
        for t in range(len(ln)):
            flat.append((kind, int(ij[t, 0]), int(ij[t, 1]), z[t], info[t]))
    data.edges.extend(flat[i] for i in order)
    data.edge_lines.extend(int(lines[i]) for i in order)


def _compose(p: np.ndarray, z: np.ndarray) -> np.ndarray:
    """p ∘ z."""
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], wrap_angle(p[2] + z[2])])


def _compose_inverse(p: np.ndarray, z: np.ndarray) -> np.ndarray:
    """q with q ∘ z = p."""
    th = wrap_angle(p[2] - z[2])
    c, s = np.cos(th), np.sin(th)
    return np.array([p[0] - (c * z[0] - s * z[1]), p[1] - (s * z[0] + c * z[1]), th])


def _edge_error(data: GraphData, t: int, message: str) -> DatasetFormatError:
    """DatasetFormatError at edge t's line (when the reader recorded it)."""
    lines = getattr(data, "edge_lines", [])
    line = lines[t] if len(lines) == len(data.edges) else None
    kind, i, j = data.edges[t][:3]
    return DatasetFormatError(data.source, line, f"{_KINDS.get(kind, kind)} edge {i} → {j}: {message}")


def initial_values(data: GraphData) -> tuple[dict, dict]:
    """(poses, points): the VERTEX values, the other poses composed from the relative-pose edges (passes in file
    order until no edge adds a pose; the first pose at the origin when the file has no VERTEX line), each landmark
    at its first observation.

    Raises DatasetFormatError at the first edge whose pose no VERTEX line or chain of relative-pose edges
    reaches (or whose landmark's first observation comes from such a pose).
    """
    poses = dict(data.poses)
    points = dict(data.points)
    pending = [e[1:4] for e in data.edges if e[0] == "se2"]
    if pending and not poses:
        poses[pending[0][0]] = np.zeros(3)
    while pending:
        still = []
        for i, j, z in pending:
            if i in poses and j not in poses:
                poses[j] = _compose(poses[i], z)
            elif j in poses and i not in poses:
                poses[i] = _compose_inverse(poses[j], z)
            elif i not in poses:
                still.append((i, j, z))
        if len(still) == len(pending):
            break
        pending = still
    unreached = ("has no initial value: no VERTEX line, and no chain of relative-pose edges to a pose that has one")
    for t, (kind, i, j, z, _) in enumerate(data.edges):
        if i not in poses:
            raise _edge_error(data, t, f"pose {i} {unreached}")
        if kind == "se2" and j not in poses:
            raise _edge_error(data, t, f"pose {j} {unreached}")
        if kind in ("rb", "xy") and j not in points:
            p = poses[i]
            local = z[0] * np.array([np.cos(z[1]), np.sin(z[1])]) if kind == "rb" else z
            c, s = np.cos(p[2]), np.sin(p[2])
            points[j] = p[:2] + np.array([c * local[0] - s * local[1], s * local[0] + c * local[1]])
    return poses, points


def build_optimizer(data: GraphData, fix_first: bool = True, pose_class: type = VertexSE2,
                    optimizer_class: type = SparseOptimizer) -> SparseOptimizer:
    """An ``optimizer_class`` graph (default: the course's SparseOptimizer) holding the dataset (pose vertices
    ``pose_class``, a VertexSE2 subclass; points VertexPointXY)."""
    if not isinstance(data, GraphData):
        raise ValueError("data must be a GraphData (from read_toro, read_g2o, read_victoria_park or read_dataset), "
                         f"got {type(data).__name__}")
    fix_first = boolean(fix_first, "fix_first")
    if not (isinstance(pose_class, type) and issubclass(pose_class, VertexSE2)):
        raise ValueError(f"pose_class must be VertexSE2 or a subclass, got {pose_class!r}")
    for t, e in enumerate(data.edges):
        if len(e) != 5 or e[0] not in _KINDS:
            raise ValueError(f"data.edges[{t}] must be (kind, i, j, z, information) with kind one of "
                             f"{sorted(_KINDS)}, got {e!r}")
    if not (isinstance(optimizer_class, type) and issubclass(optimizer_class, GraphElements)):
        raise ValueError(f"optimizer_class must be a graph class (SparseOptimizer or a subclass of GraphElements), "
                         f"got {optimizer_class!r}")
    poses, points = initial_values(data)
    for fid in data.fixed:
        if fid not in poses and fid not in points:
            raise ValueError(f"data.fixed: {fid!r} is neither a pose nor a point id of {data.source}")
    opt = optimizer_class()
    pv = {pid: pose_class(pid, poses[pid]) for pid in sorted(poses)}
    lv = {lid: VertexPointXY(lid, points[lid]) for lid in sorted(points)}
    for v in [*pv.values(), *lv.values()]:
        opt.add_vertex(v)
    kinds = {"se2": (EdgeSE2, pv, pv), "rb": (EdgeRangeBearing, pv, lv), "xy": (EdgeSE2PointXY, pv, lv)}
    grouped = {}
    for kind, i, j, z, info in data.edges:
        _, a, b = kinds[kind]
        rows, zs, infos = grouped.setdefault(kind, ([], [], []))
        rows.append((a[i], b[j]))
        zs.append(z)
        infos.append(info)
    for kind, (rows, zs, infos) in grouped.items():  # one vectorised add per edge class (file order within it)
        opt.add_edges(kinds[kind][0], rows, np.array(zs), np.array(infos))
    fixed = list(data.fixed)
    if fix_first and not fixed and pv:
        fixed = [min(pv)]
    for fid in fixed:
        (pv.get(fid) or lv[fid]).set_fixed(True)
    return opt


def pose_arrays(optimizer: SparseOptimizer) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(pose ids, poses (N, 3), point ids, points (M, 2)) of a graph, in creation order."""
    if not isinstance(optimizer, SparseOptimizer):
        raise ValueError(f"optimizer must be a SparseOptimizer, got {type(optimizer).__name__}")
    pid, pose, lid, pts = [], [], [], []
    for v in optimizer.vertices():
        if isinstance(v, VertexSE2):
            pid.append(v.id)
            pose.append(v.estimate)
        elif isinstance(v, VertexPointXY):
            lid.append(v.id)
            pts.append(v.estimate)
    return (np.array(pid, dtype=int), np.array(pose).reshape(-1, 3), np.array(lid, dtype=int),
            np.array(pts).reshape(-1, 2))
