"""Readers for the standard 2D pose-graph / SLAM datasets, and ``load_dataset`` for the copies in ``data/datasets``.

The four datasets the workbook uses (W100, W10000, Victoria Park, GTSAM's example.graph) ship gzipped in
``data/datasets/`` (origin and licence in ``data/README.md``); every reader also takes plain or ``.gz`` files.

Formats (strict: any malformed line raises ValueError naming the file and the 1-based line number):

TORO ``.graph``   VERTEX2 id x y θ
                  EDGE2 i j dx dy dθ I11 I12 I22 I33 I13 I23      (information, TORO order)
                  EQUIV i j                                        (ignored, as GTSAM does)
                  BR pose landmark bearing range σ_bearing σ_range (GTSAM's example.graph)
2D g2o            VERTEX_SE2 id x y θ;  VERTEX_XY id x y;  FIX id
                  EDGE_SE2 i j dx dy dθ I11 I12 I13 I22 I23 I33    (information, upper triangle row-major)
                  EDGE_SE2_XY i j dx dy I11 I12 I22                (point in the frame of pose i)
victoria_park     ODOMETRY i j dx dy dθ c_xx c_xy c_xθ c_yy c_yθ c_θθ   (covariance)
                  LANDMARK i l x y c_xx c_xy c_yy                  (Cartesian, in the frame of pose i)

Conventions follow ``gtsam.load2D`` so that χ² values compare one to one (χ² = 2 × GTSAM's error):
- relative pose measurements become ``EdgeSE2`` (GTSAM's BetweenFactor error);
- a LANDMARK (x, y) becomes a range-bearing edge with z = (hypot(x, y), atan2(y, x)), σ_range = √c_xx and
  σ_bearing = √(c_xx / 10) (load2D's rule); a BR line gives z = (range, bearing) with its own sigmas;
- initial poses are the VERTEX lines; poses without one are composed from the relative-pose edges in file order
  (the first pose at the origin); a landmark starts at its first observation, pose ⊞ (measurement);
- the lowest-id pose is fixed (GTSAM puts a prior on it instead).
"""

import gzip
import pathlib

import numpy as np

from .graph import (EdgeRangeBearing, EdgeSE2, EdgeSE2PointXY, SparseOptimizer, VertexPointXY, VertexSE2,
                    wrap_angle)
from .paths import data_path

__all__ = ["GraphData", "read_toro", "read_g2o", "read_victoria_park", "dataset_path", "load_dataset",
           "build_optimizer", "pose_arrays", "DATASETS"]

DATASETS = {"w100": "w100.graph.gz", "w10000": "w10000.graph.gz", "victoria_park": "victoria_park.txt.gz",
            "example": "example.graph.gz"}


class GraphData:
    """Parsed dataset: poses {id: [x, y, θ]}, points {id: [x, y]}, fixed ids, and edge lists.

    ``edges`` is a list of (kind, i, j, z, information) with kind "se2" (pose–pose), "rb" (pose → point,
    z = (range, bearing)) or "xy" (pose → point, Cartesian in the pose frame), in file order.
    """

    def __init__(self, source):
        self.source = str(source)
        self.poses = {}
        self.points = {}
        self.fixed = []
        self.edges = []

    def __repr__(self):
        kinds = {}
        for e in self.edges:
            kinds[e[0]] = kinds.get(e[0], 0) + 1
        return f"GraphData({self.source!r}, poses={len(self.poses)}, points={len(self.points)}, edges={kinds})"


def _fail(path, lineno, message):
    raise ValueError(f"{path}:{lineno}: {message}")


def _scan(path, counts):
    """Split a file into records: {tag: (line numbers, (N, counts[tag]) float array)}; strict checks.

    Field counts are checked per line; numbers are converted in bulk (and only on failure line by line, to
    report the offending line).
    """
    path = pathlib.Path(path)
    if not path.is_file():
        raise ValueError(f"dataset file not found: {path}")
    recs = {tag: ([], []) for tag in counts}
    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt", encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, start=1):
            fields = line.split()
            if not fields or fields[0].startswith("#"):
                continue
            tag = fields[0]
            if tag not in counts:
                _fail(path, lineno, f"unknown record {tag!r} (expected one of {', '.join(counts)})")
            if len(fields) - 1 != counts[tag]:
                _fail(path, lineno, f"{tag} needs {counts[tag]} numbers, got {len(fields) - 1}")
            recs[tag][0].append(lineno)
            recs[tag][1].append(fields[1:])
    out = {}
    for tag, (lines, rows) in recs.items():
        try:
            arr = np.array(rows, dtype=float).reshape(len(rows), counts[tag])
        except ValueError:
            for ln, r in zip(lines, rows):
                try:
                    [float(f) for f in r]
                except ValueError:
                    _fail(path, ln, f"{tag}: not a number in {' '.join(r)!r}")
            raise
        bad = ~np.isfinite(arr).all(axis=1)
        if bad.any():
            _fail(path, lines[int(np.argmax(bad))], f"{tag}: non-finite value")
        out[tag] = (np.array(lines, dtype=int), arr)
    return out


