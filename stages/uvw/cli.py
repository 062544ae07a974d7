"""``kinid uvw``: the patent's UVW compensation against the fitted model, on a simulated stage."""
from __future__ import annotations

import json
import math
import os

from .demo import run_demo, plot_demo
from .kinematics import ACTUATORS

__all__ = ["register"]


def register(subparsers) -> None:
    """Add the ``uvw`` verb."""
    p = subparsers.add_parser(
        "uvw", help="UVW alignment stage: patent compensation vs fitted error model (simulated stage)",
        description="Calibrate a simulated UVW stage (scale error, backlash, periodic lead error, vision noise) "
                    "with the patent's method and with a fitted per-actuator error model, then drive "
                    "random 50-2000 µm alignment moves uncompensated and with each compensation.")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise and the random moves (default 0)")
    p.add_argument("--noise-um", type=float, default=0.1, help="vision noise of the simulated stage, µm (default 0.1)")
    p.add_argument("--lead-um", type=float, default=2000.0, help="screw lead, µm (default 2000)")
    p.add_argument("--repeats", type=int, default=3, help="bidirectional sweeps of the model's test plan (default 3)")
    p.add_argument("--patent-repeats", type=int, default=18,
                   help="measurements per stroke in the patent's test (default 18, as in its example)")
    p.add_argument("--moves", type=int, default=200, help="validation moves per actuator (default 200)")
    p.add_argument("--plot", metavar="OUT.png", help="write errors before/after and residual vs position mod lead")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    p.set_defaults(run=_run)


def _run(args) -> int:
    from kinid.errors import DataError

    if not (args.lead_um > 0 and math.isfinite(args.lead_um)):
        raise DataError(f"--lead-um must be a positive number (screw lead, µm), got {args.lead_um!r}")
    if not (args.noise_um >= 0 and math.isfinite(args.noise_um)):
        raise DataError(f"--noise-um must be >= 0, got {args.noise_um!r}")
    for flag, value in (("--repeats", args.repeats), ("--patent-repeats", args.patent_repeats)):
        if value < 1:
            raise DataError(f"{flag} must be a positive integer, got {value!r}")
    if args.plot:
        folder = os.path.dirname(os.path.abspath(args.plot))
        if not os.path.isdir(folder):
            raise DataError(f"output folder {folder!r} does not exist", path=args.plot)
    result = run_demo(seed=args.seed, noise_um=args.noise_um, lead_um=args.lead_um, repeats=args.repeats,
                      patent_repeats=args.patent_repeats, moves=args.moves, progress=None)
    if args.plot:
        plot_demo(result, args.plot)
    public = {k: v for k, v in result.items() if not k.startswith("_")}
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
            parts.append(f"{name} {v['value']:.3f} ± {v['std']:.3f}{t}")
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
                     f"theta {s['max_theta_urad']:.2f} urad")
    if plot:
        lines += ["", f"plot written to {plot}"]
    return "\n".join(lines)
