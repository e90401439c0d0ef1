"""Coursework 02, Q1c(ii): the corrected compass edge (hidden tests: the instructor's value checks).

Realistic inputs from the answer key's simulator (not an exercise): the q1_c route with the compass offset 0.75π,
seed 0, where ψ + Δψ_C passes π on most of the route. The noise-free run with the same seed gives every reading's
noise. The fixture ``cw_q1c_compass_fix_hidden`` holds the answer key's errors and Jacobians, the true poses of
every tick and noisy relative-pose measurements between them (for a graph that needs no other exercise).
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_true, fixture
from scipy.stats import chi2, norm

from helpers.drivebot.events import EventType
from helpers.drivebot.runner import question_setup
from helpers.drivebot.simulator import DriveBotSimulator
from helpers.graph import EdgeHeadingPrior, EdgeSE2, SparseOptimizer, VertexSE2


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


def compass_of_run(**overrides):
    """(true pose at each compass reading (E, 3), readings (E, 1), offset) of the q1_c run with seed 0."""
    scenario, config, _ = question_setup("q1_c", **overrides)
    sim = DriveBotSimulator(config, scenario, seed=0)
    sim.start()
    x, z = [], []
    while sim.keep_running():
        for ev in sim.events():
            if ev.type is EventType.COMPASS:
                x.append(sim.ground_truth())
                z.append(ev.data)
        sim.step()
    return np.array(x), np.array(z), config.compass_angular_offset


def test_errors_at_the_true_poses_are_the_compass_noise():
    """At the true poses of the q1_c run (offset 0.75π), each compass error is minus that reading's noise"""
    x, z, offset = compass_of_run()
    _, z0, _ = compass_of_run(perturb_with_noise=False)
    e, _ = EdgeHeadingPrior.evaluate([x.copy()], z.copy(), {"offset": np.full(len(z), offset)}, False)
    noise = (z - z0 + np.pi) % (2 * np.pi) - np.pi
    expect_rows_close(e, -noise, "e at the true poses of the %d compass readings of the q1_c run" % len(z),
                      {"x": x, "z": z[:, 0], "offset": np.full(len(z), offset)}, atol=1e-9)


def test_errors_and_jacobians_equal_the_answer_key():
    """The errors and Jacobians of the q1_c run's compass edges at the true poses equal the answer key's"""
    ref = fixture("cw_q1c_compass_fix_hidden")
    e, jac = EdgeHeadingPrior.evaluate([ref["x"].copy()], ref["z"].copy(), {"offset": ref["offset"].copy()}, True)
    inputs = {"x": ref["x"], "z": ref["z"][:, 0], "offset": ref["offset"]}
    expect_rows_close(e, ref["e"], "e of the %d compass edges of the q1_c run" % len(e), inputs)
    expect_rows_close(jac[0], ref["J"], "J of the %d compass edges" % len(e), inputs)


def test_a_graph_with_the_compass_is_consistent():
    """A pose graph of the q1_c route with the compass optimises to a χ² within its 4σ interval (a compass edge
    off by 2π would add ~10⁵ per edge) and keeps every heading within 4σ of the truth"""
    ref = fixture("cw_q1c_compass_fix_hidden")
    truth, rel, sigma = ref["truth"], ref["relative_z"], ref["relative_sigma"]
    graph = SparseOptimizer()
    poses = [VertexSE2(k, truth[k], fixed=(k == 0)) for k in range(len(truth))]
    for v in poses:
        graph.add_vertex(v)
    graph.add_edges(EdgeSE2, [(poses[k], poses[k + 1]) for k in range(len(rel))], rel, np.diag(sigma ** -2.0))
    r = float(ref["r_compass"][0, 0])
    graph.add_edges(EdgeHeadingPrior, [(poses[k],) for k in ref["tick"]], ref["z"], np.array([[1.0 / r]]),
                    offset=ref["offset"])
    graph.initialize_optimization()
    value = float(graph.optimize(50))
    dof = 3 * len(rel) + len(ref["z"]) - 3 * (len(truth) - 1)
    lo, hi = chi2.interval(2 * norm.cdf(4.0) - 1, dof)
    expect_true(lo <= value <= hi, "χ² after optimising (%d degrees of freedom) within its 4σ interval "
                "[%.0f, %.0f]" % (dof, lo, hi), actual=value)
    est = np.array([v.estimate for v in poses])
    dpsi = (est[:, 2] - truth[:, 2] + np.pi) % (2 * np.pi) - np.pi
    expect_true(np.max(np.abs(dpsi)) < 4 * np.sqrt(r), "every optimised heading within 4σ_compass = %.3f rad of "
                "the truth" % (4 * np.sqrt(r)), actual=float(np.max(np.abs(dpsi))))
