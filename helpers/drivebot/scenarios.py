"""DriveBot scenarios: landmark maps and waypoint lists, stored as small CSV files in ``data/drivebot/``.

Every scenario starts at (0, 0) with heading 0. Layout::

    data/drivebot/<scenario>/landmarks.csv    header ``id,x,y``   (ids 1-based, ascending)
    data/drivebot/<scenario>/waypoints.csv    header ``x,y``      (visited in order)

Scenarios: ``q1_b``/``q1_c`` (70 m square to (70, 70)), ``q1_e`` (to (70, 0)), ``q2_b``/``q2_d`` (one loop),
``q1_d``/``q2_c`` (the loop four times), all with the base 7-landmark map; ``q3_a`` (four loops, 13
landmarks); ``large_map`` (200 landmarks uniform in [0, 100]², 20 waypoints). This module only *reads* them;
``python -m helpers.drivebot.scenario_files`` writes every file (deterministically).
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

from ..paths import data_path

__all__ = ["Scenario", "SCENARIO_NAMES", "load_scenario", "data_dir"]

SCENARIO_NAMES = ("q1_b", "q1_c", "q1_d", "q1_e", "q2_b", "q2_c", "q2_d", "q3_a", "large_map")


@dataclass(frozen=True)
class Scenario:
    """A map and a route. ``landmarks`` is 2×L (column l has id ``landmark_ids[l]``), ``waypoints`` 2×W."""

    name: str
    landmarks: np.ndarray
    landmark_ids: np.ndarray
    waypoints: np.ndarray

    def __post_init__(self):
        lm = np.asarray(self.landmarks, dtype=float)
        wp = np.asarray(self.waypoints, dtype=float)
        ids = np.asarray(self.landmark_ids)
        if lm.ndim != 2 or lm.shape[0] != 2 or not np.all(np.isfinite(lm)):
            raise ValueError(f"landmarks must be a finite 2×L array, got shape {lm.shape}")
        if ids.shape != (lm.shape[1],) or not np.issubdtype(ids.dtype, np.integer) or np.any(ids < 1) \
                or np.any(np.diff(ids) <= 0):
            raise ValueError("landmark_ids must be ascending positive integers, one per landmark column")
        if wp.ndim != 2 or wp.shape[0] != 2 or wp.shape[1] == 0 or not np.all(np.isfinite(wp)):
            raise ValueError(f"waypoints must be a finite 2×W array with W ≥ 1, got shape {wp.shape}")
        object.__setattr__(self, "landmarks", lm)
        object.__setattr__(self, "waypoints", wp)
        object.__setattr__(self, "landmark_ids", ids.astype(np.int64))


def data_dir() -> pathlib.Path:
    """``<repository>/data/drivebot``."""
    return data_path("drivebot")


def load_scenario(name: str) -> Scenario:
    """Read a scenario from ``data/drivebot/<name>/``; unknown names and unreadable, truncated or malformed files
    raise ValueError naming the file. A landmarks file may hold the header only (no landmarks)."""
    if not isinstance(name, str) or name not in SCENARIO_NAMES:
        raise ValueError(f"unknown scenario {name!r}; known scenarios: {list(SCENARIO_NAMES)}")
    folder = data_dir() / name
    lm = _read_table(folder / "landmarks.csv", "id,x,y", name)
    wp = _read_table(folder / "waypoints.csv", "x,y", name)
    if np.any(lm[:, 0] != np.round(lm[:, 0])):
        raise ValueError(f"scenario {name!r}: landmark ids in {folder / 'landmarks.csv'} must be integers")
    return Scenario(name, lm[:, 1:].T, lm[:, 0].astype(np.int64), wp.T)


def _read_table(path: pathlib.Path, header: str, name: str) -> np.ndarray:
    """The numeric rows (R, columns of ``header``) of a scenario CSV file that starts with ``header``."""
    columns = header.count(",") + 1
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
        if not lines or lines[0].strip() != header:
            raise ValueError(f"it must start with the header line {header!r}")
        body = [line for line in lines[1:] if line.strip()]
        table = np.loadtxt(body, delimiter=",", ndmin=2) if body else np.zeros((0, columns))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"cannot read scenario {name!r}: {path} is malformed: {exc}") from None
    if table.shape[1] != columns:
        raise ValueError(f"scenario {name!r}: {path} must have the {columns} columns {header}, got {table.shape[1]}")
    return table
