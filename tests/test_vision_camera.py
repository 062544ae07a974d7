"""Camera model and Zhang calibration on rendered views of a known chessboard."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError, ImageError
from kinid.vision.calibration_targets import (
    chessboard_coverage,
    chessboard_object_points,
    circle_grid_coverage,
    circle_grid_object_points,
    pinhole_image_to_plane,
)
from kinid.vision.camera import CameraModel, calibrate_camera, detect_pattern, load_camera, save_camera
from kinid.vision.render import render_pattern

# a VGA camera with strong barrel distortion and some decentring (all five coefficients non-zero)
K_TRUE = np.array([[800.0, 0.0, 322.3], [0.0, 805.0, 241.7], [0.0, 0.0, 1.0]])
D_TRUE = np.array([-0.25, 0.12, 0.001, -0.0015, -0.03])
SIZE = (640, 480)
PATTERN = (9, 6)
SQUARE_MM = 10.0


@pytest.fixture(scope="module")
def truth():
    return CameraModel(K_TRUE, D_TRUE, SIZE)


def _random_pose(rng, camera, object_points, *, tilt_rad=0.6, z_mm=(150.0, 200.0), margin_px=30):
    """A board pose (rvec, tvec) with every point at least margin_px inside the image."""
    centre = object_points.mean(axis=0)
    while True:
        rvec = rng.uniform(-tilt_rad, tilt_rad, 3)
        rvec[2] = rng.uniform(-0.3, 0.3)
        rmat, _ = cv2.Rodrigues(rvec)
        tvec = np.array([rng.uniform(-25, 25), rng.uniform(-20, 20), rng.uniform(*z_mm)]) - rmat @ centre
        pts = camera.project(object_points @ rmat.T + tvec)
        if pts.min() > margin_px and pts[:, 0].max() < SIZE[0] - margin_px and pts[:, 1].max() < SIZE[1] - margin_px:
            return rvec, tvec


@pytest.fixture(scope="module")
def views(truth):
    rng = np.random.default_rng(2026)
    coverage = chessboard_coverage(PATTERN, SQUARE_MM)
    obj = chessboard_object_points(PATTERN, SQUARE_MM)
    images = []
    for _ in range(12):
        rvec, tvec = _random_pose(rng, truth, obj)
        images.append(render_pattern(coverage, SIZE[::-1], pinhole_image_to_plane(truth, rvec, tvec),
                                     supersample=4, blur_px=0.7, noise_sigma=2.0, rng=rng))
    return images


@pytest.fixture(scope="module")
def calibrated(views):
    return calibrate_camera(views, "chessboard", PATTERN, SQUARE_MM)


def test_calibration_recovers_focal_length_within_0p1_percent(calibrated):
    assert calibrated.success
    k = calibrated.camera.camera_matrix
    assert k[0, 0] == pytest.approx(K_TRUE[0, 0], rel=1e-3)
    assert k[1, 1] == pytest.approx(K_TRUE[1, 1], rel=1e-3)
    assert k[0, 2] == pytest.approx(K_TRUE[0, 2], abs=1.5)
    assert k[1, 2] == pytest.approx(K_TRUE[1, 2], abs=1.5)


def test_calibration_reprojection_rms_below_0p1_px(calibrated):
    assert calibrated.rms_px < 0.1
    assert calibrated.camera.rms_px == calibrated.rms_px
    assert calibrated.n_views == 12 and calibrated.used_views == tuple(range(12))
    assert calibrated.per_view_rms_px.shape == (12,) and np.all(calibrated.per_view_rms_px < 0.1)
    assert len(calibrated.rvecs) == len(calibrated.tvecs) == 12
    assert np.all(np.isfinite(calibrated.std_intrinsics))


def test_calibration_recovers_distortion(calibrated, truth):
    est = calibrated.camera
    assert est.dist_coeffs[0] == pytest.approx(D_TRUE[0], abs=0.01)
    assert est.dist_coeffs[2] == pytest.approx(D_TRUE[2], abs=5e-4)
    assert est.dist_coeffs[3] == pytest.approx(D_TRUE[3], abs=5e-4)
    # k2 and k3 trade off against each other; the distortion *field* is what must match:
    # over the image (inside 90 % of the half-diagonal, where the board was seen) the undistorted
    # positions agree with the truth's
    xs, ys = np.meshgrid(np.linspace(40, 600, 15), np.linspace(30, 450, 11))
    pts = np.column_stack([xs.ravel(), ys.ravel()])
    moved_true = truth.undistort_points(pts) - pts
    moved_est = est.undistort_points(pts) - pts
    assert np.abs(moved_true).max() > 10  # the lens distorts strongly (14.6 px at the corners)
    assert np.abs(moved_est - moved_true).max() < 0.3  # 0.09 px measured


def test_views_are_detected_to_subpixel(views, truth):
    rng = np.random.default_rng(2026)
    obj = chessboard_object_points(PATTERN, SQUARE_MM)
    rvec, tvec = _random_pose(rng, truth, obj)  # the first view's pose (same seed, same draws)
    rmat, _ = cv2.Rodrigues(rvec)
    expected = truth.project(obj @ rmat.T + tvec)
    found = detect_pattern(views[0], "chessboard", PATTERN)
    if np.linalg.norm(found[0] - expected[0]) > np.linalg.norm(found[-1] - expected[0]):
        found = found[::-1]  # the board's 180 degree ambiguity
    err = np.linalg.norm(found - expected, axis=1)
    assert np.sqrt(np.mean(err ** 2)) < 0.08


@pytest.mark.slow
def test_circle_grid_calibration(truth):
    rng = np.random.default_rng(7)
    size, spacing, diameter = (4, 11), 6.0, 3.5
    coverage = circle_grid_coverage(size, spacing, diameter, asymmetric=True)
    obj = circle_grid_object_points(size, spacing, asymmetric=True)
    images = []
    for _ in range(8):
        rvec, tvec = _random_pose(rng, truth, obj, tilt_rad=0.35, z_mm=(140.0, 170.0))
        images.append(render_pattern(coverage, SIZE[::-1], pinhole_image_to_plane(truth, rvec, tvec),
                                     supersample=2, blur_px=0.7, noise_sigma=2.0, rng=rng))
    result = calibrate_camera(images, "acircles", size, spacing)
    assert len(result.used_views) >= 6
    # blob centroids are biased by perspective and distortion (small discs here keep it small:
    # fx +0.05 %, RMS 0.026 px measured): a looser check than the chessboard's
    assert result.camera.camera_matrix[0, 0] == pytest.approx(800.0, rel=0.003)
    assert result.camera.camera_matrix[1, 1] == pytest.approx(805.0, rel=0.003)
    assert result.rms_px < 0.1


@settings(max_examples=30, deadline=None)
@given(x=st.floats(0, 639), y=st.floats(0, 479))
def test_property_undistort_inverts_distort(truth, x, y):
    pt = np.array([[x, y]])
    assert np.abs(truth.distort_points(truth.undistort_points(pt)) - pt).max() < 1e-9
    assert np.abs(truth.undistort_points(truth.distort_points(pt)) - pt).max() < 1e-9


def test_project_matches_opencv(truth):
    rng = np.random.default_rng(3)
    xyz = np.column_stack([rng.uniform(-60, 60, 50), rng.uniform(-45, 45, 50), rng.uniform(150, 300, 50)])
    ours = truth.project(xyz)
    cv, _ = cv2.projectPoints(xyz, np.zeros(3), np.zeros(3), K_TRUE, D_TRUE)
    np.testing.assert_allclose(ours, cv.reshape(-1, 2), atol=1e-6)
    # undistort agrees with OpenCV where its 5 fixed-point iterations converge (image centre)
    centre = np.array([[300.0, 250.0], [350.0, 200.0]])
    cv_ideal = cv2.undistortPoints(centre.reshape(-1, 1, 2), K_TRUE, D_TRUE, P=K_TRUE).reshape(-1, 2)
    np.testing.assert_allclose(truth.undistort_points(centre), cv_ideal, atol=1e-3)


def test_project_rejects_points_behind_camera(truth):
    with pytest.raises(DataError, match="z > 0"):
        truth.project([[0.0, 0.0, -1.0]])


def test_save_load_roundtrip(tmp_path, calibrated):
    path = tmp_path / "camera.json"
    save_camera(calibrated.camera, path)
    data = json.loads(path.read_text())
    assert set(data) == {"camera_matrix", "dist_coeffs", "image_size", "rms_px"}
    assert len(data["dist_coeffs"]) == 5 and data["image_size"] == [640, 480]
    back = load_camera(path)
    np.testing.assert_array_equal(back.camera_matrix, calibrated.camera.camera_matrix)
    np.testing.assert_array_equal(back.dist_coeffs, calibrated.camera.dist_coeffs)
    assert back.image_size == (640, 480) and back.rms_px == calibrated.rms_px


def test_rms_unknown_saves_as_null(tmp_path, truth):
    path = tmp_path / "cam.json"
    save_camera(truth, path)
    assert json.loads(path.read_text())["rms_px"] is None
    assert np.isnan(load_camera(path).rms_px)


@pytest.mark.parametrize(
    "content, match",
    [
        ("{not json", "not valid JSON"),
        ('{"dist_coeffs": [0,0,0,0,0], "image_size": [640, 480]}', "camera_matrix: missing"),
        ('{"camera_matrix": [[1,0,0],[0,1,0],[0,0,1]], "dist_coeffs": [0,0,0,0,0], "image_size": [640]}',
         "image_size: must be \\[an integer in \\[1, 100000\\], an integer in \\[1, 100000\\]\\], got \\[640\\]"),
        ('{"camera_matrix": [[1,0,0],[0,1,0]], "dist_coeffs": [0,0,0,0,0], "image_size": [640, 480]}',
         "camera_matrix: must be \\[\\[a number"),
        ('{"camera_matrix": [[1,0,0],[0,1,0],[0,0,1]], "dist_coeffs": [0,0,0], "image_size": [640, 480]}',
         "dist_coeffs: must be a list of 5 numbers, got 3 item"),
        ('[1, 2]', "JSON object"),
    ],
)
def test_load_camera_errors_name_the_problem(tmp_path, content, match):
    path = tmp_path / "bad.json"
    path.write_text(content)
    with pytest.raises(DataError, match=match) as info:
        load_camera(path)
    assert str(path) in str(info.value)


def test_load_camera_missing_file(tmp_path):
    with pytest.raises(DataError, match="camera file not found"):
        load_camera(tmp_path / "absent.json")


def test_calibrate_rejects_bad_input(views):
    blank = [np.full((480, 640), 200, np.uint8)] * 3
    with pytest.raises(ImageError, match=r"found in 0 of 3 images, need at least 3"):
        calibrate_camera(blank, "chessboard", PATTERN, SQUARE_MM)
    with pytest.raises(DataError, match="pattern must be"):
        calibrate_camera(views[:3], "charuco", PATTERN, SQUARE_MM)
    with pytest.raises(DataError, match="pattern_size"):
        calibrate_camera(views[:3], "chessboard", (9,), SQUARE_MM)
    with pytest.raises(DataError, match="square_mm must be a positive number"):
        calibrate_camera(views[:3], "chessboard", PATTERN, -1)
    with pytest.raises(ImageError, match="images\\[1\\] is 320x240 px, the first is 640x480"):
        calibrate_camera([views[0], views[1][:240, :320]], "chessboard", PATTERN, SQUARE_MM)
    with pytest.raises(ImageError, match="view.png: image file does not exist"):
        calibrate_camera(["/nonexistent/view.png"], "chessboard", PATTERN, SQUARE_MM)


def test_camera_model_validation():
    with pytest.raises(DataError, match="fx, fy > 0"):
        CameraModel(np.diag([-1.0, 1.0, 1.0]), np.zeros(5), (10, 10))
    with pytest.raises(DataError, match="image_size"):
        CameraModel(K_TRUE, np.zeros(5), (0, 10))
    four = CameraModel(K_TRUE, [0.1, 0.0, 0.0, 0.0], SIZE)  # OpenCV's 4-coefficient form: k3 = 0
    assert four.dist_coeffs.tolist() == [0.1, 0.0, 0.0, 0.0, 0.0]


def test_calibrate_from_image_files(tmp_path, views, calibrated):
    paths = []
    for i, img in enumerate(views):
        path = tmp_path / f"view{i:02d}.png"
        assert cv2.imwrite(str(path), img)
        paths.append(path)
    from_files = calibrate_camera(paths, "chessboard", PATTERN, SQUARE_MM)
    np.testing.assert_allclose(from_files.camera.camera_matrix, calibrated.camera.camera_matrix, rtol=1e-6)
    assert from_files.used_views == calibrated.used_views


def test_camera_model_is_read_only(truth):
    with pytest.raises(ValueError):
        truth.camera_matrix[0, 0] = 1.0
    with pytest.raises(AttributeError):
        truth.rms_px = 0.1


def test_circle_centre_bias_is_the_centre_of_the_imaged_ellipse():
    """Against a conic fitted to 2 000 projected points of the circle (plain numpy), over random poses."""
    from kinid.vision import circle_centre_bias

    rng = np.random.default_rng(11)
    for _ in range(20):
        n = rng.normal(size=3)
        n[2] = abs(n[2]) + 0.5
        n /= np.linalg.norm(n)
        centre = np.array([*rng.uniform(-20, 20, 2), rng.uniform(80, 200)])
        r = rng.uniform(1.0, 6.0)
        u = np.cross(n, [1.0, 0.0, 0.0])
        u /= np.linalg.norm(u)
        v = np.cross(n, u)
        t = np.linspace(0, 2 * np.pi, 2000, endpoint=False)
        p = centre + r * (np.cos(t)[:, None] * u + np.sin(t)[:, None] * v)
        x, y = p[:, 0] / p[:, 2], p[:, 1] / p[:, 2]
        a, b, c, d, e, _ = np.linalg.svd(np.column_stack([x * x, x * y, y * y, x, y, np.ones_like(x)]))[2][-1]
        ellipse_centre = np.linalg.solve([[2 * a, b], [b, 2 * c]], [-d, -e])
        expected = ellipse_centre - centre[:2] / centre[2]
        got = circle_centre_bias(centre, n, r)[0]
        assert np.allclose(got, expected, atol=1e-9 + 1e-6 * np.abs(expected).max())
    # a circle facing the camera squarely has no bias
    assert np.allclose(circle_centre_bias([[1.0, 2.0, 100.0]], [0.0, 0.0, 1.0], 2.5), 0.0, atol=1e-15)
