"""Coursework 02, Q1d: the GPS with its lever arm (hidden tests: the instructor's value checks).

Realistic inputs from the answer key's simulator (not an exercise): the q1_d route (the loop four times), the lever
arm [10, −20] m, seed 0. The noise-free run with the same seed gives every reading's noise. The fixture
``cw_q1d_gps_hidden`` holds the answer key's errors, Jacobians and χ² per edge, the true poses of the first 1 000
ticks and noisy relative-pose measurements between them (for a graph that needs no other exercise).
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_true, fixture
from scipy.stats import chi2, norm

from helpers.drivebot import DriveBotSLAMSystem, Event, EventType, SimulatorConfiguration
from helpers.drivebot.runner import question_setup
from helpers.drivebot.simulator import DriveBotSimulator
from helpers.graph import EdgePositionPrior, EdgeSE2, SparseOptimizer, VertexSE2


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


def gps_of_run(**overrides):
    """(true pose at each GPS reading (E, 3), readings (E, 2), lever arm) of the q1_d run with seed 0."""
    scenario, config, _ = question_setup("q1_d", **overrides)
    sim = DriveBotSimulator(config, scenario, seed=0)
    sim.start()
    x, z = [], []
    while sim.keep_running():
        for ev in sim.events():
            if ev.type is EventType.GPS:
                x.append(sim.ground_truth())
                z.append(ev.data)
        sim.step()
    return np.array(x), np.array(z), config.gps_position_offset


def test_errors_at_the_true_poses_are_the_gps_noise():
    """At the true poses of the q1_d run (lever arm [10, −20] m), each GPS error is minus that reading's noise"""
    x, z, lever = gps_of_run()
    _, z0, _ = gps_of_run(perturb_with_noise=False)
    levers = np.tile(lever, (len(z), 1))
    e, _ = EdgePositionPrior.evaluate([x.copy()], z.copy(), {"lever_arm": levers.copy()}, False)
    expect_rows_close(e, z0 - z, "e at the true poses of the %d GPS readings of the q1_d run" % len(z),
                      {"x": x, "z": z, "lever_arm": levers}, atol=1e-9)


def test_errors_and_jacobians_equal_the_answer_key():
    """The errors and Jacobians of the q1_d run's GPS edges at the true poses equal the answer key's"""
    ref = fixture("cw_q1d_gps_hidden")
    e, jac = EdgePositionPrior.evaluate([ref["x"].copy()], ref["z"].copy(), {"lever_arm": ref["lever_arm"].copy()},
                                        True)
    inputs = {"x": ref["x"], "z": ref["z"], "lever_arm": ref["lever_arm"]}
    expect_rows_close(e, ref["e"], "e of the %d GPS edges of the q1_d run" % len(e), inputs)
    expect_rows_close(jac[0], ref["J"], "J of the %d GPS edges" % len(e), inputs)


def test_handler_adds_the_runs_first_gps_reading():
    """The q1_d run's first GPS reading, on a system started at the true pose of its tick: the edge's χ² equals the
    answer key's"""
    ref = fixture("cw_q1d_gps_hidden")
    t, x0, z, cov = float(ref["time"][0]), ref["x"][0], ref["z"][0], ref["r_gps"]
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_gps=True))
    system.process_events([Event(t, EventType.VEHICLE_ODOMETRY, [1.0, 0.0, 0.0], np.eye(3)),
                           Event(t, EventType.INITIAL_CONDITION, x0, np.zeros((3, 3))),
                           Event(t, EventType.GPS, z, cov)])
    edges = [e for e in system.graph.edges() if isinstance(e, EdgePositionPrior)]
    given = {"t": t, "true pose": x0, "z": z, "R_GPS": cov.tolist()}
    expect_equal(len(edges), 1, "GPS edges after the first reading", given=given)
    expect_close(edges[0].error(), ref["e"][0], "the edge's error", given=given, rtol=1e-7, atol=1e-9)
    expect_close(edges[0].chi2(), ref["chi2"][0], "the edge's χ² = eᵀ R⁻¹ e", given=given, rtol=1e-7, atol=1e-9)


def test_a_graph_with_the_gps_is_consistent():
    """A pose graph of the first 1 000 ticks of the q1_d route with the GPS optimises to a χ² within its 4σ interval
    and keeps every position within 1 m of the truth"""
    ref = fixture("cw_q1d_gps_hidden")
    truth, rel, sigma = ref["truth"], ref["relative_z"], ref["relative_sigma"]
    graph = SparseOptimizer()
    poses = [VertexSE2(k, truth[k], fixed=(k == 0)) for k in range(len(truth))]
    for v in poses:
        graph.add_vertex(v)
    graph.add_edges(EdgeSE2, [(poses[k], poses[k + 1]) for k in range(len(rel))], rel, np.diag(sigma ** -2.0))
    use = ref["tick"] < len(truth)
    graph.add_edges(EdgePositionPrior, [(poses[k],) for k in ref["tick"][use]], ref["z"][use],
                    np.linalg.inv(ref["r_gps"]), lever_arm=ref["lever_arm"][use])
    graph.initialize_optimization()
    value = float(graph.optimize(50))
    dof = 3 * len(rel) + 2 * int(use.sum()) - 3 * (len(truth) - 1)
    lo, hi = chi2.interval(2 * norm.cdf(4.0) - 1, dof)
    expect_true(lo <= value <= hi, "χ² after optimising (%d degrees of freedom) within its 4σ interval "
                "[%.0f, %.0f]" % (dof, lo, hi), actual=value)
    est = np.array([v.estimate for v in poses])
    dist = np.hypot(est[:, 0] - truth[:, 0], est[:, 1] - truth[:, 1])
    expect_true(dist.max() < 1.0, "every optimised position within 1 m of the truth", actual=float(dist.max()))
