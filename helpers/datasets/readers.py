"""Readers of the TORO ``.graph``, 2-D g2o and Victoria Park formats (formats and conventions: the package
docstring)."""
from __future__ import annotations

import os

import numpy as np

from .graph_data import GraphData, initial_values, merge_in_file_order
from .records import check_distinct_ends, check_spd, check_unique, fail, first_bad, ids, scan, sym3

__all__ = ["read_toro", "read_g2o", "read_victoria_park"]

_TORO = {"VERTEX2": 4, "EDGE2": 11, "EQUIV": 2, "BR": 6}
_G2O = {"VERTEX_SE2": 4, "VERTEX_XY": 3, "EDGE_SE2": 11, "EDGE_SE2_XY": 7, "FIX": 1, "LANDMARK2": 7,
        "VERTEX2": 4, "EDGE2": 11}


def _edge2_information(path, lines, v):
    """EDGE2's six information numbers, in TORO order (I11 I12 I22 I33 I13 I23) unless the file's matrices are
    all diagonal in g2o order (I11 0 0 I22 0 I33), as GTSAM's NoiseFormatAUTO decides (w100_30.g2o, w20000.txt).
    A valid TORO file never has that pattern (I22 would be 0); a file with both patterns is an error."""
    nz = v != 0
    toro_diag = nz[:, 0] & ~nz[:, 1] & nz[:, 2] & nz[:, 3] & ~nz[:, 4] & ~nz[:, 5]
    g2o_diag = nz[:, 0] & ~nz[:, 1] & ~nz[:, 2] & nz[:, 3] & ~nz[:, 4] & nz[:, 5]
    if g2o_diag.any() and not toro_diag.any():
        return sym3(*v.T)
    if g2o_diag.any():
        fail(path, lines[first_bad(g2o_diag)], "EDGE2: information in g2o order (I11 0 0 I22 0 I33), but line "
                                               f"{lines[first_bad(toro_diag)]} is in TORO order: mixed layouts")
    i11, i12, i22, i33, i13, i23 = v.T
    return sym3(i11, i12, i13, i22, i23, i33)


def _pose_edges(path, tag, ln, v, info):
    """(lines, "se2", ij, z, information) of EDGE2 / EDGE_SE2 records, checked."""
    ij = ids(path, tag, ln, v[:, :2])
    check_distinct_ends(path, tag, ln, ij)
    check_spd(path, tag, ln, info)
    return ln, "se2", ij, v[:, 2:5].copy(), info


def _poses(path, rec, tags):
    """{id: [x, y, θ]} of the VERTEX records of ``tags`` (in file order), ids unique; and their lines."""
    ln = np.concatenate([rec[t][0] for t in tags])
    v = np.concatenate([rec[t][1] for t in tags])
    order = np.argsort(ln, kind="stable")
    ln, v = ln[order], v[order]
    pid = ids(path, "/".join(tags), ln, v[:, 0])
    check_unique(path, "pose", pid, ln)
    return {int(i): v[t, 1:4].copy() for t, i in enumerate(pid)}, ln


def _require_records(path, data):
    if not data.poses and not data.points and not data.edges:
        fail(path, None, "has no vertex or edge records")


def read_toro(path: str | os.PathLike) -> GraphData:
    """Read a TORO ``.graph`` file (VERTEX2, EDGE2, EQUIV ignored, and GTSAM's BR lines)."""
    data = GraphData(path)
    rec = scan(path, _TORO)
    data.poses, _ = _poses(path, rec, ["VERTEX2"])
    ln, v = rec["EDGE2"]
    parts = [_pose_edges(path, "EDGE2", ln, v, _edge2_information(path, ln, v[:, 5:11]))]
    ln, v = rec["BR"]
    ij = ids(path, "BR", ln, v[:, :2])
    if (v[:, 4:6] <= 0).any():
        fail(path, ln[first_bad(v[:, 4:6] <= 0)], "BR: sigmas must be positive")
    if (v[:, 3] <= 0).any():
        fail(path, ln[first_bad(v[:, 3] <= 0)], "BR: the range must be positive (a negative one is impossible; "
                                                 "at range 0 the landmark sits on the sensor and its bearing is "
                                                 "undefined)")
    z = np.stack([v[:, 3], v[:, 2]], axis=1)
    info = np.zeros((len(v), 2, 2))
    info[:, 0, 0] = 1.0 / v[:, 5] ** 2
    info[:, 1, 1] = 1.0 / v[:, 4] ** 2
    parts.append((ln, "rb", ij, z, info))
    merge_in_file_order(data, parts)
    _require_records(path, data)
    initial_values(data)
    return data


