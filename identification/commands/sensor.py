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

from kinid.options import add_alias, add_json_option, json_file

__all__ = ["register"]


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
    p.add_argument("--noise-mm", dest="sigma_mm", type=float, default=None,
                   help="repeatability of one alignment, mm (default: the scatter of repeated readings)")
    p.add_argument("--base", metavar="SENSOR.json", default=None,
                   help="a sensor file whose other keys (camera, pixel size, stand-off) are kept")
    p.add_argument("--out", required=True, metavar="SENSOR.json", help="the sensor file to write")
    add_alias(p, "--sigma-mm", "--noise-mm")
    add_json_option(p, json_file("out"), "the sensor file written")
    p.set_defaults(run=_sensor, outputs={"out": "file"})


def _sensor(args) -> int:
    import math
    from pathlib import Path

    from kinid.checks import check_plausible, check_positive
    from kinid.errors import DataError
    from kinid.files import read_json, write_json
    from kinid.schema import validate
    from ..model import load_machine
    from ..data import SENSOR_SCHEMA, check_laser_offset, laser_offset, read_axis_table

    for option, value, kind in (("--standoff-mm", args.standoff_mm, "size_mm"), ("--radius-mm", args.radius_mm, "size_mm"),
                                ("--noise-mm", args.sigma_mm, "sigma_mm")):
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
    # a set-up measurement is local (one hole, one ball): z near zero says nothing of metres; laser_offset
    # judges the readings' reach instead
    table = read_axis_table(source, machine, what=f"{method} measurement", required=("role",),
                            texts=("role",), warn_metres=False)
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
        print("note: no repeated readings and no --noise-mm: the offset has no uncertainty; repeat each alignment")
    return 0
