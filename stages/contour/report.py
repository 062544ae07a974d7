"""What ``kinid contour`` draws: a ballbar-like polar plot for circles (error along the path otherwise),
the text report and the HTML report of a contour measurement."""
from __future__ import annotations

import math

import numpy as np

__all__ = ["plot_contour", "write_report", "report_text"]


def _nice(x: float) -> float:
    """1, 2 or 5 × 10^k at or above x."""
    k = np.floor(np.log10(max(x, 1e-12)))
    for m in (1, 2, 5, 10):
        if m * 10**k >= x:
            return float(m * 10**k)
    return float(10 ** (k + 1))


def plot_contour(measurement, out_png, *, magnification=None):
    """Write a PNG of the measured contour error (whole or not at all).

    Circle: polar plot of the radial deviation about the fitted/given centre,
    magnified like a ballbar plot (the nominal circle drawn at the plot's
    reference radius), plus the track. Line/polyline: the track and the error
    along it.

    Parameters
    ----------
    measurement : stages.contour.measure.ContourMeasurement
    out_png : str or path
    magnification : float or None
        Circles only: the deviation, µm, drawn as 0.4 of the plot radius
        (default: the largest absolute deviation).
    """
    from kinid.reports.figures import SHOWN_WIDTH_IN, new_figure, save_figure

    from .paths import CirclePath

    m = measurement
    xy = m.track.xy_mm
    ok = np.all(np.isfinite(xy), axis=1)
    err = m.contour.error_um
    fig = new_figure((SHOWN_WIDTH_IN, 4.6))
    if isinstance(m.contour.path, CirclePath):
        c = m.contour.path.centre_mm
        ax = fig.add_subplot(1, 2, 1, projection="polar")
        # angle from +x, counter-clockwise with y up (the machine's convention; the image's y points down)
        ang = np.arctan2(-(xy[ok, 1] - c[1]), xy[ok, 0] - c[0])
        e = err[ok]
        emax = float(np.max(np.abs(e))) if e.size else 1.0
        span = emax if magnification is None else float(magnification)
        span = max(span, 1e-9)
        ax.plot(np.linspace(0, 2 * np.pi, 361), np.ones(361), "k--", lw=0.8, label="nominal circle")
        r = 1.0 + 0.4 * e / span
        a_plot, r_plot = ang, r
        turned = np.ptp(np.unwrap(ang)) if ang.size > 2 else 0.0
        if turned >= 2 * np.pi * 0.97:  # a full turn: close the trace
            a_plot, r_plot = np.r_[ang, ang[:1]], np.r_[r, r[:1]]
        ax.plot(a_plot, r_plot, "b.-", lw=1, ms=3, label="measured")
        ax.set_ylim(0, 1.5)
        # radial scale in µm of deviation: the nominal circle is 0
        step = _nice(span / 2)
        devs = np.arange(-2, 3) * step
        devs = devs[np.abs(1.0 + 0.4 * devs / span - 0.75) <= 0.75]
        ax.set_yticks(1.0 + 0.4 * devs / span)
        ax.set_yticklabels([f"{d:+.3g} µm" if d else "0" for d in devs], fontsize=8)
        ax.set_rlabel_position(112.5)
        title = f"radial deviation from the nominal circle, magnified\n(rings every {step:.3g} µm; angle from +x, y up)"
        if m.circular is not None:
            title += f", G {m.circular.G_um:.2f} µm"
            if np.isfinite(m.circular.H_um):
                title += f", H {m.circular.H_um:.2f} µm"
        ax.set_title(title, fontsize=10)
        ax.legend(loc="upper left", bbox_to_anchor=(-0.32, 1.12), fontsize=8, frameon=False)
    else:
        ax = fig.add_subplot(1, 2, 1)
        ax.plot(np.flatnonzero(ok), err[ok], "b.-", ms=3)
        ax.set_xlabel("frame")
        ax.set_ylabel("contour error (µm)")
        ax.grid(True, alpha=0.3)
    ax2 = fig.add_subplot(1, 2, 2)
    track = xy[ok]
    if isinstance(m.contour.path, CirclePath) and len(track) > 2 and \
            np.hypot(*(track[0] - track[-1])) < 3 * np.median(np.hypot(*np.diff(track, axis=0).T)):
        track = np.r_[track, track[:1]]  # a closed circle
    # y up, as in the polar plot beside it (the image's rows run down)
    ax2.plot(track[:, 0], -track[:, 1], "b.-", ms=2, lw=0.8)
    ax2.set_aspect("equal")
    ax2.set_xlabel("x, mm (image right)")
    ax2.set_ylabel("y, mm (image up)")
    ax2.set_title(f"track of mark {m.track.reference_code}, {int(ok.sum())}/{len(ok)} frames located",
                  fontsize=9)
    ax2.grid(True, alpha=0.3)
    fig.tight_layout()
    save_figure(fig, out_png, dpi=100, tight=False)


