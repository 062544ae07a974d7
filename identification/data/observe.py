"""From images and axis readings to observations: ``kinid observe`` (docs/observe.md).

At each pose of a measurement run the camera on the tool takes one image of the
ring-coded board on the table and the axis readings (and the laser reading)
are logged. For every image the ring-code locator finds and decodes the marks;
the mark nearest the optical axis (or every mark, on request) becomes one row
of the observation CSV: the mark's board position in the workpiece frame, the
readings, and where the mark was seen relative to the tool point in the tool
frame (``mark_dx_mm``, ``mark_dy_mm`` from the image, ``mark_dz_mm`` from the
laser). Images that cannot be read with confidence are listed with the reason,
never guessed.

Sensor model (docs/formats.md, "Sensor file"): the camera looks along the tool
frame's −z axis; the image x axis is the tool x axis turned by
``image_x_angle_deg`` about tool z and the image y axis (down in the image) the
tool −y axis turned by the same angle. The tool point appears at
``optical_axis_px``. A pixel-equivalent sensor maps pixels to mm with
``pixel_mm`` (a telecentric lens, or marks within the depth of field of the
stand-off); a calibrated camera (``kinid.vision`` camera model) removes lens
distortion and scales by the distance from the camera to the mark.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinid.errors import DataError, KinidError
from kinid.files import read_image, read_json
from kinid.progress import as_progress
from kinid.schema import Either, Fields, Number, Row, Text, validate
from ..model import Machine, evaluate, tool_rotation_in_workpiece
from .laser_depth import LASER_OFFSET_FRAMES, BoardPose, board_pose, lever_in_machine_mm, mark_depth_mm, spot_in_tool_mm
from .observations import Observations

#: Passes of the calibrated camera's depth and perspective corrections (the third changes < 1e-6 µm).
PERSPECTIVE_PASSES = 3

__all__ = ["Sensor", "load_sensor", "read_run_log", "RunLog", "observe", "Rejected", "ObserveResult",
           "image_offsets_mm", "perspective_bias_n", "board_mark_mm"]


@dataclass(frozen=True)
class Sensor:
    """The camera and laser on the tool.

    Attributes
    ----------
    pixel_mm : float or None
        Size of one pixel on the board at the stand-off, mm (pixel-equivalent sensor).
    optical_axis_px : (float, float) or None
        Pixel (x, y) where the tool point appears; None: the image centre.
    image_x_angle_deg : float
        Angle of the image x axis from the tool frame's x axis, about tool z, degrees.
    laser_standoff_mm : float or None
        Laser reading when the surface passes through the tool point, mm.
    camera : CameraModel or None
        A calibrated camera (intrinsics and distortion), used instead of ``pixel_mm``.
    working_distance_mm : float or None
        With ``camera``: distance from the camera's projection centre to the tool point, mm.
    laser_offset_mm : (float, float)
        Where the laser beam (parallel to the tool z axis) crosses the tool point's plane, in the tool
        frame, mm: (0, 0) for a laser on the camera's axis; ``kinid sensor`` measures it.
    laser_offset_std_mm : (float, float) or None
        Standard deviations of ``laser_offset_mm``, mm.
    laser_offset_frame : {"machine", "tool"} or None
        The axes ``laser_offset_mm`` is in: the machine's with the rotary axes at zero (as ``kinid sensor`` measures
        it) or the camera's own (as a drawing gives it); they differ by the camera's turn on the tool, ``EC0T``.
        None (not said): the machine's.
    """

    pixel_mm: float | None = None
    optical_axis_px: tuple | None = None
    image_x_angle_deg: float = 0.0
    laser_standoff_mm: float | None = None
    camera: object = None
    working_distance_mm: float | None = None
    laser_offset_mm: tuple = (0.0, 0.0)
    laser_offset_std_mm: tuple | None = None
    laser_offset_frame: str | None = None


_PIXEL = Number(low=-1e5, high=1e5)
#: What a sensor file holds (docs/formats.md), with the ranges of a camera and a laser on a machine tool:
#: a pixel of 10 nm to 10 mm on the board, a stand-off and a working distance within a metre, a laser
#: beside the camera (within 200 mm of its axis).
SENSOR_SCHEMA = Fields({}, optional={
    "pixel_mm": Number(low=1e-5, high=10, null=True),
    "optical_axis_px": Row((_PIXEL, _PIXEL), null=True),
    "image_x_angle_deg": Number(low=-360, high=360, null=True),
    "laser_standoff_mm": Number(low=-1000, high=1000, null=True),
    "camera": Either((Text(null=True), Fields({}, other=True))),
    "working_distance_mm": Number(low=0, high=1000, open_low=True, null=True),
    "laser_offset_mm": Row((Number(low=-200, high=200), Number(low=-200, high=200)), null=True),
    "laser_offset_std_mm": Row((Number(low=0, high=200), Number(low=0, high=200)), null=True),
    "laser_offset_frame": Text(choices=LASER_OFFSET_FRAMES, null=True),
    "measured_by": Either((Text(null=True), Fields({}, other=True))),
})


#: The farthest a laser beside the camera can sit from the camera's axis on one tool, mm.
MAX_LASER_OFFSET_MM = 200.0


def check_laser_offset(offset_mm, *, path, column=None, what="a laser") -> None:
    """Refuse a laser offset (x, y) in the tool frame, mm, farther than :data:`MAX_LASER_OFFSET_MM` from the camera's
    axis: the one rule ``kinid observe`` reads a sensor file by and ``kinid sensor`` writes one by."""
    distance = math.hypot(*offset_mm)
    if math.isfinite(distance) and distance > MAX_LASER_OFFSET_MM:  # a non-finite one is refused where it is written
        raise DataError(f"{what} {distance:.4g} mm from the camera's axis, more than {MAX_LASER_OFFSET_MM:g} mm: not "
                        f"on the same tool; the offset is in mm, in the tool frame", path=path, column=column)


def load_sensor(path) -> Sensor:
    """Read a sensor file (JSON, docs/formats.md "Sensor file").

    Raises
    ------
    DataError
        Naming the file and the key: unknown or missing keys, values that are not finite numbers.
    """
    path = Path(path)
    data = read_json(path, what="sensor file")
    if not isinstance(data, dict):
        raise DataError("a sensor file is a JSON object (pixel_mm or camera, optical_axis_px, image_x_angle_deg, "
                        "laser_standoff_mm)", path=path)
    validate(data, SENSOR_SCHEMA, path=path)

    def number(key, default=None):
        return default if data.get(key) is None else float(data[key])

    def pair(key):
        return None if data.get(key) is None else (float(data[key][0]), float(data[key][1]))

    axis_px = pair("optical_axis_px")
    laser_offset = pair("laser_offset_mm") or (0.0, 0.0)
    laser_std = pair("laser_offset_std_mm")
    check_laser_offset(laser_offset, path=path, column="laser_offset_mm")
    frame = data.get("laser_offset_frame")
    camera = None
    if data.get("camera") is not None:
        from kinid.vision import camera_from_dict, load_camera

        spec = data["camera"]
        if isinstance(spec, str):
            camera = load_camera(path.parent / spec)  # an error names the camera file
        else:
            try:
                camera = camera_from_dict(spec)
            except KinidError as exc:
                raise DataError(exc.message, path=path, column="camera") from None
    sensor = Sensor(number("pixel_mm"), axis_px, number("image_x_angle_deg", default=0.0),
                    number("laser_standoff_mm"), camera, number("working_distance_mm"), laser_offset, laser_std,
                    frame)
    if (sensor.pixel_mm is None) == (sensor.camera is None):
        raise DataError("give either pixel_mm (pixel equivalent on the board) or camera with working_distance_mm",
                        path=path, column="pixel_mm")
    if sensor.camera is not None and sensor.working_distance_mm is None:
        raise DataError("a calibrated camera needs working_distance_mm (camera to tool point, mm)", path=path,
                        column="working_distance_mm")
    return sensor


def _axis_ray_n(sensor: Sensor) -> np.ndarray:
    """Normalised image coordinates of the tool point's ray (a calibrated camera; (0, 0): the principal point)."""
    if sensor.optical_axis_px is None:
        return np.zeros(2)
    cam = sensor.camera
    k = cam.camera_matrix
    a = cam.undistort_points(np.array([sensor.optical_axis_px], float))[0]
    ay = (a[1] - k[1, 2]) / k[1, 1]
    return np.array([(a[0] - k[0, 2] - k[0, 1] * ay) / k[0, 0], ay])


