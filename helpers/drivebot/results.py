"""``Results``: what a DriveBot run produced (histories, the final graph, and its statistics and reports)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..gaussian import chi2_interval, confidence_level
from ..graph import wrap_angle_mod
from ..validation import positive_number
from .config import SimulatorConfiguration
from .scenarios import Scenario
from .slam_system import DriveBotSLAMSystem

__all__ = ["Results"]


@dataclass
class Results:
    """What a run produced (N = number of processed ticks = number of vehicle vertices)."""

    question: str
    config: SimulatorConfiguration
    scenario: Scenario
    optimization_times: np.ndarray           # (N,) wall time of the optimisation at each tick, NaN where none ran
    chi2_time: np.ndarray                    # (K,) tick time of each optimisation (the final one included)
    chi2_history: np.ndarray                 # (K,) χ² after each optimisation
    vehicle_true_state_time: np.ndarray      # (N,)
    vehicle_true_state_history: np.ndarray   # (3, N)
    vehicle_state_time: np.ndarray           # (N,)
    vehicle_state_history: np.ndarray        # (3, N) smoothed estimates from the final graph
    vehicle_covariance_history: np.ndarray   # (3, N) covariance diagonals (0 for the fixed first vertex)
    vehicle_in_graph: np.ndarray             # (N,) False for vertices deleted from the graph (Q3): NaN columns above
    system: DriveBotSLAMSystem               # the final system (``system.graph`` is the optimiser)
    optimization_iterations: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))  # (N,)
    run_time: float = field(default=float("nan"))   # wall time of the whole run (s; machine-dependent)
    dropped_laser_readings: int = 0          # readings the simulator did not report (noisy range ≤ 0)
    setup: object = None                     # the ``setup`` of run_question (None: the coursework's run)

    @property
    def n_steps(self) -> int:
        """N, the number of processed ticks (= vehicle vertices created)."""
        return int(self.vehicle_state_time.size)

    @property
    def final_chi2(self) -> float:
        """χ² after the last optimisation."""
        return float(self.chi2_history[-1])

    def state_error(self) -> np.ndarray:
        """Estimate − truth (3×N), heading wrapped into [−π, π)."""
        err = self.vehicle_state_history - self.vehicle_true_state_history
        err[2] = wrap_angle_mod(err[2])
        return err

    def graph_statistics(self) -> dict:
        """Counts by vertex and edge type and the χ² degrees of freedom (see DriveBotSLAMSystem)."""
        return self.system.graph_statistics()

    def landmark_estimates(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x 2×L, P 2×2×L, ids) from the final graph."""
        return self.system.landmark_estimates()

    def chi2_bounds(self, k: float = 4.0) -> tuple[float, float]:
        """The "k-sigma" acceptance interval of χ²: the central interval of χ²_dof holding probability 2Φ(k) − 1
        ((0, 0) when dof < 1: a graph without redundancy fits exactly)."""
        k = positive_number(k, "k")
        dof = self.graph_statistics()["dof"]
        if dof < 1:
            return 0.0, 0.0
        return chi2_interval(int(dof), confidence_level(k))
