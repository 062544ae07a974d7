"""``kinid demo``: the main job end to end on the built-in five-axis machine with a hidden effect.

1. Simulate the patent's plan (7 B × 12 C angles × 4 marks = 336 alignments,
   1 µm reading noise) on the B/C double turntable with location errors,
   millimetre / degree set-up errors of the board, and one effect the default
   model lacks: a 10 mm-lead screw error of X (2.5 µm amplitude).
2. Fit the default model; see the residual above the noise.
3. Diagnose: the score test ranks the candidate library and names the effect.
4. Add it, refit, and watch the error fall to the noise floor; check held-out
   poses before and after.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..model import chosen_of, default_model, load_machine
from ..data import write_observations
from ..fitting import errors_from_mapping, patent_plan, simulate, solve_axes
from ..diagnosis import forward_select
from ..reporting import selection_report

__all__ = ["run_demo", "demo_truth", "HIDDEN_EFFECT", "CASES"]

#: The hidden effect of each demo case: ``library`` — a 10 mm-lead screw error of X, a period the
#: candidate library lists; ``lead`` — a half-inch lead (12.7 mm), which it does not: the period
#: search finds it.
CASES = {"library": "EXX:periodic:10", "lead": "EXX:periodic:12.7"}
HIDDEN_EFFECT = CASES["library"]
NOISE_UM = 1.0


def demo_truth(machine, rng, hidden: str = HIDDEN_EFFECT) -> dict:
    """The demo machine's true error set: effect name -> value(s)."""
    truth = {e.code: float(rng.normal(0.0, 15.0)) for e in default_model(machine)}
    truth.update({"EX0W": 1200.0, "EY0W": -800.0, "EZ0W": 150.0, "EC0W": 8700.0})  # board set-up: mm and 0.5°
    truth[hidden] = [2.2, 1.2]  # µm: amplitude 2.5 µm
    return truth


def _same_effect(added: str, hidden: str) -> bool:
    """``added`` is ``hidden``, or the same joint and basis at a period within 1 %."""
    a, h = added.split(":"), hidden.split(":")
    if a[:2] != h[:2]:
        return False
    if chosen_of(hidden) == "period" and len(h) == 3 and len(a) == 3:
        return abs(float(a[2]) - float(h[2])) <= 0.01 * float(h[2])
    return a == h


def _heldout_plan(machine, rng, n=60):
    """Poses the fit never saw: random tilt/table angles and marks."""
    plan = patent_plan(machine)
    idx = rng.choice(len(plan), size=n, replace=False)
    held = plan.subset(idx)
    axes = held.axes.copy()
    for j, a in enumerate(machine.axes):
        if a.kind == "revolute":
            axes[:, j] += rng.uniform(-7.0, 7.0, size=n)
    w = held.w_mm + np.c_[rng.uniform(-10, 10, size=(n, 2)), np.zeros(n)]
    from dataclasses import replace

    return replace(held, axes=axes, w_mm=w, t_s=None, directions={})


def _rms3(a, b) -> float:
    """3-D RMS distance between two sets of solved readings (µm)."""
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1)))) * 1e3


