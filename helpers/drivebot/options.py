"""Validation of the DriveBot SLAM system's options (``DriveBotSLAMSystem.__setattr__`` runs these checks on
construction and on every later assignment, so an option can never hold a value the system cannot use).

``check_period`` is the optimisation-period rule shared with the runner. ``MIN_TICK``: events less than
``_MERGE_TIME`` (1 ms) apart share one vehicle vertex, so a simulator tick must be at least 2 ms long.

``check_effective`` (``run_question``): an option changed from the question's own value must act on the run — one
that acts through a disabled sensor, or ``keep_first_prediction_edge`` without ``remove_prediction_edges``, would
be silently ignored, so it raises ValueError saying how to enable it.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from ..graph import EdgeHeadingPrior
from ..validation import boolean, function, one_of
from .config import SimulatorConfiguration
from .edges import BuggyCompassEdge
from .events import EventType

__all__ = ["check_period", "check_effective", "MIN_TICK", "SENSOR_OPTIONS"]

#: Events closer than this (s) share one vehicle vertex.
_MERGE_TIME = 1e-3
#: The shortest simulator tick a SLAM system accepts (s).
MIN_TICK = 2 * _MERGE_TIME
#: The event types of the observation sensors and their configuration flags.
_SENSOR_FLAGS = {EventType.COMPASS: "enable_compass", EventType.GPS: "enable_gps", EventType.LANDMARK: "enable_laser"}
#: Options of ``run_question`` (configuration fields, SLAM options, its own arguments) that act only through one
#: sensor: its flag → (sensor, the options).
SENSOR_OPTIONS = {
    "enable_compass": ("compass", ("compass_edge", "compass_angular_offset", "compass_measurement_period",
                                   "r_compass")),
    "enable_gps": ("GPS", ("gps_measurement_period", "r_gps", "gps_position_offset")),
    "enable_laser": ("laser", ("laser_measurement_period", "laser_detection_range", "r_laser")),
}


def check_period(period, name="optimization_period"):
    """None / inf → None (optimise only at the end); a positive integer → int; anything else ValueError."""
    if period is None:
        return None
    if isinstance(period, float) and math.isinf(period) and period > 0:
        return None
    if isinstance(period, bool) or not isinstance(period, numbers.Integral) or period <= 0:
        raise ValueError(f"{name} must be a positive integer number of steps, None or inf, got {period!r}")
    return int(period)


def _check_config(system, config):
    if "config" in system.__dict__:
        raise ValueError("config cannot be replaced after construction (the graph was built with it); "
                         "make a new DriveBotSLAMSystem")
    if not isinstance(config, SimulatorConfiguration):
        raise ValueError(f"config must be a SimulatorConfiguration, got {type(config).__name__}")
    if config.dt < MIN_TICK:
        raise ValueError(f"config.dt must be at least {MIN_TICK:g} s: events less than {_MERGE_TIME:g} s apart "
                         f"share one vehicle vertex, got dt = {config.dt!r}")
    return config


def _check_compass_edge(system, value):
    value = one_of(value, "compass_edge", ("fixed", "buggy"))
    object.__setattr__(system, "_compass_class", BuggyCompassEdge if value == "buggy" else EdgeHeadingPrior)
    return value


def _check_remove_prediction_edges(system, value):
    value = boolean(value, "remove_prediction_edges")
    config = system.__dict__.get("config")
    if value and config is not None and not any(getattr(config, f) for f in _SENSOR_FLAGS.values()):
        raise ValueError("remove_prediction_edges=True needs an observation sensor (enable_compass, enable_gps or "
                         "enable_laser): with odometry only the prediction edges are the whole graph, so removing "
                         "them leaves no edge to optimise")
    return value


#: attribute name → check(system, value) returning the value to store
_OPTION_CHECKS = {
    "config": _check_config,
    "optimization_period": lambda system, value: check_period(value),
    "compass_edge": _check_compass_edge,
    "remove_prediction_edges": _check_remove_prediction_edges,
    "keep_first_prediction_edge": lambda system, value: boolean(value, "keep_first_prediction_edge"),
    "pre_optimization_hook": lambda system, value: function(value, "pre_optimization_hook", allow_none=True),
    "optimization_algorithm": lambda system, value: one_of(value, "optimization_algorithm",
                                                           system.graph_class.ALGORITHMS),
}


def check_effective(changed, config, slam, where: str = "run_question") -> None:
    """ValueError for the first option named in ``changed`` (the options given a value other than the question's
    own) that has no effect on a run with configuration ``config`` and SLAM options ``slam``: one that acts through a
    disabled sensor (``SENSOR_OPTIONS``), or ``keep_first_prediction_edge`` while prediction edges are kept."""
    if "compass_edge" in changed:
        one_of(changed["compass_edge"], "compass_edge", ("fixed", "buggy"))
    if "keep_first_prediction_edge" in changed:
        boolean(changed["keep_first_prediction_edge"], "keep_first_prediction_edge")
    for flag, (sensor, names) in SENSOR_OPTIONS.items():
        hit = [n for n in names if n in changed]
        if hit and not getattr(config, flag):
            raise ValueError(f"{where}: {_shown(hit[0], changed)} has no effect: the run has no {sensor} ({flag}="
                             f"False); pass {flag}=True to use it, or leave {hit[0]} as the question sets it")
    if "keep_first_prediction_edge" in changed and not slam.get("remove_prediction_edges", False):
        raise ValueError(f"{where}: {_shown('keep_first_prediction_edge', changed)} has no effect while the "
                         "prediction edges are kept: it chooses which of them remove_prediction_edges=True removes; "
                         "pass that too, or leave keep_first_prediction_edge as the question sets it")


def _shown(name, options) -> str:
    """``name=value`` for a message, on one line (an array as a list)."""
    value = options[name]
    return f"{name}={value.tolist() if isinstance(value, np.ndarray) else value!r}"
