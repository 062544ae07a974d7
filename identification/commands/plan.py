"""``kinid plan``: the fewest alignments, in the order that costs least machine time, for the accuracy asked."""
from __future__ import annotations

from kinid.errors import DataError

from .data_input import add_export_options, is_observation_file, read_data

__all__ = ["register", "plan_text"]


def register(sub) -> None:
    p = sub.add_parser(
        "plan", help="the fewest alignments, ordered for machine time, that reach a stated accuracy",
        description="Choose the alignments to measure: from every mark at every combination of the preset axes' "
                    "values (--range), the fewest that bring the tool point's expanded uncertainty (k = 2, per "
                    "coordinate, RMS over the candidates' poses) within --target-um, or named parameters within "
                    "theirs (--param), keeping --detect effects detectable; ordered for machine time in blocks so "
                    "that time follows no axis; with the parameters no pose determines and the poses that would "
                    "(docs/plan.md). identify, simulate and predict read the plan file as they read poses.")
    p.add_argument("--machine", default=None, help="machine URDF (docs/machines.md); with --augment, the fit's")
    p.add_argument("--out", required=True, metavar="PLAN.csv", help="the plan to write (docs/formats.md)")
    p.add_argument("--marks-mm", type=float, nargs=3, action="append", metavar=("X", "Y", "Z"),
                   help="a mark on the workpiece, mm (repeat for each; default: the patent's four at (±40, ±40, 0))")
    p.add_argument("--board", default=None, metavar="BOARD.json",
                   help="every mark of a ring-coded board instead of --marks-mm (kinid board)")
    p.add_argument("--range", action="append", default=[], metavar="AXIS=START:STOP:STEP",
                   help="the values of a preset axis (mm / deg, STOP included), e.g. B=-60:60:10; START:STOP for 9 values "
                        "(the range configurations are drawn from on an arm); VALUE for one (default: a turntable "
                        "every 15°, a tilt axis every 10° within ±60°, others 9 values over the travel; with --augment, "
                        "as many over the span the measured data read)")
    p.add_argument("--solve", default=None, metavar="AXES",
                   help="axes that align the tool point with the mark, e.g. X,Y,Z (default: the three linear axes; "
                        "none on a machine without three, whose candidates are then joint configurations)")
    p.add_argument("--samples", type=int, default=2000,
                   help="with no solved axes (a robot arm): configurations drawn within the ranges (default 2000)")
    p.add_argument("--target-um", type=float, default=None, metavar="U",
                   help="expanded uncertainty (k = 2) of the tool point per coordinate, RMS over the candidates' "
                        "poses, µm")
    p.add_argument("--param", action="append", default=[], metavar="NAME=U",
                   help="expanded uncertainty (k = 2) of a parameter in its unit (µm, µrad), e.g. EX0C=2")
    p.add_argument("--count", type=int, default=None, help="this many alignments (instead of targets), the best ones")
    p.add_argument("--noise-um", type=float, default=None,
                   help="σ of one reading, µm (default 1; with --augment, the fit's)")
    p.add_argument("--add", nargs="+", action="extend", default=[], metavar="EFFECT",
                   help="effects to identify besides the default model, e.g. EXX:periodic:10")
    p.add_argument("--detect", action="append", default=[], metavar="EFFECT=SIZE",
                   help="an effect the diagnosis must detect at this size (norm of its parameters, their unit), "
                        "e.g. EXX:periodic:10=1")
    p.add_argument("--detect-um", type=float, default=None, metavar="S",
                   help="every error the diagnosis tests for (its candidates) that leaves S µm at the tool (2·RMS per "
                        "coordinate over the candidates' poses of what the model cannot absorb, the target's scale) "
                        "detected with --power: a first plan for a model that may grow, e.g. 1 for --target-um 0.5")
    p.add_argument("--power", type=float, default=0.9,
                   help="with --detect or --detect-um: the probability of detecting (default 0.9)")
    p.add_argument("--speed-mm-s", type=float, default=100.0, help="linear axes' positioning speed (default 100)")
    p.add_argument("--accel-mm-s2", type=float, default=500.0, help="linear axes' acceleration (default 500)")
    p.add_argument("--speed-deg-s", type=float, default=20.0, help="rotary axes' positioning speed (default 20)")
    p.add_argument("--accel-deg-s2", type=float, default=60.0, help="rotary axes' acceleration (default 60)")
    p.add_argument("--settle-s", type=float, default=1.0, help="settling after a move (default 1)")
    p.add_argument("--align-s", type=float, default=10.0, help="one alignment: image, fine alignment, laser (default 10)")
    p.add_argument("--blocks", type=int, default=None,
                   help="run the plan in this many blocks (default: the fewest whose time follows no axis; 1: the "
                        "shortest tour)")
    p.add_argument("--no-reference", action="store_true",
                   help="no reference alignment repeated at every block's start and at the end (nor --drift-checks)")
    p.add_argument("--drift-checks", type=int, default=None, metavar="N",
                   help="read the reference alignment (the run's first) N times over the run, the last alignment "
                        "among them, to see a drift apart from the geometry (default: the fewest that detect a "
                        "warm-up of --detect-um, else twice --target-um, at the tool with --power; 0: none)")
    p.add_argument("--augment", default=None, metavar="FIT.json",
                   help="plan the alignments to add to those already measured (--data) so that the target holds for "
                        "the model this fit found (its effects, and --add's): a sequential design "
                        "(docs/plan.md); --out gets the added alignments only")
    p.add_argument("--data", default=None, metavar="OBS.csv",
                   help="with --augment: the alignments already measured (kinid's observation CSV or an instrument "
                        "export)")
    add_export_options(p)
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(run=_plan, outputs={"out": "file"})


