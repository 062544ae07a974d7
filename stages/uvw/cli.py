"""``kinid uvw``: the UVW actuator error models from measured moves, or the whole story on a simulated stage."""
from __future__ import annotations

import json
import math

from .demo import run_demo, plot_demo
from .kinematics import ACTUATORS

__all__ = ["register"]


def register(subparsers) -> None:
    """Add the ``uvw`` verb."""
    p = subparsers.add_parser(
        "uvw", help="UVW alignment stage: actuator error models and compensation from measured moves",
        description="Fit each actuator's error model (offset, scale, backlash, bow, lead harmonics; chosen by "
                    "BIC) to the moves measured on a UVW stage (--moves), and write the model and the "
                    "actuators' compensation tables; or calibrate a simulated UVW stage with the patent's method "
                    "and with the fitted model and compare them on random alignment moves (--simulate).")
    mode = p.add_mutually_exclusive_group(required=True)
    mode.add_argument("--moves", metavar="MOVES.csv", help="measured moves: actuator,command_um,direction,measured_um")
    mode.add_argument("--simulate", action="store_true", help="the whole story on a simulated stage")
    p.add_argument("--lead-um", type=float, default=2000.0, help="screw lead, µm (default 2000)")
    p.add_argument("--noise-um", type=float, default=None,
                   help="vision noise, µm (measured: for the uncertainties, default from the residuals; "
                        "simulated: default 0.1)")
    p.add_argument("--out", metavar="MODEL.json", help="write the fitted actuator models as JSON")
    p.add_argument("--tables", metavar="DIR", help="write each actuator's error table (CSV, LinuxCNC, TwinCAT CNC)")
    p.add_argument("--plot", metavar="OUT.png", help="write errors before/after and residual vs position mod lead")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument("--report", metavar="DIR", help="with --moves: write an HTML report (with the plot) into DIR")
    sim = p.add_argument_group("simulated stage (--simulate)")
    sim.add_argument("--seed", type=int, default=0, help="seed of the noise and the random moves (default 0)")
    sim.add_argument("--repeats", type=int, default=3, help="bidirectional sweeps of the model's test plan (default 3)")
    sim.add_argument("--patent-repeats", type=int, default=18,
                     help="measurements per stroke in the patent's test (default 18, as in its example)")
    sim.add_argument("--validation-moves", dest="moves_n", type=int, default=200,
                     help="validation moves per actuator (default 200)")
    p.set_defaults(run=_run, outputs={"out": "file", "plot": "file", "tables": "folder", "report": "folder"})


def _quantity(name: str, value: float, std: float, truth: str = "") -> str:
    """``offset_um`` 1.653, 0.007 -> "offset 1.653 ± 0.007 µm" (the unit out of the parameter's name)."""
    stem, _, unit = name.rpartition("_")
    unit = {"um": "µm", "ppm": "ppm"}.get(unit, unit)
    return f"{stem} {value:.3f} ± {std:.3f} {unit}{truth}"


def _measured(args) -> int:
    from pathlib import Path

    from kinid.axis_tables import neutral_csv_text, write_tables
    from kinid.errors import DataError
    from kinid.files import write_json, write_text
    from .measured import actuator_tables, fit_moves, models_json, read_moves

    if args.noise_um is not None and not (args.noise_um > 0 and math.isfinite(args.noise_um)):
        raise DataError(f"--noise-um must be a positive number, got {args.noise_um!r}")
    models = fit_moves(read_moves(args.moves), args.lead_um, noise_um=args.noise_um)
    doc = models_json(models, str(args.moves))
    if args.out:
        write_json(args.out, doc)
    if args.tables:
        Path(args.tables).mkdir(parents=True, exist_ok=True)
        tables = actuator_tables(models)
        for a, table in tables.items():
            write_text(Path(args.tables) / f"{a}.csv", neutral_csv_text(f"{a.lower()}_mm", table.positions, {
                f"E{a}_um": table.forward, f"E{a}_rev_um": table.reverse}))
        write_tables(args.tables, list(tables.values()), comment="kinid uvw: error = actual - commanded")
    if args.plot:
        _plot_measured(models, args.plot)
    if args.report:
        _report_measured(models, args)
    if args.json:
        print(json.dumps(doc))
        return 0
    print(f"UVW actuator models from {args.moves} (lead {args.lead_um:g} µm; terms chosen by BIC): value ± std")
    for a, m in models.items():
        parts = [_quantity(n, v, s) for n, v, s in zip(m.names, m.values, m.std)]
        print(f"  {a} ({m.commands_um.size} moves, degree {m.degree}, {m.harmonics} harmonics): " + ", ".join(parts))
        print(f"      residual RMS {m.rms_um:.3f} µm over {m.span_um[0]:g} .. {m.span_um[1]:g} µm")
    for flag, value in (("model", args.out), ("tables", args.tables), ("plot", args.plot), ("report", args.report)):
        if value:
            print(f"{flag} written to {value}")
    return 0


