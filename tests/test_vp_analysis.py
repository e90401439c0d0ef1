"""Victoria Park analysis helpers (notebook 23): exact answers on hand-made references."""
import math
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

from helpers.datasets import read_dataset
from helpers.graph import VertexPointXY, VertexSE2
from helpers.advanced.online_slam import vp_analysis as va
from helpers.advanced.online_slam.victoria_park import victoria_park_scans

matplotlib.use("Agg")


def _dead_reckoning_reference(heading_offset_per_step=0.0):
    """A 'solution' that is the file's odometry composed from the origin (plus a heading drift per step)."""
    odo = [item[3] for item in victoria_park_scans(read_dataset("victoria_park")) if item[0] == "odometry"]
    p, X = np.zeros(3), [np.zeros(3)]
    for z in odo:
        c, s = math.cos(p[2]), math.sin(p[2])
        p = np.array([p[0] + c * z[0] - s * z[1], p[1] + s * z[0] + c * z[1], p[2] + z[2] + heading_offset_per_step])
        X.append(p)
    graph = SimpleNamespace(vertices=lambda: [VertexSE2(None, x) for x in X])
    return SimpleNamespace(graph=graph, frontend=None, landmark_vertices={})


def test_odometry_drift_is_zero_for_the_odometry_itself():
    rows = va.odometry_drift(_dead_reckoning_reference(), lengths=(5, 40), n_samples=10)
    assert [r["n"] for r in rows] == [5, 40]
    for r in rows:
        assert r["heading_error"] < 1e-9 and r["position_error"] < 1e-9 and r["nees"] < 1e-9
        assert r["heading_sigma"] > 0 and r["path"] > 0


def test_odometry_drift_sees_a_heading_bias():
    b = 1e-3
    rows = va.odometry_drift(_dead_reckoning_reference(b), lengths=(100,), n_samples=5)
    assert rows[0]["heading_bias"] == pytest.approx(100 * b, rel=1e-9)
    assert rows[0]["nees"] > 3


def test_near_duplicate_ids_and_bad_input():
    ref = SimpleNamespace(landmark_vertices={34: VertexPointXY(None, np.array([0.0, 0.0])),
                                             189: VertexPointXY(None, np.array([0.5, 0.0])),
                                             5: VertexPointXY(None, np.array([9.0, 0.0]))})
    pairs = va.near_duplicate_ids(ref, radius=1.0)
    assert len(pairs) == 1
    a, b, d, together, na, nb = pairs[0]
    assert (a, b, together, na, nb) == (34, 189, False, 41, 33) and d == pytest.approx(0.5)
    with pytest.raises(ValueError, match="radius"):
        va.near_duplicate_ids(ref, radius=-1)
    with pytest.raises(ValueError, match="reference"):
        va.near_duplicate_ids(SimpleNamespace(landmark_vertices={}))
    with pytest.raises(ValueError, match="lengths"):
        va.odometry_drift(_dead_reckoning_reference(), lengths=(0,))


def test_plot_map_draws_both_runs():
    import matplotlib.pyplot as plt
    ref = _dead_reckoning_reference()
    ref.landmark_vertices = {1: VertexPointXY(None, np.array([1.0, 2.0]))}
    fig, ax = plt.subplots()
    va.plot_map(ax, ref, ref, {"muted": "k", "alt": "g", "truth": "k"})
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[2] == "landmarks, ids known (1)" and len(ax.lines) == 4
    plt.close(fig)


def test_observed_points_and_smoothed_nearest_neighbour_on_a_one_tree_map():
    pts = va._observed_points(np.array([1.0, 2.0, math.pi / 2]), np.array([[2.0, 1.0], [0.0, math.pi / 2]]))
    np.testing.assert_allclose(pts, [[1.0, 4.0], [0.0, 2.0]], atol=1e-12)
    ref = _dead_reckoning_reference()
    ref.landmark_vertices = {34: VertexPointXY(None, np.array([0.0, 0.0]))}
    # one tree in the map: every observation's nearest tree is id 34, right for its 41 observations of 3 640
    assert va.smoothed_nearest_neighbour(ref) == pytest.approx(41 / 3640, rel=1e-12)
    with pytest.raises(ValueError, match="reference"):
        va.smoothed_nearest_neighbour(SimpleNamespace(landmark_vertices={}))


def test_known_id_nearest_neighbour_counts_every_re_observation():
    (row,) = va.known_id_nearest_neighbour(periods=(400,))
    assert row["period"] == 400 and row["re_observations"] == 3640 - 151   # all but each id's first sighting
    assert 0.5 < row["nn_correct"] < 1.0 and 0.0 < row["median_error"] < row["p90_error"]
    for bad in ((0,), (), 10, "10", (2.5,)):
        with pytest.raises(ValueError, match="periods"):
            va.known_id_nearest_neighbour(periods=bad)
    for bad in (None, SimpleNamespace()):
        with pytest.raises(ValueError, match="reference"):
            va.smoothed_nearest_neighbour(bad)


def test_scan_probe_is_for_the_known_id_run_only():
    from helpers.advanced.online_slam import run_victoria_park
    with pytest.raises(ValueError, match="scan_probe"):
        run_victoria_park("jcbb", scan_probe=lambda *a: None)
    with pytest.raises(ValueError, match="scan_probe"):
        run_victoria_park(None, scan_probe="not callable")


def test_merge_outcomes_judges_merges_by_majority_id():
    from helpers.advanced.online_slam.tracks import Track
    tracks = [Track(key=k, birth=0, parent=None, z0=np.zeros(2), R0=np.eye(2)) for k in range(4)]
    tracks[0].observations, tracks[1].observations = [0, 1, 2], [3, 4]        # 1 merged into 0: right
    tracks[2].observations, tracks[3].observations = [5, 6], [7, 8]           # 3 merged into 2, then undone: wrong
    tracks[1].alias_of = 0
    log = [{"track": 3, "old": 2, "scan": 9, "T": 40.0, "undone": True},
           {"track": 1, "old": 0, "scan": 4, "T": 0.5, "undone": False}]
    res = SimpleNamespace(frontend=SimpleNamespace(tracks=tracks, merge_log=log),
                          truth=np.array([7, 7, 7, 7, 7, 8, 8, 9, 9]))
    rows = va.merge_outcomes(res)
    assert [(r["track"], r["old"], r["scan"], r["wrong"], r["undone"]) for r in rows] == [(1, 0, 4, False, False),
                                                                                        (3, 2, 9, True, True)]
    assert rows[1]["T"] == 40.0
    with pytest.raises(ValueError, match="res"):
        va.merge_outcomes(SimpleNamespace(frontend=None, truth=np.zeros(1)))


def test_joined_ids_relabels_each_group_to_its_smallest_id():
    truth = np.array([5, 9, 7, 3, 9, 11, 2])
    out = va.joined_ids(truth, [(9, 7, 0.5, False), (11, 9)])      # 7–9–11 form one group; 5, 3, 2 stay
    np.testing.assert_array_equal(out, [5, 7, 7, 3, 7, 7, 2])
    np.testing.assert_array_equal(truth, [5, 9, 7, 3, 9, 11, 2])   # the input is not changed
    np.testing.assert_array_equal(va.joined_ids(truth, []), truth)


def test_joined_ids_rejects_bad_input():
    with pytest.raises(ValueError, match="pairs\\[0\\]"):
        va.joined_ids([1, 2], [(1,)])
    with pytest.raises(ValueError, match="truth"):
        va.joined_ids([[1, 2]], [])
