"""``kinid uvw``: the UVW actuator error models from measured moves, or the whole story on a simulated stage."""
from __future__ import annotations

import math

from kinid.options import add_alias

from ..outputs import add_output_options, check_report, refuse_unused, staged_report, staged_tables

__all__ = ["register"]


def register(subparsers) -> None:
    """Add the ``uvw`` verb."""
    p = subparsers.add_parser(
        "uvw", help="UVW alignment stage: actuator error models and compensation from measured moves",
        description="Fit each actuator's error model (offset, scale, backlash, bow, lead harmonics; chosen by "
                    "BIC) to the moves measured on a UVW stage (--data), and write the model and the "
                    "actuators' compensation tables; or calibrate a simulated UVW stage with the patent's method "
                    "and with the fitted model and compare them on random alignment moves (--simulate).")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--data", dest="moves", metavar="MOVES.csv", help="measured moves: actuator,command_um,direction,measured_um")
    mode.add_argument("--simulate", action="store_true", help="the whole story on a simulated stage")
    p.add_argument("--lead-um", type=float, default=2000.0, help="screw lead, µm (default 2000)")
    p.add_argument("--noise-um", type=float, default=None,
                   help="vision noise, µm (measured: for the uncertainties, default from the residuals; "
                        "simulated: default 0.1)")
    outputs = add_output_options(
        p, out=("MODEL.json", "write the fitted actuator models as JSON"),
        tables=("DIR", "write each actuator's error table (CSV and every format of kinid.axis_tables)"),
        plot=("OUT.png", "write errors before/after and residual vs position mod lead"),
        json="print one JSON object instead of the report",
        report=("DIR", "write an HTML report (with the plot) into DIR: of the measured moves, or of the "
                               "simulated story"))
    sim = p.add_argument_group("simulated stage (--simulate)")
    sim.add_argument("--seed", type=int, default=0, help="seed of the noise and the random moves (default 0)")
    sim.add_argument("--repeats", type=int, default=3, help="bidirectional sweeps of the model's test plan (default 3)")
    sim.add_argument("--patent-repeats", type=int, default=18,
                     help="measurements per stroke in the patent's test (default 18, as in its example)")
    sim.add_argument("--validation-moves", dest="moves_n", type=int, default=200,
                     help="validation moves per actuator (default 200)")
    add_alias(p, "--moves", "--data")
    p.set_defaults(run=_run, outputs=outputs)


def _measured(args) -> int:
    from kinid.axis_tables import neutral_csv_text, write_tables
    from kinid.errors import DataError
    from kinid.files import strict_json, write_json, write_text
    from .measured import actuator_tables, fit_moves, models_json, read_moves
    from .report import plot_measured, quantity, write_measured_report

    if args.noise_um is not None and not (args.noise_um > 0 and math.isfinite(args.noise_um)):
        raise DataError(f"--noise-um must be a positive number, got {args.noise_um!r}")
    check_report(args)
    models = fit_moves(read_moves(args.moves), args.lead_um, noise_um=args.noise_um)
    doc = models_json(models, str(args.moves))
    if args.out:
        write_json(args.out, doc)
    if args.tables:
        tables = actuator_tables(models)
        with staged_tables(args, "kinid uvw") as folder:
            for a, table in tables.items():
                write_text(folder / f"{a}.csv", neutral_csv_text(f"{a.lower()}_mm", table.positions, {
                    f"E{a}_um": table.forward, f"E{a}_rev_um": table.reverse}))
            write_tables(folder, list(tables.values()), comment="kinid uvw: error = actual - commanded")
    if args.plot:
        plot_measured(models, args.plot)
    if args.report:
        with staged_report(args) as staged:
            write_measured_report(models, staged)
    if args.json:
        print(strict_json(doc))
        return 0
    print(f"UVW actuator models from {args.moves} (lead {args.lead_um:g} µm; terms chosen by BIC): value ± std")
    for a, m in models.items():
        parts = [quantity(n, v, s) for n, v, s in zip(m.names, m.values, m.std)]
        print(f"  {a} ({m.commands_um.size} moves, degree {m.degree}, {m.harmonics} harmonics): " + ", ".join(parts))
        print(f"      residual RMS {m.rms_um:.3f} µm over {m.span_um[0]:g} .. {m.span_um[1]:g} µm")
    for flag, value in (("model", args.out), ("tables", args.tables), ("plot", args.plot), ("report", args.report)):
        if value:
            print(f"{flag} written to {value}")
    return 0


def _run(args) -> int:
    from kinid.errors import DataError

    if not (args.lead_um > 0 and math.isfinite(args.lead_um)):
        raise DataError(f"--lead-um must be a positive number (screw lead, µm), got {args.lead_um!r}")
    if args.moves:
        return _measured(args)
    refuse_unused(args, ("tables",), "--simulate",
                  "they are of measured moves (--data); the simulated story writes --plot, --out, --report and --json")
    check_report(args)
    noise_um = 0.1 if args.noise_um is None else args.noise_um
    if not (noise_um >= 0 and math.isfinite(noise_um)):
        raise DataError(f"--noise-um must be >= 0, got {noise_um!r}")
    for flag, value in (("--repeats", args.repeats), ("--patent-repeats", args.patent_repeats),
                        ("--validation-moves", args.moves_n)):
        if value < 1:
            raise DataError(f"{flag} must be a positive integer, got {value!r}")
    from .demo import plot_demo, run_demo
    from .report import demo_text

    result = run_demo(seed=args.seed, noise_um=noise_um, lead_um=args.lead_um, repeats=args.repeats,
                      patent_repeats=args.patent_repeats, moves=args.moves_n, progress=None)
    if args.plot:
        plot_demo(result, args.plot)
    if args.report:
        from .report import write_simulated_report

        with staged_report(args) as staged:
            write_simulated_report(result, staged)
    public = {k: v for k, v in result.items() if not k.startswith("_")}
    if args.out:
        from kinid.files import write_json

        write_json(args.out, public)
    if args.json:
        from kinid.files import strict_json

        print(strict_json(public))
        return 0
    print(demo_text(public, args.plot))
    if args.report:
        print(f"report written to {args.report}")
    return 0