def _ranges(texts, machine, solve, measured=None) -> dict:
    """The preset axes' values: --range's, else (with ``measured``, the readings of --augment's data) the span the
    data read, else the default over the travel."""
    import numpy as np

    from ..model import axis_limits
    from ..planning import axis_motion

    out = {}
    for text in texts:
        name, _, spec = text.partition("=")
        parts = spec.split(":")
        if name not in machine.axis_names or len(parts) not in (1, 2, 3):
            raise DataError(f"must be AXIS=START:STOP:STEP, AXIS=START:STOP or AXIS=VALUE with AXIS one of "
                            f"{', '.join(machine.axis_names)}, got {text!r}", parameter="range")
        try:
            values = [float(v) for v in parts]
        except ValueError:
            raise DataError(f"must hold numbers, got {text!r}", parameter="range") from None
        if not all(np.isfinite(values)):
            raise DataError(f"must hold finite numbers, got {text!r}", parameter="range")
        if len(values) == 3:
            start, stop, step = values
            if step <= 0 or stop < start:
                raise DataError(f"needs START ≤ STOP and STEP > 0, got {text!r}", parameter="range")
            if (stop - start) / step > 10_000:
                raise DataError(f"gives more than 10000 values, got {text!r}", parameter="range")
            values = list(np.arange(start, stop + step * 1e-9, step))
        elif len(values) == 2:
            if values[1] < values[0]:
                raise DataError(f"needs START ≤ STOP, got {text!r}", parameter="range")
            values = list(np.linspace(values[0], values[1], 9))
        out[name] = np.array(values)
    limits = axis_limits(machine)
    _, turns = axis_motion(machine)
    for j, a in enumerate(machine.axes):
        if a.name in solve or a.name in out:
            continue
        if measured is not None and np.isfinite(measured[:, j]).any():
            out[a.name] = _measured_values(measured[:, j], a.kind == "revolute", turns[j])
            continue
        lo, hi = limits[j]
        if turns[j]:
            out[a.name] = np.arange(0.0, 360.0, 15.0)
        elif a.kind == "revolute":
            out[a.name] = np.arange(max(lo, -60.0), min(hi, 60.0) + 1e-9, 10.0)
        else:
            out[a.name] = np.linspace(lo, hi, 9) if np.isfinite(hi - lo) else np.linspace(-100.0, 100.0, 9)
    return out


