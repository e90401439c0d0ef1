"""DriveBot with the ids hidden: the noise-free run reproduces the known-id graph, the harder sensor, the report,
bad input; and the Victoria Park stream."""
import math

import numpy as np
import pytest

from helpers.advanced.hidden_ids import SensorCorruption, association_report, run_hidden_ids
from helpers.advanced.online_slam.victoria_park import run_victoria_park, victoria_park_scans
from helpers.drivebot.edges import LandmarkVertex
from helpers.drivebot.events import Event, EventType
from helpers.drivebot.runner import run_question
from helpers.graph import EdgeRangeBearing

SHORT = {"maximum_step_number": 300}


def _pairs(system, key_to_id):
    """{(pose time, true landmark id)} of every range-bearing edge of a DriveBot graph."""
    out = set()
    for e in system.graph.edges():
        if isinstance(e, EdgeRangeBearing):
            lm = e.vertex(1)
            out.add((round(e.vertex(0).time, 6), key_to_id(lm)))
    return out


def test_noise_free_run_with_ids_hidden_reproduces_the_known_id_graph():
    known = run_question("q2_b", seed=3, perturb_with_noise=False, **SHORT)
    hidden = run_hidden_ids("q2_b", data_association="jcbb", seed=3, perturb_with_noise=False, **SHORT)
    report = association_report(hidden)
    assert report["precision"] == 1.0 and report["recall"] == 1.0
    matching = report["matching"]                                    # front-end key → true id
    ids = _pairs(known.system, lambda v: v.landmark_id)
    found = _pairs(hidden.system, lambda v: matching[v.landmark_id - 1])
    assert found == ids                                              # the same (pose, landmark) edges
    stats_k, stats_h = known.graph_statistics(), hidden.graph_statistics()
    for key in ("vehicle_vertices", "landmark_vertices", "landmark_edges", "dof"):
        assert stats_k[key] == stats_h[key]
    assert hidden.final_chi2 == pytest.approx(known.final_chi2, rel=1e-6, abs=1e-9)


def test_ids_given_is_the_coursework_run():
    a = run_question("q2_b", seed=1, **SHORT)
    b = run_hidden_ids("q2_b", data_association=None, seed=1, **SHORT)
    assert a.setup is None and b.setup is None
    assert b.final_chi2 == a.final_chi2
    np.testing.assert_array_equal(a.vehicle_state_history, b.vehicle_state_history)
    rep = association_report(b)
    assert rep["precision"] == 1.0 and rep["n_landmarks"] == rep["n_true_landmarks"]
    assert rep["n_pairings"] == a.graph_statistics()["landmark_edges"]


def test_clutter_and_missed_detections_with_jcbb():
    res = run_hidden_ids("q2_b", data_association="jcbb", clutter_rate=2.0, detection_probability=0.9, seed=0,
                       maximum_step_number=200)
    rep = association_report(res)
    assert rep["n_clutter"] > 300 and rep["precision"] >= 0.98 and rep["recall"] >= 0.9
    assert rep["n_matched"] == rep["n_true_landmarks"] and rep["map_rmse"] < 0.5
    a, b = (association_report(run_hidden_ids("q2_b", data_association="jcbb", clutter_rate=2.0,
                                              detection_probability=0.9, seed=4, maximum_step_number=60))
            for _ in range(2))
    assert a["n_pairings"] == b["n_pairings"] and a["n_clutter"] == b["n_clutter"]    # seeded


