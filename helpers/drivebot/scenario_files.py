"""Generating and writing the DriveBot scenario files in ``data/drivebot/`` (the reading side is ``scenarios``).

The hand-made scenarios are the lists in ``SCENARIO_DEFINITIONS``. The large map is drawn once from a fixed seed
(:func:`generate_large_map`); placing its last waypoint needs noise-free runs of the simulator, which is why this
module sits above both ``scenarios`` and ``simulator``.

``python -m helpers.drivebot.scenario_files`` rewrites every file (deterministically).
"""
from __future__ import annotations

import os
import pathlib

import numpy as np

from ..validation import boolean, integer
from .config import SimulatorConfiguration
from .scenarios import SCENARIO_NAMES, Scenario, data_dir
from .simulator import DriveBotSimulator

__all__ = ["generate_large_map", "write_scenario_files", "ticks_to_finish", "SCENARIO_DEFINITIONS", "LARGE_MAP_SEED"]

BASE_LANDMARKS = [(2, 2), (5, 3), (42, 3), (60, 2), (73, 10), (66, 68), (3, 27)]
Q3A_EXTRA_LANDMARKS = [(67, 48), (71, 35), (49, 71), (18, 58), (21, 17), (10, 45)]
ONE_LOOP = [(70, 0), (70, 70), (0, 70), (0, 0)]
LARGE_MAP_FIRST_WAYPOINTS = [(49.16, 54.47), (28.82, 16.58), (65.67, 50.65)]
#: Seed of the one-off draw of the large map (landmarks and waypoints 4–20); see generate_large_map.
LARGE_MAP_SEED = 20240229
#: The coursework's large-map run length; the last waypoint is placed to reproduce it.
LARGE_MAP_RUN_LENGTH = 5667

#: name → (landmarks [(x, y), …], waypoints [(x, y), …]) of every hand-made scenario (large_map is drawn).
SCENARIO_DEFINITIONS = {
    "q1_b": (BASE_LANDMARKS, ONE_LOOP[:2]),
    "q1_c": (BASE_LANDMARKS, ONE_LOOP[:2]),
    "q1_e": (BASE_LANDMARKS, ONE_LOOP[:1]),
    "q1_d": (BASE_LANDMARKS, ONE_LOOP * 4),
    "q2_b": (BASE_LANDMARKS, ONE_LOOP),
    "q2_c": (BASE_LANDMARKS, ONE_LOOP * 4),
    "q2_d": (BASE_LANDMARKS, ONE_LOOP),
    "q3_a": (BASE_LANDMARKS + Q3A_EXTRA_LANDMARKS, ONE_LOOP * 4),
}

_RUN_CAP = 20_000  # a route whose waypoint the controller cannot reach (it orbits it) counts as this long


def ticks_to_finish(waypoints: np.ndarray) -> int:
    """Number of processed ticks N of a noise-free, sensor-free run along ``waypoints`` (2×W, capped)."""
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
    uniform point q (up to ``max_tries`` q are drawn in turn), at the fraction α ∈ [0, 1] found by bisection so
    that the run has exactly ``run_length`` ticks (the coursework's 5667). The truth is deterministic, so so is
    N. Landmarks are drawn first, then the waypoints, from one Generator(seed).
    """
    seed = integer(seed, "seed", minimum=0)
    run_length = integer(run_length, "run_length", minimum=1)
    max_tries = integer(max_tries, "max_tries", minimum=1)
    rng = np.random.default_rng(seed)
    landmarks = np.round(rng.uniform(0.0, 100.0, size=(2, 200)), 3)
    rest = np.round(rng.uniform(5.0, 95.0, size=(2, 16)), 2)
    head = np.hstack([np.asarray(LARGE_MAP_FIRST_WAYPOINTS, dtype=float).T, rest])
    n_head = ticks_to_finish(head)
    for _ in range(max_tries):  # candidate directions for the last leg, drawn in turn
        q = np.round(rng.uniform(5.0, 95.0, size=2), 2)

        def route(alpha, q=q):
            return np.hstack([head, (head[:, -1] + alpha * (q - head[:, -1]))[:, None]])

        lo, hi = 0.0, 1.0
        if not n_head <= run_length <= ticks_to_finish(route(hi)):
            continue
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            n = ticks_to_finish(route(mid))
            if n == run_length:
                return landmarks, route(mid)
            lo, hi = (mid, hi) if n < run_length else (lo, mid)
    raise ValueError(f"seed {seed}: no last waypoint found giving exactly run_length {run_length}")


def _write(folder: pathlib.Path, landmarks: np.ndarray, waypoints: np.ndarray) -> None:
    """Write one scenario's two files; each is written to a temporary file first and then renamed, so an
    interrupted write never leaves a truncated file."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"cannot create the scenario folder {folder}: {exc}") from None
    ids = np.arange(1, landmarks.shape[1] + 1)
    lm_text = "id,x,y\n" + "".join(f"{i},{x:g},{y:g}\n" for i, (x, y) in zip(ids, landmarks.T))
    wp_text = "x,y\n" + "".join(f"{float(x)!r},{float(y)!r}\n" for x, y in waypoints.T)
    for file_name, text in (("landmarks.csv", lm_text), ("waypoints.csv", wp_text)):
        target = folder / file_name
        tmp = folder / f".{file_name}.tmp"
        try:
            with open(tmp, "w", encoding="utf-8", newline="\n") as f:
                f.write(text)
            os.replace(tmp, target)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise


def write_scenario_files(root: pathlib.Path | None = None, large_map: bool = True) -> None:
    """(Re)write every scenario's CSV files under ``root`` (default: ``data_dir()``).

    ``large_map=False`` skips the large map (its bisection runs the simulator a few dozen times)."""
    large_map = boolean(large_map, "large_map")
    try:
        root = data_dir() if root is None else pathlib.Path(root)
    except TypeError:
        raise ValueError(f"root must be a directory path or None, got {root!r}") from None
    if root.exists() and not root.is_dir():
        raise ValueError(f"root must be a directory, but {root} is a file")
    for name, (lm, wp) in SCENARIO_DEFINITIONS.items():
        _write(root / name, np.asarray(lm, dtype=float).T, np.asarray(wp, dtype=float).T)
    if large_map:
        _write(root / "large_map", *generate_large_map())


if __name__ == "__main__":
    write_scenario_files()
    print(f"wrote {len(SCENARIO_NAMES)} scenarios to {data_dir()}")