def _report_measured(models, args) -> None:
    """The HTML report of the actuator models (kinid.report_html)."""
    from pathlib import Path

    import numpy as np

    from kinid.files import write_text
    from kinid.report_html import Figure, Section, Table, file_provenance, now_utc, report_page

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    _plot_measured(models, folder / "actuators.png")
    rows = []
    for a, m in models.items():
        for n, v, s in zip(m.names, m.values, m.std):
            stem, _, unit = n.rpartition("_")
            rows.append((a, stem, f"{v:.3f}", f"{2 * s:.3f}", {"um": "µm"}.get(unit, unit)))
    table = Table(("actuator", "parameter", "value", "U (k = 2)", "unit"), tuple(rows), numeric=(2, 3),
                  caption="measured = command + offset + scale·c − d·B/2 (+ bow) + lead harmonics s_h, k_h; "
                          "U: expanded uncertainty, k = 2")
    before = {a: float(np.max(np.abs(m.error_um(m.commands_um, m.directions) + m.residuals_um))) for a, m in models.items()}
    worst = max(before, key=before.get)
    summary = [f"Uncompensated, the actuators miss their commands by up to {before[worst]:.3g} µm ({worst}); the "
               f"fitted models leave {max(m.rms_um for m in models.values()):.3g} µm RMS at most.",
               "Next: load the actuator tables (kinid uvw --moves ... --tables DIR) or the models into the "
               "alignment's compensation, and check with new moves."]
    prov = [("measured", file_provenance(args.moves)), ("lead", f"{args.lead_um:g} µm"), ("made", now_utc())]
    sections = [Section("Actuator models", tables=(table,)),
                Section("Errors before and after", figures=(Figure("actuators.png", "Top: measured − commanded "
                        "position per actuator, each approach direction, with the model. Bottom: what the model "
                        "leaves (the error after compensation)."),))]
    write_text(folder / "index.html", report_page("UVW stage: actuator error models", "kinid uvw", prov, summary,
                                                  sections))


def _plot_measured(models, path) -> None:
    """Measured error against command per actuator with the model (both directions), and the residuals."""
    import numpy as np

    from kinid.figures import new_figure, save_figure

    fig = new_figure((12, 6.5))
    axes = fig.subplots(2, len(models), squeeze=False)
    for k, (a, m) in enumerate(models.items()):
        c, d = m.commands_um, m.directions
        measured_err = m.error_um(c, d) + m.residuals_um
        grid = np.linspace(*m.span_um, 400)
        top, bottom = axes[0, k], axes[1, k]
        for sign, col, label in ((1.0, "tab:blue", "approached +"), (-1.0, "tab:red", "approached −")):
            sel = d == sign
            top.plot(c[sel] * 1e-3, measured_err[sel], "o", ms=3, color=col, label=f"measured, {label}")
            top.plot(grid * 1e-3, m.error_um(grid, sign), "-", lw=1, color=col)
            bottom.plot(c[sel] * 1e-3, m.residuals_um[sel], "o", ms=3, color=col)
        top.set_title(f"{a}: error before compensation (model lines)", fontsize=10)
        top.set_ylabel("measured − commanded (µm)")
        top.legend(fontsize=8)
        bottom.axhline(0, color="0.6", lw=0.8)
        bottom.set_title(f"{a}: left after compensation, RMS {m.rms_um:.3f} µm", fontsize=10)
        bottom.set_xlabel("command (mm)")
        bottom.set_ylabel("residual (µm)")
    fig.tight_layout()
    save_figure(fig, path, tight=False)