def run_demo(out=None, *, seed: int = 7, stream=None, case: str = "library") -> Path:
    """Run the demo, print the story to ``stream`` (default stdout) and write the report folder.

    ``case`` picks the hidden effect (:data:`CASES`).

    Returns
    -------
    Path
        The report's ``index.html``.
    """
    import sys

    say = (lambda *a: print(*a, file=stream or sys.stdout, flush=True))
    t0 = time.perf_counter()
    folder = Path(out) if out else Path(f"kinid-demo-{time.strftime('%Y%m%d-%H%M%S')}")
    from kinid.urdf import path as urdf_path

    if case not in CASES:
        from kinid.errors import DataError

        raise DataError(f"must be one of {', '.join(CASES)}, got {case!r}", parameter="case")
    hidden = CASES[case]
    from kinid.folders import check_listed_folder, listed_folder

    check_listed_folder(folder)  # a folder it could not replace is refused before the work
    machine = load_machine(urdf_path("five_axis_bc"))
    rng = np.random.default_rng(seed)
    truth = demo_truth(machine, rng, hidden)
    effects, theta = errors_from_mapping(truth, machine)
    plan = patent_plan(machine)
    say(f"kinid demo — machine {Path(machine.path).name}: axes {', '.join(machine.axis_names)}, {len(machine.error_joints)} error joints")
    say(f"[1/4] simulating the patent's plan: {len(plan)} alignments, noise σ = {NOISE_UM} µm, one hidden effect")
    obs = simulate(machine, plan, effects, theta, noise_um=NOISE_UM, rng=rng)

    held_plan = _heldout_plan(machine, rng)
    held_true = solve_axes(machine, effects, theta, held_plan)

    say("[2/4] fitting the default model (every location error and the set-up of board and sensor as constants)")
    say("[3/4] diagnosing and adding effects one at a time (score test of the candidate library, Bonferroni α = 0.01):")
    steps = forward_select(machine, obs, default_model(machine), noise_um=NOISE_UM, progress=stream or sys.stdout)
    first, last = steps[0], steps[-1]
    lines = []
    for s in steps:
        pred = solve_axes(machine, s.fit.effects, s.fit.theta, held_plan)
        err = _rms3(pred.axes[:, :], held_true.axes[:, :])
        lines.append((s.added or "default model", s.diagnosis.rms_um, err, s.diagnosis.verdict))
    say("")
    say(first.diagnosis.text(top=5))
    say("")
    say("[4/4] the error falls:")
    say(f"  {'model':<28} {'residual RMS':>12} {'held-out 3-D RMS':>17}  verdict")
    for name, rms, err, verdict in lines:
        say(f"  {name:<28} {rms:10.3f} µm {err:14.3f} µm  {verdict}")
    added = [s.added for s in steps[1:]]
    match = next((a for a in added if _same_effect(a, hidden)), None)
    say(f"hidden effect: {hidden} (truth {np.hypot(*truth[hidden]):.2f} µm amplitude) — "
        + (f"found and added as {match}" if match else f"NOT found (added: {', '.join(added) or 'nothing'})"))
    if match is not None:
        note = next((c.note for s in steps for c in s.diagnosis.live if c.effect == match and c.note), "")
        if note:
            say(f"  {note}")
        k = last.fit.effect_names.index(match)
        start = sum(e.n_params for e in last.fit.effects[:k])
        a, b = last.fit.values[start : start + 2]
        sa, sb = last.fit.std[start : start + 2]
        say(f"  identified: sin {a:.3f} ± {sa:.3f} µm, cos {b:.3f} ± {sb:.3f} µm (± 1σ; truth {truth[hidden][0]}, {truth[hidden][1]})")
    from kinid.progress import Progress

    from ..fitting import save_fit

    # the report takes seconds (its figures and PDF): one line on stderr says what the wait is for
    progress = Progress(stream=sys.stderr)  # on a terminal, as every progress line: a script's stderr keeps its errors
    if progress.enabled:
        progress.say("writing the report: figures, HTML and PDF …")
    # the run's files, written whole into a new folder that replaces ``folder`` at the end
    with listed_folder(folder, written_by="kinid demo") as stage:
        write_observations(stage / "observations.csv", obs, machine)
        save_fit(steps[0].fit, stage / "fit_default.json")
        save_fit(last.fit, stage / "fit.json")  # the report's next step, kinid compensate --fit fit.json, runs here
        held_out = ("held-out 3-D RMS (µm)", [e for _, _, e, _ in lines],
                    f"the tool point's 3-D error at {len(held_plan)} poses the fit did not see, against the simulated truth")
        page = selection_report(steps, obs, stage, held_out=held_out, whole=False,  # beside the demo's own files
                                fit_file="fit.json")
    page = folder / Path(page).relative_to(stage)
    say(f"report: {page}   ({time.perf_counter() - t0:.1f} s)")
    return page
