"""What ``kinid dual-axis`` draws: plate offsets before and after the table (simulated and measured
rounds), the text report and the HTML report."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["plot_simulation", "simulation_text", "write_measured_report", "write_simulated_report", "plot_measured"]


def plot_simulation(path, result) -> None:
    """The simulated gantry before and after compensation: plate offsets and what is left, per head axis."""
    from kinid.reports.figures import SHOWN_WIDTH_IN, legend_below, new_figure, save_figure

    g, table, smooth = result["gantry"], result["table"], result["smooth"]
    y0 = float(table.y_mm[0])
    head0 = (0.0, y0)
    ys = np.linspace(table.y_mm[0], table.y_mm[-1], 241)

    def offsets(comp):
        return g.compensated_offsets_um(y0, head0, ys, comp)

    before, after_t, after_s = offsets(None), offsets(table), offsets(smooth)
    fig = new_figure((SHOWN_WIDTH_IN, 6.4))
    axes = fig.subplots(2, 2, sharex=True)
    for col, name in enumerate(("head X", "head Y")):
        ax = axes[0, col]
        ax.plot(ys, before[:, col], "k-", label="before compensation")
        ax.plot(table.y_mm, -table.offset_mm[:, col] * 1e3, "o", ms=3, label="table vertices (negated)")
        ax.set_title(f"plate offset, {name}")
        ax.set_ylabel("offset (µm)")
        ax = axes[1, col]
        ax.set_title(f"left after compensation, {name}")
        ax.plot(ys, after_t[:, col], "-", label="after: table")
        ax.plot(ys, after_s[:, col], "-", label=f"after: smooth (degree {smooth.degree})")
        ax.plot(result["held_out_mm"], result["measured_um"]["table"][:, col], "x", ms=4,
                label="held-out, table, measured by camera")
        ax.axhline(table.spec_um, color="grey", lw=0.5, ls="--")
        ax.axhline(-table.spec_um, color="grey", lw=0.5, ls="--")
        ax.set_xlabel("camera Y (mm)")
        ax.set_ylabel("offset left (µm)")
    fig.suptitle(f"dual Y axes: {table.message}", fontsize=9)
    fig.tight_layout()
    legend_below(fig, list(axes.ravel()), columns=3)
    save_figure(fig, path)


def simulation_text(rep: dict) -> str:
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


def _pixel_words(matrix) -> str:
    """A 2 × 2 pixel-to-mm matrix in words: the matrix, the pixel size and the camera's turn."""
    (a, b), (c, d) = (tuple(float(v) for v in row) for row in matrix)
    return (f"[[{a:g}, {b:g}], [{c:g}, {d:g}]] mm per pixel (x = {a:g}·u + {b:g}·v, y = {c:g}·u + {d:g}·v for a "
            f"shift of u, v pixels): pixel size {1e3 * abs(a * d - b * c) ** 0.5:.4g} µm, camera turned "
            f"{math.degrees(math.atan2(c, a)):.3g}° from the machine axes")


