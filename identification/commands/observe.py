"""``kinid observe``: images and axis readings of a run -> the observation CSV (docs/observe.md)."""
from __future__ import annotations

from kinid.options import add_alias, add_json_option, csv_rows

from pathlib import Path

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "observe", help="images + axis readings of a run -> observation CSV (marks located and decoded)",
        description="Locate and decode the ring-coded mark nearest the optical axis in every image of a run "
                    "and write one observation row per image: the mark's position on the board, the axis "
                    "readings and where the mark was seen from the tool point (mark_dx_mm, mark_dy_mm from the "
                    "image, mark_dz_mm from the laser). Images that cannot be read with confidence are listed.")
    p.add_argument("--machine", required=True, help="machine URDF (docs/machines.md)")
    p.add_argument("--board", required=True, help="board file, JSON (docs/formats.md, 'Board file')")
    p.add_argument("--sensor", required=True, help="sensor file, JSON: camera and laser on the tool (docs/formats.md)")
    p.add_argument("--data", dest="log", required=True, help="run log CSV: image, axis readings, laser_mm (docs/formats.md)")
    p.add_argument("--out", required=True, help="observation CSV to write ('-' for standard output)")
    p.add_argument("--board-origin-mm", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="workpiece-frame position of the board's mark in row 0, column 0 (default: the board "
                        "centred on the workpiece origin)")
    p.add_argument("--marks", choices=("nearest", "all"), default="nearest",
                   help="one row per image (the mark nearest the optical axis, default) or one per decoded mark")
    p.add_argument("--fit", default=None, metavar="FIT.json",
                   help="judge the laser's reading with the board's pose as this fit finds it (its board set-up, "
                        "errors and EC0T) instead of the nominal machine's, for a file of the rows identify judges "
                        "again itself when the laser sits beside the camera, or a drawing's offset (docs/observe.md)")
    p.add_argument("--allow-outside-limits", action="store_true",
                   help="accept readings outside the axis travel given by the URDF joint limits")
    add_alias(p, "--log", "--data")
    add_json_option(p, csv_rows("out"), "the observation rows written")
    p.set_defaults(run=_observe, parameter_options={"board_origin_mm": "--board-origin-mm"})


def _observe(args) -> int:
    import numpy as np

    from kinid.errors import DataError
    from kinid.files import check_outputs
    from kinid.vision import load_board
    from ..model import load_machine
    from ..data import observations_text
    from ..data import load_sensor, observe, read_run_log
    from kinid.files import write_text

    machine = load_machine(args.machine)
    board = load_board(args.board)
    sensor = load_sensor(args.sensor)
    log = read_run_log(args.log, machine, check_limits=not args.allow_outside_limits)
    folder = Path(args.log).parent
    check_outputs([("--out", args.out, "file")], [("--data", str(folder / name)) for name in log.images])
    if args.board_origin_mm is not None and not np.all(np.isfinite(args.board_origin_mm)):
        raise DataError("--board-origin-mm must be three finite numbers")
    from kinid.progress import Progress

    pose = None if args.fit is None else _fitted_pose(args.fit, machine, log, sensor)
    with Progress(len(log.images), "images") as progress:
        result = observe(machine, board, sensor, log, board_origin_mm=args.board_origin_mm, marks=args.marks,
                         progress=progress, pose=pose)
    text = observations_text(result.observations, machine, extra={"image": list(result.images), **result.laser_columns})
    write_text(args.out, text)
    n_img = len(log.images)
    print(f"{len(result.observations)} observations from {n_img - len({r.line for r in result.rejected})} of "
          f"{n_img} images; written to {args.out}")
    if result.rejected:
        print(f"{len(result.rejected)} image(s) gave no observation (listed, not guessed):")
        for r in result.rejected:
            print(f"  {Path(args.log).name} line {r.line}: {r.image}: {r.reason}")
    lever = float(np.hypot(*sensor.laser_offset_mm))
    if args.fit is None and lever > 0 and log.laser_mm is not None:
        # a board laid by hand is tilted by some 100-500 µrad, which the nominal machine does not know
        print(f"the laser sits {lever:.1f} mm beside the camera: the board's slope was taken from the nominal "
              f"machine, and a set-up tilt of 200 µrad moves mark_dz_mm by {0.2 * lever:.1f} µm; kinid identify "
              f"judges mark_dz_mm again with the board pose it fits (the lever and slope columns)")
    return 0


