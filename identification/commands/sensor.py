"""``kinid sensor``: where the laser sits beside the camera, from the method's set-up measurements.

The five-axis method mounts the camera and the laser displacement sensor side by side on Z and
starts by measuring the laser's offset from the camera's axis (docs/observe.md, "The laser beside
the camera"):

- **hole**: the camera centred on a small hole, then the laser spot dropped into it;
- **sphere**: the laser held at its stand-off on a ball at several points, and the camera centred
  on the ball's image.

Each measurement is a CSV with a ``role`` column (``camera`` or ``laser``) and the axis columns of
the machine (as in a run log). The readings become tool-point positions on the nominal machine, so
the sign and the axes' directions come from the URDF; the offset is written, in the tool frame,
into the sensor file ``kinid observe`` reads, with its standard deviations. The locators are
:func:`kinid.vision.radial_offset_from_hole` and :func:`kinid.vision.radial_offset_from_sphere`.
"""
from __future__ import annotations

__all__ = ["register", "laser_offset"]


def register(sub) -> None:
    p = sub.add_parser(
        "sensor", help="the laser's offset beside the camera from the hole or sphere set-up measurement",
        description="Measure where the laser displacement sensor sits beside the camera: from a hole (the camera "
                    "centred on it, then the laser spot dropped into it) or a ball (the laser held at its stand-off "
                    "at points around it, the camera centred on its image). Writes the sensor file kinid observe "
                    "reads, with laser_offset_mm and its standard deviations in the tool frame (docs/observe.md). "
                    "Take the readings with the rotary axes where the tool axis is the workpiece's z axis.")
    p.add_argument("--machine", required=True, help="machine URDF (docs/machines.md)")
    kind = p.add_mutually_exclusive_group(required=True)
    kind.add_argument("--hole", metavar="CSV", help="role,<axis columns>: camera rows centred on the hole, laser rows "
                                                    "with the spot in it")
    kind.add_argument("--sphere", metavar="CSV", help="role,<axis columns>: laser rows at the stand-off on the ball, "
                                                      "camera rows centred on its image")
    p.add_argument("--standoff-mm", type=float, default=None,
                   help="with --sphere: the laser reading held on the ball, mm (default: the --base file's "
                        "laser_standoff_mm)")
    p.add_argument("--radius-mm", type=float, default=None, help="with --sphere: the ball's radius if known, mm")
    p.add_argument("--sigma-mm", type=float, default=None,
                   help="repeatability of one alignment, mm (default: the scatter of repeated readings)")
    p.add_argument("--base", metavar="SENSOR.json", default=None,
                   help="a sensor file whose other keys (camera, pixel size, stand-off) are kept")
    p.add_argument("--out", required=True, metavar="SENSOR.json", help="the sensor file to write")
    p.set_defaults(run=_sensor, outputs={"out": "file"})


