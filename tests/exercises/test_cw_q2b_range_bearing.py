"""Coursework 02, Q2b: the range-bearing edge and the SLAM system's landmark handler (public tests).

The edge's expected errors come from the landmark model of appendix A.5, computed here with numpy on hand-made
poses and landmarks; its Jacobians are checked against central differences of that model. The handler is run on a
system that has only its initial pose (and, by hand, a second pose): no prediction step is needed.
"""
from __future__ import annotations

import math

import numpy as np
from feedback import expect_close, expect_equal, expect_jacobian, expect_shape, expect_true, fail

from helpers.drivebot.config import SimulatorConfiguration
from helpers.drivebot.edges import LandmarkVertex, VehicleVertex
from helpers.drivebot.events import Event, EventType
from helpers.drivebot.slam_system import DriveBotSLAMSystem
from helpers.graph import EdgeRangeBearing

R_LASER = np.diag([0.1 ** 2, math.radians(1.0) ** 2])


def model(pose, landmark):
    """Appendix A.5 from first principles: [range, bearing relative to the heading] (bearing not wrapped)."""
    dx, dy = landmark[0] - pose[0], landmark[1] - pose[1]
    return np.array([math.hypot(dx, dy), math.atan2(dy, dx) - pose[2]])


def wrapped(angle):
    """An angle in [−π, π)."""
    return (angle + math.pi) % (2 * math.pi) - math.pi


def evaluate(poses, landmarks, z, jacobians=True):
    """EdgeRangeBearing.evaluate on (E, 3) poses, (E, 2) landmarks, (E, 2) measurements, with its output checked
    for form: e (E, 2) and, with Jacobians, [J_pose (E, 2, 3), J_landmark (E, 2, 2)]."""
    poses, landmarks, z = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (poses, landmarks, z))
    given = {"pose [x, y, ψ]": poses, "landmark [x, y]": landmarks, "z [r, β]": z}
    out = EdgeRangeBearing.evaluate([poses.copy(), landmarks.copy()], z.copy(), {}, jacobians)
    if not isinstance(out, tuple) or len(out) != 2:
        fail("evaluate returns a pair (errors, Jacobians)", given=given, actual=out)
    e, jac = out
    expect_shape(e, (len(z), 2), "the errors: one row [e_r, e_β] per edge", given=given)
    if not jacobians:
        expect_equal(jac, None, "the Jacobians when jacobians=False", given=given)
        return e, None
    if not isinstance(jac, (list, tuple)) or len(jac) != 2:
        fail("the Jacobians: a list [J_pose, J_landmark], one per vertex", given=given, actual=jac)
    expect_shape(jac[0], (len(z), 2, 3), "J_pose = ∂e/∂[x, y, ψ], one 2 × 3 block per edge", given=given)
    expect_shape(jac[1], (len(z), 2, 2), "J_landmark = ∂e/∂[m_x, m_y], one 2 × 2 block per edge", given=given)
    return e, jac


# ------------------------------------------------------------------------------------------------ the edge
def test_error_is_the_predicted_range_and_bearing_minus_the_measurement():
    """The error is [predicted range − z_r, predicted bearing − z_β] with the bearing relative to the heading"""
    cases = [  # pose, landmark, z
        ([1.0, 2.0, 0.3], [4.0, 6.0], [4.5, 0.4]),          # a 3-4-5 triangle
        ([0.0, 0.0, math.pi / 2], [0.0, 10.0], [10.0, 0.0]),  # straight ahead when heading north
        ([0.0, 0.0, 0.0], [0.0, 10.0], [9.0, 1.5]),           # to the left when heading east
        ([-3.0, 5.0, -2.0], [-8.0, -1.0], [7.0, -0.2]),
    ]
    for pose, landmark, z in cases:
        e, _ = evaluate(pose, landmark, z, jacobians=False)
        expected = model(pose, landmark) - np.array(z)
        expected[1] = wrapped(expected[1])
        expect_close(e[0], expected, "the error of one edge", given={"pose": pose, "landmark": landmark, "z": z})


def test_bearing_error_is_wrapped_into_minus_pi_to_pi():
    """The bearing error is an angle: it is wrapped into [−π, π), also when the heading and the bearing sit on
    opposite sides of the ±π cut"""
    cases = [  # pose, landmark, z: the unwrapped bearing error is close to ±2π or beyond
        ([0.0, 0.0, 0.0], [-10.0, 1e-3], [10.0, -math.pi + 1e-4]),    # behind the vehicle: atan2 ≈ +π, z_β ≈ −π
        ([0.0, 0.0, 0.0], [-10.0, -1e-3], [10.0, math.pi - 1e-4]),    # the mirror case
        ([2.0, 1.0, 3.0], [2.0, -9.0], [10.0, 1.7]),                  # heading 3 rad, landmark to the south
        ([0.0, 0.0, -3.1], [5.0, 0.1], [5.0, -2.9]),
    ]
    for pose, landmark, z in cases:
        e, _ = evaluate(pose, landmark, z, jacobians=False)
        raw = float(model(pose, landmark)[1] - z[1])
        given = {"pose": pose, "landmark": landmark, "z": z, "unwrapped bearing error": raw}
        expect_true(-math.pi <= e[0, 1] < math.pi, "the bearing error lies in [−π, π)", given=given,
                    actual=float(e[0, 1]))
        expect_close(e[0, 1], wrapped(raw), "the wrapped bearing error", given=given)


