"""Coursework 02, Q1d: the GPS as a 2-D observation with its lever arm (public tests).

The GPS model of the handout's appendix A.4 is z = [x, y] + M(ψ)[Δx_G, Δy_G] + w (the lever arm l = [Δx_G, Δy_G]
in the body frame); the edge's error is e = h(x) − z. The expected values below follow from that definition on
hand-made poses; the SLAM system's part is checked on a system given an initial condition and GPS events only.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_jacobian, expect_shape, expect_true, fail

from helpers.drivebot import DriveBotSLAMSystem, Event, EventType, SimulatorConfiguration
from helpers.graph import EdgePositionPrior

TWO_PI = 2.0 * np.pi


def wrap(a):
    """An angle (or array of angles) in [−π, π)."""
    return (np.asarray(a, dtype=float) + np.pi) % TWO_PI - np.pi


def evaluate(x, z, lever_arm, jacobians=True):
    """The student's EdgePositionPrior.evaluate on E edges, with its return value checked for form."""
    x, z, lever_arm = (np.array(a, dtype=float) for a in (x, z, lever_arm))
    given = {"E (edges)": len(z)}
    out = EdgePositionPrior.evaluate([x.copy()], z.copy(), {"lever_arm": lever_arm.copy()}, jacobians)
    if not (isinstance(out, tuple) and len(out) == 2):
        fail("evaluate returns a pair (e, Jacobians)", given=given,
             note="got %s" % (type(out).__name__ if not isinstance(out, tuple) else "a tuple of %d" % len(out)))
    e, jac = out
    expect_shape(e, (len(z), 2), "the error e (one row per edge)", given=given)
    if jacobians:
        if not (isinstance(jac, (list, tuple)) and len(jac) == 1):
            fail("the Jacobians are a list [J] (one vertex)", given=given, note="got %r" % (jac,))
        expect_shape(jac[0], (len(z), 2, 3), "J = ∂e/∂x (one 2 × 3 block per edge)", given=given)
    return e, jac


def edge_given(x, z, lever, i):
    """The inputs of edge i, for a failure message."""
    return {"x": x[i], "z": z[i], "lever_arm": lever[i]}


def random_edges(rng, n):
    """n edges: poses anywhere (two headings just inside ±π), lever arms of up to 25 m, readings near the antenna."""
    x = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-np.pi, np.pi, n)])
    x[0, 2], x[1, 2] = np.pi - 1e-3, -np.pi + 2e-3
    lever = rng.uniform(-25, 25, (n, 2))
    z = x[:, :2] + rng.normal(0, 3.0, (n, 2))
    return x, z, lever


# ---------------------------------------------------------------------------------------------- the edge
def test_error_without_a_lever_arm_is_position_minus_reading():
    """With the antenna at the body's origin (lever arm 0), e = [x, y] − z whatever the heading"""
    x = np.array([[1.0, 2.0, 0.0], [-3.0, 4.0, 2.5], [10.0, -5.0, -np.pi]])
    z = np.array([[0.5, 2.5], [-3.0, 3.0], [12.0, -4.0]])
    lever = np.zeros((3, 2))
    e, _ = evaluate(x, z, lever, jacobians=False)
    for i in range(len(z)):
        expect_close(e[i], x[i, :2] - z[i], "e of edge %d with lever_arm = [0, 0]" % i,
                     given=edge_given(x, z, lever, i), atol=1e-12)


def test_lever_arm_turns_with_the_heading():
    """The lever arm is in the body frame: e = [x, y] + M(ψ) l − z (l = [10, −20] m at ψ = π/2 is [20, 10] m)"""
    x = np.array([[1.0, 2.0, np.pi / 2], [1.0, 2.0, 0.0], [1.0, 2.0, -np.pi], [0.0, 0.0, np.pi / 6]])
    lever = np.array([[10.0, -20.0], [10.0, -20.0], [10.0, -20.0], [2.0, 0.0]])
    z = np.zeros((4, 2))
    expected = np.array([[1 + 20.0, 2 + 10.0], [1 + 10.0, 2 - 20.0], [1 - 10.0, 2 + 20.0],
                         [2 * np.cos(np.pi / 6), 2 * np.sin(np.pi / 6)]])
    e, _ = evaluate(x, z, lever, jacobians=False)
    for i in range(len(z)):
        expect_close(e[i], expected[i], "e of edge %d of 4 (z = 0, so e is the antenna's position)" % i,
                     given=edge_given(x, z, lever, i), atol=1e-9)


def error_of_edge(x, z, lever, i):
    """e of edge i as a function of its pose, through the vertex's update x ⊞ δ (which wraps the heading)."""
    def error(xi):
        a = x[i:i + 1].copy()
        a[0] = xi
        a[0, 2] = wrap(xi[2])
        return evaluate(a, z[i:i + 1], lever[i:i + 1], jacobians=False)[0][0]
    return error


def test_jacobian_matches_central_differences():
    """J = ∂e/∂x equals central differences of e, its heading column too (random poses and lever arms)"""
    for seed in (1, 2, 3):
        x, z, lever = random_edges(np.random.default_rng(seed), 5)
        _, jac = evaluate(x, z, lever)
        for i in range(len(z)):
            expect_jacobian(error_of_edge(x, z, lever, i), x[i], jac[0][i],
                            "J = ∂e/∂x of edge %d (seed %d)" % (i, seed), given=edge_given(x, z, lever, i))


