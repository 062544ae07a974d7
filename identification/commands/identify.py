"""``kinid identify``, ``predict``, ``simulate``, ``diagnose`` and ``demo`` (docs/cli.md)."""
from __future__ import annotations

import sys
from pathlib import Path

from kinid.errors import DataError
from kinid.options import add_json_option, csv_rows, json_file
from kinid.progress import step
from .data_input import (add_export_options, export_options_text, is_observation_file, read_data, refuse_export,
                         stated_std_of)

# NumPy and the modules that do the work are imported inside the function that runs the verb:
# building the parsers (``kinid identify --help``) imports none of them.

__all__ = ["register"]


def register(sub) -> None:
    p = sub.add_parser("identify", help="fit the default model plus added effects to alignment observations",
                       description="Fit the machine's error model to alignment observations: every location error "
                                   "of the URDF as a constant, plus the effects given with --add, or added one by one "
                                   "with --auto while the data ask for them. Prints the identified errors with their "
                                   "standard deviations and writes the fit (FIT.json) that diagnose, predict and "
                                   "compensate read (docs/identification.md).")
    p.add_argument("--machine", required=True, help="machine URDF (docs/machines.md)")
    p.add_argument("--data", required=True,
                   help="observation CSV, or an instrument export (a tracker's or motion capture's table; "
                        "docs/formats.md, 'Instrument exports')")
    add_export_options(p)
    p.add_argument("--add", nargs="+", action="extend", default=[], metavar="EFFECT", help="effects to add, e.g. EXX:periodic:10")
    p.add_argument("--noise-um", type=float, default=None, help="σ of one residual coordinate, µm (default: from the residuals)")
    p.add_argument("--auto", action="store_true", help="add effects one by one from the candidate library while the data ask for them")
    p.add_argument("--report", default=None, metavar="DIR", help="write the report (plots, residuals.csv, HTML) to DIR; with --auto, of every step")
    p.add_argument("--out", required=True, help="fit JSON to write")
    p.add_argument("--target-um", type=float, default=None, metavar="U",
                   help="the plan's target: say whether the final model's tool point is within U (k = 2, per "
                        "coordinate, RMS over the poses the data span) and, if not, the kinid plan --augment command "
                        "that plans the alignments to add (docs/plan.md)")
    p.add_argument("--no-robust", action="store_true",
                   help="keep gross errors (alignments beyond the Bonferroni χ²₃ bound at 0.001) instead of "
                        "setting them aside")
    p.add_argument("--allow-outside-limits", action="store_true",
                   help="accept readings outside the axis travel given by the URDF joint limits")
    p.add_argument("--prior", action="store_true",
                   help="for few, noisy alignments: a prior on the size of every location error (not the set-up), "
                        "its scale and σ chosen by the marginal likelihood; the fit is the maximum a posteriori "
                        "estimate (docs/identification.md)")
    p.add_argument("--no-check", action="store_true",
                   help="with --prior: skip the held-out check (the prior's fit against the plain fit, nested "
                        "cross-validation; about 10 s for 23 poses of a six-joint arm)")
    p.add_argument("--prior-um", type=float, default=None, metavar="S",
                   help="with --prior: the typical size of a location error along an axis, µm (default 1000)")
    p.add_argument("--prior-urad", type=float, default=None, metavar="S",
                   help="with --prior: the typical size of a location error about an axis, µrad (default 1000)")
    add_json_option(p, json_file("out"), "the fit (FIT.json)")
    p.set_defaults(run=_identify)

    p = sub.add_parser("predict", help="axis readings at which the fitted machine aligns the tool point with each mark",
                       description="Solve, for each pose of a CSV, the axis readings at which the fitted machine puts "
                                   "the tool point on the mark: the commands a compensated program would send.")
    p.add_argument("--fit", required=True, help="FIT.json written by kinid identify")
    p.add_argument("--poses", required=True, help="CSV with the observation columns without the solved axes")
    p.add_argument("--out", required=True, help="CSV to write: the poses with the solved readings")
    p.add_argument("--solve", default=None, help="axes to solve, comma-separated (default: the prismatic axes)")
    p.add_argument("--allow-outside-limits", action="store_true",
                   help="accept readings outside the axis travel given by the URDF joint limits")
    add_json_option(p, csv_rows("out"), "the rows written (one object per pose)")
    p.set_defaults(run=_predict)

    p = sub.add_parser("simulate", help="alignment readings of a machine with a known error set",
                       description="Make the observation CSV a measurement run would give on a machine whose errors "
                                   "you state: to try a plan, a model or the whole chain before the machine is free.")
    p.add_argument("--machine", required=True, help="machine URDF (docs/machines.md)")
    p.add_argument("--errors", required=True, help='JSON: effect name -> value(s), e.g. {"EX0C": 12, "EXX:periodic:10": [1.5, 0]}')
    p.add_argument("--plan", default="patent", help="'patent' (7 tilt x 12 table angles x 4 marks) or a CSV of poses")
    p.add_argument("--noise-um", type=float, default=0.0, help="σ of the reading noise, µm")
    p.add_argument("--seed", type=int, default=0, help="seed of the noise (the same seed gives the same file)")
    p.add_argument("--solve", default=None, help="axes to solve, comma-separated (default: the prismatic axes)")
    p.add_argument("--no-directions", action="store_true", help="do not write dir_<axis> columns")
    p.add_argument("--no-time", action="store_true", help="do not write the t_s column")
    p.add_argument("--stop-scatter-um", type=float, default=0.0, metavar="S",
                   help="the operator stops within about S µm of each alignment; the rows record where the mark "
                        "was seen relative to the tool point (mark_dx_mm, mark_dy_mm, mark_dz_mm)")
    p.add_argument("--out", required=True, help="observation CSV to write (docs/formats.md)")
    add_json_option(p, csv_rows("out"), "the observation rows written")
    p.set_defaults(run=_simulate)

    p = sub.add_parser("diagnose", help="compare a fit with data and rank the effects that may be missing",
                       description="Refit a model on observations, say whether what is left is noise or a missing "
                                   "effect, where (by mark, by axis), and which effects of the candidate library "
                                   "would explain it, best first; with the command that adds it.")
    p.add_argument("--fit", required=True, help="FIT.json written by kinid identify (its model is refitted)")
    p.add_argument("--data", required=True,
                   help="observation CSV, or an instrument export read as identify reads it (docs/formats.md)")
    p.add_argument("--noise-um", type=float, default=None, help="σ of one residual coordinate, µm (default: replicates, else the fit's)")
    p.add_argument("--json", action="store_true", help="print one JSON object (docs/cli.md)")
    p.add_argument("--report", default=None, metavar="DIR", help="write plots and an HTML report to DIR")
    p.add_argument("--top", type=int, default=10, help="candidates to show in the readable report")
    p.add_argument("--allow-outside-limits", action="store_true",
                   help="accept readings outside the axis travel given by the URDF joint limits")
    add_export_options(p)
    p.set_defaults(run=_diagnose)

    p = sub.add_parser("demo", help="the whole story on the built-in five-axis machine with a hidden effect",
                       description="Simulate a measurement of the shipped B/C machine with an effect the default "
                                   "model lacks, fit it, diagnose what is missing, add it and show the error fall; "
                                   "writes a report folder.")
    p.add_argument("--out", default=None, help="report folder (default: a fresh kinid-demo-<time> folder)")
    p.add_argument("--seed", type=int, default=7, help="seed of the simulated noise")
    p.add_argument("--case", choices=("library", "lead"), default="library",
                   help="hidden effect: 'library' (a 10 mm lead, a listed period) or 'lead' (a 12.7 mm lead the "
                        "library does not list: the period search finds it)")
    p.set_defaults(run=_demo, outputs={"out": "replaced folder"})


