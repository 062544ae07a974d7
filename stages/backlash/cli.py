"""``kinid backlash``: pixel equivalent and backlash from a recorded run, or on a simulated stage (``--simulate``)."""
from __future__ import annotations

from pathlib import Path

from kinid.errors import DataError
from kinid.options import add_alias
from ..outputs import add_output_options, check_report, staged_report, staged_tables

__all__ = ["register", "plot_result"]


def __getattr__(name: str):
    """``plot_result`` from :mod:`.report`, imported on first use (``kinid backlash --help`` needs no NumPy)."""
    if name == "plot_result":
        from .report import plot_result

        return plot_result
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def register(subparsers) -> None:
    """Add the ``backlash`` verb to the ``kinid`` command line."""
    p = subparsers.add_parser(
        "backlash",
        help="measure pixel equivalent and X/Y/θ lead-screw backlash from images",
        description="Image-based backlash calibration of an X-Y-θ stage: write the move plan (--plan-out), run it "
                    "on the stage saving an image after each photo move, and evaluate the run's log (--data); or "
                    "learn the method on a simulated stage (--simulate), measured against the simulated truth.")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--data", dest="log", metavar="LOG.csv", help="the run's log: the plan's rows with image file names (docs/backlash.md)")
    mode.add_argument("--plan-out", metavar="PLAN.csv", help="write the plan to run on the stage (commands and photos)")
    mode.add_argument("--simulate", action="store_true", help="run the method on a simulated stage")
    p.add_argument("--start", type=float, nargs=3, default=(0.0, 0.0, 0.0), metavar=("X", "Y", "THETA"),
                   help="with --plan-out: the stage position the plan is centred on, mm mm deg (default 0 0 0)")
    p.add_argument("--travel-mm", type=float, default=0.8, help="X/Y travel about the start, mm (default 0.8)")
    p.add_argument("--travel-deg", type=float, default=2.0, help="θ travel about the start, degrees (default 2)")
    p.add_argument("--repeats", type=int, default=1, help="reversal cycles per axis and target (default 1)")
    p.add_argument("--targets", type=int, default=1, help="target positions per linear axis (default 1)")
    outputs = add_output_options(
        p, out=("RESULT.json", "write the measured values (µm, deg, with spreads) as JSON"),
        tables=("DIR", "write X and Y backlash as controller tables (every format of kinid.axis_tables)"),
        plot=("OUT.png", "write a plot: reversal gaps before and after compensation"),
        json="print one JSON object instead of the table",
        report=("DIR", "write an HTML report (with the plot) into DIR"))
    sim = p.add_argument_group("simulated stage (--simulate)")
    sim.add_argument("--backlash-x-um", type=float, default=4.0, help="true X backlash, µm (default 4)")
    sim.add_argument("--backlash-y-um", type=float, default=3.0, help="true Y backlash, µm (default 3)")
    sim.add_argument("--backlash-theta-deg", type=float, default=0.01, help="true θ backlash, degrees (default 0.01)")
    sim.add_argument("--pixel-um", type=float, default=5.0, help="pixel size on the stage, µm (default 5)")
    sim.add_argument("--camera-angle-deg", type=float, default=7.0,
                     help="rotation of the camera about the stage axes, degrees (default 7)")
    sim.add_argument("--theta-centre-mm", type=float, nargs=2, default=(-12.0, 8.0), metavar=("DX", "DY"),
                     help="θ rotation centre relative to the fiducial, mm (default -12 8)")
    sim.add_argument("--noise-grey", dest="noise", type=float, default=2.0, help="image noise, grey levels (default 2)")
    sim.add_argument("--repeatability-um", type=float, default=0.0,
                     help="random X/Y positioning scatter per move, µm (default 0)")
    sim.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    add_alias(p, "--log", "--data")
    add_alias(p, "--noise", "--noise-grey")
    p.set_defaults(run=_run, parameter_options={"n_targets": "--targets"},
                   outputs={**outputs, "plan_out": "file"})


def _truth(stage) -> dict:
    import numpy as np

    return {
        "pixel_um_x": stage.true_pixel_mm_along((1.0, 0.0)) * 1e3,
        "pixel_um_y": stage.true_pixel_mm_along((0.0, 1.0)) * 1e3,
        "backlash_x_um": stage.backlash_x_mm * 1e3,
        "backlash_y_um": stage.backlash_y_mm * 1e3,
        "backlash_theta_deg": stage.backlash_theta_deg,
        "camera_rotation_deg": stage.camera_angle_deg,
        "theta_radius_mm": float(np.hypot(*stage.theta_centre_mm)),
    }


