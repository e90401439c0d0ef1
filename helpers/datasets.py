"""Readers for the standard 2D pose-graph / SLAM datasets shipped in the gtsam wheel, and ``load_dataset``.

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

import pathlib

import numpy as np

from .graph import (EdgeRangeBearing, EdgeSE2, SparseOptimizer, VertexPointXY, VertexSE2, wrap_angle)
from .graph.edge import BaseEdge
from .graph.vertex import VertexPointXY as _VPXY, VertexSE2 as _VSE2

__all__ = ["GraphData", "read_toro", "read_g2o", "read_victoria_park", "dataset_path", "load_dataset",
           "build_optimizer", "EdgeSE2PointXY", "pose_arrays", "DATASETS"]

DATASETS = {"w100": "w100.graph", "w10000": "w10000.graph", "victoria_park": "victoria_park.txt",
            "example": "example.graph"}


class EdgeSE2PointXY(BaseEdge):
    """Point observed in the frame of a pose (g2o EDGE_SE2_XY): e = R(ψ)ᵀ(m − t) − z.

    J_x = [−R(ψ)ᵀ | [q_y, −q_x]ᵀ] with q = R(ψ)ᵀ(m − t);  J_m = R(ψ)ᵀ.
    """

    vertex_types = (_VSE2, _VPXY)
    measurement_dimension = 2

    @staticmethod
    def evaluate(states, z, params, jacobians=True):
        x, m = states
        c, s = np.cos(x[:, 2]), np.sin(x[:, 2])
        dx, dy = m[:, 0] - x[:, 0], m[:, 1] - x[:, 1]
        qx, qy = c * dx + s * dy, -s * dx + c * dy
        e = np.stack([qx - z[:, 0], qy - z[:, 1]], axis=1)
        if not jacobians:
            return e, None
        n = len(z)
        jm = np.empty((n, 2, 2))
        jm[:, 0, 0], jm[:, 0, 1], jm[:, 1, 0], jm[:, 1, 1] = c, s, -s, c
        jx = np.zeros((n, 2, 3))
        jx[:, :, :2] = -jm
        jx[:, 0, 2], jx[:, 1, 2] = qy, -qx
        return e, [jx, jm]


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


def _parse_numbers(path, lineno, fields, counts, tag):
    if len(fields) - 1 != counts:
        _fail(path, lineno, f"{tag} needs {counts} numbers, got {len(fields) - 1}")
    try:
        vals = [float(f) for f in fields[1:]]
    except ValueError:
        _fail(path, lineno, f"{tag}: not a number in {' '.join(fields[1:])!r}")
    if not np.all(np.isfinite(vals)):
        _fail(path, lineno, f"{tag}: non-finite value")
    return vals


def _int_id(path, lineno, value, tag):
    if value != int(value) or value < 0:
        _fail(path, lineno, f"{tag}: ids must be non-negative integers, got {value}")
    return int(value)


def _check_spd(path, lineno, mat, tag, what="information"):
    try:
        np.linalg.cholesky(mat)
    except np.linalg.LinAlgError:
        _fail(path, lineno, f"{tag}: {what} matrix is not positive definite")


def _lines(path):
    path = pathlib.Path(path)
    if not path.is_file():
        raise ValueError(f"dataset file not found: {path}")
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, start=1):
            fields = line.split()
            if not fields or fields[0].startswith("#"):
                continue
            yield lineno, fields


def read_toro(path):
    """Read a TORO ``.graph`` file (VERTEX2, EDGE2, EQUIV ignored, and GTSAM's BR lines)."""
    data = GraphData(path)
    for lineno, fields in _lines(path):
        tag = fields[0]
        if tag == "VERTEX2":
            v = _parse_numbers(path, lineno, fields, 4, tag)
            data.poses[_int_id(path, lineno, v[0], tag)] = np.array(v[1:4])
        elif tag == "EDGE2":
            v = _parse_numbers(path, lineno, fields, 11, tag)
            i, j = _int_id(path, lineno, v[0], tag), _int_id(path, lineno, v[1], tag)
            i11, i12, i22, i33, i13, i23 = v[5:11]
            info = np.array([[i11, i12, i13], [i12, i22, i23], [i13, i23, i33]])
            _check_spd(path, lineno, info, tag)
            data.edges.append(("se2", i, j, np.array(v[2:5]), info))
        elif tag == "BR":
            v = _parse_numbers(path, lineno, fields, 6, tag)
            i, l = _int_id(path, lineno, v[0], tag), _int_id(path, lineno, v[1], tag)
            bearing, rng, sb, sr = v[2:6]
            if sb <= 0 or sr <= 0:
                _fail(path, lineno, "BR: sigmas must be positive")
            data.edges.append(("rb", i, l, np.array([rng, bearing]), np.diag([1 / sr ** 2, 1 / sb ** 2])))
        elif tag == "EQUIV":
            _parse_numbers(path, lineno, fields, 2, tag)
        else:
            _fail(path, lineno, f"unknown record {tag!r} (expected VERTEX2, EDGE2, EQUIV or BR)")
    return data


def read_g2o(path):
    """Read a 2D g2o file (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX)."""
    data = GraphData(path)
    for lineno, fields in _lines(path):
        tag = fields[0]
        if tag == "VERTEX_SE2":
            v = _parse_numbers(path, lineno, fields, 4, tag)
            data.poses[_int_id(path, lineno, v[0], tag)] = np.array(v[1:4])
        elif tag == "VERTEX_XY":
            v = _parse_numbers(path, lineno, fields, 3, tag)
            data.points[_int_id(path, lineno, v[0], tag)] = np.array(v[1:3])
        elif tag == "EDGE_SE2":
            v = _parse_numbers(path, lineno, fields, 11, tag)
            i, j = _int_id(path, lineno, v[0], tag), _int_id(path, lineno, v[1], tag)
            a11, a12, a13, a22, a23, a33 = v[5:11]
            info = np.array([[a11, a12, a13], [a12, a22, a23], [a13, a23, a33]])
            _check_spd(path, lineno, info, tag)
            data.edges.append(("se2", i, j, np.array(v[2:5]), info))
        elif tag == "EDGE_SE2_XY":
            v = _parse_numbers(path, lineno, fields, 7, tag)
            i, j = _int_id(path, lineno, v[0], tag), _int_id(path, lineno, v[1], tag)
            a11, a12, a22 = v[4:7]
            info = np.array([[a11, a12], [a12, a22]])
            _check_spd(path, lineno, info, tag)
            data.edges.append(("xy", i, j, np.array(v[2:4]), info))
        elif tag == "FIX":
            v = _parse_numbers(path, lineno, fields, 1, tag)
            data.fixed.append(_int_id(path, lineno, v[0], tag))
        else:
            _fail(path, lineno, f"unknown record {tag!r} (expected VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX)")
    return data


def read_victoria_park(path):
    """Read GTSAM's victoria_park.txt (ODOMETRY with covariance, LANDMARK in Cartesian robot-frame coordinates)."""
    data = GraphData(path)
    for lineno, fields in _lines(path):
        tag = fields[0]
        if tag == "ODOMETRY":
            v = _parse_numbers(path, lineno, fields, 11, tag)
            i, j = _int_id(path, lineno, v[0], tag), _int_id(path, lineno, v[1], tag)
            cxx, cxy, cxt, cyy, cyt, ctt = v[5:11]
            cov = np.array([[cxx, cxy, cxt], [cxy, cyy, cyt], [cxt, cyt, ctt]])
            _check_spd(path, lineno, cov, tag, "covariance")
            data.edges.append(("se2", i, j, np.array(v[2:5]), np.linalg.inv(cov)))
        elif tag == "LANDMARK":
            v = _parse_numbers(path, lineno, fields, 7, tag)
            i, l = _int_id(path, lineno, v[0], tag), _int_id(path, lineno, v[1], tag)
            x, y, cxx = v[2], v[3], v[4]
            if cxx <= 0:
                _fail(path, lineno, "LANDMARK: c_xx must be positive")
            z = np.array([np.hypot(x, y), np.arctan2(y, x)])
            data.edges.append(("rb", i, l, z, np.diag([1.0 / cxx, 10.0 / cxx])))
        else:
            _fail(path, lineno, f"unknown record {tag!r} (expected ODOMETRY or LANDMARK)")
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


def build_optimizer(data, fix_first=True):
    """A SparseOptimizer holding the dataset (pose vertices VertexSE2, points VertexPointXY)."""
    poses, points = _initial_values(data)
    opt = SparseOptimizer()
    pv, lv = {}, {}
    for pid in sorted(poses):
        v = VertexSE2(pid, poses[pid])
        opt.add_vertex(v)
        pv[pid] = v
    for lid in sorted(points):
        v = VertexPointXY(lid, points[lid])
        opt.add_vertex(v)
        lv[lid] = v
    kinds = {"se2": (EdgeSE2, pv, pv), "rb": (EdgeRangeBearing, pv, lv), "xy": (EdgeSE2PointXY, pv, lv)}
    for kind, i, j, z, info in data.edges:
        cls, a, b = kinds[kind]
        if i not in a or j not in b:
            raise ValueError(f"{data.source}: edge {kind} {i}-{j} refers to an unknown vertex")
        opt.add_edge(cls([a[i], b[j]], measurement=z, information=info))
    fixed = list(data.fixed)
    if fix_first and not fixed and pv:
        fixed = [min(pv)]
    for fid in fixed:
        (pv.get(fid) or lv[fid]).set_fixed(True)
    return opt


def dataset_path(name):
    """Full path of a dataset shipped in the gtsam wheel (via gtsam.findExampleDataFile)."""
    if name not in DATASETS:
        raise ValueError(f"unknown dataset {name!r}; expected one of {sorted(DATASETS)}")
    import gtsam

    return gtsam.findExampleDataFile(DATASETS[name])


def read_dataset(name):
    path = dataset_path(name)
    if name == "victoria_park":
        return read_victoria_park(path)
    return read_toro(path)


def load_dataset(name):
    """SparseOptimizer for "w100", "w10000", "victoria_park" or "example", first pose fixed, structure built."""
    opt = build_optimizer(read_dataset(name))
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