def _measured_values(readings, revolute: bool, turns: bool):
    """A preset axis's values over the span its readings cover: the default grid (a table every 15°, a tilt every
    10°, 9 values of a linear axis) within the readings' lowest and highest, both ends included; a table read all
    the way round keeps its turn."""
    import numpy as np

    lo, hi = float(np.nanmin(readings)), float(np.nanmax(readings))
    if turns and hi - lo >= 345.0:
        return np.arange(0.0, 360.0, 15.0)
    if not revolute or hi - lo < 1e-9:
        return np.linspace(lo, hi, 9) if hi > lo else np.array([lo])
    step = 15.0 if turns else 10.0
    inner = np.arange(lo, hi, step)
    return np.append(inner, hi) if hi - inner[-1] > 1e-6 else inner


def _pairs(texts, option, machine=None, effect=False) -> dict:
    out = {}
    for text in texts:
        name, _, value = text.rpartition("=")
        try:
            v = float(value)
        except ValueError:
            v = float("nan")
        if not name or not (v > 0 and v < float("inf")):
            raise DataError(f"must be NAME=U with U a positive number, got {text!r}", parameter=option)
        if effect:
            from ..model import parse_effect

            parse_effect(name, machine, source=f"--{option}")
        out[name] = v
    return out


def _plan(args) -> int:
    import numpy as np

    from ..model import model_effects
    from ..model import load_machine
    from ..data import write_observations
    from ..planning import plan_measurement
    from ..planning import candidate_poses, solved_axes
    from ..planning import advice_pool
    from ..planning import TravelModel
    from ..fitting import PATENT_MARKS_MM

    from kinid.checks import check_plausible, check_positive

    for name in ("target_um", "noise_um", "speed_mm_s", "accel_mm_s2", "speed_deg_s", "accel_deg_s2", "align_s"):
        if getattr(args, name) is not None:
            check_positive(name, getattr(args, name))
    for name, kind in (("target_um", "size_um"), ("noise_um", "sigma_um"), ("speed_mm_s", "speed_mm_s"),
                       ("accel_mm_s2", "accel_mm_s2"), ("speed_deg_s", "speed_deg_s"),
                       ("accel_deg_s2", "accel_deg_s2"), ("align_s", "time_s")):
        if getattr(args, name) is not None:
            check_plausible(name, getattr(args, name), kind)  # 1e300 µm overflowed, 1e308 s summed to infinity
    if not (args.settle_s >= 0 and args.settle_s < 3600):
        raise DataError(f"must be 0 to 3600 s, got {args.settle_s}", parameter="--settle-s")
    if args.detect_um is not None and not 0.0 < args.detect_um < 1e6:
        raise DataError(f"must be a size in µm above 0, got {args.detect_um}", parameter="--detect-um")
    if not 0.0 < args.power < 1.0:
        raise DataError(f"must be between 0 and 1, got {args.power}", parameter="--power")
    for name in ("count", "samples", "blocks"):
        v = getattr(args, name)
        if v is not None and not 0 < v <= 100_000:
            raise DataError(f"must be 1 to 100000, got {v}", parameter="--" + name)
    if args.drift_checks is not None and not 0 <= args.drift_checks <= 100_000:
        raise DataError(f"must be 0 to 100000, got {args.drift_checks}", parameter="--drift-checks")
    if args.count is not None and (args.target_um is not None or args.param):
        raise DataError("or targets (--target-um, --param): choose one", parameter="--count")
    if args.data is not None and args.augment is None:
        raise DataError("is for --augment FIT.json (the alignments the fit was made from)", parameter="--data")
    if args.augment is not None:
        if args.data is None:
            raise DataError("needs --data OBS.csv: the alignments already measured", parameter="--augment")
        for name in ("detect", "detect_um"):
            if getattr(args, name):
                raise DataError("plans a first measurement; with --augment the fit has chosen its model",
                                parameter="--" + name.replace("_", "-"))
        machine, loaded, measured = _augment_inputs(args.augment, args.data, args.machine, args)
    elif args.machine is None:
        raise DataError("give the machine (--machine URDF), or --augment FIT.json --data OBS.csv", parameter="--machine")
    else:
        machine = load_machine(args.machine)
    solve = solved_axes(machine, None if args.solve is None else [s.strip() for s in args.solve.split(",") if s.strip()])
    if args.board and args.marks_mm:
        raise DataError("or --marks-mm: choose one", parameter="--board")
    if args.board:
        from kinid.vision import load_board

        from ..data import board_mark_mm, default_board_origin_mm

        board = load_board(args.board)
        origin = default_board_origin_mm(board)  # as observe places it: centred on the workpiece origin
        marks = np.array([board_mark_mm(board, r, c, origin) for r in range(board.rows) for c in range(board.cols)])
    else:
        marks = np.array(args.marks_mm or PATENT_MARKS_MM, float)
    if not np.all(np.isfinite(marks)) or np.abs(marks).max() > 100_000:
        raise DataError("marks must be finite and within 100 m", parameter="--marks-mm")
    presets = _ranges(args.range, machine, solve, measured=None if args.augment is None else measured.axes)
    rng = np.random.default_rng(0)
    pool = candidate_poses(machine, marks, presets, solve=solve, samples=args.samples, rng=rng)
    travel = TravelModel(args.speed_mm_s, args.accel_mm_s2, args.speed_deg_s, args.accel_deg_s2, args.settle_s,
                         args.align_s)
    if args.augment is not None:
        default = _ranges(args.range, machine, solve)
        narrowed = [a for a, v in presets.items() if not np.array_equal(v, default[a])]
        return _run_augment(args, machine, loaded, measured, pool, presets, travel, _pairs(args.param, "param"),
                            sampled=not solve, narrowed=narrowed)
    effects = model_effects(machine, args.add)
    noise_um = 1.0 if args.noise_um is None else args.noise_um
    wide = advice_pool(machine, marks, solve=solve, rng=rng)
    plan = plan_measurement(
        machine, pool, effects=effects, noise_um=noise_um, target_um=args.target_um,
        param_targets=_pairs(args.param, "param"), count=args.count,
        detect=_pairs(args.detect, "detect", machine, effect=True), detect_um=args.detect_um, power=args.power,
        travel=travel,
        blocks=args.blocks, reference=not args.no_reference, drift_checks=args.drift_checks, advice_pool=wide)
    write_observations(args.out, plan.obs, machine)
    if args.json:
        from kinid.files import strict_json

        print(strict_json(plan_summary(plan, machine), indent=1))
    else:
        print(plan_text(plan, machine, presets, sampled=not solve))
        print(f"plan written to {args.out}")
    return 0


