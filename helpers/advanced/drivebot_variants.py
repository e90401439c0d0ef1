"""DriveBot runs with the advanced optimisers: the same coursework questions, another engine under the SLAM system.

``FastSLAMSystem``: the coursework's ``DriveBotSLAMSystem`` on ``fast_graph.FastOptimizer`` (its algorithms include
GTSAM's LM schedule, ``optimization_algorithm="lm-gtsam"``, for like-for-like comparisons with GTSAM).

``IncrementalSLAMSystem``: an optimisation makes one update of an ``incremental.IncrementalSmoother`` of at most n
solves instead of building the structure and running LM (no structure build: the factor of the last update is
extended; every graph change other than growth, such as Q3's edits, makes that update start afresh).

``run_fast`` and ``run_incremental`` run a coursework question with them (the arguments of ``run_question``)::

    res = run_incremental("q1_e", enable_compass=True)
"""
from __future__ import annotations

import math
import time

from ..drivebot.config import SimulatorConfiguration
from ..drivebot.edges import VehicleVertex
from ..drivebot.runner import Results, run_question
from ..drivebot.slam_system import DriveBotSLAMSystem, SLAMOptions
from .fast_graph import FastOptimizer
from .incremental import IncrementalSmoother

__all__ = ["FastSLAMSystem", "IncrementalSLAMSystem", "SystemSetup", "run_fast", "run_incremental"]


class FastSLAMSystem(DriveBotSLAMSystem):
    """DriveBotSLAMSystem on the advanced optimiser."""

    graph_class = FastOptimizer


class IncrementalSLAMSystem(DriveBotSLAMSystem):
    """DriveBotSLAMSystem whose optimisations are updates of an IncrementalSmoother (module docstring)."""

    def _solve(self, max_iterations: int) -> float:
        """One smoother update of at most max_iterations solves (none when 0); graph.statistics gets one entry per
        solve (χ² evaluated after the last one only)."""
        if max_iterations == 0:
            return self.chi2()
        smoother = self.__dict__.get("_smoother")
        if smoother is None:
            smoother = self._smoother = IncrementalSmoother(self.graph, VehicleVertex)
        t0 = time.perf_counter()
        chi2 = float(smoother.update(max_solves=max_iterations))
        solves = smoother.last["solves"]
        self.graph.statistics = [{"iteration": k, "chi2": chi2 if k == solves - 1 else math.nan, "mu": None,
                                  "rejected": 0, "time": time.perf_counter() - t0} for k in range(solves)]
        return chi2


class SystemSetup:
    """The runner's ``setup`` for a SLAM system class: builds that system, passes the events unchanged."""

    def __init__(self, system_class: type):
        self.system_class = system_class

    def system(self, config: SimulatorConfiguration, options: SLAMOptions) -> DriveBotSLAMSystem:
        return self.system_class(config, options)

    def filter(self, events: list, simulator: object) -> list:
        return events


def run_fast(name: str, seed=0, progress: bool = False, step_hook=None, **overrides) -> Results:
    """``drivebot.run_question`` with the ``FastSLAMSystem`` (same arguments)."""
    return run_question(name, seed=seed, progress=progress, step_hook=step_hook,
                        setup=SystemSetup(FastSLAMSystem), **overrides)


def run_incremental(name: str, seed=0, progress: bool = False, step_hook=None, **overrides) -> Results:
    """``drivebot.run_question`` with the ``IncrementalSLAMSystem`` (same arguments)."""
    return run_question(name, seed=seed, progress=progress, step_hook=step_hook,
                        setup=SystemSetup(IncrementalSLAMSystem), **overrides)
