"""Benchmark: chessboard detection, Zhang calibration and point undistortion.

Renders views of a 9 x 6 chessboard through a known VGA camera with strong
distortion (k1, k2, p1, p2, k3 all non-zero), blur 0.7 px and noise sigma 2,
and prints side by side:

1. corner error against truth for ``cv2.findChessboardCornersSB`` (plain and
   with ``CALIB_CB_ACCURACY``) and for :func:`vision.camera.detect_pattern`
   (SB detection + ``cv2.cornerSubPix``);
2. calibration accuracy (fx, fy, cx, cy, reprojection RMS) against the number
   of views;
3. undistortion error and time: :meth:`CameraModel.undistort_points` (Newton)
   vs ``cv2.undistortPoints`` (5 fixed-point iterations) vs
   ``cv2.undistortPoints`` with 100 iterations (its ``criteria`` argument).

Run: ``python benchmarks/bench_camera.py``
"""
from __future__ import annotations

import time

import numpy as np

K_TRUE = np.array([[800.0, 0.0, 322.3], [0.0, 805.0, 241.7], [0.0, 0.0, 1.0]])
D_TRUE = np.array([-0.25, 0.12, 0.001, -0.0015, -0.03])
SIZE = (640, 480)
PATTERN = (9, 6)
SQUARE_MM = 10.0


def render_views(n, rng):
    import cv2

    from kinid.vision.calibration_targets import chessboard_coverage, chessboard_object_points, pinhole_image_to_plane
    from kinid.vision.camera import CameraModel
    from kinid.vision.render import render_pattern

    camera = CameraModel(K_TRUE, D_TRUE, SIZE)
    obj = chessboard_object_points(PATTERN, SQUARE_MM)
    coverage = chessboard_coverage(PATTERN, SQUARE_MM)
    images, truths = [], []
    while len(images) < n:
        rvec = rng.uniform(-0.6, 0.6, 3)
        rvec[2] = rng.uniform(-0.3, 0.3)
        rmat, _ = cv2.Rodrigues(rvec)
        tvec = np.array([rng.uniform(-25, 25), rng.uniform(-20, 20), rng.uniform(150, 200)]) - rmat @ obj.mean(0)
        pts = camera.project(obj @ rmat.T + tvec)
        if pts.min() < 30 or pts[:, 0].max() > SIZE[0] - 30 or pts[:, 1].max() > SIZE[1] - 30:
            continue
        images.append(render_pattern(coverage, SIZE[::-1], pinhole_image_to_plane(camera, rvec, tvec),
                                     supersample=4, blur_px=0.7, noise_sigma=2.0, rng=rng))
        truths.append(pts)
    return camera, images, truths


def corner_errors(found, truth):
    if np.linalg.norm(found[0] - truth[0]) > np.linalg.norm(found[-1] - truth[0]):
        found = found[::-1]
    return np.linalg.norm(found - truth, axis=1)


def main():
    import cv2

    from kinid.vision.camera import calibrate_camera, detect_pattern

    rng = np.random.default_rng(20261122)
    start = time.perf_counter()
    camera, images, truths = render_views(15, rng)
    print(f"rendered 15 views 640x480 in {time.perf_counter() - start:.1f} s "
          f"(blur 0.7 px, noise sigma 2, 9x6 inner corners)\n")

    print("1. corner detection error vs truth")
    print(f"  {'detector':<34}{'rms px':>9}{'max px':>9}{'ms/view':>9}")
    detectors = {
        "findChessboardCornersSB": lambda g: cv2.findChessboardCornersSB(g, PATTERN, flags=cv2.CALIB_CB_EXHAUSTIVE),
        "findChessboardCornersSB+ACCURACY": lambda g: cv2.findChessboardCornersSB(
            g, PATTERN, flags=cv2.CALIB_CB_EXHAUSTIVE | cv2.CALIB_CB_ACCURACY),
        "detect_pattern (SB + cornerSubPix)": lambda g: (True, detect_pattern(g, "chessboard", PATTERN)),
    }
    for name, detect in detectors.items():
        errs = []
        start = time.perf_counter()
        for img, truth in zip(images, truths):
            ok, pts = detect(img)
            if ok and pts is not None:
                errs.append(corner_errors(np.asarray(pts, float).reshape(-1, 2), truth))
        ms = 1000 * (time.perf_counter() - start) / len(images)
        e = np.concatenate(errs)
        print(f"  {name:<34}{np.sqrt(np.mean(e ** 2)):9.4f}{e.max():9.4f}{ms:9.1f}   ({len(errs)}/15 found)")

    print("\n2. calibration accuracy vs number of views (truth fx 800, fy 805, cx 322.3, cy 241.7)")
    print(f"  {'views':>5}{'fx err %':>10}{'fy err %':>10}{'cx err px':>11}{'cy err px':>11}{'rms px':>9}"
          f"{'max field err px':>18}{'s':>7}")
    xs, ys = np.meshgrid(np.linspace(40, 600, 15), np.linspace(30, 450, 11))
    grid = np.column_stack([xs.ravel(), ys.ravel()])
    for n in (5, 10, 15):
        start = time.perf_counter()
        res = calibrate_camera(images[:n], "chessboard", PATTERN, SQUARE_MM)
        sec = time.perf_counter() - start
        k = res.camera.camera_matrix
        field = np.abs(res.camera.undistort_points(grid) - camera.undistort_points(grid)).max()
        print(f"  {n:5d}{100 * (k[0, 0] / 800 - 1):10.4f}{100 * (k[1, 1] / 805 - 1):10.4f}"
              f"{k[0, 2] - 322.3:11.3f}{k[1, 2] - 241.7:11.3f}{res.rms_px:9.4f}{field:18.3f}{sec:7.2f}")

    print("\n3. undistortion of 100 000 points spread over the image (max error vs exact inverse, time)")
    pts = np.random.default_rng(1).uniform([0, 0], SIZE, (100_000, 2))
    corners = np.array([[0.0, 0.0], [639.0, 479.0], [0.0, 479.0], [639.0, 0.0]])
    rows = {
        "CameraModel.undistort_points": lambda p: camera.undistort_points(p),
        "cv2.undistortPoints": lambda p: cv2.undistortPoints(p.reshape(-1, 1, 2), K_TRUE, D_TRUE,
                                                             P=K_TRUE).reshape(-1, 2),
        "cv2.undistortPoints(100 iter)": lambda p: cv2.undistortPoints(
            p.reshape(-1, 1, 2), K_TRUE, D_TRUE, R=None, P=K_TRUE,
            criteria=(cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)).reshape(-1, 2),
    }
    print(f"  {'method':<32}{'round-trip max px':>18}{'at corners px':>15}{'ms':>8}")
    for name, fn in rows.items():
        start = time.perf_counter()
        out = fn(pts)
        ms = 1000 * (time.perf_counter() - start)
        round_trip = np.abs(camera.distort_points(out) - pts).max()
        at_corners = np.abs(camera.distort_points(fn(corners)) - corners).max()
        print(f"  {name:<32}{round_trip:18.2e}{at_corners:15.2e}{ms:8.1f}")


if __name__ == "__main__":
    main()
