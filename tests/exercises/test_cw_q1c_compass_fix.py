"""Coursework 02, Q1c(ii): the corrected compass edge (public tests).

The compass model of the handout's appendix A.3 is z = ψ + Δψ_C + w; the edge's error is e = h(x) − z with
h = ψ + Δψ_C, an angle in [−π, π) like every angle error of the graph. The expected values below follow from that
definition on hand-made poses.
"""
from __future__ import annotations

import numpy as np
from feedback import expect_close, expect_equal, expect_jacobian, expect_shape, expect_true, fail

from helpers.graph import EdgeHeadingPrior

TWO_PI = 2.0 * np.pi


def wrap(a):
    """An angle (or array of angles) in [−π, π)."""
    return (np.asarray(a, dtype=float) + np.pi) % TWO_PI - np.pi


def evaluate(x, z, offset, jacobians=True):
    """The student's EdgeHeadingPrior.evaluate on E edges, with its return value checked for form."""
    x, z, offset = (np.array(a, dtype=float) for a in (x, z, offset))
    given = {"E (edges)": len(z)}
    out = EdgeHeadingPrior.evaluate([x.copy()], z.copy(), {"offset": offset.copy()}, jacobians)
    if not (isinstance(out, tuple) and len(out) == 2):
        fail("evaluate returns a pair (e, Jacobians)", given=given,
             note="got %s" % (type(out).__name__ if not isinstance(out, tuple) else "a tuple of %d" % len(out)))
    e, jac = out
    expect_shape(e, (len(z), 1), "the error e (one row per edge)", given=given)
    if jacobians:
        if not (isinstance(jac, (list, tuple)) and len(jac) == 1):
            fail("the Jacobians are a list [J] (one vertex)", given=given, note="got %r" % (jac,))
        expect_shape(jac[0], (len(z), 1, 3), "J = ∂e/∂x (one 1 × 3 block per edge)", given=given)
    return e, jac


def edge_given(x, z, offset, i, **more):
    """The inputs of edge i, for a failure message."""
    return {"x": x[i], "z": float(z[i, 0]), "offset": float(offset[i]), **more}


def random_edges(rng, n):
    """n edges with headings anywhere (two just inside ±π), offsets anywhere and readings z = wrap(ψ + offset + w)."""
    x = np.column_stack([rng.uniform(-50, 50, n), rng.uniform(-50, 50, n), rng.uniform(-np.pi, np.pi, n)])
    x[0, 2], x[1, 2] = np.pi - 1e-3, -np.pi + 2e-3
    offset = rng.uniform(-np.pi, np.pi, n)
    z = wrap(x[:, 2] + offset + rng.normal(0, 0.1, n))[:, None]
    return x, z, offset


def test_error_is_heading_plus_offset_minus_reading():
    """Away from the angle cut, e = ψ + Δψ_C − z for each edge with its own offset"""
    x = np.array([[0.0, 0.0, 0.3], [5.0, -2.0, -1.0], [1.0, 1.0, 2.0]])
    offset = np.array([0.2, 0.0, -0.5])
    z = np.array([[0.4], [-1.2], [1.0]])
    e, _ = evaluate(x, z, offset, jacobians=False)
    for i, expected in enumerate((0.1, 0.2, 0.5)):
        expect_close(e[i], [expected], "e of edge %d of 3" % i, given=edge_given(x, z, offset, i), atol=1e-12)