def _g2o_points(path, rec, poses):
    """{id: [x, y]} of VERTEX_XY; ids unique and not pose ids (g2o vertices share one id space)."""
    ln, v = rec["VERTEX_XY"]
    lid = ids(path, "VERTEX_XY", ln, v[:, 0])
    check_unique(path, "point", lid, ln)
    both = np.isin(lid, list(poses))
    if both.any():
        fail(path, ln[first_bad(both)], f"VERTEX_XY {lid[first_bad(both)]}: a pose has this id already "
                                        "(g2o vertices share one id space)")
    return {int(i): v[t, 1:3].copy() for t, i in enumerate(lid)}


def _point_edges(path, tag, ln, v):
    """(lines, "xy", ij, z, information) of EDGE_SE2_XY / LANDMARK2 records (I11 I12 I22), checked."""
    ij = ids(path, tag, ln, v[:, :2])
    info = np.stack([np.stack([v[:, 4], v[:, 5]], -1), np.stack([v[:, 5], v[:, 6]], -1)], -2)
    check_spd(path, tag, ln, info)
    return ln, "xy", ij, v[:, 2:4].copy(), info


def _check_g2o_ids(path, data, rec, parts):
    """g2o's one id space (``parts``: the g2o edges, not LANDMARK2): pose–pose edges join poses, point edges go
    from a pose to a point; FIX names a vertex of the file. Returns the FIX ids."""
    points = np.array(sorted(data.points), dtype=np.int64)
    pose_ids = set(data.poses)
    for _, kind, ij, *_ in parts:
        if kind == "se2":
            pose_ids.update(ij.ravel().tolist())
    poses = np.array(sorted(pose_ids), dtype=np.int64)
    for ln, kind, ij, *_ in parts:
        if kind == "se2" and np.isin(ij, points).any():
            t = first_bad(np.isin(ij, points))
            i, j = ij[t].tolist()
            fail(path, ln[t], f"relative-pose edge {i} → {j} joins the point {i if i in points else j}")
        if kind == "xy" and np.isin(ij[:, 0], points).any():
            t = first_bad(np.isin(ij[:, 0], points))
            fail(path, ln[t], f"point edge {ij[t, 0]} → {ij[t, 1]} starts at the point {ij[t, 0]} (it must start "
                              "at a pose)")
        if kind == "xy" and np.isin(ij[:, 1], poses).any():
            t = first_bad(np.isin(ij[:, 1], poses))
            fail(path, ln[t], f"point edge {ij[t, 0]} → {ij[t, 1]} ends at the pose {ij[t, 1]} (it must end at a "
                              "point)")
    observed = set(data.points)
    for _, kind, ij, *_ in parts:
        if kind == "xy":
            observed.update(ij[:, 1].tolist())
    ln, v = rec["FIX"]
    fixed = [int(i) for i in ids(path, "FIX", ln, v[:, 0])]
    for t, fid in enumerate(fixed):
        if fid not in pose_ids and fid not in observed:
            fail(path, ln[t], f"FIX {fid}: the file has no vertex {fid}")
    return fixed


