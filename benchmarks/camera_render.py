"""The camera's view of the ring-coded board and the laser's reading, ray-traced: no kinid kinematics.

Shared by the image-chain truths (tests/bc_camera_sim.py, tests/layout_camera_sim.py and
benchmarks/proving_chain.py): each puts the workpiece frame (the board's surface) and the tool frame where its
true machine puts them, and this module traces the rays. A telecentric lens sends every pixel's ray along the
camera's axis from the plane through the tool point; a calibrated pinhole camera (:data:`PINHOLE`) sends them from
its projection centre through the undistorted pixel (OpenCV's model). kinid.vision.render only paints the board's
ink at the plane points it is given. The laser's beam runs parallel to the camera's axis from its offset beside
the tool point (tool frame) to the board's plane.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

PITCH_MM = 16.0
BOARD_ROWS = BOARD_COLS = 8
PIXEL_MM = 0.045
IMAGE_PX = 400
IMAGE_X_ANGLE_DEG = 3.0
LASER_STANDOFF_MM = 30.0
#: A calibrated pinhole camera 120 mm above the tool point (f 4800 px: 0.025 mm per pixel there), with
#: OpenCV's distortion (k1, k2, p1, p2, k3); its principal point is where the tool point appears.
PINHOLE = {"f_px": 4800.0, "size_px": 720, "working_distance_mm": 120.0, "dist": (-0.12, 0.3, 4e-4, -3e-4, 0.0)}

#: Camera axes in tool axes (columns x, y, z): the image x axis turned IMAGE_X_ANGLE_DEG, looking down the tool.
_A = np.radians(IMAGE_X_ANGLE_DEG)
CAM = np.array([[np.cos(_A), np.sin(_A), 0.0], [np.sin(_A), -np.cos(_A), 0.0], [0.0, 0.0, -1.0]]).T


def _undistort(xd, yd, dist, iterations=30):
    """Ideal normalised coordinates of distorted ones (OpenCV's model, fixed-point iteration)."""
    k1, k2, p1, p2, k3 = dist
    x, y = xd.copy(), yd.copy()
    for _ in range(iterations):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        x = (xd - 2 * p1 * x * y - p2 * (r2 + 2 * x * x)) / radial
        y = (yd - p1 * (r2 + 2 * y * y) - 2 * p2 * x * y) / radial
    return x, y


def pinhole_sensor(camera=PINHOLE):
    """The sensor file's camera entries for ``camera`` (docs/observe.md)."""
    f, n = camera["f_px"], camera["size_px"]
    c0 = (n - 1) / 2.0
    return {"camera": {"camera_matrix": [[f, 0.0, c0], [0.0, f, c0], [0.0, 0.0, 1.0]], "dist_coeffs": list(camera["dist"]),
                       "image_size": [n, n]}, "working_distance_mm": camera["working_distance_mm"]}


def sensor_dict(camera=None) -> dict:
    """The sensor file of a run (docs/observe.md): the lens (``camera`` None: telecentric at PIXEL_MM), the image x
    angle and the laser's stand-off; not the laser's offset."""
    optics = {"pixel_mm": PIXEL_MM} if camera is None else pinhole_sensor(camera)
    return {**optics, "image_x_angle_deg": IMAGE_X_ANGLE_DEG, "laser_standoff_mm": LASER_STANDOFF_MM}


def board_dict():
    from kinid.vision import make_board

    b = make_board(BOARD_ROWS, BOARD_COLS, PITCH_MM)
    return {"pitch_mm": b.pitch_mm, "rows": b.rows, "cols": b.cols, "center_d_mm": b.center_d_mm,
            "ring_inner_d_mm": b.ring_inner_d_mm, "ring_outer_d_mm": b.ring_outer_d_mm, "bits": b.bits,
            "codes": [list(r) for r in b.codes]}


def write_setup_files(folder, camera=None) -> None:
    """The run's sensor.json (:func:`sensor_dict`) and board.json in ``folder``."""
    folder = Path(folder)
    (folder / "sensor.json").write_text(json.dumps(sensor_dict(camera)))
    (folder / "board.json").write_text(json.dumps(board_dict()))


def board_origin_w():
    """Workpiece position of mark (0, 0): the board centred, rows running towards −y."""
    half = (BOARD_COLS - 1) * PITCH_MM / 2.0
    return np.array([-half, half, 0.0])


def laser_mm(pw, Rw, pt, Rt, laser_offset_mm=(0.0, 0.0)) -> float:
    """The laser's reading (mm): its beam parallel to the camera's axis, from ``laser_offset_mm`` (tool x, y) beside
    the tool point to the board's surface, plus the stand-off. Frames as :func:`render_at`."""
    s_w = Rw.T @ (pt + Rt @ np.array([laser_offset_mm[0], laser_offset_mm[1], 0.0]) - pw)
    d_w = Rw.T @ (Rt @ np.array([0.0, 0.0, -1.0]))
    return float(LASER_STANDOFF_MM + (-s_w[2] / d_w[2]))


def render_at(pw, Rw, pt, Rt, rng, *, noise=2.0, laser_offset_mm=(0.0, 0.0), camera=None):
    """The camera's image (uint8) and the laser reading (mm) with the workpiece frame (origin ``pw``, rotation
    ``Rw``) and the tool frame (``pt``, ``Rt``) where the true machine puts them, machine frame, mm.

    ``camera`` None: a telecentric lens, IMAGE_PX² at PIXEL_MM; else a pinhole camera (see PINHOLE) whose
    pixel rays start at its projection centre, ``working_distance_mm`` above the tool point on the tool axis.
    """
    from kinid.vision import board_coverage, make_board, render_pattern

    board = make_board(BOARD_ROWS, BOARD_COLS, PITCH_MM)
    cam = CAM
    size = IMAGE_PX if camera is None else camera["size_px"]
    c0 = (size - 1) / 2.0
    origin = board_origin_w()

    def image_to_plane(xy_px):
        if camera is None:  # telecentric: every ray along the camera axis, from the plane through the tool point
            u = (xy_px[:, 0] - c0) * PIXEL_MM
            v = (xy_px[:, 1] - c0) * PIXEL_MM
            start = pt + (Rt @ (cam[:, 0:1] * u + cam[:, 1:2] * v)).T
            direction = np.broadcast_to(Rt @ cam[:, 2], start.shape)
        else:  # pinhole: from the projection centre through the undistorted pixel
            xn, yn = _undistort((xy_px[:, 0] - c0) / camera["f_px"], (xy_px[:, 1] - c0) / camera["f_px"], camera["dist"])
            start = np.broadcast_to(pt + Rt @ np.array([0.0, 0.0, camera["working_distance_mm"]]), (len(xn), 3))
            direction = (Rt @ (cam[:, 0:1] * xn + cam[:, 1:2] * yn + cam[:, 2:3])).T
        s_w = (start - pw) @ Rw  # workpiece frame
        d_w = direction @ Rw
        t = -s_w[:, 2] / d_w[:, 2]
        hit = s_w + t[:, None] * d_w
        return np.column_stack([hit[:, 0] - origin[0], -(hit[:, 1] - origin[1])])  # board frame

    img = render_pattern(board_coverage(board), (size, size), image_to_plane, blur_px=0.7,
                         noise_sigma=noise, rng=rng)
    return img, laser_mm(pw, Rw, pt, Rt, laser_offset_mm)
