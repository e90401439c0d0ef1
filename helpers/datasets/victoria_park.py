"""Reader of GTSAM's ``victoria_park.txt`` format (ODOMETRY with covariance, LANDMARK in the robot frame)."""

import numpy as np

from .graph_data import GraphData, initial_values, merge_in_file_order
from .records import check_distinct_ends, check_spd, fail, first_bad, ids, scan, sym3

__all__ = ["read_victoria_park"]

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


def read_victoria_park(path):
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
