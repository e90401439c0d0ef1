"""Coursework 02, Q1b: the prediction step (public tests).

The kinematics edge's model is the process model of the handout's appendix A.2,
x_{k+1} = x_k + ΔT_k M(ψ_k)(u_k + v_k), and its error is the process noise v_k (information R_odometry⁻¹). The
tests build poses from that model by hand, so each expected value follows from the definition. The prediction
step is checked through the SLAM system's event processing with odometry only (no compass, GPS or laser).
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_jacobian, expect_shape, expect_true, fail

from helpers.drivebot import DriveBotSLAMSystem, Event, EventType, SimulatorConfiguration, SLAMOptions
from helpers.drivebot.edges import VehicleKinematicsEdge, VehicleVertex

TWO_PI = 2.0 * np.pi


def wrap(a):
    """An angle (or array of angles) in [−π, π)."""
    return (np.asarray(a, dtype=float) + np.pi) % TWO_PI - np.pi


def rotation(psi):
    """M(ψ) of the handout's equation A.4."""
    c, s = np.cos(psi), np.sin(psi)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def process_model(x, u, dt):
    """x + ΔT M(ψ) u, the heading wrapped (as a vertex stores it)."""
    out = np.asarray(x, dtype=float) + dt * rotation(x[2]) @ np.asarray(u, dtype=float)
    out[2] = wrap(out[2])
    return out


def evaluate(xk, xn, u, dt, jacobians=True):
    """The student's VehicleKinematicsEdge.evaluate on E edges, with its return value checked for form."""
    xk, xn, u, dt = (np.array(a, dtype=float) for a in (xk, xn, u, dt))
    given = {"E (edges)": len(u)}
    out = VehicleKinematicsEdge.evaluate([xk.copy(), xn.copy()], u.copy(), {"dt": dt.copy()}, jacobians)
    if not (isinstance(out, tuple) and len(out) == 2):
        fail("evaluate returns a pair (e, Jacobians)", given=given,
             note="got %s" % (type(out).__name__ if not isinstance(out, tuple) else "a tuple of %d" % len(out)))
    e, jac = out
    expect_shape(e, (len(u), 3), "the error e (one row per edge)", given=given)
    if jacobians:
        if not (isinstance(jac, (list, tuple)) and len(jac) == 2):
            fail("the Jacobians are a list [J_k, J_k+1]", given=given, note="got %r" % (jac,))
        for name, j in zip(("J_k = ∂e/∂x_k", "J_k+1 = ∂e/∂x_k+1"), jac):
            expect_shape(j, (len(u), 3, 3), "%s (one 3 × 3 block per edge)" % name, given=given)
    return e, jac


def edge_given(xk, xn, u, dt, i, **more):
    """The inputs of edge i, for a failure message."""
    return {"x_k": xk[i], "x_k+1": xn[i], "u": u[i], "dt": float(dt[i]), **more}


def random_edges(rng, n, near_cut=True):
    """n edges: poses anywhere (two headings just inside ±π), odometry, ΔT, and x_{k+1} from the model plus noise."""
    xk = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-np.pi, np.pi, n)])
    if near_cut:
        xk[0, 2], xk[1, 2] = np.pi - 1e-3, -np.pi + 2e-3
    u = np.column_stack([rng.uniform(0.5, 5, n), np.zeros(n), rng.normal(0, 0.5, n)])
    dt = rng.uniform(0.05, 0.5, n)
    v = rng.normal(0, 0.3, (n, 3))
    xn = np.array([process_model(xk[i], u[i] + v[i], dt[i]) for i in range(n)])
    return xk, xn, u, dt


# ---------------------------------------------------------------------------------------------- the edge
def test_error_is_the_process_noise():
    """The kinematics error is the process noise: with x_{k+1} = x_k + ΔT M(ψ_k)(u + v), e = v (each edge its own
    ΔT)"""
    xk = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 0.3], [-5.0, 4.0, -2.0], [3.0, -1.0, 1.2]])
    u = np.array([[2.0, 0.0, 0.5], [3.0, 0.0, -0.2], [1.0, 0.0, 1.0], [4.0, 0.0, 0.0]])
    v = np.array([[0.0, 0.0, 0.0], [0.1, -0.05, 0.02], [-0.2, 0.1, -0.1], [0.0, 0.3, 0.0]])
    dt = np.array([0.1, 0.25, 0.1, 0.5])
    xn = np.array([process_model(xk[i], u[i] + v[i], dt[i]) for i in range(4)])
    e, _ = evaluate(xk, xn, u, dt, jacobians=False)
    for i in range(len(u)):
        expect_close(e[i], v[i], "e of edge %d of 4, whose x_k+1 is the process model's step with the noise v" % i,
                     given=edge_given(xk, xn, u, dt, i, v=v[i]), atol=1e-9)


