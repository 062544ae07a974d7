"""What ``kinid backlash`` draws: the figure of a calibration (photos, reversal gaps before and after
compensation, pixel equivalent) and its HTML report."""
from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["plot_result", "write_report", "gaps_um"]


def write_report(res, args, truth, after, source) -> None:
    """The HTML report of a backlash calibration (kinid.reports.html)."""
    from kinid.reports.html import Figure, Section, Table, file_provenance, now_utc
    from kinid.reports.html import write_report as write_pages

    folder = Path(args.report)
    folder.mkdir(parents=True, exist_ok=True)
    plot_result(res, folder / "backlash.png", truth=truth, after=after)
    m = res.summary()

    def u(spread, n):  # expanded uncertainty of the mean of n single reversals, k = 2
        return f"{2 * spread / np.sqrt(n):.3g}" if n > 1 else "—"

    rows = [("backlash of X", f"{m['backlash_x_um']:.3f}", u(m["spread_x_um"], res.reversals_x_mm.size), "µm",
             str(res.reversals_x_mm.size)),
            ("backlash of Y", f"{m['backlash_y_um']:.3f}", u(m["spread_y_um"], res.reversals_y_mm.size), "µm",
             str(res.reversals_y_mm.size)),
            ("backlash of θ", f"{m['backlash_theta_deg']:.5f}", u(m["spread_theta_deg"], res.reversals_theta_deg.size),
             "deg", str(res.reversals_theta_deg.size)),
            ("pixel equivalent along X", f"{m['pixel_um_x']:.5f}", "—", "µm/px", "—"),
            ("pixel equivalent along Y", f"{m['pixel_um_y']:.5f}", "—", "µm/px", "—"),
            ("camera rotation", f"{m['camera_rotation_deg']:.3f}", "—", "deg", "—"),
            ("ISO 230-2 reversal value B of X", f"{m['iso_reversal_x_um']:.3f}", "—", "µm", "—"),
            ("ISO 230-2 reversal value B of Y", f"{m['iso_reversal_y_um']:.3f}", "—", "µm", "—")]
    if truth is not None:
        rows = [r + (f"{truth[k]:.5g}" if k in truth else "",) for r, k in zip(rows, (
            "backlash_x_um", "backlash_y_um", "backlash_theta_deg", "pixel_um_x", "pixel_um_y", "camera_rotation_deg",
            "backlash_x_um", "backlash_y_um"))]
    header = ("quantity", "measured", "U (k = 2)", "unit", "reversals") + (("simulated",) if truth is not None else ())
    table = Table(header, tuple(rows), numeric=tuple(range(1, len(header))),
                  caption="U: expanded uncertainty of the mean of the single reversals (k = 2); one reversal gives "
                          "none — run the plan with --repeats 3 or more. The pixel equivalents and the camera rotation "
                          "come from the non-reversal moves together (their spread move by move is in the right-hand "
                          "panel below); the ISO 230-2 reversal value is the backlash of the same reversals.")
    summary = [f"The stage loses {m['backlash_x_um']:.3g} µm on X, {m['backlash_y_um']:.3g} µm on Y and "
               f"{m['backlash_theta_deg']:.3g}° on θ at each reversal.",
               "Next: load the bidirectional tables (kinid backlash --tables DIR) or the controller's backlash "
               "parameters, then run the plan again with the compensation on to check what is left."]
    prov = [("measured", "a simulated stage" if args.simulate else file_provenance(args.log)),
            ("plan", f"travel ±{args.travel_mm:g} mm, ±{args.travel_deg:g}°, {args.repeats} repeat(s), "
                     f"{args.targets} target(s); {res.moves} moves"),
            ("made", now_utc())]
    sections = [Section("Results", tables=(table,)),
                Section("Photos, reversal gaps and pixel equivalent",
                        figures=(Figure("backlash.png", "Left: the fiducial in every photo. Middle: each reversal "
                                                        "gap along its axis, before"
                                        + (" and after compensation" if after is not None else "")
                                        + ". Right: the pixel equivalent of each non-reversal move."),))]
    write_pages(folder, "Stage backlash calibration", "kinid backlash", prov, summary, sections)


def gaps_um(res):
    """Reversal gaps (down − up) along each axis: X µm, Y µm, θ as the arc at the fiducial, µm."""
    out = {}
    for axis in ("x", "y", "theta"):
        ups = [r for r in res.log if r.axis == axis and r.role == "up"]
        downs = [r for r in res.log if r.axis == axis and r.role == "down"]
        d = res.matrix.to_machine(np.array([[b.x_px - a.x_px, b.y_px - a.y_px] for a, b in zip(ups, downs)])) * 1e3
        if axis == "theta":
            v = -np.asarray(res.theta_centre_mm, float)
            tangent = np.array([-v[1], v[0]]) / np.hypot(*v)
            out[axis] = d @ tangent
        else:
            out[axis] = d[:, 0 if axis == "x" else 1]
    return out