def _tool_to_camera(sensor: Sensor, xy):
    """Camera-frame (x right, y down) components of tool-frame (x, y) components, and back (the map is its own inverse)."""
    a = math.radians(sensor.image_x_angle_deg)
    c, s = math.cos(a), math.sin(a)
    xy = np.atleast_2d(xy)
    return np.column_stack([c * xy[:, 0] + s * xy[:, 1], s * xy[:, 0] - c * xy[:, 1]])


def image_offsets_mm(sensor: Sensor, xy_px, image_size, dz_mm=0.0, bias_n=None) -> np.ndarray:
    """Tool-frame (dx, dy) in mm of image points ``xy_px`` (N, 2).

    ``image_size`` is (width, height); ``dz_mm`` (N,) the tool-frame z of the points (their depth
    below the tool point is −dz), used by a calibrated camera's scale; ``bias_n`` (N, 2), for a
    calibrated camera, is taken off the undistorted normalised coordinates first (the ellipse-centre
    bias of :func:`kinid.vision.circle_centre_bias`).
    """
    xy = np.atleast_2d(np.asarray(xy_px, float))
    if sensor.camera is not None:
        cam = sensor.camera
        ideal = cam.undistort_points(xy)
        k = cam.camera_matrix
        y_n = (ideal[:, 1] - k[1, 2]) / k[1, 1]
        x_n = (ideal[:, 0] - k[0, 2] - k[0, 1] * y_n) / k[0, 0]
        if bias_n is not None:
            x_n, y_n = x_n - bias_n[:, 0], y_n - bias_n[:, 1]
        a = _axis_ray_n(sensor)  # the tool point's ray, if it is not the principal point
        depth = sensor.working_distance_mm - np.asarray(dz_mm, float)
        u, v = (x_n - a[0]) * depth, (y_n - a[1]) * depth
    else:
        w, h = image_size
        cx, cy = sensor.optical_axis_px if sensor.optical_axis_px is not None else ((w - 1) / 2.0, (h - 1) / 2.0)
        u, v = (xy[:, 0] - cx) * sensor.pixel_mm, (xy[:, 1] - cy) * sensor.pixel_mm
    # camera frame: x right, y down, looking along tool -z  ->  tool frame (x, -y) turned by the angle
    return _tool_to_camera(sensor, np.column_stack([u, v]))