def test_heading_change_across_the_angle_cut():
    """A turn across ψ = ±π is a small turn: the heading error has no 2π jump"""
    xk = np.array([[0.0, 0.0, np.pi - 0.01], [2.0, 1.0, -np.pi + 0.01]])
    u = np.array([[1.0, 0.0, 0.2], [1.0, 0.0, -0.2]])
    dt = np.array([0.1, 0.1])
    xn = np.array([process_model(xk[i], u[i], dt[i]) for i in range(2)])   # headings −π + 0.01 and π − 0.01
    e, _ = evaluate(xk, xn, u, dt, jacobians=False)
    for i in range(len(u)):
        expect_close(e[i], np.zeros(3), "e of edge %d, whose x_k+1 is the exact prediction across the cut (the "
                     "stored headings are wrapped)" % i, given=edge_given(xk, xn, u, dt, i), atol=1e-9)


def test_error_does_not_change_when_a_heading_changes_by_two_pi():
    """ψ and ψ + 2π are the same heading: adding ±2π to either pose's heading leaves e unchanged"""
    xk, xn, u, dt = random_edges(np.random.default_rng(11), 6)
    e, _ = evaluate(xk, xn, u, dt, jacobians=False)
    for which, shift in (("x_k", TWO_PI), ("x_k", -TWO_PI), ("x_k+1", TWO_PI), ("x_k+1", -TWO_PI)):
        a, b = xk.copy(), xn.copy()
        (a if which == "x_k" else b)[:, 2] += shift
        e2, _ = evaluate(a, b, u, dt, jacobians=False)
        for i in range(len(u)):
            expect_close(e2[i], e[i], "e of edge %d after adding %+.0f·π to the heading of %s (expected: e before)"
                         % (i, shift / np.pi, which), given=edge_given(a, b, u, dt, i), atol=1e-9)


def error_of_edge(xk, xn, u, dt, i, slot):
    """e of edge i as a function of the pose in ``slot`` (0: x_k, 1: x_k+1), through the vertex's update x ⊞ δ
    (which wraps the heading)."""
    def error(x):
        a, b = xk[i:i + 1].copy(), xn[i:i + 1].copy()
        pose = (a, b)[slot]
        pose[0] = x
        pose[0, 2] = wrap(x[2])
        return evaluate(a, b, u[i:i + 1], dt[i:i + 1], jacobians=False)[0][0]
    return error


def test_jacobians_match_central_differences():
    """J_k = ∂e/∂x_k and J_k+1 = ∂e/∂x_k+1 equal central differences of e (random poses, headings near ±π too)"""
    for seed in (1, 2, 3):
        xk, xn, u, dt = random_edges(np.random.default_rng(seed), 5)
        _, jac = evaluate(xk, xn, u, dt)
        for i in range(len(u)):
            given = edge_given(xk, xn, u, dt, i)
            for slot, name in ((0, "J_k = ∂e/∂x_k"), (1, "J_k+1 = ∂e/∂x_k+1")):
                expect_jacobian(error_of_edge(xk, xn, u, dt, i, slot), (xk, xn)[slot][i], jac[slot][i],
                                "%s of edge %d (seed %d)" % (name, i, seed), given=given)


def test_returns_shapes_and_no_jacobians_on_request():
    """evaluate returns e (E, 3) and [J_k, J_k+1] (E, 3, 3) each; with jacobians=False it returns (e, None)"""
    for n in (1, 4):
        xk, xn, u, dt = random_edges(np.random.default_rng(5), n, near_cut=False)
        e, _ = evaluate(xk, xn, u, dt)                     # checks the shapes
        e2, jac = evaluate(xk, xn, u, dt, jacobians=False)
        expect_equal(jac, None, "the Jacobians returned with jacobians=False (E = %d)" % n)
        expect_close(e2, e, "e with jacobians=False against e with jacobians=True (E = %d)" % n, atol=1e-12)


