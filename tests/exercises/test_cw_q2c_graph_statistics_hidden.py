"""Coursework 02, Q2c(i): value checks against the answer key on the q2_c run (instructor's tests, not shipped).

Fixture ``cw_q2c_graph_statistics_hidden`` (tools/fixture_recipes_q2q3.py): the structure of the q2_c run's final
graph (its vertices and edges; the statistics do not depend on the estimates) and the answer key's statistics.
"""
from __future__ import annotations

from feedback import expect_close, expect_equal, fixture
from test_cw_q2c_graph_statistics import build_graph, statistics

DATA = fixture("cw_q2c_graph_statistics_hidden")


def test_statistics_of_the_q2c_run():
    """The statistics of the q2_c run's graph equal the answer key's (5273 poses, 7 landmarks, 3227 observations)"""
    stats = statistics(build_graph(DATA), "the graph of the q2_c run")
    for key in ("vehicle_vertices", "landmark_vertices", "landmark_edges", "measurement_dimensions",
                "free_state_dimensions", "dof"):
        expect_equal(int(stats[key]), DATA["stat_" + key], key + " of the q2_c run")
    expect_equal(dict(stats["edges_by_type"]),
                 dict(zip(DATA["stat_edge_classes"].tolist(), DATA["stat_edge_counts"].tolist())),
                 "edges_by_type of the q2_c run")
    for key in ("observations_per_step", "observations_per_landmark"):
        expect_close(stats[key], DATA["stat_" + key], key + " of the q2_c run", rtol=1e-12)
