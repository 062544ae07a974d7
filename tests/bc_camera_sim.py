"""An independent simulator of a camera measurement run on the B/C double-turntable machine.

Truth for the image-to-compensation tests. It does not use kinid's kinematics: the machine
``five_axis_bc`` (urdf/five_axis_bc.urdf) is written out by hand in numpy with a few errors
placed where that URDF places their error joints, and the camera's view is rendered by
intersecting pixel rays with the board plane (kinid.vision.render only paints the board's
ink at the plane points it is given).

Errors (µm, µrad): a 10 mm-lead screw error of X (EXX, after the X carriage, along x), the C
axis line offset in x and y (EX0C, EY0C, after the B rotation and the table drop), the tool
length (EZ0T) and the camera's rotation about the tool axis (EC0T), which moves nothing but
what the camera sees. The ray tracer, the board and the lenses are benchmarks/camera_render.py's (shared with
benchmarks/proving_chain.py, imported here). ``BOARD_SETUP`` adds the set-up a real run has (the board laid on the table tilted by a
fraction of a milliradian, turned and placed tens of µm off: EX0W ... EC0W, the URDF's board joints, translations
then rotations about x, y, z), for runs that pass ``truth={**TRUTH, **BOARD_SETUP}``.
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
from camera_render import (BOARD_COLS, BOARD_ROWS, CAM, IMAGE_PX, IMAGE_X_ANGLE_DEG, LASER_STANDOFF_MM,  # noqa: E402,F401
                           PINHOLE, PITCH_MM, PIXEL_MM, board_dict, board_origin_w, pinhole_sensor, render_at,
                           write_setup_files)

TRUTH = {"EX0C": 12.0, "EY0C": -8.0, "EZ0T": 15.0, "EC0T": 800.0, "EXX:periodic:10": [1.5, -0.8]}
#: A board laid on a table by hand: tilted 200 µrad about x and −150 µrad about y, turned 300 µrad, placed 40, −25, 15 µm off.
BOARD_SETUP = {"EX0W": 40.0, "EY0W": -25.0, "EZ0W": 15.0, "EA0W": 200.0, "EB0W": -150.0, "EC0W": 300.0}


def _ry(rad):
    c, s = np.cos(rad), np.sin(rad)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rx(rad):
    c, s = np.cos(rad), np.sin(rad)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _rz(rad):
    c, s = np.cos(rad), np.sin(rad)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def exx_mm(x_mm, truth=TRUTH):
    a, b = truth.get("EXX:periodic:10", (0.0, 0.0))
    return (a * np.sin(2 * np.pi * x_mm / 10.0) + b * np.cos(2 * np.pi * x_mm / 10.0)) * 1e-3


def workpiece(y, b_deg, c_deg, truth=TRUTH):
    """Origin (mm) and rotation of the workpiece (board surface) frame in the machine frame."""
    RB = _ry(np.radians(b_deg))
    R = RB @ _rz(np.radians(c_deg))
    loc = np.array([truth.get("EX0C", 0.0), truth.get("EY0C", 0.0), 0.0]) * 1e-3
    p = np.array([0.0, y, 150.0]) + RB @ (np.array([0.0, 0.0, -50.0]) + loc) + R @ np.array([0.0, 0.0, 10.0])
    # the board's set-up on the table: translations, then rotations about x, y, z (the URDF's E?0W chain)
    setup = np.array([truth.get(k, 0.0) for k in ("EX0W", "EY0W", "EZ0W")]) * 1e-3
    a, b, c = (truth.get(k, 0.0) * 1e-6 for k in ("EA0W", "EB0W", "EC0W"))
    return p + R @ setup, R @ _rx(a) @ _ry(b) @ _rz(c)


def tool(x, z, truth=TRUTH):
    """Tool point (mm) and rotation of the tool (camera) frame in the machine frame."""
    p = np.array([x + exx_mm(x, truth), 0.0, z + 110.0 + truth.get("EZ0T", 0.0) * 1e-3])
    return p, _rz(truth.get("EC0T", 0.0) * 1e-6)


def align(mark_w, b_deg, c_deg, truth=TRUTH):
    """Readings x, y, z (mm) that put the tool point on a mark (workpiece frame, mm)."""
    p0, R = workpiece(0.0, b_deg, c_deg, truth)
    target = p0 + R @ np.asarray(mark_w, float)  # the mark in the machine frame at y = 0
    y = -target[1]  # the table moves the mark onto the tool's y = 0
    x = target[0]
    for _ in range(20):  # x + e(x) = target x
        x = target[0] - exx_mm(x, truth)
    z = target[2] - 110.0 - truth.get("EZ0T", 0.0) * 1e-3
    return np.array([x, y, z])


def seen_offset(readings, b_deg, c_deg, mark_w, truth=TRUTH):
    """Where the mark lies relative to the tool point in the tool frame (mm) at these true readings."""
    x, y, z = readings
    pw, Rw = workpiece(y, b_deg, c_deg, truth)
    pt, Rt = tool(x, z, truth)
    return Rt.T @ (pw + Rw @ np.asarray(mark_w, float) - pt)


def render(readings, b_deg, c_deg, rng, truth=TRUTH, noise=2.0, laser_offset_mm=(0.0, 0.0), camera=None):
    """The camera's image (uint8) and the laser reading (mm) at these true readings (:func:`render_at`)."""
    x, y, z = readings
    pw, Rw = workpiece(y, b_deg, c_deg, truth)
    pt, Rt = tool(x, z, truth)
    return render_at(pw, Rw, pt, Rt, rng, noise=noise, laser_offset_mm=laser_offset_mm, camera=camera)


