import shutil

import cv2
import numpy as np
import pytest

from helpers.camera import Camera, load_lab_camera
from helpers.paths import data_dir
from helpers.rotation import rpy2rot

FX, FY, CX, CY = 843.79359356556120, 841.69642468249765, 960.45698792357746, 725.16973181457206
DIST = [1.4384662209855472e+00, 8.5887944643796066e-02, -1.4702987615068606e-04, -1.1224398190635136e-04,
        -9.9443369615206893e-03, 1.7323364753561379e+00, 3.8594347481219721e-01, -2.3311125504701206e-02,
        2.6322461460127498e-04, 3.8039252644823254e-05, -2.4443979731035781e-04, 1.0345767628031078e-05]
DEMO_POSE = np.array([-0.00114, 0.05088, -0.44589, 0.12179, 0.06344, 1.56839])


@pytest.fixture(scope="module")
def cam():
    return load_lab_camera()


@pytest.fixture(scope="module")
def test_cam():
    return Camera.from_xml(data_dir() / "test_camera.xml")


def random_points(rng, n, max_angle_deg=60.0):
    """Points in front of the camera within max_angle of the optical axis, 0.3–3 m away."""
    ang = np.radians(max_angle_deg) * np.sqrt(rng.uniform(0, 1, n))
    az = rng.uniform(-np.pi, np.pi, n)
    dist = rng.uniform(0.3, 3.0, n)
    return dist * np.vstack([np.sin(ang) * np.cos(az), np.sin(ang) * np.sin(az), np.cos(ang)])


def central_diff(f, x, h):
    """Jacobian of f (vector → (2,) ) at x by central differences, shape (2, len(x))."""
    cols = []
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.stack(cols, axis=-1)


# ---------------------------------------------------------------------------- calibration file
def test_lab_camera_file_holds_reference_calibration(cam):
    np.testing.assert_array_equal(cam.K, [[FX, 0, CX], [0, FY, CY], [0, 0, 1]])
    np.testing.assert_array_equal(cam.dist_coeffs, DIST)
    assert cam.image_size == (1920, 1440)
    assert cam.flags == 49152
    np.testing.assert_array_equal(cam.r_cb_b, np.zeros(3))
    np.testing.assert_array_equal(cam.R_bc, np.eye(3))


# ---------------------------------------------------------------------------- template expectations
def test_unit_test_camera_template_expectations(test_cam):
    np.testing.assert_array_equal(test_cam.K, [[5, 0, 0.1], [0, 6, 0.2], [0, 0, 1]])
    np.testing.assert_allclose(test_cam.vector_to_pixel([0.0, 0.0, 1.0]), [0.1, 0.2], atol=1e-15)
    assert test_cam.is_vector_within_fov([0.0, 0.0, 1.0])
    for v in ([0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]):
        assert not test_cam.is_vector_within_fov(v)
    np.testing.assert_allclose(test_cam.vector_to_pixel(test_cam.pixel_to_vector([5.3, 8.7])), [5.3, 8.7],
                               atol=1e-10)


def test_no_sign_check_on_z(cam):
    P = np.array([0.1, -0.2, 0.5])
    np.testing.assert_allclose(cam.vector_to_pixel(-P), cam.vector_to_pixel(P), atol=1e-12)


# ---------------------------------------------------------------------------- model vs OpenCV
def test_vector_to_pixel_matches_opencv(cam):
    rng = np.random.default_rng(0)
    P = random_points(rng, 500, 70.0)
    q, _ = cv2.projectPoints(P.T.copy(), np.zeros(3), np.zeros(3), cam.K, cam.dist_coeffs)
    # pixels up to ~2000 px: a one-ulp change of the input moves them by ≤ 7e-13 px (measured difference from
    # OpenCV 5e-13 px), so 1e-8 px is far above round-off and far below any model error
    np.testing.assert_allclose(cam.vector_to_pixel(P), q[:, 0, :].T, atol=1e-8)


def test_vector_to_pixel_single_matches_batch(cam):
    P = random_points(np.random.default_rng(1), 5)
    Q, J = cam.vector_to_pixel(P, return_jacobian=True)
    q, j = cam.vector_to_pixel(P[:, 3], return_jacobian=True)
    assert Q.shape == (2, 5) and J.shape == (5, 2, 3) and q.shape == (2,) and j.shape == (2, 3)
    np.testing.assert_array_equal(q, Q[:, 3])
    np.testing.assert_array_equal(j, J[3])


