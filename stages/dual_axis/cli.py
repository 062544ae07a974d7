"""``kinid dual-axis``: the two-parallel-Y-axes calibration on a simulated gantry.

Measures ``pixel_to_mm`` by moving the head, runs the patent's calibration
rounds, fits the smooth model, and compares both on held-out camera positions
(the mid-points between table vertices): measured by the camera and, since
the gantry is simulated, against the truth.
"""
from __future__ import annotations

import json

import numpy as np

from kinid.errors import DataError

__all__ = ["register", "run_simulation"]


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
    p.add_argument("--plot", metavar="OUT.png", help="plot of the plate offset before/after compensation")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.add_argument("--out", metavar="TABLE.csv", help="write the offset table: camera_y_mm,head_dx_mm,head_dy_mm")
    p.add_argument("--report", metavar="DIR", help="with --data: write an HTML report (with the plot) into DIR")
    sim = p.add_argument_group("simulated gantry (--simulate)")
    sim.add_argument("--y-start-mm", type=float, default=0.0, help="camera Y at the start, mm (default 0)")
    sim.add_argument("--step-mm", type=float, default=10.0, help="step of both Y axes, mm (default 10)")
    sim.add_argument("--steps", type=int, default=30, help="number of steps (default 30)")
    sim.add_argument("--max-rounds", type=int, default=5, help="rounds before giving up (default 5)")
    sim.add_argument("--seed", type=int, default=0, help="seed of the simulation (texture, noise)")
    sim.add_argument("--random-errors", action="store_true",
                     help="draw a random error set from the seed instead of the built-in one")
    sim.add_argument("--noise", type=float, default=1.5, help="image noise, grey levels (default 1.5)")
    sim.add_argument("--repeat-um", type=float, default=0.0, help="axis positioning repeatability, µm (default 0)")
    p.set_defaults(run=_run, parameter_options={"n_steps": "--steps", "y_start_mm": "--y-start-mm"},
                   outputs={"out": "file", "plot": "file", "report": "folder"})


def _stats(err_um: np.ndarray) -> dict:
    err = np.asarray(err_um, float).reshape(-1, 2)
    return {"max_x_um": float(np.max(np.abs(err[:, 0]))), "max_y_um": float(np.max(np.abs(err[:, 1]))),
            "max_um": float(np.max(np.hypot(err[:, 0], err[:, 1]))),
            "rms_um": float(np.sqrt(np.mean(np.sum(err ** 2, axis=1))))}


def run_simulation(*, y_start_mm=0.0, step_mm=10.0, n_steps=30, spec_um=1.0, max_rounds=5, degree=3, seed=0,
                   random_errors=False, noise_sigma=1.5, repeat_um=0.0):
    """Run the whole story on a simulated gantry.

    Parameters
    ----------
    y_start_mm, step_mm, n_steps, spec_um, max_rounds
        As in :func:`stages.dual_axis.calibrate`.
    degree : int
        Degree of the smooth model.
    seed : int
        Seed of ``np.random.default_rng`` for the simulation.
    random_errors : bool
        Use :func:`random_error_profiles` instead of the built-in error set.
    noise_sigma : float
        Image noise, grey levels.
    repeat_um : float
        Positioning repeatability of every axis, µm.

    Returns
    -------
    dict
        ``gantry``, ``pixel_to_mm``, ``table``, ``smooth``, ``held_out_mm`` and
        the summary ``report`` (JSON-ready).
    """
    from .calibrate import calibrate, check_plan, measure_pixel_to_mm, verify
    from .simulate import SimulatedGantry, random_error_profiles
    from .smooth import fit_smooth

    for name, v in (("noise", noise_sigma), ("repeat-um", repeat_um)):
        if not np.isfinite(v) or v < 0:
            raise DataError(f"--{name} must be a non-negative number, got {v!r}")
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
        raise DataError(f"degree must be an integer >= 1, got {degree!r}")
    # validate the plan before any move (the pixel_to_mm argument is measured later)
    check_plan(y_start_mm, (0.0, y_start_mm), step_mm, n_steps, np.eye(2), spec_um, max_rounds)
    rng = np.random.default_rng(seed)
    errors = random_error_profiles(rng) if random_errors else None
    g = SimulatedGantry(errors, noise_sigma=noise_sigma, repeat_um=repeat_um, rng=rng)
    head0 = (0.0, float(y_start_mm))  # Y = V, X = 0: the plate is centred under the camera
    mr = measure_pixel_to_mm(g, y_start_mm, head0)
    from kinid.progress import Progress

    with Progress(None, "dual-axis images") as progress:
        table = calibrate(g, y_start_mm, head0, step_mm, n_steps, mr.matrix, spec_um, max_rounds=max_rounds,
                          progress=progress)
    smooth = fit_smooth(table, degree)
    held = table.y_mm[:-1] + 0.5 * float(step_mm)
    y0 = float(y_start_mm)

    def truth(comp):
        out = []
        for p in held:
            dx, dy = (0.0, p - y0) if comp is None else comp.head_move(y0, p)
            out.append(g.plate_offset_um(y0, head0, p, (head0[0] + dx, head0[1] + dy)))
        return np.array(out)

    measured = {"table": verify(g, table, y0, head0, held, mr.matrix),
                "smooth": verify(g, smooth, y0, head0, held, mr.matrix)}
    true = {"uncompensated": truth(None), "table": truth(table), "smooth": truth(smooth)}
    better = "table" if _stats(true["table"])["max_um"] <= _stats(true["smooth"])["max_um"] else "smooth"
    report = {
        "y_start_mm": y0, "step_mm": float(step_mm), "steps": int(n_steps), "spec_um": float(spec_um),
        "pixel_to_mm": mr.matrix.tolist(), "true_pixel_to_mm": g.true_pixel_to_mm.tolist(),
        "rounds": table.rounds, "converged": table.converged,
        "max_change_um": [r.max_change_um for r in table.history],
        "smooth": {"degree": smooth.degree, "parallelism_urad": smooth.parallelism_urad,
                   "scale_um_per_m": smooth.scale_um_per_m, "fit_rms_um": smooth.rms_um.tolist()},
        "held_out": {
            "positions": len(held),
            "uncompensated_truth": _stats(true["uncompensated"]),
            "table_measured": _stats(measured["table"]), "table_truth": _stats(true["table"]),
            "smooth_measured": _stats(measured["smooth"]), "smooth_truth": _stats(true["smooth"]),
        },
        "better": better,
        "table": table.to_dict(),
    }
    return {"gantry": g, "pixel_to_mm": mr.matrix, "table": table, "smooth": smooth, "held_out_mm": held,
            "truth_um": true, "measured_um": measured, "report": report}


