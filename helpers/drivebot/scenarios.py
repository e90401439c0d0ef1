"""DriveBot scenarios: landmark maps and waypoint lists, stored as small CSV files in ``data/drivebot/``.

Every scenario starts at (0, 0) with heading 0. Layout::

    data/drivebot/<scenario>/landmarks.csv    header ``id,x,y``   (ids 1-based, ascending)
    data/drivebot/<scenario>/waypoints.csv    header ``x,y``      (visited in order)

Scenarios: ``q1_b``/``q1_c`` (70 m square to (70, 70)), ``q1_e`` (to (70, 0)), ``q2_b``/``q2_d`` (one loop),
``q1_d``/``q2_c`` (the loop four times), all with the base 7-landmark map; ``q3_a`` (four loops, 13
landmarks); ``large_map`` (200 landmarks uniform in [0, 100]², 20 waypoints, the first three fixed by the
coursework, the rest drawn once with a fixed seed by :func:`generate_large_map`, which places the last waypoint so
that the run has the coursework's 5667 ticks).

``python -m helpers.drivebot.scenarios`` rewrites every file (deterministically).
"""
from __future__ import annotations

import pathlib
from dataclasses import dataclass

import numpy as np

from ..paths import data_path

__all__ = ["Scenario", "SCENARIO_NAMES", "load_scenario", "data_dir", "write_scenario_files",
           "generate_large_map", "LARGE_MAP_SEED"]

BASE_LANDMARKS = [(2, 2), (5, 3), (42, 3), (60, 2), (73, 10), (66, 68), (3, 27)]
Q3A_EXTRA_LANDMARKS = [(67, 48), (71, 35), (49, 71), (18, 58), (21, 17), (10, 45)]
ONE_LOOP = [(70, 0), (70, 70), (0, 70), (0, 0)]
LARGE_MAP_FIRST_WAYPOINTS = [(49.16, 54.47), (28.82, 16.58), (65.67, 50.65)]
#: Seed of the one-off draw of the large map (landmarks and waypoints 4–20); see generate_large_map.
LARGE_MAP_SEED = 20240229
#: The coursework's large-map run length; the last waypoint is placed to reproduce it.
LARGE_MAP_RUN_LENGTH = 5667

_DEFINITIONS = {
    "q1_b": (BASE_LANDMARKS, ONE_LOOP[:2]),
    "q1_c": (BASE_LANDMARKS, ONE_LOOP[:2]),
    "q1_e": (BASE_LANDMARKS, ONE_LOOP[:1]),
    "q1_d": (BASE_LANDMARKS, ONE_LOOP * 4),
    "q2_b": (BASE_LANDMARKS, ONE_LOOP),
    "q2_c": (BASE_LANDMARKS, ONE_LOOP * 4),
    "q2_d": (BASE_LANDMARKS, ONE_LOOP),
    "q3_a": (BASE_LANDMARKS + Q3A_EXTRA_LANDMARKS, ONE_LOOP * 4),
}
SCENARIO_NAMES = tuple(sorted(_DEFINITIONS)) + ("large_map",)


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
    """Read a scenario from ``data/drivebot/<name>/``; unknown names raise ValueError."""
    if name not in SCENARIO_NAMES:
        raise ValueError(f"unknown scenario {name!r}; known scenarios: {list(SCENARIO_NAMES)}")
    folder = data_dir() / name
    try:
        lm = np.loadtxt(folder / "landmarks.csv", delimiter=",", skiprows=1, ndmin=2)
        wp = np.loadtxt(folder / "waypoints.csv", delimiter=",", skiprows=1, ndmin=2)
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read scenario {name!r} from {folder}: {exc}") from None
    if lm.shape[1] != 3 or wp.shape[1] != 2:
        raise ValueError(f"scenario {name!r}: landmarks.csv needs columns id,x,y and waypoints.csv x,y")
    return Scenario(name, lm[:, 1:].T, lm[:, 0].astype(np.int64), wp.T)