def _positive(value, name):
    import numpy as np

    from kinid.checks import check_plausible

    if value is not None and not (np.isfinite(value) and value > 0):
        raise DataError(f"{name} must be a positive number of µm, got {value}")
    if value is not None:
        check_plausible(name, value, "sigma_um")  # 1e-300 µm divided to infinity


def _axes_list(text, machine):
    if text is None:
        return None
    by_lower = {a.lower(): a for a in machine.axis_names}
    names = [t.strip() for t in text.split(",") if t.strip()]
    unknown = [n for n in names if n.lower() not in by_lower]
    if unknown:
        raise DataError(f"--solve: unknown axes {', '.join(unknown)}; this machine has {', '.join(machine.axis_names)}")
    return [by_lower[n.lower()] for n in names]


def _without_duplicates(obs):
    """``obs`` with rows that repeat an earlier row exactly left out, and a warning naming them.

    An exact copy (every reading equal) is the same measurement written twice; counted as
    more data it would make σ look smaller and the tests stricter than the data allow.
    """
    import numpy as np

    from ..data import exact_duplicates

    dup = exact_duplicates(obs)
    if not dup:
        return obs
    lines = obs.lines or tuple(range(1, len(obs) + 1))
    shown = ", ".join(f"line {lines[i]} = line {lines[j]}" for i, j in dup[:5]) + (" ..." if len(dup) > 5 else "")
    print(f"warning: {obs.source}: {len(dup)} row(s) repeat an earlier row exactly ({shown}); "
          "each measurement is used once", file=sys.stderr)
    copies = {i for i, _ in dup}
    return obs.subset(np.array([i for i in range(len(obs)) if i not in copies]))