def _usable(fit, machine, obs, lever_mm):
    """(design, parameter values, which were left at 0) of the fit at the poses of ``obs``: a turn the images determine
    only to milliradians (the camera's tilt on the tool, EA0T, EB0T, often EC0T) would move the depth by its σ times the
    laser's lever, so a turn whose σ × ``lever_mm`` exceeds the fit's noise is left at 0, as in the nominal pass.

    A machine term ``compensate`` writes as 0 because it is not significant (within its expanded uncertainty, or a
    curve within its own; :func:`~kinid.identification.compensation.compensate.compensation_model`) is left at 0 too:
    a tilt the fit cannot tell from 0 (the Z axis's EB0Z, 5 ± 5 µrad) turns the board's slope at every pose alike, so
    its noise times the lever moved every depth by the same 0.2 µm, which the next fit took for a length that
    compensate kept while it wrote the tilt as 0 (tests/test_sensor_models.py)."""
    import numpy as np

    from ..compensation import compensation_model
    from ..fitting import design

    vague = np.array([u == "µrad" and not (np.isfinite(s) and s * lever_mm * 1e-3 <= fit.noise.value_um)
                      for u, s in zip(fit.units, fit.std)], dtype=bool)
    small = {name for name, why in compensation_model(fit).left_out if why.startswith("not significant")}
    zero = np.concatenate([np.full(e.n_params, e.name in small) for e in fit.effects]) if fit.effects else vague
    # the board's slope from the turns of the chain that carries it: one the fit tells only through its lever on the
    # tool point (a head's tilt) may stand for an effect the model lacks, and turns the slope that far
    tool_side = (np.concatenate([np.full(e.n_params, not _turns_the_board(machine, e.name)) for e in fit.effects])
                 if fit.effects else np.zeros(len(fit.param_names), dtype=bool))
    values = np.where(vague | zero | tool_side, 0.0, fit.theta)  # held parameters at 0 too
    return design(machine, fit.effects, obs), values, vague


def marks_turn(fit) -> tuple[float, float]:
    """(the fitted camera turn on the tool ``EC0T``, µrad, that takes the marks' own offsets, seen in the camera's
    axes, into the machine's; the RMS reach of those offsets, mm, up to which it is used): vague beyond it, where its
    σ times the reach exceeds the fit's noise. (0, 0) without ``EC0T`` or where ``compensate`` writes it as 0 (not
    significant)."""
    import math

    import numpy as np

    from ..compensation import compensation_model

    codes = list(fit.param_names)
    if "EC0T" not in codes:
        return 0.0, 0.0
    k = codes.index("EC0T")
    small = {name for name, why in compensation_model(fit).left_out if why.startswith("not significant")}
    if "EC0T" in small or not np.isfinite(fit.std[k]):
        return 0.0, 0.0
    return float(fit.theta[k]), math.inf if fit.std[k] <= 0 else float(fit.noise.value_um / (fit.std[k] * 1e-3))


def _turns_the_board(machine, effect_name: str) -> bool:
    """Whether the error joint of ``effect_name`` (``EA0C``, ``EYB:poly1``) lies on the chain from the machine's base
    to the workpiece (the board's set-up and the table's axes), or is the camera's turn on the tool (``EC0T``, the
    frame of a drawing's offset)."""
    code = effect_name.split(":")[0]
    if code == "EC0T":
        return True
    if code not in machine.error_codes:
        return False
    model = machine.model
    joint = next(j for j in range(1, model.njoints) if model.idx_qs[j] == machine.error_joint(code).q_index)
    return joint in model.supports[model.frames[machine.workpiece_frame].parentJoint]