def read_g2o(path: str | os.PathLike) -> GraphData:
    """Read a 2-D g2o file (VERTEX_SE2, VERTEX_XY, EDGE_SE2, EDGE_SE2_XY, FIX; GTSAM's LANDMARK2; TORO's
    VERTEX2 and EDGE2, which GTSAM's readG2o also reads)."""
    data = GraphData(path)
    rec = scan(path, _G2O)
    data.poses, _ = _poses(path, rec, ["VERTEX_SE2", "VERTEX2"])
    data.points = _g2o_points(path, rec, data.poses)
    ln, v = rec["EDGE_SE2"]
    parts = [_pose_edges(path, "EDGE_SE2", ln, v, sym3(*v[:, 5:11].T))]
    ln, v = rec["EDGE2"]
    parts.append(_pose_edges(path, "EDGE2", ln, v, _edge2_information(path, ln, v[:, 5:11])))
    parts.append(_point_edges(path, "EDGE_SE2_XY", *rec["EDGE_SE2_XY"]))
    data.fixed = _check_g2o_ids(path, data, rec, parts)
    landmarks = _point_edges(path, "LANDMARK2", *rec["LANDMARK2"])
    if len(landmarks[0]) and (data.points or len(parts[2][0])):
        fail(path, landmarks[0][0], "LANDMARK2 landmarks have their own id space, but the file also has "
                                    "VERTEX_XY / EDGE_SE2_XY points (in the g2o id space): ambiguous")
    merge_in_file_order(data, parts + [landmarks])
    _require_records(path, data)
    initial_values(data)
    return data


#: GTSAM's load2D takes a LANDMARK covariance as isotropic when |c_xx − c_yy| < 1e-4
_ISOTROPY_TOLERANCE = 1e-4


def _check_landmarks(path, ln, v):
    """c_xx > 0; isotropic (c_xy = 0, c_xx ≈ c_yy: the only case load2D converts); not at the sensor."""
    if (v[:, 4] <= 0).any():
        fail(path, ln[first_bad(v[:, 4] <= 0)], "LANDMARK: c_xx must be positive")
    aniso = (v[:, 5] != 0) | ~(np.abs(v[:, 4] - v[:, 6]) < _ISOTROPY_TOLERANCE)
    if aniso.any():
        t = first_bad(aniso)
        fail(path, ln[t], f"LANDMARK: the covariance must be isotropic (c_xy = 0, c_xx = c_yy), got "
                          f"{v[t, 4]:g} {v[t, 5]:g} {v[t, 6]:g}; load2D's range-bearing conversion needs it")
    at_sensor = (v[:, 2] == 0) & (v[:, 3] == 0)
    if at_sensor.any():
        fail(path, ln[first_bad(at_sensor)], "LANDMARK: the landmark is at (0, 0), on the sensor: its bearing is "
                                             "undefined")


def read_victoria_park(path: str | os.PathLike) -> GraphData:
    """Read GTSAM's victoria_park.txt (ODOMETRY with covariance, LANDMARK in Cartesian robot-frame coordinates)."""
    data = GraphData(path)
    rec = scan(path, {"ODOMETRY": 11, "LANDMARK": 7})
    parts = []
    ln, v = rec["ODOMETRY"]
    ij = ids(path, "ODOMETRY", ln, v[:, :2])
    check_distinct_ends(path, "ODOMETRY", ln, ij)
    cov = sym3(*v[:, 5:11].T)
    check_spd(path, "ODOMETRY", ln, cov, "covariance")
    parts.append((ln, "se2", ij, v[:, 2:5].copy(), np.linalg.inv(cov) if len(cov) else cov))
    ln, v = rec["LANDMARK"]
    ij = ids(path, "LANDMARK", ln, v[:, :2])
    _check_landmarks(path, ln, v)
    z = np.stack([np.hypot(v[:, 2], v[:, 3]), np.arctan2(v[:, 3], v[:, 2])], axis=1)
    info = np.zeros((len(v), 2, 2))
    info[:, 0, 0] = 1.0 / v[:, 4]
    info[:, 1, 1] = 10.0 / v[:, 4]
    parts.append((ln, "rb", ij, z, info))
    merge_in_file_order(data, parts)
    if not data.edges:
        fail(path, None, "has no ODOMETRY or LANDMARK records")
    initial_values(data)
    return data
