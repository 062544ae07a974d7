"""``kinid compensate``: a fit -> axis error tables, constants, set-up, a calibrated URDF, controller files."""
from __future__ import annotations

from kinid.options import add_alias, add_json_option, json_file

__all__ = ["register"]


def register(sub) -> None:
    from kinid.axis_tables import CONTROLLER_FORMATS, default_formats
    from kinid.kinematics_formats import KINEMATICS_FORMATS

    p = sub.add_parser(
        "compensate", help="axis error tables, constants, a calibrated URDF and controller files from a fit",
        description="Write the fitted machine's compensation into a folder: <AXIS>.csv per motion axis (every "
                    "compensated error joint of the axis over its measured range), constants.json, setup.json "
                    "(the board's and the sensor's set-up, for the work and tool offsets), calibrated.urdf "
                    "(machine constants folded into the geometry, error joints kept at zero), compensation.json "
                    "(provenance, what was left out and why, how closely each controller file follows the model), "
                    "the positioning-error tables in controller formats and, on a machine with rotary axes, where "
                    "they turn in the controllers' kinematics (KINID_CYCLE800.MPF, trt-kins.hal; "
                    "docs/compensation.md). Only "
                    "significant machine errors are compensated: a term whose every parameter is within its "
                    "expanded uncertainty (k = 2) is left out, as are the set-up and drifts.")
    p.add_argument("--fit", required=True, help="FIT.json written by kinid identify")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder to write, whole or not at all (created if missing; an existing one is replaced only "
                        "if it is empty or holds an earlier compensation)")
    p.add_argument("--format", dest="formats", nargs="+", choices=sorted(CONTROLLER_FORMATS),
                   default=None,
                   help=f"controller formats to write (default: {' '.join(default_formats())})")
    p.add_argument("--kinematics-format", dest="kinematics_formats", nargs="+", choices=sorted(KINEMATICS_FORMATS),
                   default=None, help="kinematics formats for the rotary axes' geometry (pivot points and directions): "
                                      "sinumerik (CYCLE800 swivel data), linuxcnc (trunnion kinematics); default: "
                                      "every one that has a layout for the machine")
    p.add_argument("--table-range", dest="range_policy", choices=("data", "travel"), default="data",
                   help="tables over the measured readings of each axis (default) or over the URDF travel (refused "
                        "where it is unbounded, or more than a turn the readings do not go round)")
    p.add_argument("--beyond", choices=("hold", "zero"), default="hold",
                   help="beyond a table's ends: hold the end values (default) or return to zero")
    p.add_argument("--all-terms", action="store_true",
                   help="compensate every identified term, also those within their expanded uncertainty")
    p.add_argument("--axis-number", dest="axis_numbers", nargs="+", metavar="AXIS=N", default=(),
                   help="the controller's axis numbers (TwinCAT kopf.achs_nr, SINUMERIK AX<n>), e.g. X=1 Y=2 C=5; "
                        "default: the axis's place in the URDF's chain, printed and written to compensation.json")
    p.add_argument("--step-mm", type=float, default=None,
                   help="fixed grid step of linear axes, mm (default: chosen so the controller's interpolation "
                        "follows the model within 10%% of the error's RMS)")
    p.add_argument("--step-deg", type=float, default=None, help="fixed grid step of rotary axes, degrees "
                                                                "(default: chosen like --step-mm)")
    # the folder is written whole (kinid.folders.staged_folder): no input may lie anywhere in it
    add_alias(p, "--range", "--table-range")
    add_json_option(p, json_file("out", "compensation.json"), "compensation.json")
    p.set_defaults(run=_compensate, outputs={"out": "replaced folder"})


#: The axis numbers a controller's tables may name (a CNC has at most a few dozen axes).
MAX_AXIS_NUMBER = 64


def _axis_numbers(items) -> dict:
    from kinid.errors import DataError

    out = {}
    for item in items:
        axis, sep, number = item.partition("=")
        number = number.strip()
        if (not sep or not axis or not (number.isascii() and number.isdigit()) or len(number) > 3
                or not 1 <= int(number) <= MAX_AXIS_NUMBER):
            raise DataError(f"--axis-number takes AXIS=N with N a whole number from 1 to {MAX_AXIS_NUMBER}, got "
                            f"{item!r}")
        if axis in out:
            raise DataError(f"--axis-number gives axis {axis!r} twice")
        other = next((a for a, n in out.items() if n == int(number)), None)
        if other is not None:
            raise DataError(f"--axis-number gives axes {other!r} and {axis!r} the same number {int(number)}; each axis "
                            f"its own number")
        out[axis] = int(number)
    return out


def _compensate(args) -> int:
    from pathlib import Path

    from kinid.checks import check_plausible, check_positive
    from kinid.progress import step
    from ..compensation import write_compensation
    from ..fitting import load_trusted_fit

    for option, value, kind in (("--step-mm", args.step_mm, "step_mm"), ("--step-deg", args.step_deg, "step_deg")):
        if value is not None:
            check_positive(option, value)
            check_plausible(option, value, kind)
    numbers = _axis_numbers(args.axis_numbers)
    result = load_trusted_fit(args.fit)  # a fit that did not converge never reaches a controller
    with step(f"writing the tables and checking each as its controller applies it ({args.out})"):
        out = write_compensation(result, args.out, step_mm=args.step_mm, step_deg=args.step_deg,
                                 formats=None if args.formats is None else tuple(args.formats), fit_path=args.fit,
                                 range_policy=args.range_policy, beyond=args.beyond, all_terms=args.all_terms,
                                 axis_numbers=numbers, kinematics_formats=args.kinematics_formats)
    print(f"compensation of {Path(args.fit).name} written to {args.out}: {', '.join(out.files)}")
    if out.controller:
        print(out.axis_numbers.line())
    for c in out.controller:
        ends = f" (+{c['ends_added']} beyond)" if c["ends_added"] else ""
        print(f"  {c['file']}: {c['points'] - c['ends_added']} points from {c['from']:.6g} to {c['to']:.6g}{ends}; "
              f"the controller's interpolation leaves {c['left_rms']:.3g} of the {c['error_rms']:.3g} {c['unit']} "
              f"RMS error")
    print(f"  checked: each of the {out.checked} tables, applied as its controller applies it, leaves no more error "
          f"than none anywhere in the measured range")
    if out.geometry is not None:
        from ..compensation import geometry_lines

        print("\n".join(geometry_lines(out.geometry)))
    for line in out.notes:
        print(f"note: {line}")
    return 0
