"""An independent simulator of a camera measurement run on any shipped five-axis layout.

The layout-generic sibling of tests/bc_camera_sim.py. The machine is not kinid's kinematics: its
workpiece and tool frames come from benchmarks/proving_truth.py (plain numpy on the URDF text, the
product of the joint transforms), with hidden errors given as error-joint name -> value (µm, µrad).
The camera's view is rendered by intersecting pixel rays with the board plane (kinid.vision.render
only paints the board's ink at the plane points it is given), and the laser beam, parallel to the
camera's axis from its offset beside the tool point, is traced to the board plane.

The board, the image size and pixel, the image x angle, the laser stand-off, the pinhole camera and its
undistortion are bc_camera_sim's (imported, not copied).

Errors (µm, µrad): constant location errors of the layout's own error joints (its C axis line, and its
tilting axis where a constant one is not a mere shift of the whole machine), the tool length EZ0T, the
camera's rotation about the tool axis EC0T (which moves nothing but what the camera sees) and a 10 mm-lead
periodic error of X (``EXX:periodic:10``: sin, cos coefficients, added to the EXX joint as a function of
the X reading).
"""
from __future__ import annotations

import csv
import sys
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

import bc_camera_sim as bc
from bc_camera_sim import (BOARD_COLS, IMAGE_PX, IMAGE_X_ANGLE_DEG, LASER_STANDOFF_MM, PINHOLE, PITCH_MM,
                           PIXEL_MM, pinhole_sensor)

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import proving_truth as pt  # noqa: E402

__all__ = ["LAYOUTS", "TRUTHS", "PINHOLE", "PIXEL_MM", "IMAGE_PX", "Layout", "layout", "frames", "align",
           "seen_offset", "true_tool_point_mm", "render", "laser_offset_as_measured", "plan", "x_positions", "write_run",
           "pinhole_sensor", "held_out_poses"]

#: Layout -> (tilting axis, table axis), as the URDF names the joints.
LAYOUTS = {"five_axis_ac": ("A", "C"), "five_axis_bhead_c": ("B", "C")}

#: Hidden true errors per layout. On the A/C table the A axis line's y (EY0A) is seen as A turns; on the B head
#: a constant location of B is a shift of the whole tool (the same as the C line's), so the pivot's z (EZ0B) stands
#: for the head's location and the tool length (EZ0T) is seen as B swings.
TRUTHS = {
    "five_axis_ac": {"EY0A": 10.0, "EX0C": 12.0, "EY0C": -8.0, "EZ0T": 15.0, "EC0T": 800.0,
                     "EXX:periodic:10": [1.5, -0.8]},
    "five_axis_bhead_c": {"EX0C": 12.0, "EY0C": -8.0, "EZ0B": -10.0, "EZ0T": 15.0, "EC0T": 800.0,
                          "EXX:periodic:10": [1.5, -0.8]},
}

@dataclass(frozen=True)
class Layout:
    name: str
    text: str
    machine: pt.TrueMachine
    tilt: str
    table: str
    linear: tuple  # linear axes (joint names), sorted: X, Y, Z
    truth: dict

    def column(self, axis: str) -> str:
        """The run log's column of an axis, as kinid names it (``x_mm``, ``a_deg``)."""
        return f"{axis.lower()}_mm" if axis in self.linear else f"{axis.lower()}_deg"

    @property
    def axes(self) -> tuple:
        """Axes in the run log's order: linear, then the tilting and the table axis."""
        return (*self.linear, self.tilt, self.table)


@lru_cache(maxsize=None)
def layout(name: str) -> Layout:
    from kinid.urdf import path as urdf_path

    text = Path(urdf_path(name)).read_text()
    m = pt.read_urdf(text)
    linear = tuple(sorted(a for a in m.motion if m.kind(a) == "prismatic"))
    tilt, table = LAYOUTS[name]
    assert set(m.motion) == {*linear, tilt, table}, m.motion
    return Layout(name, text, m, tilt, table, linear, TRUTHS[name])


def _as_layout(lay) -> Layout:
    return layout(lay) if isinstance(lay, str) else lay