def _plot(path, result) -> None:
    
    from kinid.figures import new_figure, save_figure

    g, table, smooth = result["gantry"], result["table"], result["smooth"]
    y0 = float(table.y_mm[0])
    head0 = (0.0, y0)
    ys = np.linspace(table.y_mm[0], table.y_mm[-1], 241)

    def offsets(comp):
        out = []
        for p in ys:
            dx, dy = (0.0, p - y0) if comp is None else comp.head_move(y0, p)
            out.append(g.plate_offset_um(y0, head0, p, (head0[0] + dx, head0[1] + dy)))
        return np.array(out)

    before, after_t, after_s = offsets(None), offsets(table), offsets(smooth)
    fig = new_figure((11, 7))
    axes = fig.subplots(2, 2, sharex=True)
    for col, name in enumerate(("head X", "head Y")):
        ax = axes[0, col]
        ax.plot(ys, before[:, col], "k-", label="before compensation")
        ax.plot(table.y_mm, -table.offset_mm[:, col] * 1e3, "o", ms=3, label="table vertices (negated)")
        ax.set_title(f"plate offset, {name}")
        ax.set_ylabel("µm")
        ax.legend(fontsize=8)
        ax = axes[1, col]
        ax.plot(ys, after_t[:, col], "-", label="after: table")
        ax.plot(ys, after_s[:, col], "-", label=f"after: smooth (degree {smooth.degree})")
        ax.plot(result["held_out_mm"], result["measured_um"]["table"][:, col], "x", ms=4,
                label="held-out, table, measured by camera")
        ax.axhline(table.spec_um, color="grey", lw=0.5, ls="--")
        ax.axhline(-table.spec_um, color="grey", lw=0.5, ls="--")
        ax.set_xlabel("camera Y, mm")
        ax.set_ylabel("µm")
        ax.legend(fontsize=8)
    fig.suptitle(f"dual Y axes: {table.message}", fontsize=9)
    fig.tight_layout()
    save_figure(fig, path, tight=False)


def _format(rep: dict) -> str:
    lines = [
        f"dual-axis calibration on the simulated gantry (urdf/gantry_dual_y.urdf): {rep['steps']} steps of "
        f"{rep['step_mm']:g} mm from camera Y {rep['y_start_mm']:g} mm, spec {rep['spec_um']:g} µm",
        "pixel_to_mm measured (mm/px): " + np.array2string(np.array(rep["pixel_to_mm"]), precision=6),
        "round  max entry change (µm)",
    ]
    lines += [f"{i:5d}  {c:10.3f}" for i, c in enumerate(rep["max_change_um"], 1)]
    lines.append(f"{'converged' if rep['converged'] else 'NOT converged'} after {rep['rounds']} round(s)")
    s = rep["smooth"]
    lines.append(f"smooth model (degree {s['degree']}): parallelism {s['parallelism_urad']:.2f} µrad, "
                 f"scale {s['scale_um_per_m']:.2f} µm/m, fit RMS x {s['fit_rms_um'][0]:.3f} µm, "
                 f"y {s['fit_rms_um'][1]:.3f} µm")
    h = rep["held_out"]
    lines.append(f"held-out positions ({h['positions']} mid-steps)   max|x| µm  max|y| µm  max µm  RMS µm")
    for key, label in (("uncompensated_truth", "uncompensated (truth)"),
                       ("table_measured", "table, measured by camera"), ("table_truth", "table (truth)"),
                       ("smooth_measured", "smooth, measured by camera"), ("smooth_truth", "smooth (truth)")):
        v = h[key]
        lines.append(f"  {label:34s} {v['max_x_um']:9.3f} {v['max_y_um']:9.3f} {v['max_um']:7.3f} {v['rms_um']:7.3f}")
    lines.append(f"better on held-out positions: {rep['better']}")
    return "\n".join(lines)