def test_returns_shapes_and_no_jacobians_on_request():
    """evaluate returns e (E, 2) and [J] with J (E, 2, 3); with jacobians=False it returns (e, None)"""
    for n in (1, 5):
        x, z, lever = random_edges(np.random.default_rng(9), max(n, 2))
        x, z, lever = x[:n], z[:n], lever[:n]
        e, _ = evaluate(x, z, lever)                    # checks the shapes
        e2, jac = evaluate(x, z, lever, jacobians=False)
        expect_equal(jac, None, "the Jacobians returned with jacobians=False (E = %d)" % n)
        expect_close(e2, e, "e with jacobians=False against e with jacobians=True (E = %d)" % n, atol=1e-12)


def test_all_edges_at_once_equal_one_at_a_time():
    """Edge i's row of e and block of J depend only on edge i's pose, reading and lever arm"""
    x, z, lever = random_edges(np.random.default_rng(7), 6)
    e, jac = evaluate(x, z, lever)
    for i in range(len(z)):
        ei, ji = evaluate(x[i:i + 1], z[i:i + 1], lever[i:i + 1])
        given = edge_given(x, z, lever, i)
        expect_close(e[i], ei[0], "row %d of e (6 edges at once) against edge %d alone" % (i, i), given=given,
                     atol=1e-12)
        expect_close(jac[0][i], ji[0][0], "J of edge %d (6 at once) against edge %d alone" % (i, i), given=given,
                     atol=1e-12)


# ---------------------------------------------------------------------------------------------- the handler
R_GPS = np.array([[1.5, 0.3], [0.3, 0.8]])


def gps_system(x0, p0=None, lever=(10.0, -20.0)):
    """A SLAM system with the GPS enabled (lever arm ``lever``) after the initial condition x0 at t = 0 (P0 = 0:
    vertex 0 fixed, no prediction step involved)."""
    config = SimulatorConfiguration(enable_gps=True, gps_position_offset=np.array(lever, dtype=float))
    system = DriveBotSLAMSystem(config)
    p0 = np.zeros((3, 3)) if p0 is None else p0
    system.process_events([Event(0.0, EventType.VEHICLE_ODOMETRY, [1.0, 0.0, 0.0], np.eye(3)),
                           Event(0.0, EventType.INITIAL_CONDITION, x0, p0)])
    return system


def gps_edges(system):
    return [e for e in system.graph.edges() if isinstance(e, EdgePositionPrior)]


def test_gps_event_adds_one_position_edge_on_the_current_vertex():
    """A GPS event adds one EdgePositionPrior on the current vehicle vertex with z, R⁻¹ and the lever arm"""
    system = gps_system([3.0, -1.0, 0.7], lever=(4.0, -2.5))
    z = np.array([8.0, 1.5])
    system.process_events([Event(0.0, EventType.GPS, z, R_GPS)])
    given = {"x0": [3.0, -1.0, 0.7], "z": z, "R_GPS": R_GPS.tolist(), "gps_position_offset": [4.0, -2.5]}
    edges = gps_edges(system)
    expect_equal(len(edges), 1, "EdgePositionPrior edges in the graph after one GPS event", given=given)
    edge = edges[0]
    expect_true(edge.vertex(0) is system.current_vehicle_vertex, "the GPS edge is on the current vehicle vertex",
                actual=edge.vertex(0))
    expect_close(edge.measurement, z, "the GPS edge's measurement", given=given, atol=1e-12)
    expect_close(edge.information, np.linalg.inv(R_GPS), "the GPS edge's information", given=given, rtol=1e-9,
                 atol=1e-9)
    expect_close(edge.lever_arm, [4.0, -2.5], "the GPS edge's lever_arm", given=given, atol=1e-12)
    expect_equal(system.graph.number_of_vertices(), 1, "vertices in the graph (a GPS edge adds none)", given=given)


def test_each_gps_event_adds_its_own_edge():
    """Two GPS events at the current time give two GPS edges on the same vertex, each with its own reading"""
    system = gps_system([0.0, 0.0, 0.0])
    readings = [np.array([10.0, -20.0]), np.array([11.0, -19.0])]
    system.process_events([Event(0.0, EventType.GPS, readings[0], R_GPS)])
    system.process_events([Event(0.0, EventType.GPS, readings[1], R_GPS)])
    edges = gps_edges(system)
    expect_equal(len(edges), 2, "EdgePositionPrior edges after two GPS events", given={"readings": readings})
    got = sorted(tuple(e.measurement) for e in edges)
    expect_close(np.array(got), np.array(sorted(tuple(r) for r in readings)), "the two edges' measurements",
                 atol=1e-12)


def test_optimum_weighs_the_gps_by_its_information():
    """With a pose prior P0 and one GPS reading (lever arm 0), the optimum is their information-weighted mean"""
    p0 = np.diag([4.0, 4.0, 0.01])
    x0 = np.array([0.0, 0.0, 0.3])
    system = gps_system(x0, p0=p0, lever=(0.0, 0.0))
    z = np.array([3.0, -2.0])
    system.process_events([Event(0.0, EventType.GPS, z, R_GPS)])
    expect_equal(len(gps_edges(system)), 1, "EdgePositionPrior edges after one GPS event")
    try:
        system.optimize()
    except Exception as err:  # noqa: BLE001 — the error is the feedback
        fail("system.optimize() after the GPS event", note="it raised %s: %s" % (type(err).__name__, err))
    a, b = np.linalg.inv(p0[:2, :2]), np.linalg.inv(R_GPS)
    expected = np.linalg.solve(a + b, a @ x0[:2] + b @ z)
    x = system.current_vehicle_vertex.estimate
    expect_close(x[:2], expected, "the optimised position: (P0⁻¹ + R⁻¹)⁻¹ (P0⁻¹ x0 + R⁻¹ z)",
                 given={"x0": x0, "P0": p0.tolist(), "z": z, "R_GPS": R_GPS.tolist()}, atol=1e-6)