def _refuse_untrusted(machine, obs, result, source) -> None:
    """DataError naming why ``result`` cannot be trusted (not converged, a residual far above the σ given, data
    with a unit mistake: :func:`~kinid.identification.fitting.untrusted`) and the unit mistake the data ``obs``
    (as read) point to: such a fit is not written (docs/identification.md)."""
    from ..data import unit_hints
    from ..fitting import untrusted

    why = untrusted(result, unit_hints(machine, obs))
    if why:
        raise DataError(f"{why}; no fit written", path=source)


def _identify(args) -> int:
    from ..fitting import fit, model_effects
    from ..fitting import save_fit
    from ..model import load_machine
    from ..data import ROTATION_MARK, check_row_count, warn_units

    _positive(args.noise_um, "--noise-um")
    _positive(args.target_um, "--target-um")
    machine = load_machine(args.machine)
    # the units are judged after the fit: a fit refused names the likely unit in its one line, else a warning
    read, stated = read_data(args.data, machine, args, check_units=False, together=True, orientation=True)
    read = _without_duplicates(read)
    obs = read
    check_row_count(obs, "a diagnosis" if args.auto or args.report else "a fit")
    own = is_observation_file(args.data)  # read once: the whole file is decoded to find its header
    targets = () if own else tuple(m for m in dict.fromkeys(obs.marks) if m != ROTATION_MARK)
    effects = model_effects(machine, args.add, targets=targets)
    from .board_settle import read_levers

    levers = read_levers(args.data, obs) if own else None
    if levers is not None:  # the laser beside the camera: its depths judged with the board pose fitted, before all
        from .board_settle import settle

        board = settle(machine, obs, levers, lambda o: _robust_fit(machine, o, effects, args))
        obs = board.obs
    if args.prior_um is not None or args.prior_urad is not None:
        if not args.prior:
            raise DataError("--prior-um and --prior-urad set the sizes of --prior; add --prior")
        _positive(args.prior_um, "--prior-um")
        _positive(args.prior_urad, "--prior-urad")
    if args.prior:
        if args.auto:
            raise DataError("--prior and --auto: choose one (--auto adds effects to data that show them; a prior is "
                            "for data too few to)")
        from dataclasses import replace

        from ..fitting import PRIOR_UM, PRIOR_URAD, choose_prior, held_out_check, prior_std

        sizes = dict(prior_um=args.prior_um or PRIOR_UM, prior_urad=args.prior_urad or PRIOR_URAD)
        choice = choose_prior(machine, obs, effects, noise_um=args.noise_um, **sizes)
        result = fit(machine, obs, effects, noise_um=choice.noise_um,
                     prior_std=prior_std(machine, effects, choice.scale, **sizes))
        _refuse_untrusted(machine, read, result, args.data)
        described = choice.describe()
        if not args.no_check:
            with step(f"held-out check of the prior on {len(obs)} alignments"):
                described += "; " + held_out_check(machine, obs, effects, noise_um=args.noise_um, **sizes).describe()
        result = replace(result, prior=described, board_pose={} if levers is None else board.record())
    elif args.auto:
        from ..diagnosis import forward_select

        steps = forward_select(machine, obs, effects, noise_um=args.noise_um, progress=sys.stderr,
                               robust=not args.no_robust)
        result = steps[-1].fit
        obs = steps[-1].data
        if levers is not None:
            from dataclasses import replace

            result, obs = _settled_again(machine, obs, levers, result, board, args)
            steps = [*steps[:-1], replace(steps[-1], fit=result, data=obs)]
        _refuse_untrusted(machine, read, result, args.data)
        if args.report:
            from ..reporting import selection_report

            with step(f"writing the report to {args.report}: figures, HTML and PDF"):
                selection_report(steps, obs, args.report, fit_file=args.out)
    else:
        from dataclasses import replace

        aside, kept_fit = (), None
        with step(f"fitting {len(obs)} alignments"):
            if not args.no_robust:
                from ..fitting import set_aside_with_fit

                # its fit of the rows kept, when it has one (no row set aside in its last round), is the fit
                obs, aside, kept_fit = set_aside_with_fit(machine, obs, effects, noise_um=args.noise_um)
            result = replace(kept_fit if kept_fit is not None else fit(machine, obs, effects, noise_um=args.noise_um),
                             set_aside=aside)
        if levers is not None:
            result, obs = _settled_again(machine, obs, levers, result, board, args)
        _refuse_untrusted(machine, read, result, args.data)
        if args.report:
            from ..diagnosis import diagnose
            from ..reporting import diagnosis_report

            with step(f"scoring the candidate effects against the residual of {len(obs)} alignments"):
                diagnosis = diagnose(machine, obs, effects, noise_um=args.noise_um, result=result)
            with step(f"writing the report to {args.report}: figures, HTML and PDF"):
                diagnosis_report(diagnosis, obs, args.report)
    warn_units(machine, read.subset(~read.rotation_rows))  # the orientation's rows hold no points
    result = _check_stated_std(result, obs, stated)
    save_fit(result, args.out)
    print(result.table())
    if len(targets) > 1:
        print("\n".join(_target_lines(result, targets)))
    if result.stated_std:
        print(result.stated_std["line"])
    if obs.rotation_rows.any() and result.residuals_um is not None and len(result.residuals_um) == len(obs):
        from ..fitting import orientation_residuals

        print(orientation_residuals(obs, result.residuals_um).line)
    if result.aliases:
        from ..planning import data_advice

        advice = data_advice(machine, result, obs)
        if advice:
            print("pose advice (kinid plan):")
            print("\n".join(f"  - {line}" for line in advice))
    if args.target_um is not None:
        _target_line(result, obs, args, steps[-1].diagnosis if args.auto else None)
    print(f"fit written to {args.out}")
    return 0