def perspective_bias_n(sensor: Sensor, offsets_mm, normal_tool, radius_mm) -> np.ndarray:
    """The ellipse-centre bias (normalised image units, (N, 2)) of circles of ``radius_mm`` centred at tool-frame
    ``offsets_mm`` (N, 3) on a plane of tool-frame normal ``normal_tool`` (3,), seen by the sensor's calibrated camera."""
    from kinid.vision import circle_centre_bias

    off = np.atleast_2d(offsets_mm)
    depth = sensor.working_distance_mm - off[:, 2]
    a = _axis_ray_n(sensor)
    uv = _tool_to_camera(sensor, off[:, :2])
    centre = np.column_stack([uv[:, 0] + a[0] * depth, uv[:, 1] + a[1] * depth, depth])
    normal = np.array([*_tool_to_camera(sensor, normal_tool[:2])[0], -normal_tool[2]])
    return circle_centre_bias(centre, normal, radius_mm)


@dataclass(frozen=True)
class RunLog:
    """The log of a measurement run: one image per pose.

    Attributes
    ----------
    images : tuple of str
        Image file names as written in the log (relative to the log's folder).
    axes : array (N, n_axes)
        Readings in ``machine.axes`` order, mm / deg.
    laser_mm : array (N,) or None
    t_s : array (N,) or None
    directions : dict axis -> array (N,)
    lines : tuple of int
    source : str
    """

    images: tuple
    axes: np.ndarray
    laser_mm: np.ndarray | None
    t_s: np.ndarray | None
    directions: dict
    lines: tuple
    source: str


