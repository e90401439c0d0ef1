"""The Lab 8 exploration's redraw (helpers.association.lab_explore.draw_snn) on a small hand-made scene."""
import numpy as np
import pytest
from matplotlib.figure import Figure

from helpers.association.lab_explore import draw_snn
from helpers.association.photos import PhotoPrior
from helpers.camera import Camera
from helpers.features import Features
from helpers.rotation import rot2rpy

CAMERA = Camera([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]], np.zeros(12), (640, 480))
LANDMARKS = np.array([[0.0, 0.1, 0.2, 0.0], [0.0, 0.0, 0.0, 0.1], np.zeros(4)])
POSE = np.concatenate([[0.1, 0.05, -0.5], rot2rpy(np.eye(3))])
TRUE_PIXELS = CAMERA.world_to_pixel(LANDMARKS, POSE)
# a feature at each landmark's pixel but the last, and look-alikes 12 px to the right of each
Y = np.hstack([TRUE_PIXELS[:, :3], TRUE_PIXELS[:, :3] + [[12.0], [0.0]]])
FEATURES = Features(score=np.linspace(1.0, 0.5, Y.shape[1]), x=Y[0], y=Y[1])
IMAGE = np.full((480, 640), 128, np.uint8)
PRIOR = PhotoPrior(position_sigma=0.004, angle_sigma=0.004, pixel_sigma=0.5)


def _draw(pose_error=None, **kwargs):
    fig = Figure(figsize=(6, 5))
    error = np.zeros(6) if pose_error is None else pose_error
    result, counts = draw_snn(fig, IMAGE, CAMERA, FEATURES, PRIOR.state(LANDMARKS, POSE + error),
                              true_pixels=TRUE_PIXELS, noise=PRIOR.noise, image_scale=1.0, **kwargs)
    return fig, result, counts


def test_at_the_true_pose_every_landmark_is_right_and_the_title_says_so():
    fig, result, counts = _draw()
    assert result.idx.tolist() == [0, 1, 2, -1]
    assert counts == {"correct": 3, "correct null": 1, "missed": 0, "wrong": 0}
    title = fig.axes[0].get_title()
    assert "3 correct, 1 correct null" in title and "3σ gate" in title and "JC" not in title


def test_a_pose_error_towards_the_look_alikes_makes_snn_take_them():
    # 12 px to the right at 0.5 m with f = 500 px: the camera 12 mm to the left (x is right, so −x moves it left)
    fig, result, counts = _draw(np.array([-0.012, 0, 0, 0, 0, 0]))
    assert result.idx.tolist()[:3] == [3, 4, 5] and counts["wrong"] == 3
    assert "3 wrong" in fig.axes[0].get_title()


def test_the_gate_and_joint_compatibility_knobs_reach_the_association():
    # predictions 6 px from the corners and from the look-alikes: inside a 3σ gate, outside a 0.5σ one
    halfway = np.array([-0.006, 0, 0, 0, 0, 0])
    assert _draw(halfway)[1].n_associated == 3 and _draw(halfway, n_sigma=0.5)[1].n_associated == 0
    fig, _, _ = _draw(enforce_joint_compatibility=True)
    assert "SNN + JC" in fig.axes[0].get_title()


def test_without_true_pixels_the_title_counts_the_associations():
    fig = Figure()
    _, counts = draw_snn(fig, IMAGE, CAMERA, FEATURES, PRIOR.state(LANDMARKS, POSE), noise=PRIOR.noise,
                         label="hand-made")
    assert counts == {} and fig.axes[0].get_title().startswith("hand-made: SNN, 3σ gate — 3 of 4 associated")


def test_bad_figure_is_named():
    with pytest.raises(ValueError, match="^fig must be a matplotlib Figure"):
        draw_snn("fig", IMAGE, CAMERA, FEATURES, PRIOR.state(LANDMARKS, POSE))