def _robust_fit(machine, obs, effects, args):
    """The fit of ``effects`` on ``obs`` as identify makes it without --auto (gross errors set aside unless
    --no-robust): the board pose each pass of :func:`~.board_settle.settle` takes."""
    from ..fitting import fit, set_aside_with_fit

    if args.no_robust:
        return fit(machine, obs, effects, noise_um=args.noise_um)
    kept, _, kept_fit = set_aside_with_fit(machine, obs, effects, noise_um=args.noise_um)
    return kept_fit if kept_fit is not None else fit(machine, kept, effects, noise_um=args.noise_um)


def _settled_again(machine, obs, levers, result, board, args):
    """(fit, rows): the final model's board pose checked once more; if it moves the depths beyond the noise, they
    are judged again and the final model refitted (its set-aside rows kept aside). The fit records the passes."""
    from dataclasses import replace

    from ..fitting import fit
    from .board_settle import board_move, settle

    move = board_move(machine, result, obs, levers)
    passes, moved = board.passes, (move.rms_um, move.noise_um, move.within)
    if not move.within:
        again = settle(machine, obs, levers, lambda o: fit(machine, o, result.effects, noise_um=args.noise_um),
                       first=result, start=passes + 1)
        obs, passes, moved = again.obs, passes + again.passes, (again.move_um, again.noise_um, again.settled)
        result = replace(fit(machine, obs, result.effects, noise_um=args.noise_um), set_aside=result.set_aside)
    record = {"passes": passes, "move_um": moved[0], "noise_um": moved[1], "settled": bool(moved[2])}
    return replace(result, board_pose=record), obs


