"""helpers.drivebot — the DriveBot simulator and graph-SLAM system of the coursework (COMP0130 CW2).

Modules: ``events`` (event types, the time-ordered queue), ``config`` (``SimulatorConfiguration``),
``scenarios`` (maps and routes in ``data/drivebot/``), ``scenario_files`` (generating and writing them),
``simulator`` (``DriveBotSimulator``), ``edges``
(vehicle/landmark vertices, the kinematics edge, the buggy compass edge), ``slam_system``
(``DriveBotSLAMSystem``; its options are validated by ``options``), ``runner`` (``run_question``, ``Results``;
a run that fails part-way re-raises its error with the partial ``Results`` attached).

One entry point for every notebook::

    from helpers.drivebot import run_question
    res = run_question("q1_d", seed=0)                       # per-question settings of the coursework
    res = run_question("q1_e", enable_compass=True)          # overrides: config fields or SLAM options
    res.vehicle_state_history, res.vehicle_covariance_history, res.chi2_history, res.graph_statistics()
"""
from .config import SimulatorConfiguration
from .edges import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from .events import Event, EventQueue, EventType
from .runner import QUESTIONS, Results, RunError, run, run_question
from .scenarios import Scenario, load_scenario
from .simulator import DriveBotSimulator
from .slam_system import DriveBotSLAMSystem

__all__ = ["run_question", "run", "Results", "RunError", "QUESTIONS", "SimulatorConfiguration", "DriveBotSimulator",
           "DriveBotSLAMSystem", "Scenario", "load_scenario", "Event", "EventType", "EventQueue",
           "VehicleVertex", "LandmarkVertex", "VehicleKinematicsEdge", "BuggyCompassEdge"]