def test_all_edges_at_once_equal_one_at_a_time():
    """Edge i's row of e and block of each Jacobian depend only on edge i's poses, odometry and ΔT"""
    xk, xn, u, dt = random_edges(np.random.default_rng(7), 6)
    e, jac = evaluate(xk, xn, u, dt)
    for i in range(len(u)):
        ei, ji = evaluate(xk[i:i + 1], xn[i:i + 1], u[i:i + 1], dt[i:i + 1])
        given = edge_given(xk, xn, u, dt, i)
        expect_close(e[i], ei[0], "row %d of e (6 edges at once) against edge %d alone" % (i, i), given=given,
                     atol=1e-12)
        for k in (0, 1):
            expect_close(jac[k][i], ji[k][0], "J_%s of edge %d (6 at once) against edge %d alone"
                         % ("k" if k == 0 else "k+1", i, i), given=given, atol=1e-12)


# ---------------------------------------------------------------------------------------------- the step
R_ODO = np.array([[0.04, 0.005, 0.0], [0.005, 0.01, 0.0], [0.0, 0.0, 3e-4]])


def odometry(t, u):
    return Event(t, EventType.VEHICLE_ODOMETRY, np.asarray(u, dtype=float), R_ODO)


def started_system(x0, u0):
    """A SLAM system with odometry only (compass, GPS and laser disabled) after the tick at t = 0: the odometry u0
    and the initial condition x0 (P0 = 0, so vertex 0 is fixed)."""
    system = DriveBotSLAMSystem(SimulatorConfiguration(), SLAMOptions(optimization_period=None))
    system.process_events([odometry(0.0, u0), Event(0.0, EventType.INITIAL_CONDITION, x0, np.zeros((3, 3)))])
    return system


def graph_counts(system):
    vertices = [v for v in system.graph.vertices() if isinstance(v, VehicleVertex)]
    edges = [e for e in system.graph.edges() if isinstance(e, VehicleKinematicsEdge)]
    return vertices, edges


