"""``kinid backlash``: the backlash calibration on a simulated stage, measured vs truth."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from kinid.errors import DataError

__all__ = ["register", "plot_result"]


def register(subparsers) -> None:
    """Add the ``backlash`` verb to the ``kinid`` command line."""
    p = subparsers.add_parser(
        "backlash",
        help="measure pixel equivalent and X/Y/θ lead-screw backlash from images (simulated stage)",
        description="Run the image-based backlash calibration (CN105547173) on a simulated X-Y-θ stage "
                    "and compare the measured pixel equivalent and backlash with the simulated truth.")
    p.add_argument("--backlash-x-um", type=float, default=4.0, help="true X backlash, µm (default 4)")
    p.add_argument("--backlash-y-um", type=float, default=3.0, help="true Y backlash, µm (default 3)")
    p.add_argument("--backlash-theta-deg", type=float, default=0.01, help="true θ backlash, degrees (default 0.01)")
    p.add_argument("--pixel-um", type=float, default=5.0, help="pixel size on the stage, µm (default 5)")
    p.add_argument("--camera-angle-deg", type=float, default=7.0,
                   help="rotation of the camera about the stage axes, degrees (default 7)")
    p.add_argument("--theta-centre-mm", type=float, nargs=2, default=(-12.0, 8.0), metavar=("DX", "DY"),
                   help="θ rotation centre relative to the fiducial, mm (default -12 8)")
    p.add_argument("--noise", type=float, default=2.0, help="image noise, grey levels (default 2)")
    p.add_argument("--repeatability-um", type=float, default=0.0,
                   help="random X/Y positioning scatter per move, µm (default 0)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--travel-mm", type=float, default=0.8, help="X/Y travel about the start, mm (default 0.8)")
    p.add_argument("--travel-deg", type=float, default=2.0, help="θ travel about the start, degrees (default 2)")
    p.add_argument("--repeats", type=int, default=1, help="reversal cycles per axis and target (default 1)")
    p.add_argument("--targets", type=int, default=1, help="target positions per linear axis (default 1)")
    p.add_argument("--plot", metavar="OUT.png", help="write a plot of fiducial positions and reversal gaps")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.set_defaults(run=_run, parameter_options={"n_targets": "--targets"})


def _truth(stage) -> dict:
    return {
        "pixel_um_x": stage.true_pixel_mm_along((1.0, 0.0)) * 1e3,
        "pixel_um_y": stage.true_pixel_mm_along((0.0, 1.0)) * 1e3,
        "backlash_x_um": stage.backlash_x_mm * 1e3,
        "backlash_y_um": stage.backlash_y_mm * 1e3,
        "backlash_theta_deg": stage.backlash_theta_deg,
        "camera_rotation_deg": stage.camera_angle_deg,
        "theta_radius_mm": float(np.hypot(*stage.theta_centre_mm)),
    }


def _run(args) -> int:
    from .calibrate import calibrate
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
    if args.plot:
        folder = Path(args.plot).parent
        if not folder.is_dir():
            raise DataError(f"output folder {str(folder)!r} does not exist", path=args.plot, column="--plot")
    stage = SimulatedStage(
        pixel_mm=args.pixel_um * 1e-3, camera_angle_deg=args.camera_angle_deg,
        backlash_x_mm=args.backlash_x_um * 1e-3, backlash_y_mm=args.backlash_y_um * 1e-3,
        backlash_theta_deg=args.backlash_theta_deg, theta_centre_mm=tuple(args.theta_centre_mm),
        noise_sigma=args.noise, repeatability_mm=args.repeatability_um * 1e-3,
        rng=np.random.default_rng(args.seed))
    res = calibrate(stage, travel_mm=args.travel_mm, travel_deg=args.travel_deg, repeats=args.repeats,
                    n_targets=args.targets)
    measured = res.summary()
    truth = _truth(stage)
    if args.plot:
        plot_result(res, args.plot, truth=truth)
    if args.json:
        errors = {k: measured[k] - truth[k] for k in truth if k in measured}
        print(json.dumps({"measured": measured, "truth": truth, "errors": errors}, sort_keys=True))
        return 0
    print(f"backlash calibration on a simulated stage: pixel {args.pixel_um:g} µm, camera rotated "
          f"{args.camera_angle_deg:g}°, fiducial {truth['theta_radius_mm']:.1f} mm from the θ centre, "
          f"noise {args.noise:g} grey levels, seed {args.seed}")
    print(f"{res.moves} moves ({sum(r.role != 'preload' for r in res.log)} photos)")
    print(f"{'quantity':<24}{'measured':>12}{'simulated':>12}{'error':>12}")
    rows = [
        ("pixel along X (µm/px)", "pixel_um_x", "{:.5f}", True),
        ("pixel along Y (µm/px)", "pixel_um_y", "{:.5f}", True),
        ("backlash X (µm)", "backlash_x_um", "{:.3f}", False),
        ("backlash Y (µm)", "backlash_y_um", "{:.3f}", False),
        ("backlash θ (deg)", "backlash_theta_deg", "{:.5f}", False),
        ("camera rotation (deg)", "camera_rotation_deg", "{:.3f}", False),
        ("θ radius (mm)", "theta_radius_mm", "{:.3f}", False),
    ]
    for label, key, fmt, relative in rows:
        m, t = measured[key], truth[key]
        err = f"{(m / t - 1) * 100:+.4f} %" if relative else ("{:+" + fmt[2:]).format(m - t)
        print(f"{label:<24}{fmt.format(m):>12}{fmt.format(t):>12}{err:>12}")
    print(f"ISO 230-2 reversal value B: X {measured['iso_reversal_x_um']:.3f} µm, "
          f"Y {measured['iso_reversal_y_um']:.3f} µm; mean reversal X {measured['iso_mean_reversal_x_um']:+.3f} µm, "
          f"Y {measured['iso_mean_reversal_y_um']:+.3f} µm")
    print(f"patent formula r·|p1-p2|: X {res.backlash_x_patent_mm * 1e3:.3f} µm, "
          f"Y {res.backlash_y_patent_mm * 1e3:.3f} µm, θ {res.backlash_theta_patent_deg:.5f}°")
    if args.plot:
        print(f"plot written to {args.plot}")
    return 0


def plot_result(res, path, *, truth=None) -> None:
    """Write a PNG: fiducial per photo, reversal gap vectors, per-move pixel equivalent.

    Parameters
    ----------
    res : BacklashResult
    path : str or path-like
        Output PNG, written whole or not at all.
    truth : dict or None
        Simulated truth (keys ``backlash_x_um``, ``backlash_y_um``,
        ``backlash_theta_deg``, ``pixel_um_x``, ``pixel_um_y``) drawn for comparison.
    """
    from kinid.figures import new_figure, save_figure


    fig = new_figure((13, 4.2))
    ax0, ax1, ax2 = fig.subplots(1, 3)
    colours = {"scale": "tab:blue", "up": "tab:green", "down": "tab:red", "centre": "tab:purple"}
    for role, col in colours.items():
        recs = [r for r in res.log if r.role == role]
        if recs:
            ax0.plot([r.x_px for r in recs], [r.y_px for r in recs], "o", color=col, ms=5, label=role,
                     mfc="none" if role == "down" else col)
    for r in res.log:
        if r.role == "scale" or r.role == "centre":
            ax0.annotate(str(r.index), (r.x_px, r.y_px), fontsize=7, xytext=(3, 3), textcoords="offset points")
    ax0.invert_yaxis()
    ax0.set_aspect("equal", adjustable="datalim")
    ax0.set_xlabel("image x (px)")
    ax0.set_ylabel("image y (px)")
    ax0.set_title(f"fiducial per photo ({res.moves} moves)")
    ax0.legend(fontsize=7)

    # Gap vectors down - up in machine µm (θ: the arc of the fiducial about the θ centre).
    for axis, col in (("x", "tab:blue"), ("y", "tab:orange"), ("theta", "tab:green")):
        ups = [r for r in res.log if r.axis == axis and r.role == "up"]
        downs = [r for r in res.log if r.axis == axis and r.role == "down"]
        d = res.matrix.to_machine(np.array([[b.x_px - a.x_px, b.y_px - a.y_px] for a, b in zip(ups, downs)])) * 1e3
        label = {"x": "X", "y": "Y", "theta": "θ (arc)"}[axis]
        ax1.plot(d[:, 0], d[:, 1], "o", color=col, label=f"{label} measured")
    if truth is not None:
        ax1.plot([truth["backlash_x_um"]], [0.0], "x", color="tab:blue", ms=10, label="X true")
        ax1.plot([0.0], [truth["backlash_y_um"]], "x", color="tab:orange", ms=10, label="Y true")
        # True θ gap: an arc of R·Bθ along the tangent at the fiducial (centre is relative to it).
        v = -np.asarray(res.theta_centre_mm, float)
        tangent = np.array([-v[1], v[0]]) / np.hypot(*v)
        arc = tangent * np.radians(truth["backlash_theta_deg"]) * np.hypot(*v) * 1e3
        ax1.plot([arc[0]], [arc[1]], "x", color="tab:green", ms=10, label="θ true")
    ax1.axhline(0, color="0.7", lw=0.8)
    ax1.axvline(0, color="0.7", lw=0.8)
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.set_xlabel("machine X gap (µm)")
    ax1.set_ylabel("machine Y gap (µm)")
    title = (f"reversal gaps: X {res.backlash_x_mm * 1e3:.3f} µm, Y {res.backlash_y_mm * 1e3:.3f} µm,\n"
             f"θ {res.backlash_theta_deg:.5f}° at r = {res.theta_radius_mm:.2f} mm")
    if truth is not None:
        title += (f" (true {truth['backlash_x_um']:.3f}, {truth['backlash_y_um']:.3f} µm, "
                  f"{truth['backlash_theta_deg']:.5f}°)")
    ax1.set_title(title, fontsize=8)
    ax1.legend(fontsize=7)

    per = res.scale.per_move * 1e3
    idx = np.arange(1, per.size + 1)
    cols = ["tab:blue" if a == "x" else "tab:orange" if a == "y" else "0.4" for a in res.scale.axes]
    ax2.scatter(idx, per, c=cols)
    for i, a in zip(idx, res.scale.axes):
        ax2.annotate(a.upper(), (i, per[i - 1]), fontsize=7, xytext=(4, 2), textcoords="offset points")
    if truth is not None:
        ax2.axhline(truth["pixel_um_x"], color="tab:blue", ls="--", lw=1, label="true along X")
        ax2.axhline(truth["pixel_um_y"], color="tab:orange", ls=":", lw=1, label="true along Y")
        ax2.legend(fontsize=7)
    ax2.set_xticks(idx)
    ax2.set_xlabel("non-reversal move")
    ax2.set_ylabel("pixel equivalent (µm/px)")
    ax2.set_title(f"pixel equivalent X {res.pixel_mm_x * 1e3:.5f}, Y {res.pixel_mm_y * 1e3:.5f} µm/px", fontsize=9)
    ax2.ticklabel_format(axis="y", useOffset=False)
    fig.tight_layout()
    save_figure(fig, path, tight=False)
