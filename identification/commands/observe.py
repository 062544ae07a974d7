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

    with Progress(len(log.images), "images") as progress:
        result = observe(machine, board, sensor, log, board_origin_mm=args.board_origin_mm, marks=args.marks,
                         progress=progress)
    text = observations_text(result.observations, machine, extra={"image": list(result.images)})
    write_text(args.out, text)
    n_img = len(log.images)
    print(f"{len(result.observations)} observations from {n_img - len({r.line for r in result.rejected})} of "
          f"{n_img} images; written to {args.out}")
    if result.rejected:
        print(f"{len(result.rejected)} image(s) gave no observation (listed, not guessed):")
        for r in result.rejected:
            print(f"  {Path(args.log).name} line {r.line}: {r.image}: {r.reason}")
    return 0