def error_values(lay: Layout, readings: dict, truth: dict, n: int) -> dict:
    """Error-joint values (µm, µrad), arrays (n,), at the readings: the constants and EXX's periodic term."""
    out = {}
    for name, v in truth.items():
        if ":" in name:
            joint, kind, lead = name.split(":")
            assert kind == "periodic", name
            x = np.broadcast_to(np.asarray(readings["X"], float), (n,))
            a, b = v
            phase = 2 * np.pi * x / float(lead)
            out[joint] = out.get(joint, 0.0) + a * np.sin(phase) + b * np.cos(phase)
        else:
            assert name in lay.machine.errors, (name, lay.name)
            out[name] = out.get(name, 0.0) + np.full(n, float(v))
    return out


def frames(lay, readings: dict, truth=None, n: int | None = None):
    """Workpiece and tool frames in the machine frame at the readings (mm / deg, arrays (n,)):
    (pw (n, 3) mm, Rw (n, 3, 3), pt (n, 3) mm, Rt (n, 3, 3)). ``truth`` None: the layout's; {}: nominal."""
    lay = _as_layout(lay)
    truth = lay.truth if truth is None else truth
    n = len(np.atleast_1d(next(iter(readings.values())))) if n is None else n
    readings = {k: np.broadcast_to(np.asarray(v, float), (n,)) for k, v in readings.items()}
    values = pt.joint_values(lay.machine, readings, error_values(lay, readings, truth, n))
    Rw, pw = pt._pose(lay.machine, "workpiece", values, n)
    Rt, ptool = pt._pose(lay.machine, "tool", values, n)
    return pw * 1e3, Rw, ptool * 1e3, Rt


def true_tool_point_mm(lay, readings: dict, truth=None, n: int | None = None) -> np.ndarray:
    """The tool point in the workpiece frame (n, 3), mm, on the machine with ``truth`` (None: the layout's)."""
    pw, Rw, ptool, _ = frames(lay, readings, truth, n)
    return np.einsum("nji,nj->ni", Rw, ptool - pw)


def align(lay, tilt_deg, table_deg, marks_w) -> dict:
    """Readings (arrays (n,)) that put the NOMINAL tool point on each mark (workpiece frame, mm) at these rotary
    angles: the operator drives the nominal machine (proving_truth.align_linear)."""
    lay = _as_layout(lay)
    marks_w = np.atleast_2d(np.asarray(marks_w, float))
    n = len(marks_w)
    presets = {lay.tilt: np.broadcast_to(np.asarray(tilt_deg, float), (n,)).copy(),
               lay.table: np.broadcast_to(np.asarray(table_deg, float), (n,)).copy()}
    presets.update({a: np.zeros(n) for a in lay.linear})
    return pt.align_linear(lay.machine, presets, marks_w)


def seen_offset(lay, readings: dict, mark_w, truth=None) -> np.ndarray:
    """Where the mark lies relative to the tool point in the tool frame (mm, (n, 3)) at these true readings."""
    pw, Rw, ptool, Rt = frames(lay, readings, truth)
    mark = pw + np.einsum("nij,nj->ni", Rw, np.atleast_2d(np.asarray(mark_w, float)))
    return np.einsum("nji,nj->ni", Rt, mark - ptool)


def render(lay, readings: dict, rng, truth=None, noise=2.0, laser_offset_mm=(0.0, 0.0), camera=None):
    """The camera's image (uint8) and the laser reading (mm) at one pose's true readings (scalars): the true
    machine's frames traced by bc_camera_sim's ray tracer (:func:`bc_camera_sim.render_at`)."""
    lay = _as_layout(lay)
    pw, Rw, ptool, Rt = (v[0] for v in frames(lay, {k: np.atleast_1d(v) for k, v in readings.items()}, truth, 1))
    img, laser = bc.render_at(pw, Rw, ptool, Rt, rng, noise=noise, laser_offset_mm=laser_offset_mm, camera=camera)
    return img, float(laser)


def laser_offset_as_measured(lay, offset_mm, truth=None):
    """The laser's offset as the hole measurement finds it: in machine axes with every rotary axis (and every
    linear axis) at 0 on the true machine (the tool's own rotation EC0T turns the laser with the camera)."""
    lay = _as_layout(lay)
    _, _, _, Rt = frames(lay, {a: np.zeros(1) for a in lay.axes}, truth, 1)
    return tuple(float(v) for v in (Rt[0] @ np.array([offset_mm[0], offset_mm[1], 0.0]))[:2])


