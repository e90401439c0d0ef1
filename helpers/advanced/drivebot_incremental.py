"""DriveBot optimised after every step with the incremental smoother (``incremental.IncrementalSmoother``).

``IncrementalSLAMSystem`` is the coursework's ``DriveBotSLAMSystem`` with one duty changed: an optimisation makes one
update of an ``IncrementalSmoother`` of at most n solves instead of building the structure and running LM (no
structure build: the factor of the last update is extended; every graph change other than growth, such as Q3's
edits, makes that update start afresh). ``run_incremental`` runs a coursework question with it::

    res = run_incremental("q1_e", enable_compass=True)
"""
from __future__ import annotations

import math
import time

from ..drivebot.edges import VehicleVertex
from ..drivebot.runner import Results, run_question
from ..drivebot.slam_system import DriveBotSLAMSystem
from .incremental import IncrementalSmoother

__all__ = ["IncrementalSLAMSystem", "run_incremental"]


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


class _IncrementalSetup:
    """The runner's ``setup``: the incremental system, the events unchanged."""

    def system(self, config, **slam_options):
        return IncrementalSLAMSystem(config, **slam_options)

    def filter(self, events, simulator):
        return events


def run_incremental(name: str, seed=0, progress: bool = False, step_hook=None, **overrides) -> Results:
    """``drivebot.run_question`` with the ``IncrementalSLAMSystem`` (same arguments)."""
    return run_question(name, seed=seed, progress=progress, step_hook=step_hook, setup=_IncrementalSetup(),
                        **overrides)