def _run(args) -> int:
    from kinid.errors import DataError

    if not (args.lead_um > 0 and math.isfinite(args.lead_um)):
        raise DataError(f"--lead-um must be a positive number (screw lead, µm), got {args.lead_um!r}")
    if args.moves:
        return _measured(args)
    noise_um = 0.1 if args.noise_um is None else args.noise_um
    if not (noise_um >= 0 and math.isfinite(noise_um)):
        raise DataError(f"--noise-um must be >= 0, got {noise_um!r}")
    for flag, value in (("--repeats", args.repeats), ("--patent-repeats", args.patent_repeats),
                        ("--validation-moves", args.moves_n)):
        if value < 1:
            raise DataError(f"{flag} must be a positive integer, got {value!r}")
    result = run_demo(seed=args.seed, noise_um=noise_um, lead_um=args.lead_um, repeats=args.repeats,
                      patent_repeats=args.patent_repeats, moves=args.moves_n, progress=None)
    if args.plot:
        plot_demo(result, args.plot)
    public = {k: v for k, v in result.items() if not k.startswith("_")}
    if args.out:
        from kinid.files import write_json

        write_json(args.out, public)
    if args.json:
        print(json.dumps(public))
        return 0
    print(_report(public, args.plot))
    return 0


def _report(r: dict, plot) -> str:
    w = r["worked_example"]
    lines = [
        f"UVW stage, simulated: lead {r['lead_um']:g} µm, vision noise {r['noise_um']:g} µm, seed {r['seed']}",
        "",
        "Patent worked example (fig. 6):",
        f"  dXn {w['delta_xn_um']:.2f}  dXm {w['delta_xm_um']:.2f}  dX {w['delta_x_um']:.2f} µm, "
        f"X1 = X2 = {w['stroke_um']:g} µm -> forward {w['forward_um']:.2f} µm, reverse {w['reverse_um']:.2f} µm",
        "",
        f"Patent test on this stage ({r['calibration_moves']['patent']} moves): errors are shortfalls, µm",
        "  actuator    dXn     dXm      dX   slope_ppm",
    ]
    for n in ACTUATORS:
        p = r["patent"][n]
        lines.append(f"  {n:8s} {p['delta_xn_um']:6.2f}  {p['delta_xm_um']:6.2f}  {p['delta_x_um']:6.2f}  "
                     f"{p['slope_ppm']:9.0f}")
    lines += ["", f"Model fit ({r['calibration_moves']['model']} moves; terms chosen by BIC): value ± std (truth)"]
    for n in ACTUATORS:
        m = r["model"][n]
        parts = []
        for name, v in m["parameters"].items():
            t = f" ({v['truth']:g})" if "truth" in v else ""
            parts.append(_quantity(name, v["value"], v["std"], t))
        lines.append(f"  {n} (degree {m['degree']}, {m['harmonics']} harmonics): " + ", ".join(parts))
        lines.append(f"      residual rms {m['rms_um']:.3f} µm; without the periodic terms "
                     f"{m['linear_only_rms_um']:.3f} µm (what the patent's linear model misses)")
    lines += ["", f"Validation: {r['moves_per_actuator']} random alignment moves of 50-2000 µm per actuator "
                  "(true position error, µm)",
              "  actuator   uncompensated      patent          model",
              "             max    rms      max    rms      max    rms"]
    val = r["validation"]
    for n in list(ACTUATORS) + ["all"]:
        v = val["all"] if n == "all" else val["per_actuator"][n]
        lines.append(f"  {n:8s} " + "  ".join(f"{v[k]['max_um']:6.2f} {v[k]['rms_um']:6.2f}"
                                              for k in ("uncompensated", "patent", "model")))
    lines += ["", "Stage moves (x, y and rotation together; max |error|):"]
    for k, s in r["stage"].items():
        lines.append(f"  {k:14s} x {s['max_x_um']:.2f} µm  y {s['max_y_um']:.2f} µm  "
                     f"theta {s['max_theta_urad']:.2f} µrad")
    if plot:
        lines += ["", f"plot written to {plot}"]
    return "\n".join(lines)