def plan_summary(plan, machine) -> dict:
    """The plan's figures as a JSON-ready mapping."""
    return {
        "alignments": len(plan.obs), "chosen": len(plan.chosen), "candidates": len(plan.candidates.obs),
        "noise_um": plan.noise_um, "target_um": plan.target_um,
        "tool_point_U_k2_um": plan.u_tool_um, "tool_point_U_k2_worst_pose_um": plan.u_tool_worst_um,
        "held_out_3d_rms_expected_um": plan.u_tool_um / 2 * 3**0.5,
        "parameters_U_k2": {n: {"U": u, "target": t} for n, (u, t) in plan.u_params.items()},
        "bound_alignments": plan.bound_count, "efficiency": plan.efficiency,
        "detect": {n: {"size": s, "power": p} for n, (s, p) in plan.powers.items()},
        "detects": None if plan.reach is None else {
            "size_um": plan.reach.size_um, "power": plan.reach.power, "candidates": plan.reach.probes,
            "added": plan.reach.added, "weakest": plan.reach.weakest, "weakest_power": plan.reach.weakest_power,
            "unreachable": list(plan.reach.unreachable)},
        "drift_checks": None if getattr(plan, "checks", None) is None else {
            "count": plan.checks.count, "interval_s": plan.checks.interval_s, "size_um": plan.checks.size_um,
            "power": plan.checks.power, "weakest": plan.checks.weakest, "weakest_power": plan.checks.weakest_power,
            "probes": plan.checks.probes, "most": plan.checks.most, "unreachable": list(plan.checks.unreachable)},
        "machine_time_s": plan.order.total_s, "moving_s": plan.order.move_s, "blocks": plan.order.blocks,
        "time_correlation": plan.order.correlation,
        "held": [{"name": a.name, "message": a.message,
                  "advice": None if a.poses is None else {"alignments": len(a.poses), "seconds": a.seconds,
                                                          "poses": a.text(machine)}} for a in plan.advice],
        "travel": plan.travel.describe(),
    }