#: The columns observe writes with the laser beside the camera, with which identify judges the depths again.
LEVER_COLUMNS = ("laser_lever_x_mm", "laser_lever_y_mm", "board_slope_x", "board_slope_y")
#: With ``--fit`` where the normals are in the machine's axes but the fit's EC0T turns the marks' own offsets into them:
#: that turn, µrad (the lever's mark part is written as seen, in the camera's axes).
MARKS_TURN_COLUMN = "laser_marks_turn_urad"


#: Set-up parameters whose σ moves the laser's depth: the board's tilt, and the camera's turn on the tool.
POSE_SOURCES = ("EA0W", "EB0W", "EC0T")


def _fitted_pose(fit_path, machine, log, sensor):
    """The board's pose at the log's readings as the fit finds it, with its set-up parameters one σ off each; warns
    when a drawing's offset (camera axes) is turned into the machine's by an EC0T too loose for the laser's noise."""
    import math
    import re
    import warnings
    from dataclasses import replace

    import numpy as np

    from kinid.errors import DataError
    from ..data import Observations, board_pose, drawing_turn_um
    from ..fitting import joint_values, load_fit

    fit = load_fit(fit_path)
    if tuple(fit.machine.axis_names) != tuple(machine.axis_names) or fit.machine.error_codes != machine.error_codes:
        raise DataError(f"the fit is of a machine with axes {', '.join(fit.machine.axis_names)} and "
                        f"{len(fit.machine.error_codes)} error joints, not --machine's; give the fit of this machine",
                        path=fit_path)
    n = len(log.images)
    poses = Observations(tuple(log.images), np.zeros((n, 3)), log.axes, log.t_s, log.directions, log.lines, log.source)
    d, values, vague = _usable(fit, machine, poses, float(np.hypot(*sensor.laser_offset_mm)))
    codes = list(fit.param_names)
    k_turn = codes.index("EC0T") if "EC0T" in codes else None
    turn, turn_std = (0.0, math.nan) if k_turn is None else (float(fit.theta[k_turn]), float(fit.std[k_turn]))
    drawing = sensor.laser_offset_frame == "tool"
    shifted = {}
    for k, (name, std) in enumerate(zip(codes, fit.std)):
        if name not in POSE_SOURCES or not (np.isfinite(std) and std > 0) or (vague[k] and not (k == k_turn and drawing)):
            continue
        moved = values.copy()
        moved[k] += 0.0 if vague[k] else std
        shifted["fit_" + re.sub(r"[^a-z0-9]+", "_", name.lower())] = (
            joint_values(machine, d, moved), turn + (std if k == k_turn else 0.0))
    pose = board_pose(machine, log.axes, joint_values(machine, d, values), camera_turn_urad=turn, shifted=shifted,
                      source=str(fit_path))
    # the marks' own offsets are seen in the camera's axes: turned into the normals' by the fitted EC0T the normals
    # leave out (the rule of identify's settle: used while its σ times the marks' reach is within the noise)
    marks_urad, reach_limit_mm = marks_turn(fit)
    if k_turn is not None and marks_urad != values[k_turn]:
        pose = replace(pose, marks_turn_urad=marks_urad - float(values[k_turn]), marks_reach_limit_mm=reach_limit_mm)
    moves = drawing_turn_um(pose, sensor.laser_offset_mm, turn_std) if drawing and math.isfinite(turn_std) else 0.0
    if moves > fit.noise.value_um:
        warnings.warn(f"{fit_path}: laser_offset_mm is a drawing's, in the camera's axes (laser_offset_frame 'tool'); "
                      f"turning it into the machine's needs the camera's turn EC0T, identified as {turn:.0f} ± "
                      f"{turn_std:.0f} µrad, whose σ moves mark_dz_mm by {moves:.2f} µm RMS, more than the fit's noise "
                      f"({fit.noise.value_um:.2f} µm): measure the offset with kinid sensor (the machine's axes)",
                      stacklevel=2)
    return pose
