"""What ``kinid uvw`` draws: the measured actuator models' figure and HTML report, and the text report
of the simulated story."""
from __future__ import annotations

from .kinematics import ACTUATORS

__all__ = ["write_measured_report", "write_simulated_report", "plot_measured", "demo_text", "quantity"]


#: The actuator error model in words, for the captions of both reports' parameter tables.
MODEL_WORDS = ("The error of each actuator, measured − commanded position at command c (µm), approached in direction "
               "d = ±1: offset + scale·c − d·B/2 + Σ_h (s_h sin 2πhc/L + k_h cos 2πhc/L), B the backlash, L the screw "
               "lead, s_h and k_h the sine and cosine parts of the h-th harmonic of the lead error")


def quantity(name: str, value: float, std: float, truth: str = "") -> str:
    """``offset_um`` 1.653, 0.007 -> "offset 1.653 ± 0.007 µm (1σ)" (the unit out of the parameter's name)."""
    stem, _, unit = name.rpartition("_")
    unit = {"um": "µm", "ppm": "ppm"}.get(unit, unit)
    return f"{stem} {value:.3f} ± {std:.3f} {unit} (1σ){truth}"


def write_measured_report(models, args) -> None:
    """The HTML report of the actuator models (kinid.reports.html)."""
    from pathlib import Path

    import numpy as np

    from kinid.reports.html import Figure, Section, Table, file_provenance, now_utc, write_report

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    plot_measured(models, folder / "actuators.png")
    rows = []
    for a, m in models.items():
        for n, v, s in zip(m.names, m.values, m.std):
            stem, _, unit = n.rpartition("_")
            rows.append((a, _parameter_words(stem), f"{v:.3f}", f"{2 * s:.3f}", {"um": "µm"}.get(unit, unit)))
    table = Table(("actuator", "parameter", "value", "U (k = 2)", "unit"), tuple(rows), numeric=(2, 3),
                  caption=MODEL_WORDS + " (and a bow, polynomial terms q_p, when the data ask for one). U: expanded "
                                        "uncertainty, k = 2.")
    before = {a: float(np.max(np.abs(m.error_um(m.commands_um, m.directions) + m.residuals_um))) for a, m in models.items()}
    worst = max(before, key=before.get)
    summary = [f"Uncompensated, the actuators miss their commands by up to {before[worst]:.3g} µm ({worst}); the "
               f"fitted models leave {max(m.rms_um for m in models.values()):.3g} µm RMS at most.",
               f"Next: write the actuator tables (kinid uvw --data {args.moves} --lead-um {args.lead_um:g} --tables "
               "tables), load them or the models into the alignment's compensation, and check with new moves."]
    prov = [("measured", file_provenance(args.moves)), ("lead", f"{args.lead_um:g} µm"), ("made", now_utc())]
    sections = [Section("Actuator models", tables=(table,)),
                Section("Errors before and after", figures=(Figure("actuators.png", "Top: measured − commanded "
                        "position per actuator, each approach direction, with the model. Bottom: what the model "
                        "leaves (the error after compensation)."),))]
    write_report(folder, "UVW stage: actuator error models", "kinid uvw", prov, summary, sections)