def _ids(path, tag, lines, values, what="ids"):
    bad = (values != np.round(values)) | (values < 0)
    if bad.any():
        t = int(np.argmax(bad.any(axis=1) if bad.ndim > 1 else bad))
        _fail(path, lines[t], f"{tag}: {what} must be non-negative integers")
    return values.astype(np.int64)


def _check_spd_batch(path, tag, lines, mats, what="information"):
    if len(mats) == 0:
        return
    eig = np.linalg.eigvalsh(mats).min(axis=1)
    bad = ~(eig > 0)
    if bad.any():
        _fail(path, lines[int(np.argmax(bad))], f"{tag}: {what} matrix is not positive definite")


def _sym3(a11, a12, a13, a22, a23, a33):
    return np.stack([np.stack([a11, a12, a13], -1), np.stack([a12, a22, a23], -1),
                     np.stack([a13, a23, a33], -1)], -2)


def _merge_in_file_order(data, parts):
    """parts: list of (line numbers, kind, ij, z, info); edges are appended in file order."""
    if not parts:
        return
    lines = np.concatenate([p[0] for p in parts])
    order = np.argsort(lines, kind="stable")
    flat = []
    for ln, kind, ij, z, info in parts:
        for t in range(len(ln)):
            flat.append((kind, int(ij[t, 0]), int(ij[t, 1]), z[t], info[t]))
    data.edges.extend(flat[i] for i in order)


def read_toro(path):
    """Read a TORO ``.graph`` file (VERTEX2, EDGE2, EQUIV ignored, and GTSAM's BR lines)."""
    data = GraphData(path)
    rec = _scan(path, {"VERTEX2": 4, "EDGE2": 11, "EQUIV": 2, "BR": 6})
    ln, v = rec["VERTEX2"]
    ids = _ids(path, "VERTEX2", ln, v[:, 0])
    data.poses = {int(i): v[t, 1:4].copy() for t, i in enumerate(ids)}
    parts = []
    ln, v = rec["EDGE2"]
    ij = _ids(path, "EDGE2", ln, v[:, :2])
    i11, i12, i22, i33, i13, i23 = v[:, 5:11].T
    info = _sym3(i11, i12, i13, i22, i23, i33)
    _check_spd_batch(path, "EDGE2", ln, info)
    parts.append((ln, "se2", ij, v[:, 2:5].copy(), info))
    ln, v = rec["BR"]
    ij = _ids(path, "BR", ln, v[:, :2])
    if (v[:, 4:6] <= 0).any():
        _fail(path, ln[int(np.argmax((v[:, 4:6] <= 0).any(axis=1)))], "BR: sigmas must be positive")
    z = np.stack([v[:, 3], v[:, 2]], axis=1)
    info = np.zeros((len(v), 2, 2))
    info[:, 0, 0] = 1.0 / v[:, 5] ** 2
    info[:, 1, 1] = 1.0 / v[:, 4] ** 2
    parts.append((ln, "rb", ij, z, info))
    _merge_in_file_order(data, parts)
    return data


def read_g2o(path):
    """Read a 2D g2o file (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX)."""
    data = GraphData(path)
    rec = _scan(path, {"VERTEX_SE2": 4, "VERTEX_XY": 3, "EDGE_SE2": 11, "EDGE_SE2_XY": 7, "FIX": 1})
    ln, v = rec["VERTEX_SE2"]
    data.poses = {int(i): v[t, 1:4].copy() for t, i in enumerate(_ids(path, "VERTEX_SE2", ln, v[:, 0]))}
    ln, v = rec["VERTEX_XY"]
    data.points = {int(i): v[t, 1:3].copy() for t, i in enumerate(_ids(path, "VERTEX_XY", ln, v[:, 0]))}
    ln, v = rec["FIX"]
    data.fixed = [int(i) for i in _ids(path, "FIX", ln, v[:, 0])]
    parts = []
    ln, v = rec["EDGE_SE2"]
    ij = _ids(path, "EDGE_SE2", ln, v[:, :2])
    info = _sym3(*v[:, 5:11].T)
    _check_spd_batch(path, "EDGE_SE2", ln, info)
    parts.append((ln, "se2", ij, v[:, 2:5].copy(), info))
    ln, v = rec["EDGE_SE2_XY"]
    ij = _ids(path, "EDGE_SE2_XY", ln, v[:, :2])
    info = np.stack([np.stack([v[:, 4], v[:, 5]], -1), np.stack([v[:, 5], v[:, 6]], -1)], -2)
    _check_spd_batch(path, "EDGE_SE2_XY", ln, info)
    parts.append((ln, "xy", ij, v[:, 2:4].copy(), info))
    _merge_in_file_order(data, parts)
    return data