def plan_text(plan, machine, presets=None, sampled: bool = False) -> str:
    """What a user reads: the count, the promise and its bound, the time, what stays undetermined."""
    import numpy as np

    n, k = len(plan.obs), len(plan.chosen)
    lines = []
    if presets and sampled:
        ranges = ", ".join(f"{a} {np.min(v):g}…{np.max(v):g}" for a, v in presets.items())
        lines.append(f"candidates: {len(plan.candidates.obs)} configurations drawn uniformly within {ranges}")
    elif presets:
        grid = " × ".join(f"{a} {_grid_text(v)}" for a, v in presets.items())
        lines.append(f"candidates: {len(plan.candidates.obs)} alignments ({grid}, every mark; those within the travel)")
    repeats = n - k
    lines.append(f"plan: {n} alignments ({k} chosen" + (f" + {repeats} repeats of a reference alignment" if repeats else "")
                 + ")")
    lines.append(f"tool point: U = {plan.u_tool_um:.3g} µm (k = 2, per coordinate, RMS over the candidates' poses; worst "
                 f"pose {plan.u_tool_worst_um:.3g} µm) for reading noise σ = {plan.noise_um:.3g} µm"
                 + (f" — target {plan.target_um:g} µm" if plan.target_um else ""))
    lines.append(f"  expected held-out 3-D RMS {plan.u_tool_um / 2 * 3**0.5:.3g} µm")
    for name, (u, t) in plan.u_params.items():
        lines.append(f"{name}: U = {u:.3g} (k = 2) — target {t:g}")
    if plan.bound_count:
        lines.append(f"no plan from these candidates meets the target with fewer than {plan.bound_count} alignments "
                     f"(the convex relaxation's bound); this plan is {plan.efficiency:.0%} efficient")
    for name, (size, p) in plan.powers.items():
        lines.append(f"{name} of size {size:g}: detected with probability {p:.2f}")
    if plan.reach is not None:
        r = plan.reach
        lines.append(f"detects: every error of the diagnosis's {r.probes} candidates that leaves {r.size_um:g} µm at the "
                     f"tool (2·RMS per coordinate of what the model cannot absorb), with probability ≥ {r.power:g} "
                     f"({r.added} alignments added for it; the least sure {r.weakest}, {r.weakest_power:.2f})")
        if r.unreachable:
            lines.append(f"  not even every candidate detects {', '.join(r.unreachable)} at that size: not planned for")
    o = plan.order
    if getattr(plan, "checks", None) is not None:
        c = plan.checks
        lines.append(f"drift checks: the first alignment read {c.count} times over the run, the last among them, at "
                     f"most {c.interval_s / 60:.1f} min apart")
        if c.size_um:
            seen = f"{c.weakest} {c.weakest_power:.2f}" if c.weakest else "none"
            lines.append(f"  a drift or warm-up that would move the cold machine's prediction by {c.size_um:g} µm: "
                         + (f"{len(c.unreachable)} of the diagnosis's {c.probes} time candidates stay below "
                            f"probability {c.power:g} even at {c.most} checks; " if c.unreachable else "")
                         + f"the least sure of the rest {seen}")
    corr = ", ".join(f"{a} {v:+.2f}" for a, v in o.correlation.items())
    lines.append(f"machine time ≈ {o.total_s / 60:.1f} min ({o.move_s / 60:.1f} min moving and settling; "
                 f"{plan.travel.describe()})")
    lines.append(f"order: {o.blocks} block{'s' if o.blocks > 1 else ''}"
                 + (", each over every axis's range, every other one backwards" if o.blocks > 1 else "")
                 + (", a reference alignment at every block's start and at the end"
                    if o.blocks > 1 and o.reference >= 0 and getattr(plan, "checks", None) is None else "")
                 + f"; correlation of time with each axis: {corr}")
    if plan.advice:
        from ..planning import advice_lines

        lines.append(f"held: {len(plan.advice)} parameters no candidate determines")
        lines += [f"  - {line}" for line in advice_lines(plan.advice, machine)]
    return "\n".join(lines)