def laser_offset_as_measured(offset_mm, truth=TRUTH):
    """The laser's offset as the hole measurement finds it: in machine axes at B = C = 0 (the tool's own
    rotation EC0T turns the laser with the camera)."""
    return tuple(float(v) for v in (tool(0.0, 0.0, truth)[1] @ np.array([offset_mm[0], offset_mm[1], 0.0]))[:2])


def plan(tilts=(-40.0, 0.0, 40.0), turns=(0.0, 60.0, 120.0, 180.0, 240.0, 300.0), marks=((40.0, 40.0), (-40.0, 40.0), (-40.0, -40.0), (40.0, -40.0))):
    return [(b, c, (mx, my, 0.0)) for b in tilts for c in turns for mx, my in marks]


def write_run(folder, poses, *, rng, stop_mm=0.1, reading_noise_um=0.5, laser_noise_um=0.5, truth=TRUTH, image_noise=2.0,
              laser_offset_mm=(0.0, 0.0), camera=None):
    """Render a run into ``folder``: images, run log, sensor and board files. Returns the true readings.

    The sensor file describes the camera (``camera``: a pinhole, see :func:`render`) but not the laser's offset."""
    import cv2

    folder = Path(folder)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    rows, truth_rows = [], []
    for k, (b, c, m) in enumerate(poses):
        true = align(m, b, c, truth) + rng.normal(0.0, stop_mm, 3)
        img, laser = render(true, b, c, rng, truth, noise=image_noise, laser_offset_mm=laser_offset_mm, camera=camera)
        name = f"images/{k:03d}.png"
        cv2.imwrite(str(folder / name), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        logged = true + rng.normal(0.0, reading_noise_um * 1e-3, 3)
        rows.append([name, *(f"{v:.6f}" for v in logged), f"{b:.6f}", f"{c:.6f}",
                     f"{laser + rng.normal(0.0, laser_noise_um * 1e-3):.6f}"])
        truth_rows.append((true, b, c, m))
    with open(folder / "log.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["image", "x_mm", "y_mm", "z_mm", "b_deg", "c_deg", "laser_mm"])
        w.writerows(rows)
    write_setup_files(folder, camera)
    return truth_rows