def write_simulated_report(args, result) -> None:
    """The HTML report of the simulated method (``kinid dual-axis --simulate --report DIR``): the table found by
    the rounds, and the table and the smooth model checked at held-out positions against the simulated truth."""
    from pathlib import Path

    from kinid.reports.html import Figure, Section, Table, now_utc, write_report

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    plot_simulation(folder / "dual_axis_simulated.png", result)
    rep, table, smooth = result["report"], result["table"], result["smooth"]
    rows = tuple((f"{y:.3f}", f"{dx:.3f}", f"{dy:.3f}") for y, (dx, dy) in zip(table.y_mm, table.offset_mm * 1e3))
    offsets = Table(("camera Y (mm)", "head dx (µm)", "head dy (µm)"), rows, numeric=(0, 1, 2),
                    caption=f"The offset table after {rep['rounds']} round(s) "
                            f"({'converged' if rep['converged'] else 'NOT converged'}: the last round changed no entry "
                            f"by more than {rep['max_change_um'][-1]:.3g} µm; spec {rep['spec_um']:g} µm).")
    h = rep["held_out"]
    labels = (("uncompensated_truth", "uncompensated (truth)"), ("table_truth", "with the table (truth)"),
              ("table_measured", "with the table, measured by the camera"),
              ("smooth_truth", f"with the smooth model, degree {smooth.degree} (truth)"),
              ("smooth_measured", "with the smooth model, measured by the camera"))
    held = Table(("", "max |x| (µm)", "max |y| (µm)", "max (µm)", "RMS (µm)"),
                 tuple((label, *(f"{h[key][k]:.3f}" for k in ("max_x_um", "max_y_um", "max_um", "rms_um")))
                       for key, label in labels), numeric=(1, 2, 3, 4),
                 caption=f"Plate offset at {h['positions']} held-out positions (half-way between the table's), the "
                         "simulated truth and what the camera measures there.")
    summary = [f"The table brings the two Y axes' offset from {h['uncompensated_truth']['max_um']:.3g} µm to "
               f"{h['table_truth']['max_um']:.3g} µm at most at positions it was not measured at; the smooth model "
               f"to {h['smooth_truth']['max_um']:.3g} µm — the {rep['better']} is the better compensation here.",
               "Next: measure the real gantry (kinid dual-axis --data MEAS.csv --pixel-to-mm A B C D --report DIR)."]
    prov = [("measured", f"the simulated gantry (seed {args.seed}{', random errors' if args.random_errors else ''}, "
                         f"image noise {args.noise:g} grey levels, axis repeatability {args.repeat_um:g} µm)"),
            ("plan", f"{rep['steps']} steps of {rep['step_mm']:g} mm from camera Y {rep['y_start_mm']:g} mm"),
            ("pixel to mm", _pixel_words(rep["pixel_to_mm"]) + "; simulated: "
                            + _pixel_words(rep["true_pixel_to_mm"]).split(" mm per pixel")[0]),
            ("made", now_utc())]
    sections = [Section("Offset table", tables=(offsets,)),
                Section("Checked at held-out positions", tables=(held,), figures=(Figure(
                    "dual_axis_simulated.png", "Top: the plate offset before compensation per head axis and the "
                    "table's vertices (negated). Bottom: what is left with the table and with the smooth model, and "
                    "the camera's measurement at the held-out positions (dashed: the spec)."),)),
                Section("Text output", details=simulation_text(rep))]
    write_report(folder, "Dual-axis offset table, simulated gantry", "kinid dual-axis --simulate", prov, summary,
                 sections)


def write_measured_report(args, table, smooth) -> None:
    """The HTML report of one measured round (kinid.reports.html)."""
    from pathlib import Path

    from kinid.reports.html import Figure, Section, Table, file_provenance, now_utc, write_report

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    plot_measured(folder / "offset_table.png", table, smooth)
    rows = tuple((f"{y:.3f}", f"{dx:.3f}", f"{dy:.3f}") for y, (dx, dy) in zip(table.y_mm, table.offset_mm * 1e3))
    big = float(abs(table.offset_mm).max() * 1e3)
    summary = [f"Between the two Y axes the head is off by up to {big:.3g} µm along the travel; parallelism "
               f"{smooth.parallelism_urad:.3g} µrad, scale {smooth.scale_um_per_m:.3g} µm/m.",
               f"{table.message[0].upper() + table.message[1:]}."]
    a, b, c, d = (float(v) for v in args.pixel_to_mm)
    pixel = _pixel_words(((a, b), (c, d)))
    prov = [("measured", file_provenance(args.data)), ("pixel to mm", pixel), ("made", now_utc())]
    caption = ("One measurement per point, so one round cannot tell its uncertainty; the points scatter about the "
               f"smooth model by {smooth.rms_um[0]:.3g} µm RMS in x and {smooth.rms_um[1]:.3g} µm in y (an upper "
               "bound of their repeatability, k = 1). Measure a second round: the difference of the two tables "
               "gives it.")
    sections = [Section("Offset table", tables=(Table(("camera Y (mm)", "head dx (µm)", "head dy (µm)"), rows,
                                                      numeric=(0, 1, 2), caption=caption),)),
                Section("Table and smooth model", figures=(Figure("offset_table.png", "The measured table and the "
                        f"smooth model (degree {smooth.degree}) fitted to it"),))]
    write_report(folder, "Dual-axis offset table", "kinid dual-axis", prov, summary, sections)


def plot_measured(path, table, smooth) -> None:
    from kinid.reports.figures import SHOWN_WIDTH_IN, new_figure, save_figure

    fig = new_figure((SHOWN_WIDTH_IN, 3.8))
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