def test_sensor_corruption():
    rng = np.random.default_rng(0)
    cov = np.diag([0.01, 0.0003])
    event = Event(1.0, EventType.LANDMARK, np.array([[3.0, 4.0], [0.1, -0.2]]), cov, landmark_ids=np.array([5, 9]))
    c = SensorCorruption(3.0, 0.5, 10.0, cov, rng)
    kept = []
    for _ in range(200):
        new, truth = c.scan(1.0, event)
        assert new is None or (new.data.shape[1] == truth.size and np.all(new.data[0] <= 10.0))
        if new is not None:
            assert np.array_equal(new.landmark_ids, np.arange(1, truth.size + 1))    # ids hidden
            for col, t in enumerate(truth):
                if t:
                    assert new.data[0, col] == {5: 3.0, 9: 4.0}[t]
        kept.append(np.count_nonzero(truth))
    assert 0.4 < np.mean(kept) / 2 < 0.6
    empty, truth = SensorCorruption(0.0, 1.0, 10.0, cov, rng).scan(1.0, None)
    assert empty is None and truth.size == 0
    shown, truth = SensorCorruption(0.0, 1.0, 10.0, cov, rng).scan(1.0, event, hide_ids=False)
    assert sorted(shown.landmark_ids.tolist()) == [5, 9]
    for new in (shown, c.scan(2.0, event)[0] or shown):      # what the checking constructor would have built
        checked = Event(new.time, new.type, new.data, new.covariance, landmark_ids=new.landmark_ids)
        for name in ("time", "type", "data", "covariance", "landmark_ids"):
            a, b = getattr(new, name), getattr(checked, name)
            assert type(a) is type(b) and (a == b if not isinstance(a, np.ndarray) else
                                            a.dtype == b.dtype and np.array_equal(a, b))
    with pytest.raises(ValueError, match="covariance must be the laser's finite"):
        SensorCorruption(0.0, 1.0, 10.0, np.eye(3), rng)


@pytest.mark.parametrize("kwargs, name", [
    ({"data_association": "hungarian"}, "data_association"),
    ({"clutter_rate": -1.0}, "clutter_rate"),
    ({"clutter_rate": math.inf}, "clutter_rate"),
    ({"detection_probability": 1.5}, "detection_probability"),
    ({"detection_probability": -0.1}, "detection_probability"),
    ({"data_association": None, "clutter_rate": 1.0}, "clutter_rate"),
    ({"seed": -1}, "seed"),
    ({"association_period": 0}, "association_period"),
])
def test_bad_arguments(kwargs, name):
    args = {"data_association": "jcbb", **kwargs}
    with pytest.raises(ValueError, match=name):
        run_hidden_ids("q2_b", **args)


def test_missed_detections_with_ids_given_thin_the_known_id_scans():
    full = run_question("q2_b", seed=2, **SHORT)
    thin = run_hidden_ids("q2_b", data_association=None, detection_probability=0.5, seed=2, **SHORT)
    assert thin.setup is not None and not hasattr(thin.system, "frontend")
    n_full = full.graph_statistics()["landmark_edges"]
    n_thin = thin.graph_statistics()["landmark_edges"]
    assert 0.35 * n_full < n_thin < 0.65 * n_full
    rep = association_report(thin)
    assert rep["precision"] == 1.0 and rep["detection_probability"] == 0.5
    with pytest.raises(ValueError, match="options of the association"):
        run_hidden_ids("q2_b", data_association=None, detection_probability=0.5, n_sigma=2.0, **SHORT)


def test_landmark_vertices_are_registered_for_the_estimates():
    res = run_hidden_ids("q2_b", data_association="mahalanobis", seed=0, maximum_step_number=150)
    x, P, ids = res.landmark_estimates()
    assert x.shape[1] == len(res.system.frontend.confirmed_tracks()) == ids.size > 0
    assert all(isinstance(res.system.landmark_vertices[i], LandmarkVertex) for i in ids)


def test_victoria_park_stream_and_bad_input():
    from helpers.datasets import read_dataset
    stream = victoria_park_scans(read_dataset("victoria_park"))
    scans = [s for s in stream if s[0] == "scan"]
    assert sum(s[0] == "odometry" for s in stream) == 6968 and len(scans) == 3331
    assert sum(s[2].shape[1] for s in scans) == 3640 and max(s[2].shape[1] for s in scans) == 2
    with pytest.raises(ValueError, match="data_association"):
        run_victoria_park("nearest")
    with pytest.raises(ValueError, match="optimization_period"):
        run_victoria_park("jcbb", optimization_period=0)
    with pytest.raises(ValueError, match="measurement_sigmas"):
        run_victoria_park("jcbb", measurement_sigmas=(0.1, -1.0))
