"""Association on photographs scored against the board's corners (helpers.association.photos), on a hand-made case
whose every count is known, and its argument checks."""
import dataclasses

import numpy as np
import pytest

from helpers.association.common import finish, prepare
from helpers.association.nearest_neighbour import surprisal_nn
from helpers.association.photos import (Photo, PhotoPrior, evaluate_photos, feature_truth, merge_results,
                                        photo_trial)
from helpers.camera import Camera
from helpers.features import Features
from helpers.rotation import rot2rpy

CAMERA = Camera([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]], np.zeros(12), (640, 480))
#: six landmarks: a 3 × 2 board of 30 mm squares, seen square-on from 0.5 m (camera axes = board axes)
BOARD = np.array([[0.0, 0.03, 0.06, 0.0, 0.03, 0.06], [0.0, 0.0, 0.0, 0.03, 0.03, 0.03], np.zeros(6)])
POSE = np.concatenate([[0.03, 0.015, -0.5], rot2rpy(np.eye(3))])
CORNERS = CAMERA.world_to_pixel(BOARD, POSE)
#: the detector's features: corner 0 exact, 1 at 1.5 px, 2 at 2.5 px, 3 at 0.4 px, none near 4, corner 5 at 0.2 px
#: with a look-alike 6 px away, and two far features
OFFSETS = {0: (0.0, 0.0), 1: (1.5, 0.0), 2: (0.0, 2.5), 3: (0.4, 0.0), 5: (0.2, 0.0)}
Y = np.column_stack([CORNERS[:, j] + np.array(o) for j, o in OFFSETS.items()]
                    + [CORNERS[:, 5] + [0.0, 6.0], [20.0, 20.0], [600.0, 400.0]])


def _photo(tol=2.0):
    truth, dist = feature_truth(Y, CORNERS, tol)
    features = Features(score=np.linspace(1.0, 0.5, Y.shape[1]), x=Y[0], y=Y[1])
    return Photo("hand-made", np.zeros((480, 640), np.uint8), POSE, CORNERS, features, truth, dist)


def nearest_within_4px(density, Y):
    """A stand-in algorithm: each landmark takes its nearest feature within 4 px of the predicted mean."""
    problem = prepare(density, Y)
    mu = density.mean.reshape(-1, 2).T
    d = np.hypot(Y[0][None] - mu[0][:, None], Y[1][None] - mu[1][:, None])
    return finish(problem, np.where(d.min(axis=1) <= 4.0, d.argmin(axis=1), -1), "nearest within 4 px")


def test_feature_truth_by_hand():
    truth, dist = feature_truth(Y, CORNERS, 2.0)
    assert truth.tolist() == [0, 1, -1, 3, -1, 4]
    assert np.allclose(dist, [0.0, 1.5, 2.5, 0.4, dist[4], 0.2]) and dist[4] > 20
    assert feature_truth(Y, CORNERS, 3.0)[0].tolist() == [0, 1, 2, 3, -1, 4]
    empty_truth, empty_dist = feature_truth(np.zeros((2, 0)), CORNERS)
    assert empty_truth.tolist() == [-1] * 6 and np.all(np.isinf(empty_dist))


def test_counts_of_a_hand_made_evaluation():
    prior = PhotoPrior(position_sigma=1e-4, angle_sigma=1e-4, pixel_sigma=0.5)
    ev = evaluate_photos({"near": nearest_within_4px}, [_photo()], CAMERA, BOARD, prior, n_draws=3, seed=5,
                         error_scale=0.0)                    # no pose error: every draw is the same
    assert ev.idx["near"].shape == (1, 3, 6)
    assert np.all(ev.idx["near"] == [0, 1, 2, 3, -1, 4])     # corner 2's 2.5-px feature is taken
    at2, at3 = ev.overall(2.0).summary()["near"], ev.overall(3.0).summary()["near"]
    c = ev.overall(2.0).counts["near"]
    assert c["tp"].tolist() == [4] * 3 and c["n_pred"].tolist() == [5] * 3 and c["n_true"].tolist() == [4] * 3
    assert at2["precision"] == pytest.approx(4 / 5) and at2["recall"] == 1.0
    assert at3["precision"] == 1.0 and at3["recall"] == 1.0
    lo, hi = ev.overall(2.0).interval("near", "precision")
    assert lo < 0.8 < hi


def test_snn_on_the_hand_made_photo_finds_every_true_feature():
    prior = PhotoPrior(position_sigma=5e-4, angle_sigma=5e-4, pixel_sigma=0.5)
    sU = float(np.log(640 * 480))
    ev = evaluate_photos({"SNN": lambda D, Y: surprisal_nn(D, Y, sU)}, [_photo()], CAMERA, BOARD, prior,
                         n_draws=4, seed=1)
    # corners 0, 1, 3, 5 are found; the look-alike 6 px from corner 5 is never taken; corner 4 has nothing
    assert np.all(ev.idx["SNN"][..., [0, 1, 3, 5]] == [0, 1, 3, 4])
    assert np.all(ev.idx["SNN"][..., 4] == -1)


def test_pose_errors_are_drawn_at_the_stated_scale():
    prior = PhotoPrior(position_sigma=0.002, angle_sigma=0.005, pixel_sigma=0.5)
    errors = np.array([photo_trial((3, 0, t), _photo(), CAMERA, BOARD, prior, error_scale=2.0).pose_est - POSE
                       for t in range(400)])
    sd = errors.std(axis=0)
    # 400 draws: the sample σ is within 15 % of the true σ with probability > 0.999 (χ² with 399 dof)
    assert np.allclose(sd, 2.0 * np.array([0.002] * 3 + [0.005] * 3), rtol=0.15)


def test_merge_results_concatenates_the_photos():
    prior = PhotoPrior(position_sigma=1e-4, angle_sigma=1e-4)
    two = [_photo(), dataclasses.replace(_photo(), name="second")]
    ev = evaluate_photos({"near": nearest_within_4px}, two, CAMERA, BOARD, prior, 2, 0, 0.0)
    assert list(ev.results(2.0)) == ["hand-made", "second"]
    merged = ev.overall(2.0)
    assert merged.n_trials == 4 and merged.counts["near"]["tp"].sum() == 16


@pytest.mark.parametrize("kwargs, message", [
    ({"algorithms": {}}, r"^algorithms"),
    ({"photos": []}, r"^photos"),
    ({"photos": [_photo(), _photo()]}, r"^photos must have distinct names"),
    ({"prior": "tight"}, r"^prior"),
    ({"n_draws": 0}, r"^n_draws"),
    ({"seed": -1}, r"^seed"),
    ({"error_scale": -1.0}, r"^error_scale"),
])
def test_bad_arguments_name_themselves(kwargs, message):
    args = {"algorithms": {"near": nearest_within_4px}, "photos": [_photo()], "camera": CAMERA, "board": BOARD,
            "prior": PhotoPrior(), "n_draws": 1, "seed": 0, **kwargs}
    with pytest.raises(ValueError, match=message):
        evaluate_photos(**args)
    with pytest.raises(ValueError, match="^pixel_sigma"):
        PhotoPrior(pixel_sigma=0.0)
    with pytest.raises(ValueError, match="^results"):
        merge_results({})