def laser_offset(machine, table, *, method: str, standoff_mm=None, radius_mm=None, sigma_mm=None):
    """(offset (x, y), std (x, y), the locator's result) of the laser in the tool frame, mm.

    ``table`` is an :class:`~kinid.identification.data.axis_columns.AxisTable` with a ``role`` column.
    """
    import numpy as np

    from kinid.errors import DataError
    from kinid.vision import radial_offset_from_hole, radial_offset_from_sphere
    from ..model import evaluate, tool_rotation_in_workpiece

    roles = [r.lower() for r in table.texts("role", "role")]
    bad = sorted(set(roles) - {"camera", "laser"})
    if bad:
        raise DataError(f"role must be camera or laser, found {bad[0]!r}", path=table.path, column="role")
    zero = np.zeros(len(machine.error_joints))
    points = evaluate(machine, table.axes, zero, jacobian=False)  # tool point in the workpiece frame, mm
    R = tool_rotation_in_workpiece(machine, table.axes, zero)
    tilt = np.abs(R[:, 2, 2])
    if np.any(tilt < 0.999):
        i = int(np.argmin(tilt))
        raise DataError("the tool axis is not the workpiece's z axis at this reading; take the set-up readings with "
                        "the rotary axes at zero", path=table.path, line=table.lines[i])
    cam, las = np.array(roles) == "camera", np.array(roles) == "laser"
    if not cam.any() or not las.any():
        raise DataError("needs camera rows and laser rows", path=table.path, column="role")
    if method == "hole":
        result = radial_offset_from_hole(points[las, :2], points[cam, :2], sigma_mm=sigma_mm)
    else:
        if standoff_mm is None:
            raise DataError("the sphere method needs the laser's stand-off: --standoff-mm or a --base sensor file with "
                            "laser_standoff_mm")
        # the tool point with the laser at its stand-off: the surface lies standoff below the laser along −z,
        # i.e. at the spot's tool-frame depth; radial_offset_from_sphere takes the reading's position
        result = radial_offset_from_sphere(points[las] + np.array([0.0, 0.0, standoff_mm]), standoff_mm,
                                           points[cam, :2], radius_mm=radius_mm, sigma_mm=sigma_mm)
    d = np.array([result.dx_mm, result.dy_mm])
    Rm = R[las].mean(axis=0)[:2, :2]
    offset = Rm.T @ (-d)  # the tool moved by d to bring the laser onto the feature: the spot sits at −d
    cov = Rm.T @ np.asarray(result.covariance_mm2, float)[:2, :2] @ Rm
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return offset, std, result


def _sensor(args) -> int:
    import math
    from pathlib import Path

    from kinid.checks import check_plausible, check_positive
    from kinid.errors import DataError
    from kinid.files import read_json, write_json
    from kinid.schema import validate
    from ..data import read_axis_table
    from ..model import load_machine
    from ..data import SENSOR_SCHEMA, check_laser_offset

    for option, value, kind in (("--standoff-mm", args.standoff_mm, "size_mm"), ("--radius-mm", args.radius_mm, "size_mm"),
                                ("--sigma-mm", args.sigma_mm, "sigma_mm")):
        if value is not None:
            check_positive(option, value)
            check_plausible(option, value, kind)
    machine = load_machine(args.machine)
    base = {}
    if args.base:
        base = read_json(args.base, what="sensor file")
        if not isinstance(base, dict):
            raise DataError("a sensor file is a JSON object", path=args.base)
        validate(base, SENSOR_SCHEMA, path=args.base)
    source = args.hole or args.sphere
    method = "hole" if args.hole else "sphere"
    table = read_axis_table(source, machine, what=f"{method} measurement", required=("role",),
                            texts=("role",))
    standoff = args.standoff_mm if args.standoff_mm is not None else base.get("laser_standoff_mm")
    offset, std, result = laser_offset(machine, table, method=method, standoff_mm=standoff,
                                       radius_mm=args.radius_mm, sigma_mm=args.sigma_mm)
    check_laser_offset(offset, path=source, what="the readings put the laser")  # the rule observe reads it by
    out = dict(base)
    out["laser_offset_mm"] = [round(float(v), 6) for v in offset]
    out["laser_offset_std_mm"] = [round(float(v), 6) if math.isfinite(v) else None for v in std]
    if any(v is None for v in out["laser_offset_std_mm"]):
        del out["laser_offset_std_mm"]
    out["measured_by"] = f"kinid sensor --{method} {Path(source).name}"
    # a non-finite offset is a failed measurement, not a value: a DataError naming the file, never null
    write_json(args.out, out, indent=2)
    u = "" if "laser_offset_std_mm" not in out else \
        f" ± ({2 * std[0]:.4f}, {2 * std[1]:.4f}) mm (k = 2)"
    print(f"laser beside the camera ({method}, {result.n_points} readings): ({offset[0]:.4f}, {offset[1]:.4f}) mm in "
          f"the tool frame{u}; written to {args.out}")
    if "laser_offset_std_mm" not in out:
        print("note: no repeated readings and no --sigma-mm: the offset has no uncertainty; repeat each alignment")
    return 0
