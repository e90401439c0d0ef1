"""Calibration from chessboard photographs (helpers.calibration): a rendered board seen by a known camera is
recovered; the workbook's camera model reproduces cv2.projectPoints on a fitted camera; the camera file round-trips;
bad folders raise clear errors."""
import functools

import cv2
import numpy as np
import pytest

from helpers.calibration import DISTORTION_MODELS, calibrate, calibrate_folder, choose_model, find_boards
from helpers.camera import Camera
from helpers.paths import data_dir
from helpers.rotation import rot2rpy, rpy2rot
from helpers.scene import SQUARE_SIZE, render_lab_scene

PATTERN = (10, 7)
#: the known camera: 640 × 480, barrel distortion with a small decentring (the k1k2p1p2 model)
TRUE_K = np.array([[410.0, 0.0, 318.0], [0.0, 412.0, 243.0], [0.0, 0.0, 1.0]])
TRUE_D = np.array([-0.22, 0.06, 0.0015, -0.0008])


def _look_at(position, target=(0.099, 0.066, 0.0), up=(1.0, 0.0, 0.0)):
    """Camera pose [rCNn; Θnc] at ``position`` with its optical axis through ``target``."""
    r = np.asarray(position, float)
    z = np.asarray(target, float) - r
    z /= np.linalg.norm(z)
    x = np.asarray(up, float) - z * (z @ np.asarray(up, float))
    x /= np.linalg.norm(x)
    return np.concatenate([r, rot2rpy(np.column_stack([x, np.cross(z, x), z]))])


#: nine views from 0.30–0.38 m, tilted up to about 35°, with the board near the centre and in each quarter of the
#: image (the optical axis aimed beside it), so that the distortion is seen out to the corners
_C = np.array([0.099, 0.066, 0.0])
POSES = [_look_at(p, _C + t) for p, t in (
    ([0.10, 0.07, -0.36], [0, 0, 0]), ([0.25, 0.07, -0.33], [0, 0, 0]), ([-0.05, 0.07, -0.34], [0, 0, 0]),
    ([0.10, 0.22, -0.33], [0, 0, 0]), ([0.10, -0.09, -0.35], [0, 0, 0]),
    ([0.12, 0.09, -0.30], [0.07, 0.05, 0]), ([0.08, 0.09, -0.30], [-0.07, 0.05, 0]),
    ([0.12, 0.05, -0.30], [0.07, -0.05, 0]), ([0.08, 0.05, -0.30], [-0.07, -0.05, 0]))]


@functools.lru_cache(maxsize=1)
def _rendered_folder(tmp_root):
    camera = Camera(TRUE_K, TRUE_D, (640, 480))
    for k, pose in enumerate(POSES):
        image = render_lab_scene(camera, pose, seed=k, markers=np.zeros((3, 0)), card=False).image
        cv2.imwrite(str(tmp_root / f"view{k:02d}.png"), image)
    (tmp_root / "notes.txt").write_text("not an image")
    return camera