def _measured(args) -> int:
    from kinid.files import write_text
    from .measured import read_round, table_from_round
    from .smooth import fit_smooth

    if args.pixel_to_mm is None:
        raise DataError("--data needs --pixel-to-mm A B C D (image shift px -> head move mm; measure it as "
                        "docs/dual_axis.md shows)")
    if not (np.isfinite(args.spec_um) and args.spec_um > 0):
        raise DataError(f"--spec-um must be a positive number, got {args.spec_um!r}")
    y, shift, used = read_round(args.data)
    table = table_from_round(y, shift, used, np.reshape(args.pixel_to_mm, (2, 2)), args.spec_um)
    smooth = fit_smooth(table, args.degree)
    if args.out:
        write_text(args.out, table.csv_text())
    if args.plot:
        _plot_measured(args.plot, table, smooth)
    if args.report:
        _report_measured(args, table, smooth)
    report = {"source": str(args.data), "table": table.to_dict(), "message": table.message,
              "smooth": {"degree": smooth.degree, "parallelism_urad": smooth.parallelism_urad,
                         "scale_um_per_m": smooth.scale_um_per_m, "fit_rms_um": smooth.rms_um.tolist()}}
    if args.json:
        print(json.dumps(report))
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


def _report_measured(args, table, smooth) -> None:
    """The HTML report of one measured round (kinid.report_html)."""
    from pathlib import Path

    from kinid.files import write_text
    from kinid.report_html import Figure, Section, Table, file_provenance, now_utc, report_page

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    _plot_measured(folder / "offset_table.png", table, smooth)
    rows = tuple((f"{y:.3f}", f"{dx:.3f}", f"{dy:.3f}") for y, (dx, dy) in zip(table.y_mm, table.offset_mm * 1e3))
    big = float(abs(table.offset_mm).max() * 1e3)
    summary = [f"Between the two Y axes the head is off by up to {big:.3g} µm along the travel; parallelism "
               f"{smooth.parallelism_urad:.3g} µrad, scale {smooth.scale_um_per_m:.3g} µm/m.",
               f"{table.message[0].upper() + table.message[1:]}."]
    prov = [("measured", file_provenance(args.data)), ("pixel to mm", " ".join(f"{v:g}" for v in args.pixel_to_mm)),
            ("made", now_utc())]
    sections = [Section("Offset table", tables=(Table(("camera Y (mm)", "head dx (µm)", "head dy (µm)"), rows,
                                                      numeric=(0, 1, 2)),)),
                Section("Table and smooth model", figures=(Figure("offset_table.png", "The measured table and the "
                        f"smooth model (degree {smooth.degree}) fitted to it"),))]
    write_text(folder / "index.html", report_page("Dual-axis offset table", "kinid dual-axis", prov, summary, sections))


def _plot_measured(path, table, smooth) -> None:
    from kinid.figures import new_figure, save_figure

    fig = new_figure((10, 4))
    ax0, ax1 = fig.subplots(1, 2)
    yy = np.linspace(table.y_mm[0], table.y_mm[-1], 400)
    fitted = smooth.correction_mm(yy) * 1e3
    for k, (ax, label) in enumerate(((ax0, "head X"), (ax1, "head Y"))):
        ax.plot(table.y_mm, table.offset_mm[:, k] * 1e3, "o", ms=4, label="offset table (measured)")
        ax.plot(yy, fitted[:, k], "-", lw=1.2, label=f"smooth model (degree {smooth.degree})")
        ax.set_xlabel("camera Y (mm)")
        ax.set_ylabel(f"{label} correction (µm)")
        ax.set_title(f"{label}: fit RMS {smooth.rms_um[k]:.3f} µm", fontsize=10)
        ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, tight=False)


def _run(args) -> int:
    from pathlib import Path

    if args.plot and not Path(args.plot).resolve().parent.is_dir():
        raise DataError(f"output folder {str(Path(args.plot).parent)!r} does not exist", path=args.plot)
    if args.data:
        return _measured(args)
    result = run_simulation(y_start_mm=args.y_start_mm, step_mm=args.step_mm, n_steps=args.steps,
                            spec_um=args.spec_um, max_rounds=args.max_rounds, degree=args.degree,
                            seed=args.seed, random_errors=args.random_errors, noise_sigma=args.noise,
                            repeat_um=args.repeat_um)
    if args.plot:
        _plot(args.plot, result)
    if args.out:
        from kinid.files import write_text

        write_text(args.out, result["table"].csv_text())
    rep = result["report"]
    if args.json:
        print(json.dumps(rep))
    else:
        print(_format(rep))
        if args.plot:
            print(f"plot written to {args.plot}")
        if args.out:
            print(f"offset table written to {args.out}")
    return 0
