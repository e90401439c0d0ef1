"""Writing the DriveBot scenario files (helpers.drivebot.scenario_files) reproduces data/drivebot exactly."""
import filecmp

import numpy as np

from helpers.drivebot import scenario_files
from helpers.drivebot.scenario_files import SCENARIO_DEFINITIONS
from helpers.drivebot.scenarios import data_dir, load_scenario


def test_written_files_equal_the_shipped_ones(tmp_path):
    scenario_files.write_scenario_files(tmp_path, large_map=False)
    for name in SCENARIO_DEFINITIONS:
        for f in ("landmarks.csv", "waypoints.csv"):
            assert filecmp.cmp(tmp_path / name / f, data_dir() / name / f, shallow=False), (name, f)
    assert not (tmp_path / "large_map").exists()


def test_ticks_to_finish_matches_the_simulator_run_length():
    # q1_e drives (0, 0) → (70, 0): 324 ticks (as in test_drivebot_simulator.test_run_lengths)
    assert scenario_files.ticks_to_finish(load_scenario("q1_e").waypoints) == 324


def test_scenarios_module_does_not_import_the_simulator():
    import ast
    import inspect

    from helpers.drivebot import scenarios

    imported = {n.module for n in ast.walk(ast.parse(inspect.getsource(scenarios))) if isinstance(n, ast.ImportFrom)}
    assert not {"simulator", "config", "runner"} & imported
    assert np.array_equal(load_scenario("q1_b").waypoints, np.array(SCENARIO_DEFINITIONS["q1_b"][1], float).T)
