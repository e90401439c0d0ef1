"""Coursework 02, Q1b: the prediction step (hidden tests: the instructor's value checks, not in the student edition).

Realistic inputs from the answer key's simulator (not an exercise): the q1_b route, seed 0. A run with
perturb_with_noise=False has the same controls and truth as the noisy run with the same seed, so the odometry
noise of every tick is known exactly. The recorded fixture ``cw_q1b_prediction_hidden`` holds the answer key's
errors, Jacobians and a 200-tick run's histories.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_true, fixture

from helpers.drivebot import run_question
from helpers.drivebot.edges import VehicleKinematicsEdge
from helpers.drivebot.events import EventType
from helpers.drivebot.runner import question_setup
from helpers.drivebot.simulator import DriveBotSimulator


def expect_rows_close(actual, expected, what, inputs=None, *, rtol=1e-7, atol=1e-9):
    """Row by row (row i = edge or tick i): the first row of ``actual`` that differs from ``expected`` fails, shown
    with that row's ``inputs`` {name: array with one row per edge}."""
    actual, expected = np.asarray(actual, dtype=float), np.asarray(expected, dtype=float)
    if actual.shape != expected.shape:
        expect_close(actual, expected, what)                 # fails and says the shapes differ
    bad = ~np.isclose(actual, expected, rtol=rtol, atol=atol)
    rows = np.flatnonzero(bad.reshape(len(bad), -1).any(axis=1))
    if rows.size:
        i = int(rows[0])
        given = {name: (float(value[i]) if np.ndim(value[i]) == 0 else value[i])
                 for name, value in (inputs or {}).items()}
        expect_close(actual[i], expected[i], "%s — row %d (%d of %d rows differ)" % (what, i, rows.size, len(bad)),
                     given=given or None, rtol=rtol, atol=atol)


def odometry_of_run(**overrides):
    """(times, true poses, odometry) of every tick of the q1_b simulator run with seed 0."""
    scenario, config, _ = question_setup("q1_b", **overrides)
    sim = DriveBotSimulator(config, scenario, seed=0)
    sim.start()
    times, truth, u = [], [], []
    while sim.keep_running():
        times.append(sim.time)
        truth.append(sim.ground_truth())
        u.append(next(ev.data for ev in sim.events() if ev.type is EventType.VEHICLE_ODOMETRY))
        sim.step()
    return np.array(times), np.array(truth), np.array(u)


def test_noise_free_run_equals_the_truth():
    """Q1b's noise-free run: the estimate equals the truth at every one of the 654 ticks and χ² is zero"""
    res = run_question("q1_b", perturb_with_noise=False)
    expect_equal(res.n_steps, 654, "the number of ticks (vehicle vertices) of the q1_b run")
    err = res.state_error().T
    expect_rows_close(err, np.zeros_like(err), "estimate − truth at each tick of the noise-free q1_b run",
                      {"tick time": res.vehicle_state_time, "true state": res.vehicle_true_state_history.T}, atol=1e-9)
    expect_close(res.final_chi2, 0.0, "the final χ² of the noise-free run", atol=1e-12)
    var = res.vehicle_covariance_history
    expect_true(np.all(var[:, 0] == 0) and np.all(np.diff(var[0, 1:]) > 0),
                "the first vertex is fixed (variance 0) and the x variance grows at every tick after it",
                actual=var[0, :6])


def test_errors_at_the_true_poses_are_the_odometry_noise():
    """At the true poses of a noisy q1_b run, each kinematics error is minus that tick's odometry noise"""
    times, truth, u = odometry_of_run()
    _, truth0, u0 = odometry_of_run(perturb_with_noise=False)
    expect_close(truth0, truth, "the noise-free run's truth against the noisy run's (set-up of this test)", atol=0)
    e, _ = VehicleKinematicsEdge.evaluate([truth[:-1].copy(), truth[1:].copy()], u[:-1].copy(),
                                          {"dt": np.diff(times)}, False)
    expect_rows_close(e, u0[:-1] - u[:-1], "e between consecutive true poses of the q1_b run (653 edges)",
                      {"x_k": truth[:-1], "x_k+1": truth[1:], "u": u[:-1], "dt": np.diff(times)}, atol=1e-9)


def test_errors_and_jacobians_equal_the_answer_key():
    """The errors and Jacobians of 653 realistic edges (true poses and noisy odometry) equal the answer key's"""
    ref = fixture("cw_q1b_prediction_hidden")
    truth, u, dt = ref["truth"], ref["odometry"], np.diff(ref["times"])
    e, jac = VehicleKinematicsEdge.evaluate([truth[:-1].copy(), truth[1:].copy()], u[:-1].copy(), {"dt": dt}, True)
    inputs = {"x_k": truth[:-1], "x_k+1": truth[1:], "u": u[:-1], "dt": dt}
    expect_rows_close(e, ref["e"], "e of the 653 edges of the q1_b run", inputs)
    expect_rows_close(jac[0], ref["J_k"], "J_k of the 653 edges", inputs)
    expect_rows_close(jac[1], ref["J_k1"], "J_k+1 of the 653 edges", inputs)


def test_short_run_equals_the_answer_key():
    """The first 200 ticks of the noisy q1_b run: the estimates and their variances equal the answer key's"""
    ref = fixture("cw_q1b_prediction_hidden")
    res = run_question("q1_b", maximum_step_number=200)
    expect_rows_close(res.vehicle_state_time, ref["run_time"], "the vertex times of the 200-tick run", atol=1e-12)
    ticks = {"tick time": ref["run_time"]}
    expect_rows_close(res.vehicle_state_history.T, ref["run_x"].T, "the estimated state at each tick of the 200-tick "
                      "run", ticks)
    expect_rows_close(res.vehicle_covariance_history.T, ref["run_p"].T, "the state variances at each tick of the "
                      "200-tick run", ticks, atol=1e-12)