def write_report(m, args, *, frames, board, scale, simulated=False) -> None:
    """The HTML report of a contour measurement (kinid.reports.html)."""
    from pathlib import Path

    from kinid.reports.html import Figure, Section, Table, file_provenance, now_utc
    from kinid.reports.html import write_report as write_pages
    from .report import plot_contour

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    plot_contour(m, folder / "contour.png")
    tr, ce, c = m.track, m.contour, m.circular
    rows = [("contour error, RMS", f"{ce.rms_um:.3f}", "µm"), ("contour error, largest", f"{ce.max_um:.3f}", "µm")]
    if c is not None:
        rows += [("ISO 230-4 circular deviation G", f"{c.G_um:.3f}", "µm"),
                 ("ISO 230-4 radial deviation F, max / min", f"{c.F_max_um:+.3f} / {c.F_min_um:+.3f}", "µm")]
        if math.isfinite(c.H_um):
            rows.append(("ISO 230-4 circular hysteresis H", f"{c.H_um:.3f}", "µm"))
    rows += [("frames located", f"{int(tr.located.sum())} of {len(tr.located)}", ""),
             ("board rotation in the image", f"{tr.angle_deg:.4f}", "deg")]
    summary = [f"The machine follows the programmed path within {ce.max_um:.3g} µm (RMS {ce.rms_um:.3g} µm)"
               + (f"; ISO 230-4 circular deviation G = {c.G_um:.3g} µm." if c is not None else "."),
               "Next: compare with the machine's specification; the polar plot shows where on the path the "
               "deviation comes from (reversal spikes at the quadrants, an ellipse from a servo mismatch)."]
    prov = [("frames", f"{frames} ({len(tr.located)} frames{', rendered by --simulate' if simulated else ''})"),
            ("board", file_provenance(board)),
            ("scale", scale if isinstance(scale, str) else f"camera {file_provenance(scale)}"),
            ("made", now_utc())]
    sections = [Section("Results", tables=(Table(("quantity", "value", "unit"), tuple(rows), numeric=(1,)),)),
                Section("Test conditions (ISO 230-4)", tables=(_conditions(m, args, simulated),)),
                Section("Radial deviation and track", figures=(Figure("contour.png", "Left: the deviation from the "
                        "path, magnified (circle) or along the path. Right: the reference mark's track."),))]
    write_pages(folder, "Contour error", "kinid contour", prov, summary, sections)


def _conditions(m, args, simulated):
    """What ISO 230-4 asks a circular test report to state, as far as the run knows it; the rest named as
    to be stated by whoever ran the test."""
    from kinid.reports.html import Table

    tr, c = m.track, m.circular
    n = len(tr.located)
    rows = []
    if c is not None:
        given = getattr(args, "radius", None) is not None
        rows += [("nominal radius R0", f"{c.nominal_radius_mm:.4f} mm" + ("" if given else " (fitted: no --radius-mm "
                  "given, so F is against the least-squares circle)")),
                 ("least-squares circle", f"centre ({c.centre_mm[0]:.4f}, {c.centre_mm[1]:.4f}) mm, "
                                          f"radius {c.radius_mm:.4f} mm"),
                 ("direction of contouring", ", ".join({"+": "counter-clockwise (x right, y up)",
                                                        "-": "clockwise (x right, y up)"}.get(d, d)
                                                       for d in c.G_by_direction_um))]
    if m.fps:
        t = np.asarray(m.t_s, float)
        located = tr.located & np.isfinite(t)
        xy = tr.xy_mm[located]
        if xy.shape[0] > 2 and np.ptp(t[located]) > 0:
            length = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
            rows.append(("contouring feed (measured)", f"{60 * length / np.ptp(t[located]):.1f} mm/min"))
        rows.append(("data acquisition", f"{n} frames at {m.fps:g} frames/s"))
    else:
        rows += [("contouring feed", "not known: give --fps (or a video) and the feed follows from the track"),
                 ("data acquisition", f"{n} frames, no frame rate")]
    rows += [("measuring instrument", "camera and ring-coded board (kinid contour)"
              + ("; images rendered by kinid contour --simulate" if simulated else "")),
             ("plane, axes, position in the working zone", "to be stated by the tester (not in the images)"),
             ("compensation, temperature, warm-up", "to be stated by the tester (not in the images)")]
    return Table(("item", "value"), tuple(rows), caption="ISO 230-4:2005 asks a circular test to state these; "
                 "items the images cannot tell are left for the tester to fill in.")


def report_text(m, settings) -> str:
    tr, ce = m.track, m.contour
    unit = settings.unit
    lines = [f"frames            {len(tr.located)}  (located {int(tr.located.sum())})",
             f"reference mark    code {tr.reference_code} at row {tr.reference_rc[0]}, column {tr.reference_rc[1]}",
             f"board rotation    {tr.angle_deg:.4f} deg (in the image, clockwise as seen)"]
    if unit == "mm":
        lines.append(f"pixel size        {settings.pixel_mm * 1e3 / tr.scale:.5f} µm from the board's pitch "
                     f"(given {settings.pixel_mm * 1e3:.5f} µm)")
    else:
        lines.append(f"pixel size        {1e3 / tr.scale:.5f} µm (object side, ideal pixels)")
    res = tr.residual_rms / tr.scale * 1e3
    lines.append(f"mark residual     {res:.3f} µm RMS per coordinate" if math.isfinite(res) else
                 "mark residual     n/a (no frame with two marks)")
    path = ce.path
    name = type(path).__name__.replace("Path", "").lower()
    if name == "circle":
        lines.append(f"path              circle, centre ({path.centre_mm[0]:.4f}, {path.centre_mm[1]:.4f}) mm, "
                     f"radius {path.radius_mm:.4f} mm")
    else:
        lines.append(f"path              {name}")
    lines.append(f"contour error     RMS {ce.rms_um:.3f} µm, max |e| {ce.max_um:.3f} µm")
    c = m.circular
    if c is not None:
        h = f"{c.H_um:.3f} µm" if math.isfinite(c.H_um) else "n/a (one direction only)"
        lines += [f"ISO 230-4 G       {c.G_um:.3f} µm (circular deviation)",
                  f"ISO 230-4 F       max {c.F_max_um:+.3f} µm, min {c.F_min_um:+.3f} µm (radial deviation, "
                  f"R0 {c.nominal_radius_mm:.4f} mm)",
                  f"ISO 230-4 H       {h} (circular hysteresis)"]
    return "\n".join(lines)
