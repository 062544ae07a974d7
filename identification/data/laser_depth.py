"""The mark's depth from the laser reading, judged with a board pose (docs/observe.md, "The board's pose").

The laser reads the board's height at its spot, beside the tool point when the laser sits beside the camera;
the mark's depth follows from the board's slope between the spot and the mark:
``dz = dz_spot − (n_x·(d_x − s_x) + n_y·(d_y − s_y)) / n_z`` with ``n`` the board's normal and ``s`` the spot, both in
the tool frame. A first ``observe`` takes ``n`` from the nominal machine; the board's own set-up tilt (a board laid on a
table: hundreds of µrad, the joints ``EA0W``, ``EB0W``) times the laser's offset (18 mm) is micrometres, so
``observe --fit FIT.json`` takes ``n`` and the spot from the fitted machine instead: its board set-up, its errors
and the camera's turn on the tool (``EC0T``), which says where a measured offset lies in the camera's axes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..model import tool_rotation_in_workpiece

__all__ = ["BoardPose", "board_pose", "spot_in_tool_mm", "mark_depth_mm", "drawing_turn_um", "LASER_OFFSET_FRAMES",
           "turned_xy", "lever_in_machine_mm"]

#: The frames a sensor file's ``laser_offset_mm`` may be given in: ``machine`` — the machine's axes with the rotary
#: axes at zero, as ``kinid sensor`` measures it (the default); ``tool`` — the camera's own axes (the tool frame turned
#: with the camera by ``EC0T``), as a drawing of the mount gives it.
LASER_OFFSET_FRAMES = ("machine", "tool")


@dataclass(frozen=True)
class BoardPose:
    """The board's normal at each pose of a run and the camera's turn on the tool, as a fit finds them.

    Attributes
    ----------
    normals : array (N, 3)
        The board's normal in the tool frame at each pose of the run log.
    turn_urad : float
        The camera's turn about the tool axis (``EC0T``) the normals were taken with, µrad: 0 when the fit
        determines it too loosely to use (the normals are then in the machine's axes' frame, where a measured offset
        lies).
    camera_turn_urad : float
        The fit's best value of that turn, µrad (turns a drawing's offset, in the camera's axes, into the normals').
    shifted : dict source -> BoardPose
        The same with one fitted set-up parameter moved by its standard deviation (``shift_<source>_dz_mm``).
    source : str
        Where the pose comes from (the FIT.json's name), for messages.
    marks_turn_urad : float
        The turn that takes the marks' own offsets (seen in the camera's axes) into the normals' frame, µrad: the
        fit's EC0T where the normals leave it out, else 0 (:func:`lever_in_machine_mm`).
    marks_reach_limit_mm : float
        The RMS reach of the marks' offsets up to which that turn is used (the fit's noise over the turn's σ).
    """

    normals: np.ndarray
    turn_urad: float = 0.0
    camera_turn_urad: float = 0.0
    shifted: dict = field(default_factory=dict)
    source: str = "the nominal machine"
    marks_turn_urad: float = 0.0
    marks_reach_limit_mm: float = 0.0


def _normals(machine, axes, errors) -> np.ndarray:
    R = tool_rotation_in_workpiece(machine, axes, errors)
    return R[:, 2, :]  # the workpiece z axis in the tool frame: row 2 of each rotation


def _ec0t(machine, errors) -> float:
    codes = machine.error_codes
    if "EC0T" not in codes:
        return 0.0
    return float(np.mean(np.atleast_2d(errors)[:, codes.index("EC0T")]))


def board_pose(machine, axes, errors_user=None, *, camera_turn_urad=None, shifted=None,
               source="the nominal machine") -> BoardPose:
    """The board's pose at readings ``axes`` (N, n_axes) with error-joint values ``errors_user`` ((N, n_errors) or
    (n_errors,), µm / µrad; None: the nominal machine); ``camera_turn_urad`` the fit's EC0T (default: the one in
    ``errors_user``); ``shifted`` dict source -> (errors, camera turn) with one parameter moved by its σ."""
    errors = np.zeros(len(machine.error_joints)) if errors_user is None else np.asarray(errors_user, float)
    turn = _ec0t(machine, errors)
    camera = turn if camera_turn_urad is None else float(camera_turn_urad)
    moved = {k: board_pose(machine, axes, v, camera_turn_urad=c) for k, (v, c) in (shifted or {}).items()}
    return BoardPose(_normals(machine, axes, errors), turn, camera, moved, source)


def _turn(xy, urad: float) -> np.ndarray:
    a = urad * 1e-6
    c, s = math.cos(a), math.sin(a)
    return np.array([c * xy[0] - s * xy[1], s * xy[0] + c * xy[1]])


def spot_in_tool_mm(offset_mm, frame, pose: BoardPose) -> np.ndarray:
    """Where the laser's spot lies in the frame of ``pose.normals``, mm (2,).

    The normals are in the tool frame turned by ``pose.turn_urad``. An offset in the machine's axes (``frame``
    "machine" or None, as ``kinid sensor`` measures it) is turned back by that turn; one in the camera's axes
    (``frame`` "tool", a drawing's) is turned by the camera's turn less that turn: on the nominal machine and when the
    fit leaves EC0T at 0, it is turned by the fit's EC0T (and is as good as that is)."""
    offset = np.asarray(offset_mm, float)
    if frame == "tool":
        return _turn(offset, pose.camera_turn_urad - pose.turn_urad)
    return _turn(offset, -pose.turn_urad)


def drawing_turn_um(pose: BoardPose, offset_mm, turn_std_urad: float) -> float:
    """RMS over the run's poses of how far ``mark_dz_mm`` moves when a drawing's offset (in the camera's axes) is
    turned into the machine's by a camera turn ``turn_std_urad`` off, µm."""
    d = _turn(np.asarray(offset_mm, float), turn_std_urad) - np.asarray(offset_mm, float)
    n = pose.normals
    return float(np.sqrt(np.mean(((n[:, 0] * d[0] + n[:, 1] * d[1]) / n[:, 2]) ** 2)) * 1e3)


def mark_depth_mm(dz_spot_mm: float, normal, d_xy_mm, spot_mm) -> np.ndarray:
    """Tool-frame z (mm, (M,)) of marks at tool-frame (x, y) ``d_xy_mm`` (M, 2) on the plane of tool-frame normal
    ``normal`` (3,) that passes through the laser's spot ``spot_mm`` (2,) at z ``dz_spot_mm``."""
    d = np.atleast_2d(d_xy_mm)
    return dz_spot_mm - (normal[0] * (d[:, 0] - spot_mm[0]) + normal[1] * (d[:, 1] - spot_mm[1])) / normal[2]


def turned_xy(xy, urad) -> np.ndarray:
    """Points ``xy`` (N, 2) turned by ``urad`` (scalar or (N,), µrad) about the tool axis."""
    a = np.asarray(urad, float) * 1e-6
    c, s = np.cos(a), np.sin(a)
    return np.column_stack([c * xy[:, 0] - s * xy[:, 1], s * xy[:, 0] + c * xy[:, 1]])


def lever_in_machine_mm(lever, marks_xy, turn_urad) -> np.ndarray:
    """The lever (mark − spot, (N, 2) mm) in the machine's axes: the spot's part is there already (the offset as
    ``kinid sensor`` measures it), the mark's own part was seen in the camera's axes and is turned by ``turn_urad``."""
    return lever + turned_xy(marks_xy, turn_urad) - marks_xy