def write_simulated_report(result: dict, args) -> None:
    """The HTML report of the simulated story (``kinid uvw --simulate --report DIR``): the fitted models against
    the simulated truth, and the patent's method and the model on the same random alignment moves."""
    from pathlib import Path

    from kinid.reports.html import Figure, Section, Table, now_utc, write_report

    from .demo import plot_demo

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    plot_demo(result, folder / "uvw_simulated.png")
    rows = []
    for a in ACTUATORS:
        for n, v in result["model"][a]["parameters"].items():
            stem, _, unit = n.rpartition("_")
            truth = f"{v['truth']:.3f}" if "truth" in v else "—"
            rows.append((a, _parameter_words(stem), f"{v['value']:.3f}", f"{2 * v['std']:.3f}", truth,
                         {"um": "µm"}.get(unit, unit)))
    models = Table(("actuator", "parameter", "fitted", "U (k = 2)", "simulated", "unit"), tuple(rows),
                   numeric=(2, 3, 4),
                   caption=MODEL_WORDS + "; terms chosen by BIC. —: not a term of the simulated stage (there it is "
                                         "zero). U: expanded uncertainty, k = 2.")
    val = result["validation"]
    methods = ("uncompensated", "patent", "model")
    words = {"uncompensated": "uncompensated", "patent": "the patent's method", "model": "the fitted model"}
    vrows = tuple((("all actuators" if a == "all" else a) if m == methods[0] else "", words[m],
                   *(f"{(val['all'] if a == 'all' else val['per_actuator'][a])[m][k]:.3f}" for k in ("rms_um", "max_um")))
                  for a in (*ACTUATORS, "all") for m in methods)
    validation = Table(("actuator", "compensation", "RMS (µm)", "max (µm)"), vrows, numeric=(2, 3),
                       caption=f"True position error after {result['moves_per_actuator']} random alignment moves of "
                               "50–2000 µm per actuator, each compensated by the patent's method (a shortfall "
                               "interpolated between two strokes) and by the fitted model.")
    prows = tuple((a, *(f"{result['patent'][a][k]:.3f}" for k in ("delta_xn_um", "delta_xm_um", "delta_x_um")),
                   f"{result['patent'][a]['slope_ppm']:.0f}") for a in ACTUATORS)
    patent = Table(("actuator", "shortfall at stroke m (µm)", "at stroke n (µm)", "mean (µm)", "slope (ppm)"),
                   prows, numeric=(1, 2, 3, 4),
                   caption=f"The patent's test: {result['patent'][ACTUATORS[0]]['repeats']} measurements per stroke of "
                           f"m = {result['patent'][ACTUATORS[0]]['m_um']:g} µm and n = "
                           f"{result['patent'][ACTUATORS[0]]['n_um']:g} µm; the shortfall is interpolated linearly in "
                           "the stroke.")
    a = val["all"]
    summary = [f"On random alignment moves the fitted model leaves {a['model']['rms_um']:.3g} µm RMS "
               f"({a['model']['max_um']:.3g} µm at most) of the uncompensated {a['uncompensated']['rms_um']:.3g} µm; "
               f"the patent's method leaves {a['patent']['rms_um']:.3g} µm ({a['patent']['max_um']:.3g} µm at most).",
               f"Next: measure the real stage's moves and fit them (kinid uvw --data MOVES.csv --lead-um "
               f"{result['lead_um']:g} --report DIR)."]
    prov = [("measured", f"a simulated UVW stage (seed {result['seed']}, vision noise {result['noise_um']:g} µm, "
                         f"screw lead {result['lead_um']:g} µm)"),
            ("plan", f"model test {result['calibration_moves']['model']} moves, patent test "
                     f"{result['calibration_moves']['patent']} moves, {result['moves_per_actuator']} validation moves "
                     "per actuator"),
            ("made", now_utc())]
    sections = [Section("Fitted models against the simulated stage", tables=(models,)),
                Section("The patent's method and the model on the same moves", tables=(validation, patent),
                        figures=(Figure("uvw_simulated.png", "Left: the true error after each validation move, "
                                        "uncompensated, by the patent's method and by the model (dashed: ±0.6 µm). "
                                        "Middle: what a scale-and-reversal model (the patent's kind) leaves, against "
                                        "the commanded position modulo the lead. Right: what the full model leaves."),)),
                Section("Text output", details=demo_text({k: v for k, v in result.items() if not k.startswith("_")},
                                                         None))]
    write_report(folder, "UVW stage, simulated: the patent's method and the actuator model", "kinid uvw --simulate",
                 prov, summary, sections)


def _parameter_words(stem: str) -> str:
    """``s1`` → ``lead error, 1st harmonic, sine part (s1)``: a model parameter in words and symbol."""
    import re

    m = re.fullmatch(r"([sk])(\d+)|poly(\d+)", stem)
    if not m:
        return {"backlash": "backlash (B)"}.get(stem, stem)
    if m.group(3):
        return f"bow, term of degree {m.group(3)} (q{m.group(3)})"
    h = int(m.group(2))
    nth = {1: "1st", 2: "2nd", 3: "3rd"}.get(h, f"{h}th")
    return f"lead error, {nth} harmonic, {'sine' if m.group(1) == 's' else 'cosine'} part ({stem})"


def plot_measured(models, path) -> None:
    """Measured error against command per actuator with the model (both directions), and the residuals."""
    import numpy as np

    from kinid.reports.figures import SHOWN_WIDTH_IN, legend_below, new_figure, save_figure

    fig = new_figure((SHOWN_WIDTH_IN, 6.4))
    axes = fig.subplots(2, len(models), squeeze=False)
    for k, (a, m) in enumerate(models.items()):
        c, d = m.commands_um, m.directions
        measured_err = m.error_um(c, d) + m.residuals_um
        grid = np.linspace(*m.span_um, 400)
        top, bottom = axes[0, k], axes[1, k]
        for sign, col, label in ((1.0, "tab:blue", "approached +"), (-1.0, "tab:red", "approached −")):
            sel = d == sign
            top.plot(c[sel] * 1e-3, measured_err[sel], "o", ms=3, color=col, label=f"measured, {label}")
            top.plot(grid * 1e-3, m.error_um(grid, sign), "-", lw=1, color=col, label=f"model, {label}")
            bottom.plot(c[sel] * 1e-3, m.residuals_um[sel], "o", ms=3, color=col)
        top.set_title(f"{a}: error before compensation", fontsize=10)
        top.set_ylabel("measured − commanded (µm)")
        bottom.axhline(0, color="0.6", lw=0.8)
        bottom.set_title(f"{a}: left after it, RMS {m.rms_um:.3f} µm", fontsize=10)
        bottom.set_xlabel("command (mm)")
        bottom.set_ylabel("residual (µm)")
    fig.tight_layout()
    legend_below(fig, axes[0, 0], columns=4)
    save_figure(fig, path)


def demo_text(r: dict, plot) -> str:
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
            parts.append(quantity(name, v["value"], v["std"], t))
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