def _check_stated_std(result, obs, stated):
    """``result`` with the instrument's stated std of the rows fitted checked against its residuals
    (:func:`~kinid.identification.diagnosis.check_stated_std`), when the data stated them."""
    from dataclasses import replace

    from ..diagnosis import check_stated_std

    if result.residuals_um is None or len(result.residuals_um) != len(obs):
        return result
    points = ~obs.rotation_rows  # the orientation's rows are checked on their own (orientation_residuals)
    std_mm = stated_std_of(obs.subset(points), stated)
    if std_mm is None:
        return result
    dof = result.dof if points.all() else int(result.dof * points.sum() / len(obs))  # the points' share
    check = check_stated_std(result.residuals_um[points], std_mm * 1e3, dof)
    return result if check is None else replace(result, stated_std=check.summary())


def _target_lines(result, targets) -> list:
    """One line per target of several fitted together: its point on the tool (x, y, z in the tool frame, mm, its
    set-up ``E?0T:target:<mark>``) with σ, or held where the data see it only with another term (the other
    targets' coordinate then from the held one's)."""
    import numpy as np

    values = dict(zip(result.param_names, zip(result.values, result.std, result.identifiable)))
    seen_with = {a.name: a.partners[0][0] for a in result.aliases if a.partners}
    name = {(m, c): f"E{c.upper()}0T:target:{m}" for m in targets for c in "xyz"}
    # a target's coordinate held (seen only with a machine's term): the others' are from it
    held = {c: m for m in targets for c in "xyz" if not values.get(name[m, c], (0, 0, False))[2]}
    out = ["the targets' points on the tool (E?0T:target:<mark>, in the URDF's tool frame):"]
    for mark in targets:
        parts = []
        for c in "xyz":
            v, s, ok = values.get(name[mark, c], (np.nan, np.nan, False))
            if ok:
                parts.append(f"{c} {v / 1e3:+.4f} ± {s / 1e3:.4f} mm" + (f" (from {held[c]}'s)" if c in held else ""))
            else:
                parts.append(f"{c} held" + (f" (seen only with {seen_with[name[mark, c]]})"
                                            if name[mark, c] in seen_with else ""))
        out.append(f"{mark}: tool point {', '.join(parts)}")
    return out


def _target_line(result, obs, args, diagnosis=None) -> None:
    """One line: the tool point's U the final model promises over the poses the data span, against --target-um; if
    above it, or if ``diagnosis`` (--auto's last) has suspects, the command that plans the alignments to add."""
    import shlex

    from ..planning import fit_volume_u_um, suspects_of

    u, poses = fit_volume_u_um(result, obs)
    said = (f"tool point: U = {u:.3g} µm (k = 2, per coordinate, RMS over the {poses} poses the data span) for this "
            f"model")
    hints = suspects_of(diagnosis, result.effects) if diagnosis is not None else ()
    if hints:
        said += (f" — but the data hint at {', '.join(h.effect for h in hints)} (p = "
                 f"{', '.join(f'{h.p_value:.2g}' for h in hints)}, the threshold {hints[0].threshold:.2g}), which this "
                 f"model lacks")
    if u <= args.target_um and not hints:
        print(f"{said}: within the target {args.target_um:g} µm")
    else:
        print(f"{said}: {'above' if u > args.target_um else 'within'} the target {args.target_um:g} µm; plan the "
              f"alignments to add{' and settle what the data hint at' if hints else ''}: kinid plan --augment "
              f"{shlex.quote(args.out)} --data {shlex.quote(args.data)}{export_options_text(args)} "
              f"--target-um {args.target_um:g}"
              + (f" --noise-um {args.noise_um:g}" if args.noise_um is not None else "") + " --out more.csv")


def _predict(args) -> int:
    from ..fitting import solve_axes
    from ..fitting import load_fit
    from ..data import read_observations, write_observations

    loaded = load_fit(args.fit)
    machine = loaded.machine
    solve = _axes_list(args.solve, machine)
    solve_names = solve or [a.name for a in machine.axes if a.kind == "prismatic"]
    refuse_export(args.poses, "--poses", "predict solves the axes that put the tool point on each pose's mark, "
                  "given in kinid's observation CSV (docs/formats.md); an export holds the points measured with "
                  "every axis read, nothing left to solve")
    poses = read_observations(args.poses, machine, optional_axes=solve_names, check_limits=not args.allow_outside_limits)
    out = solve_axes(machine, loaded.effects, loaded.theta, poses, solve_names)
    _warn_outside_travel(machine, out, solve_names, args.poses)
    write_observations(args.out, out, machine)
    print(f"{len(out)} poses solved for {', '.join(solve_names)}; written to {args.out}")
    return 0