def test_jacobians_match_central_differences():
    """Both Jacobians (with respect to the pose and to the landmark) equal central differences of the model"""
    rng = np.random.default_rng(7)
    for _ in range(8):
        pose = np.r_[rng.uniform(-20, 20, 2), rng.uniform(-math.pi, math.pi)]
        direction = rng.uniform(-math.pi, math.pi)
        landmark = pose[:2] + rng.uniform(2, 30) * np.array([math.cos(direction), math.sin(direction)])
        z = model(pose, landmark) + rng.normal(0, [0.1, 0.02])   # bearing error small: far from the ±π cut
        _, (j_pose, j_landmark) = evaluate(pose, landmark, z)
        given = {"pose": pose, "landmark": landmark, "z": z}
        expect_jacobian(lambda x, m=landmark, z=z: model(x, m) - z, pose, j_pose[0], "∂e/∂pose", given=given)
        expect_jacobian(lambda m, x=pose, z=z: model(x, m) - z, landmark, j_landmark[0], "∂e/∂landmark",
                        given=given)


def test_all_edges_at_once_equal_one_at_a_time():
    """Evaluated together, E edges give row by row what each edge gives on its own (no mixing of rows)"""
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(-10, 10, (6, 2)), rng.uniform(-3, 3, 6)])
    landmarks = poses[:, :2] + rng.uniform(-15, 15, (6, 2))
    z = np.column_stack([rng.uniform(1, 20, 6), rng.uniform(-3, 3, 6)])
    e, (j_pose, j_landmark) = evaluate(poses, landmarks, z)
    e_only, _ = evaluate(poses, landmarks, z, jacobians=False)
    expect_close(e_only, e, "the errors with jacobians=False equal those with jacobians=True",
                 given={"poses": poses, "landmarks": landmarks, "z": z})
    for t in range(6):
        e1, (jp1, jl1) = evaluate(poses[t], landmarks[t], z[t])
        given = {"edge": t, "pose": poses[t], "landmark": landmarks[t], "z": z[t]}
        expect_close(e[t], e1[0], "row %d of the errors of all edges" % t, given=given, rtol=1e-12, atol=1e-12)
        expect_close(j_pose[t], jp1[0], "block %d of J_pose of all edges" % t, given=given, rtol=1e-12, atol=1e-12)
        expect_close(j_landmark[t], jl1[0], "block %d of J_landmark of all edges" % t, given=given,
                     rtol=1e-12, atol=1e-12)


# ------------------------------------------------------------------------------------------------ the handler
def initialised_system(x0):
    """A SLAM system with the laser enabled and only its first (fixed) vehicle vertex at ``x0``."""
    system = DriveBotSLAMSystem(SimulatorConfiguration(enable_laser=True))
    system.process_events([Event(0.0, EventType.INITIAL_CONDITION, np.asarray(x0, float), np.zeros((3, 3)))])
    return system


def landmark_event(time, z, ids, covariance=R_LASER):
    return Event(time, EventType.LANDMARK, np.asarray(z, float), covariance, np.asarray(ids))


def inverse_observation(pose, z):
    """The landmark position that the model of A.5 maps to z = [r, β] from ``pose`` (first principles)."""
    a = pose[2] + z[1]
    return np.array([pose[0] + z[0] * math.cos(a), pose[1] + z[0] * math.sin(a)])


def range_bearing_edges(system):
    return [e for e in system.graph.edges() if isinstance(e, EdgeRangeBearing)]