def _grid_text(v) -> str:
    import numpy as np

    v = np.asarray(v, float)
    if len(v) == 1:
        return f"{v[0]:g}"
    steps = np.diff(v)
    if len(v) > 2 and np.allclose(steps, steps[0]):
        return f"{v[0]:g}…{v[-1]:g} step {steps[0]:g}"
    return "{" + ", ".join(f"{x:g}" for x in v[:6]) + (" …}" if len(v) > 6 else "}")


def _augment_inputs(fit_path, data_path, machine_path, args):
    """(machine, fit, measured observations) of ``--augment``, the data read as identify reads them (an instrument
    export with the export options of ``args``, every target of several); DataError where they do not belong
    together: a --machine other than the fit's, data with another machine's axis columns, a fit that does not
    describe the data."""
    import csv

    import numpy as np

    from ..fitting import design, load_fit, residuals
    from ..model import evaluate, load_machine

    loaded = load_fit(fit_path)
    machine = loaded.machine
    if machine_path is not None:
        given = load_machine(machine_path)
        same = (given.axis_names == machine.axis_names
                and [e.code for e in given.error_joints] == [e.code for e in machine.error_joints])
        if same:
            rng = np.random.default_rng(0)
            q = np.column_stack([rng.uniform(-30, 30, 20) for _ in machine.axes])
            zero = np.zeros((20, len(machine.error_joints)))
            same = np.abs(evaluate(given, q, zero, jacobian=False) - evaluate(machine, q, zero, jacobian=False)).max() < 1e-6
        if not same:
            raise DataError(f"{machine_path} is not the machine {fit_path} was fitted on ({machine.path}, its URDF kept "
                            f"in the fit): leave --machine out, or give the fit of this machine", parameter="--machine")
    if is_observation_file(data_path):
        with open(data_path, newline="", encoding="utf-8", errors="replace") as f:
            header = next(csv.reader(line for line in f if line.strip() and not line.startswith("#")), [])
        known = {a.column for a in machine.axes} | {"wx_mm", "wy_mm", "wz_mm", "mark_dx_mm", "mark_dy_mm", "mark_dz_mm"}
        alien = [h for h in header if (h.endswith("_mm") or h.endswith("_deg")) and h not in known
                 and not h.startswith("shift_")]
        if alien:
            raise DataError(f"column {alien[0]!r} is an axis the machine of {fit_path} lacks (its axes: "
                            f"{', '.join(a.column for a in machine.axes)}): data of another machine?", path=data_path)
    measured, _ = read_data(data_path, machine, args, together=True)
    r = residuals(machine, design(machine, loaded.effects, measured), measured, loaded.theta, jacobian=False)
    typical = float(np.median(np.linalg.norm(r, axis=1))) / np.sqrt(3.0)
    scale = max(loaded.rms_um if np.isfinite(loaded.rms_um) else 0.0, loaded.noise_um, 1e-3)
    if typical > 5.0 * scale:
        raise DataError(f"{fit_path} does not describe these data (median residual {typical:.3g} µm per coordinate "
                        f"against the fit's RMS {scale:.3g} µm): a fit of another machine or of other data?",
                        path=data_path)
    return machine, loaded, measured