# ---------------------------------------------------------------------------- Jacobians
@pytest.mark.parametrize("max_angle", [60.0, 1e-4])  # general and (almost) on the optical axis
def test_vector_to_pixel_jacobian_central_differences(cam, max_angle):
    rng = np.random.default_rng(2)
    P = random_points(rng, 20, max_angle)
    _, J = cam.vector_to_pixel(P, return_jacobian=True)
    for k in range(P.shape[1]):
        fd = central_diff(cam.vector_to_pixel, P[:, k], 1e-6)
        np.testing.assert_allclose(J[k], fd, rtol=1e-6, atol=2e-5)


def test_vector_to_pixel_jacobian_exactly_on_axis(cam):
    _, J = cam.vector_to_pixel([0.0, 0.0, 2.0], return_jacobian=True)
    assert np.all(np.isfinite(J))
    np.testing.assert_allclose(J, central_diff(cam.vector_to_pixel, np.array([0.0, 0.0, 2.0]), 1e-6), atol=2e-5)


def test_world_to_pixel_jacobians_central_differences(cam):
    rng = np.random.default_rng(3)
    for _ in range(5):
        eta = np.concatenate([rng.normal(scale=0.3, size=3), rng.uniform(-np.pi, np.pi, 3)])
        Rnc = rpy2rot(eta[3:])
        P = eta[:3, None] + Rnc @ random_points(rng, 4, 55.0)
        Q, jac = cam.world_to_pixel(P, eta, return_jacobian=True)
        assert jac.wrt_point.shape == (4, 2, 3)
        for k in range(4):
            p = P[:, k]
            fd_point = central_diff(lambda x, eta=eta: cam.world_to_pixel(x, eta), p, 1e-6)
            np.testing.assert_allclose(jac.wrt_point[k], fd_point, rtol=1e-6, atol=1e-4)
            fd_pos = central_diff(lambda r, p=p, eta=eta: cam.world_to_pixel(p, np.concatenate([r, eta[3:]])), eta[:3],
                                  1e-6)
            np.testing.assert_allclose(jac.wrt_position[k], fd_pos, rtol=1e-6, atol=1e-4)
            fd_ang = central_diff(lambda a, p=p, eta=eta: cam.world_to_pixel(p, np.concatenate([eta[:3], a])), eta[3:],
                                  1e-7)
            np.testing.assert_allclose(jac.wrt_angles[k], fd_ang, rtol=1e-6, atol=1e-3)
        q, j1 = cam.world_to_pixel(P[:, 1], eta, return_jacobian=True)
        np.testing.assert_allclose(q, Q[:, 1], rtol=1e-13)
        np.testing.assert_allclose(j1.wrt_angles, jac.wrt_angles[1], rtol=1e-13)


def test_body_to_pixel_with_mounting_offset_central_differences(cam):
    rng = np.random.default_rng(4)
    mounted = Camera(cam.K, cam.dist_coeffs, cam.image_size, r_cb_b=[0.05, -0.02, 0.1],
                     R_bc=rpy2rot([0.1, -0.2, 0.3]))
    eta_b = np.array([0.1, -0.2, -0.5, 0.2, -0.1, 1.0])
    eta_c = mounted.camera_pose_from_body(eta_b)
    P = eta_c[:3, None] + rpy2rot(eta_c[3:]) @ random_points(rng, 6, 50.0)
    Q, jac = mounted.body_to_pixel(P, eta_b, return_jacobian=True)
    np.testing.assert_allclose(Q, mounted.world_to_pixel(P, eta_c), atol=1e-9)
    for k in range(6):
        p = P[:, k]
        f_b = lambda e, p=p: mounted.body_to_pixel(p, e)  # noqa: E731
        fd = central_diff(f_b, eta_b, 1e-7)
        np.testing.assert_allclose(jac.wrt_position[k], fd[:, :3], rtol=1e-6, atol=1e-3)
        np.testing.assert_allclose(jac.wrt_angles[k], fd[:, 3:], rtol=1e-6, atol=1e-3)
        np.testing.assert_allclose(jac.wrt_point[k], central_diff(lambda x: mounted.body_to_pixel(x, eta_b), p, 1e-6),
                                   rtol=1e-6, atol=1e-4)


def test_camera_pose_from_body_identity_mount(cam):
    np.testing.assert_allclose(cam.camera_pose_from_body(DEMO_POSE), DEMO_POSE, atol=1e-12)


