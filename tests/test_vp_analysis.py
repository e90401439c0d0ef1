"""Victoria Park analysis helpers (notebook 23): exact answers on hand-made references and front-ends."""
import math
from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest

from helpers.advanced.online_slam import vp_analysis as va
from helpers.advanced.online_slam.victoria_park import victoria_park_scans
from helpers.datasets import read_dataset
from helpers.graph import VertexPointXY, VertexSE2

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


def test_odometry_drift_bad_input():
    with pytest.raises(ValueError, match="lengths"):
        va.odometry_drift(_dead_reckoning_reference(), lengths=(0,))
    with pytest.raises(ValueError, match="n_samples"):
        va.odometry_drift(_dead_reckoning_reference(), n_samples=0)
    short = SimpleNamespace(graph=SimpleNamespace(vertices=lambda: [VertexSE2(None, np.zeros(3))]))
    with pytest.raises(ValueError, match="reference"):
        va.odometry_drift(short)


def test_plot_map_draws_both_runs():
    import matplotlib.pyplot as plt
    ref = _dead_reckoning_reference()
    ref.landmark_vertices = {1: VertexPointXY(None, np.array([1.0, 2.0]))}
    fig, ax = plt.subplots()
    va.plot_map(ax, ref, ref, {"muted": "k", "alt": "g", "truth": "k"})
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[2] == "landmarks, ids known (1)" and len(ax.lines) == 4
    plt.close(fig)


def test_duplicate_landmarks_are_later_landmarks_of_an_earlier_majority_id():
    from helpers.advanced.online_slam.tracks import CONFIRMED, Track
    tracks = [Track(key=k, birth=0, parent=None, z0=np.zeros(2), R0=np.eye(2), status=CONFIRMED) for k in range(4)]
    for t, end in zip(tracks, (5, 2, 9, 3)):
        t.end = end
    assigned = np.array([1, 1, 0, 0, 0, 2, 2, 2, -1])                     # landmark of each observation
    truth = np.array([7, 7, 7, 7, 8, 8, 8, 7, 8])                         # file id of each observation
    steps = np.array([0, 4, 30, 31, 40, 41, 50, 60, 61])                  # odometry steps before each one
    fe = SimpleNamespace(confirmed_tracks=lambda: tracks, observation_assignment=lambda: assigned)
    rows = va.duplicate_landmarks(SimpleNamespace(frontend=fe, truth=truth), steps=steps)
    # landmark 1 (confirmed first, id 7, last seen at step 4); landmark 3 has no observation; landmark 0 is id 7
    # again, from step 30 on; landmark 2 is id 8, a tree of its own
    assert rows == [{"key": 0, "id": 7, "first": 1, "gap": 26}]
    with pytest.raises(ValueError, match="steps"):
        va.duplicate_landmarks(SimpleNamespace(frontend=fe, truth=truth), steps=steps[:-1])
    with pytest.raises(ValueError, match="res"):
        va.duplicate_landmarks(SimpleNamespace(frontend=None, truth=truth))


def test_observation_steps_follow_the_file():
    steps = va._observation_steps()
    stream = victoria_park_scans(read_dataset("victoria_park"))
    assert steps.shape == (3640,) and np.all(np.diff(steps) >= 0) and steps[-1] <= 6968
    first_scan = next(k for k, item in enumerate(stream) if item[0] == "scan")
    assert steps[0] == sum(item[0] == "odometry" for item in stream[:first_scan])