def test_one_vertex_and_one_kinematics_edge_per_tick():
    """Each tick adds one vehicle vertex and one kinematics edge from the previous vertex to it"""
    system = started_system([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    for k, t in enumerate((0.1, 0.2, 0.3), start=1):
        system.process_events([odometry(t, [1.0, 0.0, 0.1])])
        vertices, edges = graph_counts(system)
        expect_equal((len(vertices), len(edges)), (k + 1, k), "(vehicle vertices, kinematics edges) in the graph "
                     "after %d tick(s)" % k, given={"ticks at": [0.1 * j for j in range(1, k + 1)]})
    vv = system.vehicle_vertices
    expect_equal(len(vv), 4, "len(system.vehicle_vertices) after 3 ticks")
    expect_equal([v.id for v in vv], [0, 1, 2, 3], "the vertex ids (each its index in vehicle_vertices)")
    expect_close([v.time for v in vv], [0.0, 0.1, 0.2, 0.3], "the vertex times", atol=1e-12)
    expect_true(system.current_vehicle_vertex is vv[-1], "current_vehicle_vertex is the newest vertex",
                actual=system.current_vehicle_vertex)
    _, edges = graph_counts(system)
    pme = system.process_model_edges
    expect_equal(len(pme), 3, "len(system.process_model_edges) after 3 ticks")
    for j, e in enumerate(pme):
        expect_true(e in edges, "process_model_edges[%d] is a kinematics edge of the graph" % j, actual=e)
        expect_equal([v.id for v in e.vertices()], [j, j + 1], "the vertex ids of process_model_edges[%d], in slot "
                     "order [x_k, x_k+1]" % j)


def test_new_vertex_is_predicted_with_the_stored_odometry():
    """The new vertex starts at the process model's prediction from the previous vertex with the odometry
    received BEFORE this tick, over this tick's ΔT (heading wrapped)"""
    x0, u0, u1, u2 = [1.0, -2.0, 3.0], [2.0, 0.0, 0.5], [1.0, 0.0, -0.3], [5.0, 0.0, 0.0]
    system = started_system(x0, u0)
    system.process_events([odometry(0.4, u1)])         # x1 from x0 with u0 over 0.4 s: crosses ψ = π
    system.process_events([odometry(0.6, u2)])         # x2 from x1 with u1 over 0.2 s
    x1 = process_model(np.array(x0), u0, 0.4)
    x2 = process_model(x1, u1, 0.2)
    given = {"x0": x0, "u at t=0": u0, "u at t=0.4": u1, "u at t=0.6": u2, "ticks": [0.0, 0.4, 0.6]}
    vv = system.vehicle_vertices
    expect_equal(len(vv), 3, "len(vehicle_vertices) after the ticks at 0.4 s and 0.6 s", given=given)
    expect_close(vv[1].estimate, x1, "the estimate of vertex 1 (x0 ⊞ 0.4 M(ψ0) u0)", given=given, atol=1e-9)
    expect_close(vv[2].estimate, x2, "the estimate of vertex 2 (x1 ⊞ 0.2 M(ψ1) u1)", given=given, atol=1e-9)
    expect_close([vv[1].time, vv[2].time], [0.4, 0.6], "the times of vertices 1 and 2", given=given, atol=1e-12)


def test_edge_holds_the_odometry_its_information_and_dt():
    """The kinematics edge's measurement is the stored odometry, its information R⁻¹ and its dt the tick length"""
    us = [[2.0, 0.0, 0.5], [1.0, 0.0, -0.3], [3.0, 0.0, 0.1]]
    system = started_system([0.0, 0.0, 0.0], us[0])
    system.process_events([odometry(0.25, us[1])])
    system.process_events([odometry(0.35, us[2])])
    given = {"ticks at": [0.0, 0.25, 0.35], "odometry then": us, "R": R_ODO.tolist()}
    _, edges = graph_counts(system)
    expect_equal(len(edges), 2, "kinematics edges in the graph after two ticks", given=given)
    by_first = {e.vertex(0).id: e for e in edges}
    for k, dt in ((0, 0.25), (1, 0.1)):
        e = by_first.get(k)
        if e is None:
            fail("a kinematics edge from vertex %d" % k, given=given, note="none starts at vertex %d" % k)
        expect_close(e.measurement, us[k], "the measurement of the edge from vertex %d" % k, given=given, atol=1e-12)
        expect_close(e.dt, dt, "the dt of the edge from vertex %d" % k, given=given, atol=1e-12)
        expect_close(e.information, np.linalg.inv(R_ODO), "the information of the edge from vertex %d" % k,
                     given=given, rtol=1e-9, atol=1e-9)


def test_the_graph_can_be_optimised_after_every_tick():
    """After each tick the system optimises (its structure is rebuilt); noise-free predictions give χ² = 0"""
    system = started_system([0.0, 0.0, 0.5], [1.0, 0.0, 0.2])
    for t in (0.1, 0.2, 0.3, 0.4):
        system.process_events([odometry(t, [1.0, 0.0, 0.2])])
        try:
            chi2 = system.optimize()
        except Exception as err:  # noqa: BLE001 — the error is the feedback
            fail("system.optimize() after the tick at t = %.1f s" % t,
                 note="it raised %s: %s" % (type(err).__name__, err))
        expect_close(chi2, 0.0, "χ² after the tick at t = %.1f s (every vertex at its prediction)" % t, atol=1e-12)
    x, _ = system.platform_estimate()
    expect_close(x, system.vehicle_vertices[-1].estimate, "platform_estimate() is the newest vertex", atol=0)


def test_a_current_vertex_that_left_the_graph_is_added_back():
    """If the current vertex has left the graph (its edge was removed), the next tick adds it back and links it"""
    system = started_system([0.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    system.process_events([odometry(0.1, [1.0, 0.0, 0.0])])
    system.process_events([odometry(0.2, [1.0, 0.0, 0.0])])
    last = system.vehicle_vertices[-1]
    system.graph.remove_edge(system.process_model_edges[-1])   # as Q3a does: vertex 2 leaves the graph with it
    expect_true(last.graph is None, "vertex 2 left the graph with its only edge (set-up of this test)")
    system.process_events([odometry(0.3, [1.0, 0.0, 0.0])])
    expect_true(last.graph is system.graph, "vertex 2 is back in the graph after the next tick")
    vertices, edges = graph_counts(system)
    expect_equal((len(vertices), len(edges)), (4, 2), "(vehicle vertices, kinematics edges) in the graph")
    newest = system.vehicle_vertices[-1]
    linked = [e for e in edges if e.vertex(0) is last and e.vertex(1) is newest]
    expect_equal(len(linked), 1, "kinematics edges from vertex 2 to the new vertex 3")
    expect_close(newest.estimate, [0.3, 0.0, 0.0], "the estimate of vertex 3 (predicted from vertex 2)", atol=1e-9)