_RUN_CAP = 20_000  # a route whose waypoint the controller cannot reach (it orbits it) counts as this long


def _run_length(waypoints: np.ndarray) -> int:
    """Number of processed ticks N of a noise-free, sensor-free run along ``waypoints`` (capped)."""
    from .config import SimulatorConfiguration
    from .simulator import DriveBotSimulator

    sim = DriveBotSimulator(SimulatorConfiguration(perturb_with_noise=False, maximum_step_number=_RUN_CAP),
                            Scenario("probe", np.zeros((2, 0)), np.zeros(0, dtype=np.int64), waypoints), seed=0)
    sim.start()
    n = 0
    while sim.keep_running():
        n += 1
        sim.step()
    return n


def generate_large_map(seed: int = LARGE_MAP_SEED, run_length: int = LARGE_MAP_RUN_LENGTH, max_tries: int = 20):
    """The large map, drawn once: (landmarks 2×200 uniform in [0, 100]², waypoints 2×20).

    The first three waypoints are the coursework's (49.16, 54.47), (28.82, 16.58), (65.67, 50.65);
    waypoints 4–19 are uniform in [5, 95]²; the 20th lies on the segment from the 19th towards a further
    uniform point q (up to ``max_tries`` q are drawn in turn), at the fraction α ∈ [0, 1] found by bisection so that the run has exactly
    ``run_length`` ticks (the coursework's 5667). The truth is deterministic, so so is N. Landmarks are
    drawn first, then the waypoints, from one Generator(seed).
    """
    rng = np.random.default_rng(seed)
    landmarks = np.round(rng.uniform(0.0, 100.0, size=(2, 200)), 3)
    rest = np.round(rng.uniform(5.0, 95.0, size=(2, 16)), 2)
    head = np.hstack([np.asarray(LARGE_MAP_FIRST_WAYPOINTS, dtype=float).T, rest])
    n_head = _run_length(head)
    for _ in range(max_tries):  # candidate directions for the last leg, drawn in turn
        q = np.round(rng.uniform(5.0, 95.0, size=2), 2)

        def route(alpha, q=q):
            return np.hstack([head, (head[:, -1] + alpha * (q - head[:, -1]))[:, None]])

        lo, hi = 0.0, 1.0
        if not n_head <= run_length <= _run_length(route(hi)):
            continue
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            n = _run_length(route(mid))
            if n == run_length:
                return landmarks, route(mid)
            lo, hi = (mid, hi) if n < run_length else (lo, mid)
    raise ValueError(f"seed {seed}: no last waypoint found giving exactly run_length {run_length}")


def _write(folder: pathlib.Path, landmarks: np.ndarray, waypoints: np.ndarray) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    ids = np.arange(1, landmarks.shape[1] + 1)
    with open(folder / "landmarks.csv", "w", encoding="utf-8", newline="\n") as f:
        f.write("id,x,y\n")
        for i, (x, y) in zip(ids, landmarks.T):
            f.write(f"{i},{x:g},{y:g}\n")
    with open(folder / "waypoints.csv", "w", encoding="utf-8", newline="\n") as f:
        f.write("x,y\n")
        for x, y in waypoints.T:
            f.write(f"{float(x)!r},{float(y)!r}\n")


def write_scenario_files(root: pathlib.Path | None = None) -> None:
    """(Re)write every scenario's CSV files under ``root`` (default: ``data_dir()``)."""
    root = data_dir() if root is None else pathlib.Path(root)
    for name, (lm, wp) in _DEFINITIONS.items():
        _write(root / name, np.asarray(lm, dtype=float).T, np.asarray(wp, dtype=float).T)
    _write(root / "large_map", *generate_large_map())


if __name__ == "__main__":
    # use the package's module (not this __main__ copy) so the classes are the ones the simulator checks
    from helpers.drivebot import scenarios as _scenarios

    _scenarios.write_scenario_files()
    print(f"wrote {len(SCENARIO_NAMES)} scenarios to {data_dir()}")