@pytest.fixture(scope="module")
def rendered(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rendered_board")
    return folder, _rendered_folder(folder)


def test_rendered_board_recovers_the_known_camera(rendered):
    folder, truth = rendered
    cal = calibrate_folder(folder, PATTERN, SQUARE_SIZE, model="k1k2p1p2")
    assert cal.views.names == tuple(f"view{k:02d}.png" for k in range(len(POSES)))
    assert cal.rms < 0.15 and cal.per_image_rms.max() < 0.2
    K, d = cal.camera.K, cal.camera.dist_coeffs
    assert np.allclose(np.diag(K)[:2], np.diag(TRUE_K)[:2], rtol=5e-3)
    assert np.allclose(K[:2, 2], TRUE_K[:2, 2], atol=2.0)
    assert np.allclose(d[:2], TRUE_D[:2], atol=0.02) and np.allclose(d[2:4], TRUE_D[2:], atol=1e-3)
    assert np.all(d[4:] == 0)
    # the fitted camera projects like the true one over the image (the board poses are ~0.1 m wide; compare rays)
    u, v = np.meshgrid(np.linspace(-0.6, 0.6, 13), np.linspace(-0.45, 0.45, 9))
    rays = np.vstack([u.ravel(), v.ravel(), np.ones(u.size)])
    assert np.max(np.abs(cal.camera.vector_to_pixel(rays) - truth.vector_to_pixel(rays))) < 1.5
    for pose, fitted in zip(POSES, cal.poses):
        assert np.linalg.norm(fitted[:3] - pose[:3]) < 2e-3
        assert np.linalg.norm(rot2rpy(rpy2rot(fitted[3:]).T @ rpy2rot(pose[3:]))) < 5e-3


def test_camera_model_reproduces_opencv_projection_and_the_file_round_trips(rendered, tmp_path):
    folder, _ = rendered
    views = find_boards(folder, PATTERN, SQUARE_SIZE)
    for model in ("k1k2p1p2k3", "rational+thin-prism"):
        cal = calibrate(views, model)
        for pose in cal.poses:
            Rcn = rpy2rot(pose[3:]).T
            ref, _ = cv2.projectPoints(views.board.T, cv2.Rodrigues(Rcn)[0], -Rcn @ pose[:3], cal.camera.K,
                                       cal.camera.dist_coeffs)
            assert np.max(np.abs(ref.reshape(-1, 2).T - cal.camera.world_to_pixel(views.board, pose))) < 1e-6
        path = cal.write(tmp_path / f"{model}.xml")
        back = Camera.from_xml(path)
        assert np.array_equal(back.K, cal.camera.K) and np.array_equal(back.dist_coeffs, cal.camera.dist_coeffs)
        assert back.flags == DISTORTION_MODELS[model][0] and back.image_size == (640, 480)


def test_model_choice_prefers_fewer_coefficients_within_the_tolerance():
    rows = ({"model": "a", "n_coefficients": 2, "loo_rms": 0.200},
            {"model": "b", "n_coefficients": 4, "loo_rms": 0.190},
            {"model": "c", "n_coefficients": 5, "loo_rms": 0.1895},
            {"model": "d", "n_coefficients": 8, "loo_rms": 0.25})
    assert choose_model(rows) == "b"
    assert choose_model(rows, tolerance=0.06) == "a"


def test_the_workbook_photographs_choose_four_coefficients():
    """On the 13 photographs the extra coefficients fit the training views a little better and predict a held-out
    view worse (the margins here are 4 % and more); the choice is k1 k2 p1 p2 and its RMS is under 0.5 px."""
    cal = calibrate_folder(data_dir() / "chessboard", (9, 6), 0.025)
    rows = {r["model"]: r for r in cal.comparison}
    assert cal.model == "k1k2p1p2" and len(cal.views.names) == 13 and cal.views.skipped == ()
    assert rows["rational+thin-prism"]["rms"] < rows["k1k2p1p2"]["rms"]
    assert rows["rational+thin-prism"]["loo_rms"] > 1.04 * rows["k1k2p1p2"]["loo_rms"]
    assert rows["k1k2"]["loo_rms"] > 1.02 * rows["k1k2p1p2"]["loo_rms"]
    assert abs(rows["rational"]["k1"]) > 1 and rows["rational"]["k1_sigma"] > 0.5     # k1 undetermined
    assert cal.rms < 0.5 and cal.per_image_rms.max() < 0.5
    assert np.allclose(cal.per_image_rms, np.sqrt(np.mean(np.sum(
        (np.array([cal.camera.world_to_pixel(cal.views.board, p) for p in cal.poses]) - cal.views.corners) ** 2,
        axis=1), axis=1)))


def test_a_write_that_fails_leaves_the_old_file(tmp_path):
    cam = Camera(TRUE_K, TRUE_D, (640, 480))
    path = tmp_path / "camera.xml"
    from helpers.camera_io import write_camera_xml
    write_camera_xml(path, cam.K, cam.dist_coeffs, cam.image_size, cam.flags)
    before = path.read_bytes()
    with pytest.raises(ValueError, match="^K"):
        write_camera_xml(path, np.eye(2), cam.dist_coeffs, cam.image_size, cam.flags)
    assert path.read_bytes() == before and [p.name for p in tmp_path.iterdir()] == ["camera.xml"]


def test_folders_without_boards_raise_clear_errors(tmp_path):
    with pytest.raises(ValueError, match=r"^folder: .* is not a folder"):
        find_boards(tmp_path / "missing", PATTERN, SQUARE_SIZE)
    with pytest.raises(ValueError, match=r"^folder: .* holds no photograph"):
        find_boards(tmp_path, PATTERN, SQUARE_SIZE)
    for k in range(4):
        cv2.imwrite(str(tmp_path / f"blank{k}.png"), np.full((120, 160), 90 + 10 * k, np.uint8))
    with pytest.raises(ValueError, match=r"^folder: a 10 × 7 chessboard .* found in 0 of the 4 photographs"):
        calibrate_folder(tmp_path, PATTERN, SQUARE_SIZE)
    # the workbook's photographs with a pattern larger than their 9 × 6 board: no board either
    with pytest.raises(ValueError, match=r"found in 0 of the 13 photographs"):
        find_boards(data_dir() / "chessboard", (10, 7), 0.025)
    (tmp_path / "broken.jpg").write_bytes(b"not a jpeg")
    with pytest.raises(ValueError, match=r"^folder: broken.jpg .* is not a readable image"):
        find_boards(tmp_path, PATTERN, SQUARE_SIZE)


@pytest.mark.parametrize("kwargs, message", [
    ({"folder": 3}, r"^folder must be a folder name"),
    ({"pattern_size": (9,)}, r"^pattern_size"),
    ({"square_size": -0.02}, r"^square_size"),
    ({"model": "fisheye"}, r"^model"),
])
def test_bad_arguments_name_themselves(kwargs, message):
    args = {"folder": data_dir() / "chessboard", "pattern_size": (9, 6), "square_size": 0.025, "model": "k1k2",
            **kwargs}
    with pytest.raises(ValueError, match=message):
        calibrate_folder(**args)


def test_mixed_image_sizes_are_refused(tmp_path):
    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((100, 120), np.uint8))
    cv2.imwrite(str(tmp_path / "b.png"), np.zeros((90, 120), np.uint8))
    with pytest.raises(ValueError, match=r"^folder: b.png is 120 × 90 px"):
        find_boards(tmp_path, PATTERN, SQUARE_SIZE)
