"""``kinid compensate``: a fit -> axis error tables, constants, a calibrated URDF, controller files."""
from __future__ import annotations

__all__ = ["register"]


def register(sub) -> None:
    from kinid.axis_tables import FORMATS

    p = sub.add_parser(
        "compensate", help="axis error tables, constants, a calibrated URDF and controller files from a fit",
        description="Write the fitted machine's compensation into a folder: <AXIS>.csv per motion axis (every "
                    "error joint of the axis over its travel), constants.json, calibrated.urdf (constants folded "
                    "into the geometry, error joints kept at zero), compensation.json (provenance) and the "
                    "positioning-error tables in controller formats (docs/compensation.md).")
    p.add_argument("--fit", required=True, help="FIT.json written by kinid identify")
    p.add_argument("--out", required=True, metavar="DIR", help="folder to write (created if missing)")
    p.add_argument("--step-mm", type=float, default=1.0, help="grid step of linear axes, mm (default 1)")
    p.add_argument("--step-deg", type=float, default=1.0, help="grid step of rotary axes, degrees (default 1)")
    p.add_argument("--format", dest="formats", nargs="+", choices=sorted(FORMATS), default=sorted(FORMATS),
                   help="controller formats to write (default: all)")
    p.set_defaults(run=_compensate, outputs={"out": "folder"})


def _compensate(args) -> int:
    from pathlib import Path

    from kinid.checks import check_positive
    from .compensate import write_compensation
    from .fit import load_fit

    check_positive("--step-mm", args.step_mm)
    check_positive("--step-deg", args.step_deg)
    result = load_fit(args.fit)
    out = write_compensation(result, args.out, step_mm=args.step_mm, step_deg=args.step_deg,
                             formats=tuple(args.formats), fit_path=args.fit)
    print(f"compensation of {Path(args.fit).name} written to {args.out}: {', '.join(out.files)}")
    for line in out.notes:
        print(f"note: {line}")
    return 0