def _warn_outside_travel(machine, obs, names, source) -> None:
    """One warning per solved axis whose readings leave the URDF travel: the machine cannot reach those poses."""
    import warnings

    import numpy as np

    from ..model import axis_limits

    limits = axis_limits(machine)
    for name in names:
        j = machine.axis_names.index(name)
        lo, hi = limits[j]
        q = obs.axes[:, j]
        out = np.flatnonzero((q < lo) | (q > hi))
        if out.size:
            a = machine.axes[j]
            unit = "mm" if a.kind == "prismatic" else "deg"
            beyond = float(np.max(np.maximum(lo - q[out], q[out] - hi)))
            lines = ", ".join(str(obs.lines[i]) if obs.lines else str(i + 1) for i in out[:8]) + (" …" if out.size > 8 else "")
            warnings.warn(f"{source}: {out.size} solved reading(s) of {a.column} outside the URDF travel ({lo:g} .. "
                          f"{hi:g} {unit}) by up to {beyond:.4g} {unit} (lines {lines}): the machine cannot reach "
                          f"those poses", stacklevel=2)


def _simulate(args) -> int:
    from dataclasses import replace

    import numpy as np

    from ..model import load_machine
    from ..data import write_observations
    from ..fitting import load_errors, load_plan, simulate

    if args.noise_um < 0 or not np.isfinite(args.noise_um):
        raise DataError(f"--noise-um must be zero or positive, got {args.noise_um}")
    if args.stop_scatter_um < 0 or not np.isfinite(args.stop_scatter_um):
        raise DataError(f"--stop-scatter-um must be zero or positive, got {args.stop_scatter_um}")
    machine = load_machine(args.machine)
    effects, theta = load_errors(args.errors, machine)
    solve = _axes_list(args.solve, machine)
    plan = load_plan(args.plan, machine, solve)
    obs = simulate(machine, plan, effects, theta, noise_um=args.noise_um, rng=np.random.default_rng(args.seed), solve=solve, directions=not args.no_directions,
                   stop_scatter_um=args.stop_scatter_um)
    if args.no_time:
        obs = replace(obs, t_s=None)
    write_observations(args.out, obs, machine)
    print(f"{len(obs)} alignments simulated with {len(effects)} effects, noise {args.noise_um} µm; written to {args.out}")
    return 0


def _diagnose(args) -> int:
    import numpy as np

    from kinid.files import strict_json

    from ..diagnosis import diagnose
    from ..fitting import load_fit
    from ..fitting import Noise
    from ..data import check_row_count
    from ..model import basis_of

    _positive(args.noise_um, "--noise-um")
    loaded = load_fit(args.fit)
    together = any(basis_of(e).driver == "mark" for e in loaded.effects)  # a fit of several targets together
    obs = _without_duplicates(read_data(args.data, loaded.machine, args, together=together, orientation=True)[0])
    check_row_count(obs, "a diagnosis")
    aside_lines = {a.line for a in loaded.set_aside if a.line is not None}
    if aside_lines and obs.lines:  # the rows the fit set aside as gross errors stay aside
        obs = obs.subset(np.array([i for i, ln in enumerate(obs.lines) if ln not in aside_lines]))
    carried = Noise(loaded.noise_um, "fit") if loaded.noise.known else None
    with step(f"scoring the candidate effects against the residual of {len(obs)} alignments"):
        result = diagnose(loaded.machine, obs, loaded.effects, noise_um=args.noise_um, carried_noise=carried)
    if loaded.set_aside:
        from dataclasses import replace

        result = replace(result, fit=replace(result.fit, set_aside=loaded.set_aside))
    if args.report:
        from kinid.reports.html import file_provenance
        from ..reporting import diagnosis_report

        with step(f"writing the report to {args.report}: figures, HTML and PDF"):
            diagnosis_report(result, obs, args.report, provenance=[("fit", file_provenance(args.fit))])
    if args.json:
        print(strict_json(result.summary()))
    else:
        print(result.text(top=args.top))
        if args.report:
            print(f"report written to {Path(args.report) / 'index.html'}")
    return 0


def _demo(args) -> int:
    from .demo import run_demo

    run_demo(args.out, seed=args.seed, case=args.case)
    return 0
