"""DriveBot edge models: analytic Jacobians against central differences through ⊞, and their semantics."""
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers.drivebot import BuggyCompassEdge, LandmarkVertex, VehicleKinematicsEdge, VehicleVertex
from helpers.drivebot.edges import predict
from helpers.graph import EdgeHeadingPrior, EdgePositionPrior, SparseOptimizer, VertexSE2


def _numeric_jacobians(cls, states, z, params, eps=1e-6):
    out = []
    for k, x in enumerate(states):
        d = x.shape[1]
        J = np.zeros((len(z), cls.measurement_dimension, d))
        for j in range(d):
            step = np.zeros_like(x)
            step[:, j] = eps
            plus = list(states)
            minus = list(states)
            plus[k] = type_oplus(k, cls)(x, step)
            minus[k] = type_oplus(k, cls)(x, -step)
            ep, _ = cls.evaluate(plus, z, params, jacobians=False)
            em, _ = cls.evaluate(minus, z, params, jacobians=False)
            J[:, :, j] = (ep - em) / (2 * eps)
        out.append(J)
    return out


def type_oplus(k, cls):
    return cls.vertex_types[k].oplus_batch


def _random_poses(rng, n):
    x = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-3.0, 3.0, n)])
    return x


@settings(max_examples=20, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000))
def test_kinematics_jacobians_central_differences(seed):
    rng = np.random.default_rng(seed)
    n = 7
    xk = _random_poses(rng, n)
    dt = rng.uniform(0.05, 0.5, n)
    u = np.column_stack([rng.uniform(0, 5, n), rng.normal(0, 0.2, n), rng.normal(0, 0.3, n)])
    xn = predict(xk, u + rng.normal(0, 0.5, (n, 3)), dt)
    e, J = VehicleKinematicsEdge.evaluate([xk, xn], u, {"dt": dt})
    Jn = _numeric_jacobians(VehicleKinematicsEdge, [xk, xn], u, {"dt": dt})
    for a, b in zip(J, Jn):
        assert np.allclose(a, b, rtol=1e-5, atol=1e-5)


@settings(max_examples=20, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000))
def test_buggy_compass_jacobian_central_differences(seed):
    rng = np.random.default_rng(seed)
    x = _random_poses(rng, 5)
    z = rng.uniform(-math.pi, math.pi, (5, 1))
    p = {"offset": rng.uniform(-3, 3, 5)}
    _, J = BuggyCompassEdge.evaluate([x], z, p)
    assert np.allclose(J[0], _numeric_jacobians(BuggyCompassEdge, [x], z, p)[0], atol=1e-6)


def test_kinematics_error_is_the_process_noise():
    rng = np.random.default_rng(1)
    xk = _random_poses(rng, 4)
    u = rng.normal(0, 1, (4, 3))
    v = rng.normal(0, 0.1, (4, 3))
    dt = np.full(4, 0.1)
    xn = predict(xk, u + v, dt)
    e, _ = VehicleKinematicsEdge.evaluate([xk, xn], u, {"dt": dt}, jacobians=False)
    assert np.allclose(e, v, atol=1e-9)


def test_initialize_gives_zero_error_and_wraps_heading():
    a = VehicleVertex(0.0, estimate=[1.0, 2.0, 3.1])
    b = VehicleVertex(0.1)
    e = VehicleKinematicsEdge([a, b], measurement=[2.0, 0.0, 1.0], information=np.eye(3), dt=0.1)
    e.initialize()
    assert -math.pi <= b.estimate[2] < math.pi
    assert np.allclose(e.error(), 0.0, atol=1e-12)
    assert b.time == pytest.approx(0.1) and isinstance(b, VertexSE2)


def test_buggy_and_fixed_compass_differ_by_two_pi_past_45_degrees():
    x = np.array([[0.0, 0.0, math.pi / 4 + 0.1]])
    off = 0.75 * math.pi
    z = np.array([[(x[0, 2] + off + math.pi) % (2 * math.pi) - math.pi]])  # the simulator's wrapped reading
    eb, _ = BuggyCompassEdge.evaluate([x], z, {"offset": np.array([off])}, jacobians=False)
    ef, _ = EdgeHeadingPrior.evaluate([x], z, {"offset": np.array([off])}, jacobians=False)
    assert eb[0, 0] == pytest.approx(2 * math.pi) and ef[0, 0] == pytest.approx(0.0, abs=1e-12)
    x[0, 2] = math.pi / 4 - 0.1
    z[0, 0] = x[0, 2] + off
    eb, _ = BuggyCompassEdge.evaluate([x], z, {"offset": np.array([off])}, jacobians=False)
    assert eb[0, 0] == pytest.approx(0.0, abs=1e-12)


def test_gps_edge_has_the_heading_column():
    v = VehicleVertex(0.0, estimate=[0.0, 0.0, 0.3])
    e = EdgePositionPrior([v], measurement=[0.0, 0.0], information=np.eye(2), lever_arm=[10.0, -20.0])
    J = e.jacobians()[0]
    c, s = math.cos(0.3), math.sin(0.3)
    assert np.allclose(J, [[1, 0, -s * 10 + c * 20], [0, 1, c * 10 + s * 20]])


def test_vertices_in_a_graph_and_bad_input():
    g = SparseOptimizer()
    a = VehicleVertex(0.0, id=0, estimate=[0, 0, 0], fixed=True)
    m = LandmarkVertex(3, id=3, estimate=[1.0, 2.0])
    g.add_vertex(a)
    g.add_vertex(m)
    assert m.landmark_id == 3 and g.number_of_vertices() == 2
    with pytest.raises(ValueError):
        VehicleKinematicsEdge([a, VehicleVertex(0.1)], measurement=[1, 0], information=np.eye(3))
    with pytest.raises(ValueError):
        VehicleKinematicsEdge([a, VehicleVertex(0.1)], measurement=[1, 0, 0], information=-np.eye(3))
