"""helpers.drivebot — the DriveBot simulator and graph-SLAM system of the coursework (COMP0130 CW2).

Modules: ``events``, ``config`` (``SimulatorConfiguration``), ``scenarios``, ``simulator`` (``DriveBotSimulator``),
``edges``, ``slam_system`` (``DriveBotSLAMSystem``, ``SLAMOptions``), ``runner`` (``run_question``), ``results``.
One entry point for every notebook::

    from helpers.drivebot import run_question
    res = run_question("q1_d", seed=0)                       # per-question settings of the coursework
    res = run_question("q1_e", enable_compass=True)          # overrides: config fields or SLAM options
    res.vehicle_state_history, res.vehicle_covariance_history, res.chi2_history, res.graph_statistics()
"""
from .config import SimulatorConfiguration
from .edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from .events import Event, EventQueue, EventType
from .runner import QUESTIONS, Results, run_question
from .scenarios import Scenario, load_scenario
from .simulator import DriveBotSimulator
from .slam_system import DriveBotSLAMSystem, SLAMOptions

__all__ = ["run_question", "Results", "QUESTIONS", "SimulatorConfiguration", "DriveBotSimulator",
           "DriveBotSLAMSystem", "SLAMOptions", "Scenario", "load_scenario", "Event", "EventType", "EventQueue",
           "VehicleVertex", "LandmarkVertex", "VehicleKinematicsEdge", "BuggyCompassEdge"]