def test_first_sighting_creates_the_landmark_at_the_inverse_observation():
    """A landmark seen for the first time gets a LandmarkVertex where the observation puts it (appendix A.5
    inverted at the current vehicle pose), recorded in landmark_vertices under its id"""
    x0 = np.array([2.0, -1.0, 0.7])
    system = initialised_system(x0)
    z = np.array([[5.0, 12.0], [0.4, -2.5]])
    system._handle_landmarks(landmark_event(0.0, z, [3, 7]))
    given = {"vehicle pose": x0, "z (columns [r; β])": z, "landmark_ids": [3, 7]}
    expect_equal(sorted(system.landmark_vertices), [3, 7], "the keys of landmark_vertices", given=given)
    for col, lid in enumerate([3, 7]):
        v = system.landmark_vertices[lid]
        expect_true(isinstance(v, LandmarkVertex), "landmark_vertices[%d] is a LandmarkVertex" % lid, given=given,
                    actual=type(v).__name__)
        expect_true(v.graph is system.graph, "landmark %d's vertex is in the system's graph" % lid, given=given)
        expect_equal((v.landmark_id, v.id), (lid, lid), "landmark %d's (landmark_id, id)" % lid, given=given)
        expect_close(v.estimate, inverse_observation(x0, z[:, col]), "the initial position of landmark %d" % lid,
                     given=given, rtol=1e-12, atol=1e-12)


def test_one_range_bearing_edge_per_observation():
    """Every observation adds one EdgeRangeBearing from the current vehicle vertex to its landmark, with the
    observation as its measurement and the inverse of the event's covariance as its information"""
    system = initialised_system([0.0, 0.0, 0.0])
    z = np.array([[3.0, 4.0, 8.0], [0.1, 2.0, -1.0]])
    system._handle_landmarks(landmark_event(0.0, z, [5, 1, 2]))
    edges = range_bearing_edges(system)
    given = {"z (columns [r; β])": z, "landmark_ids": [5, 1, 2], "covariance": R_LASER}
    expect_equal(len(edges), 3, "the number of range-bearing edges after one event with 3 observations",
                 given=given)
    for col, (edge, lid) in enumerate(zip(edges, [5, 1, 2])):
        expect_true(edge.vertex(0) is system.current_vehicle_vertex and edge.vertex(1) is system.landmark_vertices[lid],
                    "edge %d joins (current vehicle vertex, landmark %d), in that order" % (col, lid), given=given,
                    actual=repr(edge))
        expect_close(edge.measurement, z[:, col], "edge %d's measurement" % col, given=given)
        expect_close(edge.information, np.linalg.inv(R_LASER), "edge %d's information" % col, given=given,
                     rtol=1e-9)


def test_later_sightings_add_edges_and_do_not_move_the_landmark():
    """A landmark seen again gets a new edge from the new pose but keeps its vertex and its estimate; a new one
    in the same event is placed from the new pose"""
    system = initialised_system([0.0, 0.0, 0.0])
    system._handle_landmarks(landmark_event(0.0, [[10.0], [0.5]], [7]))
    first = system.landmark_vertices[7]
    before = first.estimate
    # a second pose, added by hand (the prediction step is another exercise)
    pose = np.array([3.0, 1.0, -0.4])
    vehicle = VehicleVertex(0.1, id=1, estimate=pose)
    system.graph.add_vertex(vehicle)
    system.vehicle_vertices.append(vehicle)
    system.current_vehicle_vertex = vehicle
    z = np.array([[8.0, 6.0], [0.9, -1.2]])
    system._handle_landmarks(landmark_event(0.1, z, [7, 9]))
    given = {"first pose": [0, 0, 0], "first z": [10.0, 0.5], "second pose": pose, "second z": z,
             "landmark_ids": [7, 9]}
    expect_true(system.landmark_vertices[7] is first, "landmark 7 keeps its vertex", given=given)
    expect_close(first.estimate, before, "landmark 7's estimate after it is seen again", given=given)
    expect_equal(sum(isinstance(v, LandmarkVertex) for v in system.graph.vertices()), 2,
                 "the number of landmark vertices in the graph", given=given)
    expect_close(system.landmark_vertices[9].estimate, inverse_observation(pose, z[:, 1]),
                 "the initial position of landmark 9, first seen from the second pose", given=given,
                 rtol=1e-12, atol=1e-12)
    edges = range_bearing_edges(system)
    expect_equal(len(edges), 3, "the number of range-bearing edges", given=given)
    for edge, lid in zip(edges[1:], [7, 9]):
        expect_true(edge.vertex(0) is vehicle and edge.vertex(1) is system.landmark_vertices[lid],
                    "the new edge of landmark %d starts at the second pose" % lid, given=given, actual=repr(edge))


def test_the_optimiser_structure_is_rebuilt_after_new_landmarks():
    """The handler marks the system's structure as changed, so the next build includes the new landmarks"""
    system = initialised_system([0.0, 0.0, 0.0])
    system.ensure_structure()
    system._handle_landmarks(landmark_event(0.0, [[4.0, 9.0], [0.3, 2.2]], [1, 2]))
    system.ensure_structure()
    expect_equal(system.graph.dimension, 4, "the free state dimension after ensure_structure() (two landmarks of "
                 "2 states; the first vehicle vertex is fixed)", given={"landmark_ids": [1, 2]})
