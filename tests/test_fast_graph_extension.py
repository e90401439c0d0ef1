"""Incremental structure: a graph that only grew is extended (``structure.extend_structure``), and the result is
the structure a fresh ``build_structure`` gives, array for array; anything else falls back to a fresh build."""

import dataclasses

import numpy as np
import pytest

from helpers.advanced.fast_graph import FastOptimizer
from helpers.advanced.fast_graph import structure as structure_module
from helpers.advanced.fast_graph.structure import build_structure, extend_structure
from helpers.graph import EdgeRangeBearing, EdgeSE2, EdgeSE2Prior, GaugeFreedomError, VertexPointXY, VertexSE2


def assert_same_structure(a, b):
    """Every array of two GraphStructures equal (blocks, groups and the Hessian pattern included)."""
    assert (a.dimension, a.handle_count, a.manifold) == (b.dimension, b.handle_count, b.manifold)
    for name in ("hessian_index", "free_state_index", "gradient_rows"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in ("n", "nnz"):
        assert getattr(a.pattern, name) == getattr(b.pattern, name)
    for name in ("indices", "indptr", "diag_pos", "scatter"):
        np.testing.assert_array_equal(getattr(a.pattern, name), getattr(b.pattern, name), err_msg=name)
    assert [g.cls for g in a.vertex_groups] == [g.cls for g in b.vertex_groups]
    for ga, gb in zip(a.vertex_groups, b.vertex_groups):
        for f in ("state_index", "hessian_rows", "handles"):
            np.testing.assert_array_equal(getattr(ga, f), getattr(gb, f))
    assert [blk.store for blk in a.blocks] == [blk.store for blk in b.blocks]
    for ba, bb in zip(a.blocks, b.blocks):
        for f in dataclasses.fields(ba):
            va, vb = getattr(ba, f.name), getattr(bb, f.name)
            if isinstance(va, list):
                for x, y in zip(va, vb):
                    np.testing.assert_array_equal(x, y)
            elif isinstance(va, dict):
                assert va.keys() == vb.keys()
                for k in va:
                    np.testing.assert_array_equal(va[k], vb[k])
            elif isinstance(va, np.ndarray):
                np.testing.assert_array_equal(va, vb, err_msg=f.name)
            else:
                assert va == vb or va is vb


def grow(g, rng, poses, points, ticks):
    """DriveBot-like growth: a new pose per tick with odometry from the last, observations of old or new points."""
    for _ in range(ticks):
        last = poses[-1]
        p = VertexSE2(len(poses), last.estimate + rng.normal(0, 0.1, 3) + [1.0, 0.0, 0.0])
        g.add_vertex(p)
        info = np.diag(rng.uniform(50, 200, 3))
        g.add_edge(EdgeSE2([last, p], measurement=rng.normal(0, 0.1, 3) + [1.0, 0, 0], information=info))
        poses.append(p)
        if rng.random() < 0.3:
            q = VertexPointXY(len(points), p.estimate[:2] + rng.normal(0, 3, 2))
            g.add_vertex(q)
            points.append(q)
        seen = rng.choice(len(points), size=min(len(points), 2), replace=False).tolist() if points else []
        if points and len(points) - 1 not in seen and points[-1].graph is g and not points[-1].edges():
            seen.append(len(points) - 1)             # a new point is seen at once (it would float otherwise)
        rows = [(p, points[i]) for i in seen]
        if rows:
            z = np.column_stack([rng.uniform(1, 5, len(rows)), rng.uniform(-1, 1, len(rows))])
            g.add_edges(EdgeRangeBearing, rows, z, np.diag([50.0, 200.0]))


def start(seed=0, n=4):
    rng = np.random.default_rng(seed)
    g = FastOptimizer()
    poses = [VertexSE2(0, [0.0, 0.0, 0.0], fixed=True)]
    g.add_vertex(poses[0])
    points = []
    grow(g, rng, poses, points, n)
    g.initialize_optimization()
    return g, rng, poses, points


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_growing_graph_is_extended_and_equals_a_fresh_build(seed):
    g, rng, poses, points = start(seed)
    for _ in range(6):
        old = g._structure
        grow(g, rng, poses, points, int(rng.integers(1, 4)))
        ext = extend_structure(old, g._vertex_store, g._edge_stores)
        assert ext is not None
        assert_same_structure(ext, build_structure(g._vertex_store, g._edge_stores))
        g.initialize_optimization()
        assert_same_structure(g._structure, ext)


def test_optimize_after_extension_equals_optimize_after_a_fresh_build():
    results = []
    for fresh in (False, True):
        g, rng, poses, points = start(3)
        chi2 = []
        for _ in range(8):
            grow(g, rng, poses, points, 2)
            if fresh:
                g._rebuild_needed = True
            g.initialize_optimization()
            chi2.append(g.optimize(5, algorithm="lm-gtsam"))
        results.append((chi2, [v.estimate.tolist() for v in g.vertices()]))
    assert results[0] == results[1]


def test_new_edge_class_and_new_fixed_vertex_extend():
    g, rng, poses, points = start(4)
    old = g._structure
    anchor = VertexSE2(1000, [5.0, 5.0, 0.0], fixed=True)
    g.add_vertex(anchor)
    extra = VertexSE2(1001, [6.0, 5.0, 0.0])
    g.add_vertex(extra)
    g.add_edge(EdgeSE2([anchor, extra], measurement=[1.0, 0.0, 0.0], information=np.eye(3)))
    p = VertexSE2(1002, [0.0, 1.0, 0.0])
    g.add_vertex(p)
    g.add_edge(EdgeSE2Prior([p], measurement=[0.0, 1.0, 0.0], information=np.eye(3)))   # a class new to the graph
    ext = extend_structure(old, g._vertex_store, g._edge_stores)
    assert ext is not None
    assert_same_structure(ext, build_structure(g._vertex_store, g._edge_stores))


def test_edge_between_old_vertices_falls_back_to_a_fresh_build(monkeypatch):
    g, rng, poses, points = start(5, n=6)
    old = g._structure
    g.add_edge(EdgeSE2([poses[1], poses[4]], measurement=[3.0, 0.0, 0.0], information=np.eye(3)))  # a loop closure
    assert extend_structure(old, g._vertex_store, g._edge_stores) is None
    calls = []
    monkeypatch.setattr(structure_module, "build_structure",
                        lambda *a: calls.append(1) or build_structure(*a))
    import helpers.advanced.fast_graph.optimizer as optimizer_module
    monkeypatch.setattr(optimizer_module, "build_structure", structure_module.build_structure)
    g.initialize_optimization()
    assert calls == [1]
    assert_same_structure(g._structure, build_structure(g._vertex_store, g._edge_stores))


def test_removal_or_fixing_forces_a_fresh_build():
    g, rng, poses, points = start(6, n=5)
    assert not g._rebuild_needed
    g.remove_edge(next(iter(poses[-1].edges())))
    assert g._rebuild_needed
    g.add_edge(EdgeSE2([poses[-2], poses[-1]], measurement=[1.0, 0.0, 0.0], information=np.eye(3)))
    g.initialize_optimization()
    assert not g._rebuild_needed
    poses[2].set_fixed(True)
    assert g._rebuild_needed
    g.initialize_optimization()
    assert_same_structure(g._structure, build_structure(g._vertex_store, g._edge_stores))


def test_floating_new_vertices_raise_gauge_freedom_and_keep_the_old_structure():
    g, rng, poses, points = start(7)
    old = g._structure
    a, b = VertexSE2(500, [0.0, 0.0, 0.0]), VertexSE2(501, [1.0, 0.0, 0.0])
    g.add_vertex(a)
    g.add_vertex(b)
    g.add_edge(EdgeSE2([a, b], measurement=[1.0, 0.0, 0.0], information=np.eye(3)))
    with pytest.raises(GaugeFreedomError) as err:
        g.initialize_optimization()
    assert {v.id for v in err.value.component} == {500, 501}
    assert g._structure is old
    g.add_edge(EdgeSE2([poses[-1], a], measurement=[1.0, 0.0, 0.0], information=np.eye(3)))
    g.initialize_optimization()
    assert_same_structure(g._structure, build_structure(g._vertex_store, g._edge_stores))


@pytest.mark.parametrize("length", [1, 5, 40])
def test_gauge_check_of_new_chains_short_and_long(length):
    """A chain of new poses anchored at its far end only (reached by spreading, or by the connected-components
    fallback for long chains), and the same chain floating."""
    for anchored in (True, False):
        g, rng, poses, points = start(8)
        old = g._structure
        chain = [VertexSE2(2000 + i, [float(i), 9.0, 0.0]) for i in range(length)]
        for v in chain:
            g.add_vertex(v)
        for u, v in zip(chain, chain[1:]):
            g.add_edge(EdgeSE2([u, v], measurement=[1.0, 0.0, 0.0], information=np.eye(3)))
        if anchored:
            g.add_edge(EdgeSE2([chain[-1], poses[-1]], measurement=[1.0, 0.0, 0.0], information=np.eye(3)))
            ext = extend_structure(old, g._vertex_store, g._edge_stores)
            assert_same_structure(ext, build_structure(g._vertex_store, g._edge_stores))
        else:
            with pytest.raises(GaugeFreedomError) as err:
                extend_structure(old, g._vertex_store, g._edge_stores)
            assert {v.id for v in err.value.component} == {v.id for v in chain}


def test_old_blocks_are_joined_or_regathered_as_a_fresh_build_would():
    """Diagonal old whitening joined with a full one (regathered), and an old edge's value edited before the
    extension (its class regathered): both equal a fresh build, and the edit reaches the linearisation."""
    g, rng, poses, points = start(9)
    old = g._structure
    p = VertexSE2(3000, poses[-1].estimate + [1.0, 0.0, 0.0])
    g.add_vertex(p)
    full = np.array([[100.0, 5.0, 0.0], [5.0, 100.0, 0.0], [0.0, 0.0, 50.0]])
    g.add_edge(EdgeSE2([poses[-1], p], measurement=[1.0, 0.0, 0.0], information=full))
    ext = extend_structure(old, g._vertex_store, g._edge_stores)
    assert_same_structure(ext, build_structure(g._vertex_store, g._edge_stores))
    g.initialize_optimization()
    old = g._structure
    edge = next(e for e in g.edges() if isinstance(e, EdgeRangeBearing))
    edge.set_measurement([2.5, 0.25])
    q = VertexSE2(3001, p.estimate + [1.0, 0.0, 0.0])
    g.add_vertex(q)
    g.add_edge(EdgeSE2([p, q], measurement=[1.0, 0.0, 0.0], information=full))
    g.initialize_optimization()
    assert_same_structure(g._structure, build_structure(g._vertex_store, g._edge_stores))
    assert g._structure.blocks[[b.store.cls for b in g._structure.blocks].index(EdgeRangeBearing)] is not \
        old.blocks[[b.store.cls for b in old.blocks].index(EdgeRangeBearing)]