def read_run_log(path, machine: Machine, *, check_limits: bool = True) -> RunLog:
    """Read a run log CSV: ``image``, every axis column (``x_mm`` ... ``c_deg``), optional
    ``laser_mm``, ``t_s``, ``dir_<axis>`` (docs/formats.md, "Run log").

    Raises
    ------
    DataError
        Naming the file, line and column of the first problem.
    """
    from .axis_columns import read_axis_table

    t = read_axis_table(path, machine, what="run log", required=("image",), check_limits=check_limits,
                        texts=("image",))
    images = t.texts("image", "image name")
    laser = t.numbers("laser_mm") if "laser_mm" in t.header else None
    return RunLog(tuple(images), t.axes, laser, t.t_s, t.directions, t.lines, str(t.path))


@dataclass(frozen=True)
class Rejected:
    """An image that gave no observation, and why."""

    line: int
    image: str
    reason: str


@dataclass(frozen=True)
class ObserveResult:
    """Observations made from a run's images.

    Attributes
    ----------
    observations : Observations
        With ``offsets_mm``; ``lines`` are the run log's lines.
    images : tuple of str
        The image each row comes from (as named in the log).
    rejected : tuple of Rejected
    laser_columns : dict column -> array (N,)
        With the laser beside the camera: each row's ``laser_lever_x_mm``, ``laser_lever_y_mm`` (the mark's tool-frame
        x, y from the laser's spot) and ``board_slope_x``, ``board_slope_y`` (the normal's x, y over its z it was
        judged with), so that ``identify`` can say how far a fitted board pose would move ``mark_dz_mm``.
    """

    observations: Observations
    images: tuple
    rejected: tuple
    laser_columns: dict = field(default_factory=dict)


def board_mark_mm(board, row, col, origin_mm):
    """Workpiece-frame position of a board mark: board x along workpiece x, board y (rows down the
    printed board) along workpiece −y, the board lying face up on the workpiece x-y plane."""
    x_b, y_b = board.mark_mm(row, col)
    return np.array([origin_mm[0] + x_b, origin_mm[1] - y_b, origin_mm[2]])


def default_board_origin_mm(board) -> tuple:
    """Board placed with its centre on the workpiece origin: the position of mark (0, 0)."""
    return (-(board.cols - 1) * board.pitch_mm / 2.0, (board.rows - 1) * board.pitch_mm / 2.0, 0.0)


def _laser_offset_shifts(sensor: Sensor, slope) -> dict:
    """How far each row's mark_dz moves when the laser's offset is one standard deviation off in x or y:
    the board's slope at the spot (``slope`` (N, 2): the board normal's tool-frame x, y over its z) times σ."""
    if sensor.laser_offset_std_mm is None:
        return {}
    shifts = {}
    for j, axis in enumerate("xy"):
        if sensor.laser_offset_std_mm[j] > 0:
            shift = np.zeros((len(slope), 3))
            shift[:, 2] = slope[:, j] * sensor.laser_offset_std_mm[j]
            shifts[f"laser_offset_{axis}"] = shift
    return shifts


def _pose_shifts(rows, shifted) -> dict:
    """The depth's change per row (as a shift of (0, 0, dz)) for each fitted set-up parameter one σ off."""
    out = {}
    for src in shifted:
        shift = np.zeros((len(rows), 3))
        shift[:, 2] = [r[5][src] for r in rows]
        out[src] = shift
    return out