def plot_result(res, path, *, truth=None, after=None) -> None:
    """Write a PNG: fiducial per photo, reversal gaps before (and after) compensation, pixel equivalent.

    Parameters
    ----------
    res : BacklashResult
    path : str or path-like
        Output PNG, written whole or not at all.
    truth : dict or None
        Simulated truth (keys ``backlash_x_um``, ``backlash_y_um``, ``backlash_theta_deg``,
        ``pixel_um_x``, ``pixel_um_y``) drawn for comparison.
    after : BacklashResult or None
        The same plan run again through the compensation: its gaps are drawn as "after".
    """
    from kinid.reports.figures import SHOWN_WIDTH_IN, new_figure, save_figure

    fig = new_figure((SHOWN_WIDTH_IN, 3.9))
    ax0, ax1, ax2 = fig.subplots(1, 3)
    colours = {"scale": "tab:blue", "up": "tab:green", "down": "tab:red", "centre": "tab:purple"}
    for role, col in colours.items():
        recs = [r for r in res.log if r.role == role]
        if recs:
            ax0.plot([r.x_px for r in recs], [r.y_px for r in recs], "o", color=col, ms=5, label=role,
                     mfc="none" if role == "down" else col)
    spots: dict = {}  # photos at one place (within 2 px) share one label: "2, 8" rather than two labels on top
    for r in res.log:
        if r.role == "scale" or r.role == "centre":
            key = next((k for k in spots if abs(k[0] - r.x_px) <= 2 and abs(k[1] - r.y_px) <= 2), (r.x_px, r.y_px))
            spots.setdefault(key, []).append(str(r.index))
    for (x, y), names in spots.items():
        ax0.annotate(", ".join(names), (x, y), fontsize=8, xytext=(3, 3), textcoords="offset points")
    ax0.invert_yaxis()
    ax0.set_aspect("equal", adjustable="datalim")
    ax0.set_xlabel("image x (px)")
    ax0.set_ylabel("image y (px)")
    ax0.set_title(f"fiducial per photo ({res.moves} moves)")
    ax0.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=4, handletextpad=0.2,
               columnspacing=0.8, frameon=False)  # below the photos: no point or label under it

    # reversal gaps along each axis, before and after compensation
    before = gaps_um(res)
    labels = {"x": "X", "y": "Y", "theta": f"θ: arc at\nr = {res.theta_radius_mm:.3g} mm"}
    for k, axis in enumerate(("x", "y", "theta")):
        g = before[axis]
        ax1.plot(np.full(g.size, k - 0.12), g, "o", color="tab:red", ms=7, label="before" if k == 0 else None)
        if after is not None:
            a = gaps_um(after)[axis]
            ax1.plot(np.full(a.size, k + 0.12), a, "o", color="tab:green", ms=7, label="after" if k == 0 else None)
    if truth is not None:
        arc = np.radians(truth["backlash_theta_deg"]) * res.theta_radius_mm * 1e3
        ax1.plot([-0.3, 0.3], [truth["backlash_x_um"]] * 2, "k--", lw=1, label="simulated backlash")
        ax1.plot([0.7, 1.3], [truth["backlash_y_um"]] * 2, "k--", lw=1)
        ax1.plot([1.7, 2.3], [arc] * 2, "k--", lw=1)
    ax1.axhline(0, color="0.7", lw=0.8)
    ax1.set_xticks([0, 1, 2], [labels[a] for a in ("x", "y", "theta")])
    ax1.set_xlim(-0.6, 2.6)
    ax1.set_ylabel("reversal gap along the axis (µm)")
    title = (f"backlash X {res.backlash_x_mm * 1e3:.3f} µm,\nY {res.backlash_y_mm * 1e3:.3f} µm, "
             f"θ {res.backlash_theta_deg:.5f}°")
    if after is not None:
        title += (f"\nafter: X {after.backlash_x_mm * 1e3:+.3f} µm,\nY {after.backlash_y_mm * 1e3:+.3f} µm, "
                  f"θ {after.backlash_theta_deg:+.5f}°")
    else:
        title += "\n(after: measure again with\nthe compensation on)"
    ax1.set_title(title, fontsize=9)
    ax1.legend(fontsize=8, loc="upper right")

    per = res.scale.per_move * 1e3
    idx = np.arange(1, per.size + 1)
    cols = ["tab:blue" if a == "x" else "tab:orange" if a == "y" else "0.4" for a in res.scale.axes]
    ax2.scatter(idx, per, c=cols)
    for i, a in zip(idx, res.scale.axes):
        ax2.annotate(a.upper(), (i, per[i - 1]), fontsize=8, xytext=(4, 2), textcoords="offset points")
    if truth is not None:
        ax2.axhline(truth["pixel_um_x"], color="tab:blue", ls="--", lw=1, label="true along X")
        ax2.axhline(truth["pixel_um_y"], color="tab:orange", ls=":", lw=1, label="true along Y")
        ax2.legend(fontsize=8)
    ax2.set_xticks(idx)
    ax2.set_xlim(0.5, per.size + 0.8)  # room for the last point's label inside the frame
    ax2.set_xlabel("non-reversal move")
    ax2.set_ylabel("pixel equivalent (µm/px)")
    ax2.set_title(f"pixel equivalent (µm/px)\nX {res.pixel_mm_x * 1e3:.5f}, Y {res.pixel_mm_y * 1e3:.5f}", fontsize=9)
    ax2.ticklabel_format(axis="y", useOffset=False)
    fig.tight_layout()
    save_figure(fig, path, tight=False)
