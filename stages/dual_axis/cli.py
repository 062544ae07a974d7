"""``kinid dual-axis``: the two-parallel-Y-axes calibration on a simulated gantry.

Measures ``pixel_to_mm`` by moving the head, runs the patent's calibration
rounds, fits the smooth model, and compares both on held-out camera positions
(the mid-points between table vertices): measured by the camera and, since
the gantry is simulated, against the truth.
"""
from __future__ import annotations


from kinid.errors import DataError
from kinid.options import add_alias
from ..outputs import add_output_options, check_report, staged_report

__all__ = ["register", "run_simulation"]


def __getattr__(name: str):
    """``run_simulation`` from :mod:`.demo`, imported on first use (``kinid dual-axis --help`` needs no NumPy)."""
    if name == "run_simulation":
        from .demo import run_simulation

        return run_simulation
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def register(subparsers) -> None:
    """Add the ``dual-axis`` verb to the ``kinid`` command line."""
    p = subparsers.add_parser(
        "dual-axis",
        help="offset table between two parallel Y axes (camera Y / head Y) of a gantry",
        description="Dual-axis offset table method: from one measured round (--data: camera Y and the plate's "
                    "shift in the image at each step), the new offset table and the smooth model "
                    "(parallelism + straightness polynomial); or the whole method on the simulated gantry "
                    "urdf/gantry_dual_y.urdf, rounds until the spec is met and held-out checks (--simulate).")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--data", metavar="MEAS.csv", help="one measured round: camera_y_mm,shift_x_px,shift_y_px"
                                                          "[,table_dx_mm,table_dy_mm] (docs/dual_axis.md)")
    mode.add_argument("--simulate", action="store_true", help="the whole method on the simulated gantry")
    p.add_argument("--pixel-to-mm", type=float, nargs=4, metavar=("A", "B", "C", "D"),
                   help="with --data: the 2 x 2 matrix from image shift (px) to head X/Y move (mm), row by row")
    p.add_argument("--spec-um", type=float, default=1.0, help="acceptance limit per table entry, µm (default 1)")
    p.add_argument("--degree", type=int, default=3, help="degree of the smooth model's polynomial (default 3)")
    outputs = add_output_options(
        p, out=("TABLE.csv", "write the offset table: camera_y_mm,head_dx_mm,head_dy_mm"),
        plot=("OUT.png", "plot of the plate offset before/after compensation"),
        json="print one JSON object instead of the report",
        report=("DIR", "write an HTML report (with the plot) into DIR: of the measured round, or of the "
                               "simulated method"))
    sim = p.add_argument_group("simulated gantry (--simulate)")
    sim.add_argument("--y-start-mm", type=float, default=0.0, help="camera Y at the start, mm (default 0)")
    sim.add_argument("--step-mm", type=float, default=10.0, help="step of both Y axes, mm (default 10)")
    sim.add_argument("--steps", type=int, default=30, help="number of steps (default 30)")
    sim.add_argument("--max-rounds", type=int, default=5, help="rounds before giving up (default 5)")
    sim.add_argument("--seed", type=int, default=0, help="seed of the simulation (texture, noise)")
    sim.add_argument("--random-errors", action="store_true",
                     help="draw a random error set from the seed instead of the built-in one")
    sim.add_argument("--noise-grey", dest="noise", type=float, default=1.5, help="image noise, grey levels (default 1.5)")
    sim.add_argument("--repeatability-um", dest="repeat_um", type=float, default=0.0, help="axis positioning repeatability, µm (default 0)")
    add_alias(p, "--noise", "--noise-grey")
    add_alias(p, "--repeat-um", "--repeatability-um")
    p.set_defaults(run=_run, parameter_options={"n_steps": "--steps", "y_start_mm": "--y-start-mm",
                                                "noise_sigma": "--noise-grey", "repeat_um": "--repeatability-um"},
                   outputs=outputs)


def _measured(args) -> int:
    import numpy as np

    from kinid.files import write_text
    from .measured import read_round, table_from_round
    from .report import plot_measured, write_measured_report
    from .smooth import fit_smooth

    if args.pixel_to_mm is None:
        raise DataError("--data needs --pixel-to-mm A B C D (image shift px -> head move mm; measure it as "
                        "docs/dual_axis.md shows)")
    if not (np.isfinite(args.spec_um) and args.spec_um > 0):
        raise DataError(f"--spec-um must be a positive number, got {args.spec_um!r}")
    check_report(args)
    y, shift, used = read_round(args.data)
    table = table_from_round(y, shift, used, np.reshape(args.pixel_to_mm, (2, 2)), args.spec_um)
    smooth = fit_smooth(table, args.degree)
    if args.out:
        write_text(args.out, table.csv_text())
    if args.plot:
        plot_measured(args.plot, table, smooth)
    if args.report:
        with staged_report(args) as staged:
            write_measured_report(staged, table, smooth)
    report = {"source": str(args.data), "table": table.to_dict(), "message": table.message,
              "smooth": {"degree": smooth.degree, "parallelism_urad": smooth.parallelism_urad,
                         "scale_um_per_m": smooth.scale_um_per_m, "fit_rms_um": smooth.rms_um.tolist()}}
    if args.json:
        from kinid.files import strict_json

        print(strict_json(report))
        return 0
    print(f"dual-axis offset table from {args.data}: {len(y)} vertices, camera Y {y[0]:g} .. {y[-1]:g} mm")
    print(f"{'camera Y (mm)':>14}{'head dx (µm)':>14}{'head dy (µm)':>14}")
    for yy, (dx, dy) in zip(table.y_mm, table.offset_mm * 1e3):
        print(f"{yy:14.3f}{dx:14.3f}{dy:14.3f}")
    print(table.message)
    print(f"smooth model (degree {smooth.degree}): parallelism {smooth.parallelism_urad:.2f} µrad, "
          f"scale {smooth.scale_um_per_m:.2f} µm/m, fit RMS x {smooth.rms_um[0]:.3f} µm, y {smooth.rms_um[1]:.3f} µm")
    for flag, value in (("offset table", args.out), ("plot", args.plot), ("report", args.report)):
        if value:
            print(f"{flag} written to {value}")
    return 0


def _run(args) -> int:
    from pathlib import Path

    if args.plot and not Path(args.plot).resolve().parent.is_dir():
        raise DataError(f"output folder {str(Path(args.plot).parent)!r} does not exist", path=args.plot)
    if args.data:
        return _measured(args)
    check_report(args)
    from .demo import run_simulation
    from .report import plot_simulation, simulation_text, write_simulated_report

    result = run_simulation(y_start_mm=args.y_start_mm, step_mm=args.step_mm, n_steps=args.steps,
                            spec_um=args.spec_um, max_rounds=args.max_rounds, degree=args.degree,
                            seed=args.seed, random_errors=args.random_errors, noise_sigma=args.noise,
                            repeat_um=args.repeat_um)
    if args.plot:
        plot_simulation(args.plot, result)
    if args.report:
        with staged_report(args) as staged:
            write_simulated_report(staged, result)
    if args.out:
        from kinid.files import write_text

        write_text(args.out, result["table"].csv_text())
    rep = result["report"]
    if args.json:
        from kinid.files import strict_json

        print(strict_json(rep))
    else:
        print(simulation_text(rep))
        if args.plot:
            print(f"plot written to {args.plot}")
        if args.out:
            print(f"offset table written to {args.out}")
        if args.report:
            print(f"report written to {args.report}")
    return 0