def _marks_turned(offsets_mm, slope, pose: BoardPose):
    """(offsets with ``mark_dz_mm`` judged with the marks' own part of the lever turned by ``pose.marks_turn_urad``
    into the normals' frame, the turn used): the marks (x, y) are seen in the camera's axes, the normals and the
    spot in the machine's where the fit's EC0T is left out of them; the turn is used while the marks' RMS reach is
    within ``pose.marks_reach_limit_mm``. The depth is linear in the mark's (x, y): it moves by −slope · the turn's
    move."""
    marks = offsets_mm[:, :2]
    if not pose.marks_turn_urad or np.sqrt(np.mean(np.sum(marks**2, axis=1))) > pose.marks_reach_limit_mm:
        return offsets_mm, 0.0
    moved = offsets_mm.copy()
    moved[:, 2] -= np.sum(slope * (lever_in_machine_mm(np.zeros_like(marks), marks, pose.marks_turn_urad)), axis=1)
    return moved, float(pose.marks_turn_urad)


def observe(machine: Machine, board, sensor: Sensor, log: RunLog, *, board_origin_mm=None, marks: str = "nearest",
            progress=None, pose: BoardPose | None = None) -> ObserveResult:
    """Locate and decode the board's marks in every image of a run and make observation rows.

    Parameters
    ----------
    machine : Machine
    board : kinid.vision.Board
    sensor : Sensor
    log : RunLog
    board_origin_mm : (3,), optional
        Workpiece-frame position of mark (row 0, col 0); default: the board centred on the
        workpiece origin (:func:`default_board_origin_mm`).
    marks : {"nearest", "all"}
        One row per image (the mark nearest the optical axis) or one per decoded mark.
    progress : Progress, callable (done, total) or None
        Counted once per image, at its start (:func:`kinid.progress.as_progress`).
    pose : BoardPose, optional
        The board's pose at every pose of the log (:func:`~kinid.identification.data.laser_depth.board_pose`) as a
        fit finds it; the laser's reading is judged with it, and each fitted set-up parameter's standard deviation
        becomes a ``shift_<source>_dz_mm`` column. None: the nominal machine's.

    Returns
    -------
    ObserveResult
    """
    from kinid.vision import detect_markers

    if marks not in ("nearest", "all"):
        raise DataError(f"must be 'nearest' or 'all', got {marks!r}", parameter="marks")
    origin = np.asarray(default_board_origin_mm(board) if board_origin_mm is None else board_origin_mm, float)
    folder = Path(log.source).parent
    n = len(log.images)
    # nominal tool frame and tool point at each pose: the board's normal for the laser, and the expected marks
    zero = np.zeros(len(machine.error_joints))
    R_nominal = tool_rotation_in_workpiece(machine, log.axes, zero)
    p_nominal = evaluate(machine, log.axes, zero, jacobian=False)
    pose = board_pose(machine, log.axes) if pose is None else pose
    spot = spot_in_tool_mm(sensor.laser_offset_mm, sensor.laser_offset_frame, pose)
    shifted = {k: (p.normals, spot_in_tool_mm(sensor.laser_offset_mm, sensor.laser_offset_frame, p))
               for k, p in pose.shifted.items()}
    rows, rejected = [], []
    progress = as_progress(progress, total=n)
    for i, name in enumerate(log.images):
        progress.update()
        line = log.lines[i]
        img = read_image(folder / name)
        h, w = img.shape
        if sensor.camera is not None and (w, h) != tuple(sensor.camera.image_size):
            raise DataError(f"{name} is {w} × {h} px, but the sensor's camera was calibrated on "
                            f"{sensor.camera.image_size[0]} × {sensor.camera.image_size[1]} px images",
                            path=log.source, line=line, column="image")
        found = detect_markers(img, bits=board.bits)
        if not found:
            rejected.append(Rejected(line, name, "no ring-coded mark decoded"))
            continue
        codes = [m.code for m in found]
        on_board = [m for m in found if board.position_of(m.code) is not None and codes.count(m.code) == 1]
        off = sorted({m.code for m in found if board.position_of(m.code) is None})
        twice = sorted({c for c in codes if codes.count(c) > 1})
        if not on_board:
            why = (f"code {off[0]} is not on the board" if off else f"code {twice[0]} decoded twice in one image")
            rejected.append(Rejected(line, name, why))
            continue
        # the laser spot: the surface on the tool axis at dz_spot; the board plane through it
        dz_spot = 0.0 if log.laser_mm is None or sensor.laser_standoff_mm is None else -(log.laser_mm[i] - sensor.laser_standoff_mm)
        normal = pose.normals[i]  # board normal in the tool frame (nominal, or as the fit finds it)
        if abs(normal[2]) < 0.2:
            rejected.append(Rejected(line, name, "the board is seen edge-on (tilted more than 78° from the camera axis)"))
            continue
        xy = np.array([[m.x_px, m.y_px] for m in on_board])
        # the spot is where the laser beam meets the board: at the laser's offset from the tool axis
        d_xy = image_offsets_mm(sensor, xy, (w, h), dz_spot)
        dz = mark_depth_mm(dz_spot, normal, d_xy, spot)
        if sensor.camera is not None:
            # depth changes a calibrated camera's scale, and a tilted mark's ellipse centre is not the image of
            # its centre: redo with the marks' depth and the perspective bias at the nominal board pose
            for k in range(PERSPECTIVE_PASSES):
                bias = None if k == 0 else perspective_bias_n(sensor, np.column_stack([d_xy, dz]), normal,
                                                              board.center_d_mm / 2.0)
                d_xy = image_offsets_mm(sensor, xy, (w, h), dz, bias)
                dz = mark_depth_mm(dz_spot, normal, d_xy, spot)
        offsets = np.column_stack([d_xy, dz])
        # a fitted set-up parameter one σ off: the depth's change
        pose_shift = {k: mark_depth_mm(dz_spot, n_k[i], d_xy, s_k) - dz for k, (n_k, s_k) in shifted.items()}
        w_mm = np.array([board_mark_mm(board, *board.position_of(m.code), origin) for m in on_board])
        # where the nominal machine expects each decoded mark: a misread code lands a pitch or more away
        expected = np.einsum("ji,nj->ni", R_nominal[i], w_mm - p_nominal[i])
        miss = np.linalg.norm(expected[:, :2] - offsets[:, :2], axis=1)
        order = np.argsort(np.hypot(offsets[:, 0], offsets[:, 1]))
        chosen = order[:1] if marks == "nearest" else order
        for k in chosen:
            if miss[k] > 0.5 * board.pitch_mm:
                rejected.append(Rejected(line, name, f"code {on_board[k].code} decoded {miss[k]:.1f} mm from where the "
                                                     f"readings put it (a misread code or a wrong board origin)"))
                continue
            rows.append((i, on_board[k].code, w_mm[k], offsets[k], normal[:2] / normal[2],
                         {src: v[k] for src, v in pose_shift.items()}, d_xy[k] - spot))
    if not rows:
        raise DataError(f"no image of the run gave an observation ({len(rejected)} rejected; the first: line "
                        f"{rejected[0].line}, {rejected[0].image}: {rejected[0].reason})" if rejected else
                        "the run log lists no image", path=log.source)
    idx = np.array([r[0] for r in rows])
    offsets_mm, marks_turn = _marks_turned(np.array([r[3] for r in rows]), np.array([r[4] for r in rows]), pose)
    obs = Observations(
        marks=tuple(f"M{r[1]}" for r in rows),
        w_mm=np.array([r[2] for r in rows]),
        axes=log.axes[idx],
        t_s=None if log.t_s is None else log.t_s[idx],
        directions={k: v[idx] for k, v in log.directions.items()},
        lines=tuple(log.lines[j] for j in idx),
        source=log.source,
        offsets_mm=offsets_mm,
        shifts_mm={**_laser_offset_shifts(sensor, np.array([r[4] for r in rows])), **_pose_shifts(rows, shifted)},
    )
    columns = {}
    if log.laser_mm is not None and np.hypot(*sensor.laser_offset_mm) > 0:
        lever, slope = np.array([r[6] for r in rows]), np.array([r[4] for r in rows])
        columns = {"laser_lever_x_mm": lever[:, 0], "laser_lever_y_mm": lever[:, 1], "board_slope_x": slope[:, 0],
                   "board_slope_y": slope[:, 1], **({"laser_marks_turn_urad": np.full(len(rows), marks_turn)}
                                                     if marks_turn else {})}
    return ObserveResult(obs, tuple(log.images[j] for j in idx), tuple(rejected), columns)