# ----------------------------------------------------- demo board points (reference pixels at the demo pose)
@pytest.mark.parametrize("point, pixel", [
    ((0.0, 0.0, 0.0), (810.4, 824.4)), ((0.198, 0.132, 0.0), (1053.0, 477.3)),
    ((-0.022, -0.022, 0.0), (768.8, 865.2)), ((0.22, -0.022, 0.0), (786.2, 437.5)),
    ((0.22, 0.154, 0.0), (1088.8, 445.1)), ((-0.022, 0.154, 0.0), (1099.4, 866.0))])
def test_demo_board_points(cam, point, pixel):
    np.testing.assert_allclose(cam.world_to_pixel(np.array(point), DEMO_POSE), pixel, atol=0.06)
    assert cam.is_world_within_fov(np.array(point), DEMO_POSE)


# ---------------------------------------------------------------------------- inversion and FOV
def test_pixel_to_vector_round_trip_vectorised(cam):
    xs, ys = np.meshgrid(np.linspace(0, 1919, 41), np.linspace(0, 1439, 31))
    pix = np.vstack([xs.ravel(), ys.ravel()])
    # keep the pixels inside the image of the invertible range (the extreme corners fold back)
    V = cam.pixel_to_vector(pix, strict=False)
    ok = np.abs(cam.vector_to_pixel(V) - pix).max(axis=0) < 1e-6
    assert ok.mean() > 0.95
    V = cam.pixel_to_vector(pix[:, ok])
    np.testing.assert_allclose(np.linalg.norm(V, axis=0), 1.0, atol=1e-15)
    np.testing.assert_allclose(cam.vector_to_pixel(V), pix[:, ok], atol=1e-7)
    assert np.all(V[2] > 0)


def test_pixel_to_vector_matches_forward_of_random_rays(cam):
    P = random_points(np.random.default_rng(5), 300, 65.0)
    V = cam.pixel_to_vector(cam.vector_to_pixel(P))
    np.testing.assert_allclose(V, P / np.linalg.norm(P, axis=0), atol=1e-9)


def test_pixel_to_vector_corner_is_beyond_the_fold(cam):
    with pytest.raises(ValueError, match="pixels"):
        cam.pixel_to_vector([0.0, 0.0])
    v = cam.pixel_to_vector([0.0, 0.0], strict=False)
    off_axis = np.degrees(np.arctan2(np.hypot(v[0], v[1]), v[2]))
    assert off_axis == pytest.approx(np.degrees(cam.max_off_axis_angle()), abs=0.05)  # at the fold


def test_fov_angles(cam):
    fov = cam.fov_angles()._replace(**{k: np.degrees(v) for k, v in cam.fov_angles()._asdict().items()})
    assert fov.horizontal == pytest.approx(122.1, abs=0.1)
    assert fov.vertical == pytest.approx(94.4, abs=0.05)
    assert fov.diagonal == pytest.approx(143.0, abs=0.1)
    assert np.degrees(cam.max_off_axis_angle()) == pytest.approx(71.5, abs=0.1)


def test_fov_vectorised(cam):
    P = np.array([[0.0, 0.0, 0.0, 1.0, 0.3], [0.0, 0.0, 1.0, 0.0, 0.2], [1.0, -1.0, 0.0, 0.0, 1.0]])
    np.testing.assert_array_equal(cam.is_vector_within_fov(P), [True, False, False, False, True])
    # 70° off-axis horizontally: inside the model's range but outside the image (hFOV/2 ≈ 61°)
    a = np.radians(70.0)
    assert not cam.is_vector_within_fov([np.sin(a), 0.0, np.cos(a)])
    a = np.radians(55.0)
    assert cam.is_vector_within_fov([np.sin(a), 0.0, np.cos(a)])


# ---------------------------------------------------------------------------- bad inputs
def test_constructor_bad_inputs(cam):
    K, d = cam.K, cam.dist_coeffs
    with pytest.raises(ValueError, match="K must be a finite"):
        Camera(np.eye(2), d, (10, 10))
    with pytest.raises(ValueError, match="K must have the form"):
        Camera([[1, 0.1, 0], [0, 1, 0], [0, 0, 1]], d, (10, 10))
    with pytest.raises(ValueError, match="K must have positive"):
        Camera([[-1, 0, 0], [0, 1, 0], [0, 0, 1]], d, (10, 10))
    with pytest.raises(ValueError, match="dist_coeffs must have 12"):
        Camera(K, np.zeros(7), (10, 10))
    with pytest.raises(ValueError, match="dist_coeffs must be finite"):
        Camera(K, np.full(12, np.nan), (10, 10))
    for bad in [(0, 10), (10, -1), (10,), (10.5, 3), (np.nan, 3)]:
        with pytest.raises(ValueError, match="image_size"):
            Camera(K, d, bad)
    with pytest.raises(ValueError, match="r_cb_b"):
        Camera(K, d, (10, 10), r_cb_b=[0, 0])
    with pytest.raises(ValueError, match="R_bc"):
        Camera(K, d, (10, 10), R_bc=2 * np.eye(3))
    with pytest.raises(ValueError, match="flags"):
        Camera(K, d, (10, 10), flags=16384)