def read_victoria_park(path):
    """Read GTSAM's victoria_park.txt (ODOMETRY with covariance, LANDMARK in Cartesian robot-frame coordinates)."""
    data = GraphData(path)
    rec = _scan(path, {"ODOMETRY": 11, "LANDMARK": 7})
    parts = []
    ln, v = rec["ODOMETRY"]
    ij = _ids(path, "ODOMETRY", ln, v[:, :2])
    cov = _sym3(*v[:, 5:11].T)
    _check_spd_batch(path, "ODOMETRY", ln, cov, "covariance")
    parts.append((ln, "se2", ij, v[:, 2:5].copy(), np.linalg.inv(cov) if len(cov) else cov))
    ln, v = rec["LANDMARK"]
    ij = _ids(path, "LANDMARK", ln, v[:, :2])
    if (v[:, 4] <= 0).any():
        _fail(path, ln[int(np.argmax(v[:, 4] <= 0))], "LANDMARK: c_xx must be positive")
    z = np.stack([np.hypot(v[:, 2], v[:, 3]), np.arctan2(v[:, 3], v[:, 2])], axis=1)
    info = np.zeros((len(v), 2, 2))
    info[:, 0, 0] = 1.0 / v[:, 4]
    info[:, 1, 1] = 10.0 / v[:, 4]
    parts.append((ln, "rb", ij, z, info))
    _merge_in_file_order(data, parts)
    return data


def _compose(p, z):
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], wrap_angle(p[2] + z[2])])


def _compose_inverse(p, z):
    """q with q ∘ z = p."""
    th = wrap_angle(p[2] - z[2])
    c, s = np.cos(th), np.sin(th)
    return np.array([p[0] - (c * z[0] - s * z[1]), p[1] - (s * z[0] + c * z[1]), th])


def _initial_values(data):
    poses = dict(data.poses)
    points = dict(data.points)
    for kind, i, j, z, _ in data.edges:
        if kind == "se2":
            if not poses:
                poses[i] = np.zeros(3)
            if i in poses and j not in poses:
                poses[j] = _compose(poses[i], z)
            elif j in poses and i not in poses:
                poses[i] = _compose_inverse(poses[j], z)
    for kind, i, j, z, _ in data.edges:
        if kind in ("rb", "xy") and j not in points:
            if i not in poses:
                raise ValueError(f"{data.source}: landmark {j} observed from pose {i}, which has no initial value")
            p = poses[i]
            if kind == "rb":
                local = z[0] * np.array([np.cos(z[1]), np.sin(z[1])])
            else:
                local = z
            c, s = np.cos(p[2]), np.sin(p[2])
            points[j] = p[:2] + np.array([c * local[0] - s * local[1], s * local[0] + c * local[1]])
    for kind, i, j, *_ in data.edges:
        if i not in poses or (kind == "se2" and j not in poses):
            raise ValueError(f"{data.source}: edge {kind} {i}-{j} refers to a pose without an initial value")
    return poses, points


def build_optimizer(data, fix_first=True, pose_class=VertexSE2):
    """A SparseOptimizer holding the dataset (pose vertices ``pose_class``, points VertexPointXY).

    ``pose_class=VertexSE2Exp`` gives GTSAM's Pose2 update (exponential map) instead of the coursework's additive one.
    """
    if not (isinstance(pose_class, type) and issubclass(pose_class, VertexSE2)):
        raise ValueError(f"pose_class must be VertexSE2 or a subclass, got {pose_class!r}")
    poses, points = _initial_values(data)
    opt = SparseOptimizer()
    pv, lv = {}, {}
    for pid in sorted(poses):
        v = pose_class(pid, poses[pid])
        opt.add_vertex(v)
        pv[pid] = v
    for lid in sorted(points):
        v = VertexPointXY(lid, points[lid])
        opt.add_vertex(v)
        lv[lid] = v
    kinds = {"se2": (EdgeSE2, pv, pv), "rb": (EdgeRangeBearing, pv, lv), "xy": (EdgeSE2PointXY, pv, lv)}
    grouped = {}
    for kind, i, j, z, info in data.edges:
        cls, a, b = kinds[kind]
        if i not in a or j not in b:
            raise ValueError(f"{data.source}: edge {kind} {i}-{j} refers to an unknown vertex")
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


def dataset_path(name):
    """Full path of a dataset shipped with the workbook (``data/datasets/<file>.gz``)."""
    if name not in DATASETS:
        raise ValueError(f"unknown dataset {name!r}; expected one of {sorted(DATASETS)}")
    return data_path("datasets", DATASETS[name])


def read_dataset(name):
    path = dataset_path(name)
    if name == "victoria_park":
        return read_victoria_park(path)
    return read_toro(path)


def load_dataset(name, pose_class=VertexSE2):
    """SparseOptimizer for "w100", "w10000", "victoria_park" or "example", first pose fixed, structure built."""
    opt = build_optimizer(read_dataset(name), pose_class=pose_class)
    opt.initialize_optimization()
    return opt


def pose_arrays(optimizer):
    """(pose ids, poses (N, 3), point ids, points (M, 2)) of a graph, in creation order."""
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