def _simulated_stage(args):
    import numpy as np

    from .simulate import SimulatedStage

    if not args.pixel_um > 0:
        raise DataError(f"--pixel-um must be > 0, got {args.pixel_um!r}", column="--pixel-um")
    for name in ("backlash_x_um", "backlash_y_um", "backlash_theta_deg", "noise", "repeatability_um"):
        v = getattr(args, name)
        if not (np.isfinite(v) and v >= 0):
            flag = "--" + name.replace("_", "-")
            raise DataError(f"{flag} must be >= 0, got {v!r}", column=flag)
    for flag, vals in (("--camera-angle-deg", [args.camera_angle_deg]), ("--theta-centre-mm", args.theta_centre_mm)):
        if not np.all(np.isfinite(vals)):
            raise DataError(f"{flag} must be finite, got {' '.join(map(str, vals))}", column=flag)
    return SimulatedStage(
        pixel_mm=args.pixel_um * 1e-3, camera_angle_deg=args.camera_angle_deg,
        backlash_x_mm=args.backlash_x_um * 1e-3, backlash_y_mm=args.backlash_y_um * 1e-3,
        backlash_theta_deg=args.backlash_theta_deg, theta_centre_mm=tuple(args.theta_centre_mm),
        noise_sigma=args.noise, repeatability_mm=args.repeatability_um * 1e-3,
        rng=np.random.default_rng(args.seed))