def plan(tilts=(-40.0, 0.0, 40.0), turns=(0.0, 60.0, 120.0, 180.0, 240.0, 300.0),
         marks=((40.0, 40.0), (-40.0, 40.0), (-40.0, -40.0), (40.0, -40.0)), stagger_deg=0.0):
    """Presets (tilt deg, table deg, mark (x, y, 0) mm in the workpiece frame), tilt-major as bc_camera_sim.plan
    (the same list when ``stagger_deg`` is 0); the k-th tilt's table angles turned by k × ``stagger_deg``.

    Why stagger: on the A/C table A turns about x, so the X reading of a mark depends on C and the mark only; with
    the same six table angles at every tilt X visits 6 positions (±14.6, ±40.0, ±54.6 mm), where a 10 mm lead
    cannot be told from a 2 or 20 mm one. Staggered by 20° per tilt it visits 18."""
    out = bc.plan(tilts, turns, marks)
    if stagger_deg:
        index = {t: k for k, t in enumerate(tilts)}
        out = [(t, c + index[t] * stagger_deg, m) for t, c, m in out]
    return out


def x_positions(lay, poses) -> np.ndarray:
    """The distinct nominal X readings (to 1 µm) of the plan's alignments, mm."""
    r = align(lay, [p[0] for p in poses], [p[1] for p in poses], [p[2] for p in poses])
    return np.unique(np.round(r["X"], 3))


def held_out_poses(lay, n, rng, tilt_range=(-40.0, 40.0), table_range=(0.0, 360.0), half_mm=None, stop_mm=0.1):
    """``n`` held-out readings (dict axis -> (n,)): random rotary angles within the ranges, random board points
    (within the board's marks), aligned on the nominal machine and stopped ~``stop_mm`` off."""
    lay = _as_layout(lay)
    half = (BOARD_COLS - 1) * PITCH_MM / 2.0 if half_mm is None else half_mm
    tilt = rng.uniform(*tilt_range, n)
    table = rng.uniform(*table_range, n)
    points = np.column_stack([rng.uniform(-half, half, n), rng.uniform(-half, half, n), np.zeros(n)])
    r = align(lay, tilt, table, points)
    for a in lay.linear:
        r[a] = r[a] + rng.normal(0.0, stop_mm, n)
    return r


def write_run(folder, lay, poses, *, rng, stop_mm=0.1, reading_noise_um=0.5, laser_noise_um=0.5, truth=None,
              image_noise=2.0, laser_offset_mm=(0.0, 0.0), camera=None):
    """Render a run into ``folder``: images, run log, sensor and board files (bc_camera_sim's formats). Returns the
    true readings of each image as a list of (readings dict of scalars, tilt, table, mark).

    The sensor file describes the camera (``camera``: a pinhole, see :func:`render`) but not the laser's offset."""
    import cv2

    lay = _as_layout(lay)
    folder = Path(folder)
    (folder / "images").mkdir(parents=True, exist_ok=True)
    tilts = np.array([p[0] for p in poses], float)
    turns = np.array([p[1] for p in poses], float)
    marks = np.array([p[2] for p in poses], float)
    nominal = align(lay, tilts, turns, marks)
    rows, truth_rows = [], []
    for k, (tilt, turn, mark) in enumerate(poses):
        stop = rng.normal(0.0, stop_mm, len(lay.linear))
        true = {a: float(nominal[a][k]) + s for a, s in zip(lay.linear, stop)}
        true.update({lay.tilt: float(tilt), lay.table: float(turn)})
        img, laser = render(lay, true, rng, truth, noise=image_noise, laser_offset_mm=laser_offset_mm, camera=camera)
        name = f"images/{k:03d}.png"
        cv2.imwrite(str(folder / name), img, [cv2.IMWRITE_PNG_COMPRESSION, 9])
        logged = [true[a] + rng.normal(0.0, reading_noise_um * 1e-3) for a in lay.linear]
        rows.append([name, *(f"{v:.6f}" for v in logged), f"{tilt:.6f}", f"{turn:.6f}",
                     f"{laser + rng.normal(0.0, laser_noise_um * 1e-3):.6f}"])
        truth_rows.append((true, tilt, turn, tuple(mark)))
    with open(folder / "log.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["image", *(lay.column(a) for a in lay.axes), "laser_mm"])
        w.writerows(rows)
    bc.write_setup_files(folder, camera)
    return truth_rows