def _run_augment(args, machine, loaded, measured, pool, presets, travel, param_targets, sampled: bool,
                 narrowed=()) -> int:
    from ..data import write_observations
    from ..model import model_effects
    from ..planning import augment_plan

    effects = tuple(loaded.effects) + tuple(e for e in model_effects(machine, args.add) if e not in loaded.effects
                                             and e.name not in loaded.effect_names)
    noise_um = loaded.noise_um if args.noise_um is None else args.noise_um
    hints = suspected(machine, measured, effects, args.noise_um)
    aug = augment_plan(machine, measured, pool, effects, noise_um=noise_um, target_um=args.target_um,
                       param_targets=param_targets, count=args.count, travel=travel, blocks=args.blocks,
                       reference=not args.no_reference, drift_checks=args.drift_checks, suspects=hints)
    if len(aug.plan.obs):
        write_observations(args.out, aug.plan.obs, machine)
    if args.json:
        from kinid.files import strict_json

        summary = plan_summary(aug.plan, machine) if len(aug.plan.obs) else {"alignments": 0}
        summary.update(suspects={h.effect: {"p_value": h.p_value, "threshold": h.threshold} for h in hints})
        summary.update(measured=aug.measured, tool_point_U_k2_measured_um=aug.u_measured_um, effects=list(aug.effects),
                       settled_by_the_order=list(aug.settled), noise_um=noise_um, target_um=args.target_um)
        print(strict_json(summary, indent=1))
        return 0
    print(augment_text(aug, machine, presets, args.data, args.augment, sampled=sampled, suspects=hints))
    if narrowed:
        print(f"note: the candidates keep within the span the measured data read on {', '.join(narrowed)} "
              f"(--range to go beyond)")
    if args.noise_um is None:
        print(f"note: planned for the fit's σ = {noise_um:.3g} µm (from its {loaded.noise_source}; --noise-um to plan "
              f"for another)")
    elif abs(loaded.noise_um - noise_um) > 0.2 * noise_um:
        print(f"note: the fit's σ is {loaded.noise_um:.3g} µm (from its {loaded.noise_source}); planned for "
              f"{noise_um:g} µm (--noise-um)")
    print(f"added alignments written to {args.out}" if len(aug.plan.obs) else f"nothing to add; {args.out} not written")
    return 0


def suspected(machine, measured, effects, noise_um) -> tuple:
    """The effects the measured data hint at without establishing them, given the fit's model: the diagnosis of
    ``identify --auto`` (its score test) on the measured alignments (:func:`~kinid.identification.planning.suspects_of`)."""
    from ..diagnosis import diagnose
    from ..planning import suspects_of

    return suspects_of(diagnose(machine, measured, effects, noise_um=noise_um), effects)


def augment_text(aug, machine, presets, data_path, fit_path, sampled: bool = False, suspects=()) -> str:
    """What a user reads of a sequential design: the measured, the model planned for, the added and the promise of both."""
    from ..model import default_model

    plan = aug.plan
    base = {e.name for e in default_model(machine)} | {h.effect for h in suspects}
    extra = [n for n in aug.effects if n not in base]
    model = "the default model" + (" + " + ", ".join(extra) if extra else "")
    lines = [f"measured: {aug.measured} alignments ({data_path}); the model of {fit_path}: {model}"
             + (f" ({', '.join(aug.settled)}: settled by the order, not by the poses)" if aug.settled else "")]
    for h in suspects:
        planned = plan.powers.get(h.effect)
        lines.append(f"  suspected: {h.effect} (p = {h.p_value:.2g}, the diagnosis's threshold {h.threshold:.2g}): "
                     + (f"planned for with the model; the measured and added detect it at its estimated size with "
                        f"probability {planned[1]:.2f}" if planned else
                        "driven by time or the approach direction: the order settles it, not the poses"))
    target = f" — target {plan.target_um:g} µm" if plan.target_um else ""
    lines.append(f"  measured alone: U = {aug.u_measured_um:.3g} µm (k = 2, per coordinate, RMS over the candidates' "
                 f"poses) for reading noise σ = {plan.noise_um:.3g} µm{target}")
    if not len(plan.obs):
        lines.append("the measured alignments meet the targets for this model: nothing to add")
        return "\n".join(lines)
    text = plan_text(plan, machine, presets, sampled=sampled).splitlines()
    for line in text:
        if line.startswith("plan: "):
            line = "added: " + line[len("plan: "):]
        elif line.startswith("tool point: "):
            line = "measured and added: " + line[len("tool point: "):]
        elif line.startswith("no plan from these candidates"):
            line = (f"no fewer than {plan.bound_count} added alignments from these candidates meet the target with "
                    f"the measured ones (the convex relaxation's bound, the measured information fixed); this choice "
                    f"is {plan.efficiency:.0%} efficient")
        lines.append(line)
    return "\n".join(lines)
