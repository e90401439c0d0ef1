"""Recipes of the grading fixtures of coursework 02, question 1 (``tools/exercise_fixtures.py``).

The public Q1 tests use hand-made inputs only; these fixtures hold the hidden tests' realistic inputs (from the
answer key's simulator, which is not an exercise) and the answer key's outputs on them:

- ``cw_q1b_prediction_hidden``: the true poses and the odometry of every tick of a q1_b run (seed 0), with the
  answer key's kinematics errors and Jacobians between consecutive true poses; and the vehicle state and
  covariance histories of the answer key's ``run_question("q1_b", maximum_step_number=200)``.
- ``cw_q1c_compass_fix_hidden``: the compass events of a q1_c run (offset 0.75π, seed 0) with the true pose of
  their tick, the answer key's compass errors and Jacobians; the true poses of every tick and noisy relative-pose
  measurements between consecutive ones (seeded), for the hidden test that optimises a graph with the compass.
- ``cw_q1d_gps_hidden``: the GPS events of a q1_d run (lever arm [10, −20] m, seed 0) with the true pose of their
  tick, the answer key's GPS errors and Jacobians and each edge's χ²; the true poses of every tick of the first
  1 000 and noisy relative-pose measurements between them (seeded).

Tolerances: poses and measurements are sums of a few thousand simulator steps (round-off ≈ 1e-12 m); the errors
divide pose differences by ΔT ≈ 0.1 s (≈ 1e-11); the q1_b histories come from a tree-shaped graph (dead
reckoning, no iteration changes them) and its marginals (well conditioned: relative ≈ 1e-12).
"""
from __future__ import annotations

import numpy as np
from exercise_fixtures import recipe

from helpers.drivebot.edges import VehicleKinematicsEdge
from helpers.drivebot.events import EventType
from helpers.drivebot.runner import question_setup, run_question
from helpers.drivebot.simulator import DriveBotSimulator
from helpers.graph import EdgeHeadingPrior, EdgePositionPrior

#: the standard deviations of the relative-pose (EdgeSE2) measurements of the hidden graph tests: x, y (m), ψ (rad)
SE2_SIGMA = np.array([0.02, 0.01, 0.002])


def _simulate(name: str, ticks: int | None = None, seed: int = 0):
    """(times (N,), truth (N, 3), events per tick) of question ``name``'s simulator, the first ``ticks`` ticks."""
    scenario, config, _ = question_setup(name)
    sim = DriveBotSimulator(config, scenario, seed=seed)
    sim.start()
    times, truth, batches = [], [], []
    while sim.keep_running() and (ticks is None or len(times) < ticks):
        times.append(sim.time)
        truth.append(sim.ground_truth())
        batches.append(sim.events())
        sim.step()
    return np.array(times), np.array(truth), batches, config


def _relative_poses(truth: np.ndarray, seed: int) -> np.ndarray:
    """Noisy relative poses z_i = (t, θ) of truth[i + 1] in the frame of truth[i] (EdgeSE2's measurement)."""
    rng = np.random.default_rng(seed)
    a, b = truth[:-1], truth[1:]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    d = b[:, :2] - a[:, :2]
    z = np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1],
                         (b[:, 2] - a[:, 2] + np.pi) % (2 * np.pi) - np.pi])
    return z + SE2_SIGMA * rng.standard_normal(z.shape)


def _sensor_rows(times, truth, batches, event_type):
    """(truth pose (E, 3), data (E, m), covariance, tick index (E,)) of every event of ``event_type``."""
    rows = [(truth[k], ev.data, ev.covariance, k) for k, batch in enumerate(batches) for ev in batch
            if ev.type is event_type]
    return (np.array([r[0] for r in rows]), np.array([r[1] for r in rows]), rows[0][2],
            np.array([r[3] for r in rows], dtype=np.int64))


@recipe("cw_q1b_prediction_hidden", rtol=1e-9, atol=1e-9)
def q1b_hidden() -> dict:
    times, truth, batches, config = _simulate("q1_b")
    u = np.array([next(ev.data for ev in batch if ev.type is EventType.VEHICLE_ODOMETRY) for batch in batches])
    xk, xn, dt = truth[:-1], truth[1:], np.diff(times)
    e, (jk, jn) = VehicleKinematicsEdge.evaluate([xk, xn], u[:-1], {"dt": dt})
    run = run_question("q1_b", maximum_step_number=200)
    return {"times": times, "truth": truth, "odometry": u, "r_odometry": config.r_odometry,
            "e": e, "J_k": jk, "J_k1": jn,
            "run_time": run.vehicle_state_time, "run_x": run.vehicle_state_history,
            "run_p": run.vehicle_covariance_history}


@recipe("cw_q1c_compass_fix_hidden", rtol=1e-9, atol=1e-9)
def q1c_hidden() -> dict:
    times, truth, batches, config = _simulate("q1_c")
    x, z, cov, tick = _sensor_rows(times, truth, batches, EventType.COMPASS)
    offset = np.full(len(z), config.compass_angular_offset)
    e, (j,) = EdgeHeadingPrior.evaluate([x], z, {"offset": offset})
    return {"x": x, "z": z, "offset": offset, "r_compass": cov, "tick": tick, "e": e, "J": j,
            "truth": truth, "relative_z": _relative_poses(truth, seed=21), "relative_sigma": SE2_SIGMA}


@recipe("cw_q1d_gps_hidden", rtol=1e-9, atol=1e-9)
def q1d_hidden() -> dict:
    times, truth, batches, config = _simulate("q1_d")
    x, z, cov, tick = _sensor_rows(times, truth, batches, EventType.GPS)
    lever = np.tile(config.gps_position_offset, (len(z), 1))
    e, (j,) = EdgePositionPrior.evaluate([x], z, {"lever_arm": lever})
    chi2 = np.einsum("ei,ij,ej->e", e, np.linalg.inv(cov), e)
    first = truth[:1000]
    return {"time": times[tick], "x": x, "z": z, "lever_arm": lever, "r_gps": cov, "tick": tick, "e": e, "J": j,
            "chi2": chi2, "truth": first, "relative_z": _relative_poses(first, seed=31),
            "relative_sigma": SE2_SIGMA}