def _run(args) -> int:
    import numpy as np

    from kinid.files import strict_json, write_json, write_text
    from .calibrate import calibrate
    from .recorded import RecordedStage, plan_rows, plan_text
    from .report import plot_result, write_report

    if args.plan_out:
        if not np.all(np.isfinite(args.start)):
            raise DataError("--start must be three finite numbers (x mm, y mm, theta deg)")
        rows = plan_rows(args.travel_mm, args.travel_deg, repeats=args.repeats, n_targets=args.targets,
                         start=tuple(args.start))
        write_text(args.plan_out, plan_text(rows))
        print(f"{len(rows)} moves, {sum(r[4] for r in rows)} photos; plan written to {args.plan_out}")
        return 0
    stage = _simulated_stage(args) if args.simulate else RecordedStage(args.log)
    check_report(args)
    res = calibrate(stage, travel_mm=args.travel_mm, travel_deg=args.travel_deg, repeats=args.repeats,
                    n_targets=args.targets)
    if not args.simulate:
        stage.check_complete()
    measured = res.summary()
    truth = _truth(stage) if args.simulate else None
    source = "a simulated stage" if args.simulate else str(args.log)
    if args.out:
        write_json(args.out, _result_json(res, source, truth))
    if args.tables:
        with staged_tables(args, "kinid backlash") as folder:
            _write_tables(res, folder, args.travel_mm)
    after = None
    if (args.plot or args.report) and args.simulate:  # measure again through the compensation: the gaps left
        from .compensated import CompensatedStage

        after = calibrate(CompensatedStage(stage, (res.backlash_x_mm, res.backlash_y_mm, res.backlash_theta_deg)),
                          travel_mm=args.travel_mm, travel_deg=args.travel_deg, repeats=args.repeats,
                          n_targets=args.targets)
    if args.plot:
        plot_result(res, args.plot, truth=truth, after=after)
    if args.report:
        with staged_report(args) as staged:
            write_report(res, staged, truth, after, source)
    if args.json:
        out = {"measured": measured, "source": source}
        if truth is not None:
            out.update(truth=truth, errors={k: measured[k] - truth[k] for k in truth if k in measured})
        print(strict_json(out, sort_keys=True))
        return 0
    if args.simulate:
        print(f"backlash calibration on a simulated stage: pixel {args.pixel_um:g} µm, camera rotated "
              f"{args.camera_angle_deg:g}°, fiducial {truth['theta_radius_mm']:.1f} mm from the θ centre, "
              f"noise {args.noise:g} grey levels, seed {args.seed}")
    else:
        print(f"backlash calibration from {args.log}")
    print(f"{res.moves} moves ({sum(r.role != 'preload' for r in res.log)} photos)")
    rows = [
        ("pixel along X", "pixel_um_x", "µm/px", "{:.5f}", True, None),
        ("pixel along Y", "pixel_um_y", "µm/px", "{:.5f}", True, None),
        ("backlash X", "backlash_x_um", "µm", "{:.3f}", False, ("spread_x_um", res.reversals_x_mm.size)),
        ("backlash Y", "backlash_y_um", "µm", "{:.3f}", False, ("spread_y_um", res.reversals_y_mm.size)),
        ("backlash θ", "backlash_theta_deg", "deg", "{:.5f}", False, ("spread_theta_deg", res.reversals_theta_deg.size)),
        ("camera rotation", "camera_rotation_deg", "deg", "{:.3f}", False, None),
        ("θ radius", "theta_radius_mm", "mm", "{:.3f}", False, None),
    ]
    if truth is not None:
        print(f"{'quantity':<22}{'measured':>12}{'simulated':>12}{'error':>14}")
        for label, key, unit, fmt, relative, _ in rows:
            m, t = measured[key], truth[key]
            err = f"{(m / t - 1) * 100:+.4f} %" if relative else ("{:+" + fmt[2:]).format(m - t) + f" {unit}"
            print(f"{label + ' (' + unit + ')':<22}{fmt.format(m):>12}{fmt.format(t):>12}{err:>14}")
    else:
        print(f"{'quantity':<22}{'measured':>12}  spread of the single reversals")
        for label, key, unit, fmt, _, spread in rows:
            extra = ("" if not spread else f"  ± {fmt.format(measured[spread[0]])} {unit} ({spread[1]} reversals)"
                     if spread[1] > 1 else "  (one reversal: no spread; --repeats 3 gives one)")
            print(f"{label + ' (' + unit + ')':<22}{fmt.format(measured[key]):>12}{extra}")
    print(f"ISO 230-2 reversal value B: X {measured['iso_reversal_x_um']:.3f} µm, "
          f"Y {measured['iso_reversal_y_um']:.3f} µm; mean reversal X {measured['iso_mean_reversal_x_um']:+.3f} µm, "
          f"Y {measured['iso_mean_reversal_y_um']:+.3f} µm")
    print(f"patent formula r·|p1-p2|: X {res.backlash_x_patent_mm * 1e3:.3f} µm, "
          f"Y {res.backlash_y_patent_mm * 1e3:.3f} µm, θ {res.backlash_theta_patent_deg:.5f}°")
    for flag, value in (("result", args.out), ("tables", args.tables), ("plot", args.plot),
                        ("report", args.report and str(Path(args.report) / "index.html"))):
        if value:
            print(f"{flag} written to {value}")
    return 0


def _result_json(res, source, truth) -> dict:
    """The measured values for a file: units in the keys, the spreads and counts of the single reversals."""
    out = {"source": source, "measured": res.summary(),
           "reversals": {"x_um": (res.reversals_x_mm * 1e3).tolist(), "y_um": (res.reversals_y_mm * 1e3).tolist(),
                         "theta_deg": res.reversals_theta_deg.tolist()},
           "sign": "backlash = position approached from + minus position approached from −, along the axis"}
    if truth is not None:
        out["truth"] = truth
    return out


def _write_tables(res, folder, travel_mm) -> None:
    """X and Y backlash as bidirectional axis tables: forward −B/2, reverse +B/2 (error = actual − commanded)
    over the measured range, in every controller format of kinid.axis_tables."""
    import numpy as np

    from kinid.axis_tables import AxisErrorTable, neutral_csv_text, write_tables
    from kinid.files import write_text

    tables = []
    for k, (axis, b_mm) in enumerate((("X", res.backlash_x_mm), ("Y", res.backlash_y_mm))):
        centre = res.start[k]
        q = np.array([centre - travel_mm, centre + travel_mm])
        half_um = 0.5 * b_mm * 1e3
        table = AxisErrorTable(axis, False, q, np.full(2, -half_um), np.full(2, half_um))
        write_text(Path(folder) / f"{axis}.csv", neutral_csv_text(f"{axis.lower()}_mm", q, {
            f"E{axis}{axis}_um": table.forward, f"E{axis}{axis}_rev_um": table.reverse}))
        tables.append(table)
    write_tables(folder, tables, comment="kinid backlash: error = actual - commanded")