def test_error_is_an_angle_in_minus_pi_to_pi():
    """The error is the smallest angle from the reading to ψ + Δψ_C: in [−π, π), also when ψ + Δψ_C − z is not"""
    # ψ + Δψ_C = π/4 + 0.1 + 0.75π passes π, while the sensor's reading z is wrapped into [−π, π)
    psi, off = np.pi / 4 + 0.1, 0.75 * np.pi
    x = np.array([[0.0, 0.0, psi], [0.0, 0.0, -3.0], [0.0, 0.0, 3.0], [0.0, 0.0, 1.0]])
    offset = np.array([off, -1.0, 1.0, 0.0])
    z = np.array([[wrap(psi + off)], [wrap(-4.0 + 0.05)], [wrap(4.0 - 0.05)], [1.0 - 0.2]])
    expected = np.array([[0.0], [-0.05], [0.05], [0.2]])
    e, _ = evaluate(x, z, offset, jacobians=False)
    for i in range(len(z)):
        expect_close(e[i], expected[i], "e of edge %d of 4" % i,
                     given=edge_given(x, z, offset, i, **{"ψ + Δψ_C − z": float(x[i, 2] + offset[i] - z[i, 0])}),
                     atol=1e-9)
    x, z, offset = random_edges(np.random.default_rng(3), 40)
    e, _ = evaluate(x, z, offset, jacobians=False)
    for i in range(len(z)):
        raw = float(x[i, 2] + offset[i] - z[i, 0])
        given = edge_given(x, z, offset, i, **{"ψ + Δψ_C − z": raw})
        expect_true(-np.pi <= e[i, 0] < np.pi, "e of random edge %d lies in [−π, π)" % i, actual=float(e[i, 0]),
                    given=given)
        expect_close([np.cos(e[i, 0]), np.sin(e[i, 0])], [np.cos(raw), np.sin(raw)], "e of random edge %d is the "
                     "same angle as ψ + Δψ_C − z (cos and sin)" % i, given=given, atol=1e-9)


def test_error_does_not_change_when_an_angle_changes_by_two_pi():
    """ψ, Δψ_C or z plus 2π is the same angle: e is unchanged"""
    x, z, offset = random_edges(np.random.default_rng(5), 8)
    e, _ = evaluate(x, z, offset, jacobians=False)
    for name in ("ψ", "offset", "z"):
        for shift in (TWO_PI, -TWO_PI):
            a, b, c = x.copy(), z.copy(), offset.copy()
            if name == "ψ":
                a[:, 2] += shift
            elif name == "z":
                b += shift
            else:
                c += shift
            e2, _ = evaluate(a, b, c, jacobians=False)
            for i in range(len(b)):
                expect_close(e2[i], e[i], "e of edge %d after adding %+.0f·π to %s (expected: e before)"
                             % (i, shift / np.pi, name), given=edge_given(a, b, c, i), atol=1e-9)


def error_of_edge(x, z, offset, i):
    """e of edge i as a function of its pose, through the vertex's update x ⊞ δ (which wraps the heading)."""
    def error(xi):
        a = x[i:i + 1].copy()
        a[0] = xi
        a[0, 2] = wrap(xi[2])
        return evaluate(a, z[i:i + 1], offset[i:i + 1], jacobians=False)[0][0]
    return error


def test_jacobian_matches_central_differences():
    """J = ∂e/∂x equals central differences of e (random poses, headings near ±π too)"""
    for seed in (1, 2):
        x, z, offset = random_edges(np.random.default_rng(seed), 6)
        _, jac = evaluate(x, z, offset)
        for i in range(len(z)):
            expect_jacobian(error_of_edge(x, z, offset, i), x[i], jac[0][i],
                            "J = ∂e/∂x of edge %d (seed %d)" % (i, seed), given=edge_given(x, z, offset, i))


def test_returns_shapes_and_no_jacobians_on_request():
    """evaluate returns e (E, 1) and [J] with J (E, 1, 3); with jacobians=False it returns (e, None)"""
    for n in (1, 5):
        x, z, offset = random_edges(np.random.default_rng(9), max(n, 2))
        x, z, offset = x[:n], z[:n], offset[:n]
        e, _ = evaluate(x, z, offset)                   # checks the shapes
        e2, jac = evaluate(x, z, offset, jacobians=False)
        expect_equal(jac, None, "the Jacobians returned with jacobians=False (E = %d)" % n)
        expect_close(e2, e, "e with jacobians=False against e with jacobians=True (E = %d)" % n, atol=1e-12)


def test_all_edges_at_once_equal_one_at_a_time():
    """Edge i's row of e and block of J depend only on edge i's pose, reading and offset"""
    x, z, offset = random_edges(np.random.default_rng(7), 6)
    e, jac = evaluate(x, z, offset)
    for i in range(len(z)):
        ei, ji = evaluate(x[i:i + 1], z[i:i + 1], offset[i:i + 1])
        given = edge_given(x, z, offset, i)
        expect_close(e[i], ei[0], "row %d of e (6 edges at once) against edge %d alone" % (i, i), given=given,
                     atol=1e-12)
        expect_close(jac[0][i], ji[0][0], "J of edge %d (6 at once) against edge %d alone" % (i, i), given=given,
                     atol=1e-12)
