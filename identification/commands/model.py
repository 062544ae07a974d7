"""``kinid model``: an existing URDF (a ROS robot, a machine drawn elsewhere) -> a machine kinid identifies."""
from __future__ import annotations

from kinid.options import add_json_option

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser(
        "model", help="an existing URDF (a ROS robot, a machine drawn elsewhere) -> a machine kinid can identify",
        description="Write the identification machine of an existing URDF: the chain from --base to --tool (and to "
                    "--workpiece for a machine tool), every joint origin kept, location-error joints before every "
                    "motion joint, the set-up of the measured point on the tool and of the measurement frame on the "
                    "base; motion joints keep their names (short names J1, J2 … where they are not letters and "
                    "digits). With every error joint at zero it has the source's kinematics (docs/machines.md).")
    p.add_argument("--urdf", required=True, help="the source URDF")
    p.add_argument("--tool", required=True, metavar="LINK", help="the link the measured point is fixed to (a flange)")
    p.add_argument("--base", default=None, metavar="LINK", help="the link both chains start from (default: the root)")
    p.add_argument("--workpiece", default=None, metavar="LINK",
                   help="the link the measurement frame is fixed to (a machine's table; default: --base)")
    p.add_argument("--tool-offset-mm", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "Z"),
                   help="the measured point (a marker) in the tool link's frame, mm")
    p.add_argument("--position-errors", action="store_true",
                   help="also the six position-dependent error joints after every motion joint (straightness, "
                        "positioning, angular errors of a machine tool's axes)")
    p.add_argument("--out", required=True, metavar="URDF", help="the identification machine to write")
    add_json_option(p, _summary, "the machine written: its axes (name, joint, kind, chain, column) and error "
                               "parameters")
    p.set_defaults(run=_model, outputs={"out": "file"})


def _model(args) -> int:
    import math
    from pathlib import Path

    from kinid.errors import DataError, KinidError, MachineError
    from kinid.files import read_limited_text, shown_path, write_text

    from ..model import machine_from_urdf
    from ..model import MAX_URDF_BYTES, identification_urdf

    if not all(math.isfinite(v) and abs(v) <= 10_000.0 for v in args.tool_offset_mm):
        raise DataError(f"must be three finite numbers of at most 10 m, got {list(args.tool_offset_mm)}",
                        parameter="tool_offset_mm")
    text = read_limited_text(args.urdf, what="URDF", max_bytes=MAX_URDF_BYTES, error=MachineError)
    out = identification_urdf(text, tool=args.tool, base=args.base, workpiece=args.workpiece,
                              tool_offset_m=tuple(v / 1e3 for v in args.tool_offset_mm),
                              position_errors=args.position_errors, path=shown_path(args.urdf))
    try:
        machine = machine_from_urdf(out, args.out)  # kinid's own loader accepts it, or nothing is written
    except KinidError as exc:  # the source's fault or kinid model's: either way the message names the source
        raise MachineError(f"the identification machine made from it does not load ({exc.message})",
                           path=shown_path(args.urdf)) from None
    write_text(args.out, out)
    axes = ", ".join(a.name if a.joint == a.name else f"{a.name} ({shown_path(a.joint)})" for a in machine.axes)
    print(f"{len(machine.axes)} motion axes: {axes}; {len(machine.error_joints)} error joints "
          f"(location errors before every axis{', position-dependent after it' if args.position_errors else ''}, "
          f"set-up W and T); written to {shown_path(Path(args.out).name)}")
    if any(a.joint != a.name for a in machine.axes):
        print("the short names (kept in the machine's <kinid> element) name the axes in observations, fits and "
              "tables; the URDF's joints keep their names")
    print(f"next: kinid simulate or kinid identify --machine {shown_path(args.out)} --data <observations.csv> "
          f"(columns {', '.join(a.column for a in machine.axes)})")
    return 0


def _summary(args) -> dict:
    """``--json``: the machine written, as kinid reads it back."""
    from ..model import load_machine

    machine = load_machine(args.out)
    return {"machine": str(args.out),
            "axes": [{"name": a.name, "joint": a.joint, "kind": a.kind, "chain": a.chain, "column": a.column}
                     for a in machine.axes],
            "error_parameters": list(machine.error_codes)}