def test_projection_bad_inputs(cam):
    with pytest.raises(ValueError, match="rPCc must have shape"):
        cam.vector_to_pixel(np.zeros((2, 4)))
    with pytest.raises(ValueError, match="rPCc must be finite"):
        cam.vector_to_pixel([np.nan, 0.0, 1.0])
    with pytest.raises(ValueError, match="rPCc has points with z = 0"):
        cam.vector_to_pixel([1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="rPNn must have shape"):
        cam.world_to_pixel(np.zeros(4), DEMO_POSE)
    with pytest.raises(ValueError, match="eta must have shape"):
        cam.world_to_pixel(np.zeros(3), DEMO_POSE[:5])
    with pytest.raises(ValueError, match="eta must be finite"):
        cam.world_to_pixel(np.zeros(3), np.full(6, np.nan))
    with pytest.raises(ValueError, match="eta_body must have shape"):
        cam.body_to_pixel(np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="eta_body"):
        cam.camera_pose_from_body(np.zeros(7))
    with pytest.raises(ValueError, match="pixels must have shape"):
        cam.pixel_to_vector(np.zeros(3))
    with pytest.raises(ValueError, match="pixels must be finite"):
        cam.pixel_to_vector([np.inf, 1.0])
    with pytest.raises(ValueError, match="rPCc must have shape"):
        cam.is_vector_within_fov([1.0, 2.0])
    with pytest.raises(ValueError, match="rPNn"):
        cam.is_world_within_fov([1.0, 2.0], DEMO_POSE)


XML_OK = (data_dir() / "test_camera.xml").read_text(encoding="utf-8")


@pytest.mark.parametrize("text, message", [
    ("this is not xml <", "path"),
    ('<?xml version="1.0"?>\n<opencv_storage>\n<other>1</other>\n</opencv_storage>\n', "'camera'"),
    (XML_OK.replace("camera_matrix", "cam_matrix"), "camera/camera_matrix"),
    (XML_OK.replace("<rows>12</rows>", "<rows>6</rows>").replace("0. 0. 0. 0. 0. 0. 0. 0. 0. 0. 0. 0.",
                                                                  "0. 0. 0. 0. 0. 0."), "distortion_coefficients"),
    (XML_OK.replace("<flags>49152</flags>", ""), "camera/flags"),
    (XML_OK.replace("<flags>49152</flags>", "<flags>16384</flags>"), "flags must include"),
    (XML_OK.replace("1920 1440", "1920"), "camera/imageSize"),
    (XML_OK.replace("1920 1440", "0 1440"), "image_size"),
])
def test_from_xml_malformed(tmp_path, text, message):
    path = tmp_path / "bad.xml"
    path.write_text(text)
    with pytest.raises(ValueError, match=message) as info:
        Camera.from_xml(path)
    assert "bad.xml" in str(info.value)


def test_from_xml_missing_file(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        Camera.from_xml(tmp_path / "nope.xml")


def test_test_camera_file_is_well_formed(tmp_path):
    shutil.copy(data_dir() / "test_camera.xml", tmp_path / "c.xml")
    assert Camera.from_xml(tmp_path / "c.xml").image_size == (1920, 1440)


def test_distort_public_and_bad_input(cam):
    ud, vd = cam.distort(np.array([0.3]), np.array([-0.2]))
    q = cam.vector_to_pixel([0.3, -0.2, 1.0])
    np.testing.assert_allclose([cam.K[0, 0] * ud[0] + cam.K[0, 2], cam.K[1, 1] * vd[0] + cam.K[1, 2]], q, rtol=1e-14)
    with pytest.raises(ValueError, match="u and v must be finite"):
        cam.distort(np.nan, 0.0)


def test_camera_io_reads_the_raw_values(tmp_path):
    from helpers.camera_io import read_camera_xml

    K, d, size, flags = read_camera_xml(data_dir() / "test_camera.xml")
    assert K.shape == (3, 3) and d.size == 12 and len(size) == 2 and isinstance(flags, int)
    with pytest.raises(ValueError, match="does not exist"):
        read_camera_xml(tmp_path / "missing.xml")
