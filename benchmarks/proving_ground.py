"""Proving ground of the diagnosis: how often ``identify --auto`` ends right on machines nobody described.

Run: ``python benchmarks/proving_ground.py [--scenarios N] [--seed S] [--kinds K ...] [--json OUT] [--figure PNG]``;
the table and figure of several runs together: ``python benchmarks/proving_ground.py --merge A.json B.json ...
[--figure PNG]``; the scenarios a run recorded, again (before and after a change to kinid):
``python benchmarks/proving_ground.py --rerun A.json [--kinds K ...] --json B.json``. With ``--kinds``, each
scenario has one hidden effect of the kinds named, in turn; the families of shapes nobody named
(benchmarks/proving_families.py: ``smooth-1``, ``smooth-2``, ``step``, ``instrument``) are drawn only so, and
each is its own class in the table.

Each scenario is drawn from a seeded generator (:func:`draw`):

- **a machine**: each shipped five-axis layout (B/C, A/C, B-head + C), the dual-Y gantry, or a
  six-joint arm with location-error joints only; its constant location errors drawn at random
  (5–40 µm / µrad; the set-up of board and sensor, millimetres);
- **a plan and its order**: the patent plan (7 tilts × 12 turns × 4 marks), a smaller and a larger
  grid, a random half; visited axis-major (the tilt as the outer loop: time follows the tilt),
  serpentine, or in random order; arms at random configurations;
- **hidden effects**, most outside kinid's vocabulary: a lead of a period off any list, a short
  rotary period (a worm gear of 36–90 teeth), polynomial straightness and sag, a local bump, a
  saturating warm-up A·(1 − e^(−t/τ)), an error of one axis growing with another axis's position,
  a gear error of an arm joint, a linear drift; none, one, or two or three at once;
- **faults**: misreads (10–40 µm) in 0–5 % of rows, readings quantised to 0.1 µm / 0.0001°, linear axes read
  where an alignment stopped them (0.5–3 µm from where the plan sent them, in 30 % of scenarios: repeated
  poses are not read alike), σ declared correctly, 0.3–3× the true 1 µm, or not at all.

The truth (benchmarks/proving_truth.py) is plain numpy on the URDF text. kinid sees the rows as a
user would give them, runs ``forward_select`` (``identify --auto``), and the final model predicts
20 % of the plan held out (noise-free truth). The oracle is the true structure: the default model
and each hidden effect's exact shape with its size free (a basis registered for it here), fitted on
the same rows with the misreads known and left out. A scenario with hidden effects passes when the
final held-out 3-D RMS is ≤ 1.5× the oracle's, or the final verdict is "missing-effect" naming an
axis the hidden effect involves (the axis of an error whose period the selection says the positions do not
determine; else its best candidate's when that is significant — and the other's of a pair it names inseparable
and adds neither of; else the axis along which the neighbour test finds the residual most structured). Printed per class: pass rate, median
and worst held-out/oracle, the share worse than the default model (by > 5 %), on no-effect
scenarios with σ given correctly the share that added anything, and the pass rate against the
stricter floor of earlier runs ("pass/floor": the default model fitted on rows of the machine
without the hidden effects and the faults). The held-out share of a small plan is a dozen poses, so
"worse" is also judged on every pose of the plan ("on plan": the final and the default model's error
against the noise-free truth at all poses, the fitted ones included — for a fixed set of poses its
expectation is the held-out error less the noise, from five times the poses), and by how far beyond
the spread between the held-out poses it is ("> 2 SE": more than 5 % worse by more than two standard
errors of the pose-by-pose difference of the squared errors, final − 1.05² × default). The table
counts the scenarios worse than the default model; the JSON keeps each one's ``worse_z``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(Path(__file__).resolve().parent))
import proving_families as families  # noqa: E402
import proving_truth as truth  # noqa: E402

NOISE_UM = 1.0
HELD_OUT_SHARE = 0.2
LAYOUTS = ("five_axis_bc", "five_axis_ac", "five_axis_bhead_c", "gantry_dual_y", "arm6")


# -- machines ---------------------------------------------------------------------------------------
def arm6_urdf() -> str:
    """A six-joint arm with location-error joints only, written with kinid's URDF builder (what a user
    would give kinid); the truth reads the text."""
    from kinid.identification.model.urdf_builder import Axis, Fixed, machine_urdf, setup

    pi = np.pi
    loc = ("X", "Y", "Z", "A", "B", "C")
    tool = [Axis("J1", "revolute", (0, 0, 1), location_errors=loc, pdge=False, limit=(-pi, pi)),
            Fixed("shoulder", (0, 0, 0.30)),
            Axis("J2", "revolute", (0, 1, 0), location_errors=loc, pdge=False, limit=(-pi, pi)),
            Fixed("upper_arm", (0.35, 0, 0)),
            Axis("J3", "revolute", (0, 1, 0), location_errors=loc, pdge=False, limit=(-pi, pi)),
            Fixed("forearm", (0.30, 0, 0)),
            Axis("J4", "revolute", (1, 0, 0), location_errors=loc, pdge=False, limit=(-pi, pi)),
            Fixed("wrist1", (0.08, 0, 0)),
            Axis("J5", "revolute", (0, 1, 0), location_errors=loc, pdge=False, limit=(-pi, pi)),
            Fixed("wrist2", (0.06, 0, 0)),
            Axis("J6", "revolute", (1, 0, 0), location_errors=loc, pdge=False, limit=(-pi, pi)),
            Fixed("flange", (0.05, 0.02, 0.03)), setup("T")]
    return machine_urdf("arm6", [Fixed("table", (0.45, 0.0, 0.0)), setup("W")], tool, "six-joint arm, proving ground")


def urdf_text(layout: str) -> str:
    if layout == "arm6":
        return arm6_urdf()
    from kinid.urdf import path

    return Path(path(layout)).read_text()


# -- hidden effects: plain formulas of the readings (mm, deg) and time (s) -----------------------------
@dataclass(frozen=True)
class Hidden:
    kind: str
    joint: str
    axes: tuple  # the axes (or "time") a right diagnosis names
    value: object  # callable(readings dict, t_s) -> array (N,) in µm / µrad
    how: str = ""  # the shape drawn, for the record (the families of random shapes)

    def __call__(self, r, t):
        return self.value(r, t)


def _half(lo, hi, default):
    return default if not np.isfinite(lo) else 0.5 * (hi - lo)


def hidden_effects(tm, kind: str, rng, ranges: dict) -> list:
    """One hidden effect of ``kind`` on this machine (empty when the machine has no place for it)."""
    linear = [a for a in tm.motion if tm.kind(a) == "prismatic"]
    rotary = [a for a in tm.motion if tm.kind(a) != "prismatic"]
    has = set(tm.errors)

    def pick(options):
        options = [o for o in options if o[0] in has]
        return options[rng.integers(len(options))] if options else None

    def span(a):
        lo, hi = ranges[a]
        return 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-6)

    if kind == "lead" and linear:
        a = linear[rng.integers(len(linear))]
        if f"E{a}{a}" not in has:
            return []
        period, amp, ph = rng.uniform(3.0, 40.0), rng.uniform(1.5, 4.0), rng.uniform(0, 2 * np.pi)
        return [Hidden(kind, f"E{a}{a}", (a,), lambda r, t: amp * np.sin(2 * np.pi * r[a] / period + ph))]
    if kind == "rotary-period" and rotary:
        a = rotary[rng.integers(len(rotary))]
        choice = pick([(f"E{a}{a}", a), (f"EX{a}", a), (f"EY{a}", a), (f"EZ{a}", a)])
        if choice is None or a.startswith("J"):
            return []
        teeth = int(rng.integers(36, 91)) if rng.random() < 0.6 else int(rng.integers(1, 9))
        amp = rng.uniform(8.0, 20.0) if choice[0] == f"E{a}{a}" else rng.uniform(2.0, 5.0)
        ph = rng.uniform(0, 2 * np.pi)
        return [Hidden(kind, choice[0], (a,), lambda r, t: amp * np.sin(np.radians(r[a]) * teeth + ph))]
    if kind in ("straightness", "sag") and linear:
        a = linear[rng.integers(len(linear))]
        others = [c for c in "XYZ" if c != a and f"E{c}{a}" in has] if len(a) == 1 else []
        if not others:
            return []
        c = "Z" if kind == "sag" and "Z" in others else others[rng.integers(len(others))]
        mid, half = span(a)
        amp = rng.uniform(3.0, 8.0)
        if kind == "sag":
            return [Hidden(kind, f"E{c}{a}", (a,), lambda r, t: -amp * ((r[a] - mid) / half) ** 2)]
        b = rng.uniform(-1, 1)
        return [Hidden(kind, f"E{c}{a}", (a,), lambda r, t: amp * (((r[a] - mid) / half) ** 2 * b
                                                                  + ((r[a] - mid) / half) ** 3))]
    if kind == "bump" and linear:
        a = linear[rng.integers(len(linear))]
        if f"E{a}{a}" not in has:
            return []
        lo, hi = ranges[a]
        centre = rng.uniform(lo + 0.2 * (hi - lo), hi - 0.2 * (hi - lo))
        fwhm, amp = rng.uniform(8.0, 20.0), rng.uniform(3.0, 6.0) * rng.choice([-1, 1])
        s = fwhm / 2.3548
        return [Hidden(kind, f"E{a}{a}", (a,), lambda r, t: amp * np.exp(-0.5 * ((r[a] - centre) / s) ** 2))]
    if kind == "warm-up":
        joint = pick([(f"E{c}0T", "T") for c in "XYZ"])
        if joint is None:
            return []
        amp, tau = rng.uniform(3.0, 10.0) * rng.choice([-1, 1]), rng.uniform(600.0, 2400.0)
        return [Hidden(kind, joint[0], ("time",), lambda r, t: amp * (1 - np.exp(-t / tau)))]
    if kind == "drift":
        joint = pick([(f"E{c}0T", "T") for c in "XYZ"])
        if joint is None:
            return []
        rate = rng.uniform(2.0, 6.0) * rng.choice([-1, 1]) / 3600.0
        return [Hidden(kind, joint[0], ("time",), lambda r, t: rate * t)]
    if kind == "cross-axis" and len(linear) >= 2:
        a, b = rng.choice(linear, 2, replace=False)
        if f"E{a}{a}" not in has:
            return []
        mid, half = span(b)
        amp = rng.uniform(2.0, 5.0) * rng.choice([-1, 1])
        mid_a, half_a = span(a)
        # positioning of a that grows along a, at a rate set by where b stands (a thermal gradient)
        return [Hidden(kind, f"E{a}{a}", (a, b), lambda r, t: amp * ((r[a] - mid_a) / half_a) * ((r[b] - mid) / half))]
    if kind == "gear" and rotary:
        a = [j for j in rotary if j.startswith("J")]
        if not a:
            return []
        j = a[rng.integers(len(a))]
        code = next((c for c in (f"EB0{j}", f"EA0{j}", f"EC0{j}") if c in has and _turns_about(tm, c, j)), None)
        if code is None:
            return []
        period, amp, ph = rng.uniform(20.0, 60.0), rng.uniform(40.0, 100.0), rng.uniform(0, 2 * np.pi)
        return [Hidden(kind, code, (j,), lambda r, t: amp * np.sin(2 * np.pi * r[j] / period + ph))]
    return []


def _turns_about(tm, code, joint) -> bool:
    """Whether error joint ``code`` turns about the same axis as motion joint ``joint``."""
    by_name = {j.name: j for j in tm.joints.values()}
    e, m = by_name[code], by_name[joint]
    return e.kind == "revolute" and abs(abs(float(np.dot(e.axis, m.axis))) - 1.0) < 1e-9


KINDS = ("none", "lead", "rotary-period", "straightness", "sag", "bump", "warm-up", "drift", "cross-axis", "gear")


# -- plans ----------------------------------------------------------------------------------------------
def plan(tm, layout: str, rng, kind=None, order=None):
    """(name, readings dict (N,), order name[, mark labels]) for the scenario; readings in visiting order.
    ``kind`` and ``order`` fix what is otherwise drawn."""
    if layout == "arm6":
        n = int(rng.choice([80, 150, 300]))
        lims = {"J1": (-90, 90), "J2": (-80, -10), "J3": (20, 120), "J4": (-90, 90), "J5": (-90, 90), "J6": (-180, 180)}
        r = {j: rng.uniform(*lims[j], n) for j in tm.motion}
        order = order or str(rng.choice(["random", "axis-major"]))
        idx = np.argsort(r["J1"], kind="stable") if order == "axis-major" else np.arange(n)
        return f"arm {n} poses", {k: v[idx] for k, v in r.items()}, order
    rotary = [a for a in tm.motion if tm.kind(a) != "prismatic"]
    linear = [a for a in tm.motion if tm.kind(a) == "prismatic"]
    marks = np.array([[40.0, 40.0, 0.0], [-40.0, 40.0, 0.0], [-40.0, -40.0, 0.0], [40.0, -40.0, 0.0]])
    kind = kind or str(rng.choice(["patent", "small", "large", "random half", "fine turns"]))
    if rotary:
        turn = [a for a in rotary if not np.isfinite(tm.limits[a][0]) or tm.limits[a][1] - tm.limits[a][0] >= 359.0]
        tilt = [a for a in rotary if a not in turn]
        n_tilt, n_turn = {"patent": (7, 12), "small": (3, 6), "large": (9, 18), "random half": (7, 12),
                          "fine turns": (3, 72)}[kind]
        tilts = np.linspace(-40, 40, n_tilt) if tilt else np.zeros(1)
        turns = np.arange(n_turn) * 360.0 / n_turn
        grid = [(b, c, k) for b in tilts for c in turns for k in range(4)]
        order = order or str(rng.choice(["axis-major", "serpentine", "random"]))
        if order == "serpentine":
            grid = [(b, c, k) for i, b in enumerate(tilts) for c in (turns if i % 2 == 0 else turns[::-1]) for k in range(4)]
        grid = np.array(grid)
        if kind == "random half":
            grid = grid[np.sort(rng.choice(len(grid), len(grid) // 2, replace=False))]
        if order == "random":
            grid = grid[rng.permutation(len(grid))]
        presets = {}
        for a in tilt:
            presets[a] = grid[:, 0].copy()
        for a in turn:
            presets[a] = grid[:, 1].copy()
        w = marks[grid[:, 2].astype(int)]
        labels = grid[:, 2].astype(int)
    else:  # the gantry: the plate's marks at positions along the rails
        n_pos = {"patent": 84, "small": 18, "large": 168, "random half": 42, "fine turns": 84}[kind]
        v = np.linspace(-400, 400, n_pos)
        grid = np.array([(p, k) for p in v for k in range(4)])
        order = order if order in ("axis-major", "random") else str(rng.choice(["axis-major", "random"]))
        if order == "random":
            grid = grid[rng.permutation(len(grid))]
        presets = {"V": grid[:, 0].copy()}
        w = marks[grid[:, 1].astype(int)]
        labels = grid[:, 1].astype(int)
    for a in linear:
        presets.setdefault(a, np.zeros(len(w)))
    r = truth.align_linear(tm, presets, w)
    return f"{kind} ({len(w)})", r, order, labels


# -- one scenario -----------------------------------------------------------------------------------------
@dataclass
class Scenario:
    seed: int
    layout: str
    plan: str
    order: str
    hidden: list
    misread_share: float
    quantised: bool
    sigma_declared: float | None
    jitter_um: float = 0.0
    result: dict = field(default_factory=dict)
    marks_mm: object = None  # (N, 3) where the marks are, when the machine stops near them and offsets are read
    fixed_kinds: list | None = None  # the kinds asked for (None: drawn)

    @property
    def kinds(self) -> str:
        return "+".join(sorted({h.kind for h in self.hidden})) or "none"


def draw(seed: int, layout: str | None = None, kinds=None, *, plan_kind=None, order=None, misread_share=None,
         sigma="draw", jitter_um=None):
    """A scenario and its data: (Scenario, machine URDF text, truth machine, rows...). The keywords fix what is
    otherwise drawn (the draws are made all the same, so the rest of the scenario does not change)."""
    rng = np.random.default_rng(seed)
    layout = layout or LAYOUTS[rng.integers(len(LAYOUTS))]
    text = urdf_text(layout)
    tm = truth.read_urdf(text)
    drawn = plan(tm, layout, rng, plan_kind, order)
    name, readings, order = drawn[:3]
    labels = drawn[3] if len(drawn) > 3 else np.arange(len(next(iter(readings.values()))))
    n = len(next(iter(readings.values())))
    # solved readings: an alignment reads the linear axes where it stopped them, a few µm from where the plan sent
    # them (drawn from a generator of its own: every other draw, and so every scenario without it, stays as it was)
    jitter_rng = np.random.default_rng([seed, 1])
    linear = [a for a in readings if tm.kind(a) == "prismatic"]
    drawn_jitter = float(jitter_rng.uniform(0.5, 3.0)) if jitter_rng.random() < 0.3 and linear else 0.0
    jitter_um = drawn_jitter if jitter_um is None else jitter_um
    if jitter_um:
        readings = {a: v + jitter_rng.normal(0.0, jitter_um * 1e-3, n) if a in linear else v
                    for a, v in readings.items()}
    t_s = np.arange(n) * 12.0 + rng.uniform(0, 2, n)
    ranges = {a: (float(np.min(v)), float(np.max(v))) for a, v in readings.items()}
    errors = {}
    for code in tm.errors:  # constant location errors: the machine's geometry
        if "0" in code[2:3] or layout == "arm6":
            big = code.endswith("W") or code.endswith("T")
            errors[code] = np.full(n, rng.uniform(-1, 1) * (500.0 if big else 30.0))
    fixed_kinds = None if kinds is None else [str(k) for k in kinds]
    if kinds is None:
        count = rng.choice([0, 1, 1, 1, 2, 3])
        pool = [k for k in KINDS if k != "none"]
        kinds = list(rng.choice(pool, count, replace=False)) if count else []
    hidden = []
    for k in kinds:
        hidden += (families.family_effects(tm, k, rng, readings, t_s) if k in families.FAMILIES
                   else hidden_effects(tm, k, rng, ranges))
    marks_mm = None
    instruments = [h for h in hidden if isinstance(h, families.Instrument)]
    if instruments:  # the machine stops near each mark, the instrument reads the offset (a generator of its own)
        marks_mm = truth.tool_point_mm(tm, readings, {}, n)
        readings = families.stop_near(tm, readings, max(h.spread_mm for h in instruments),
                                      np.random.default_rng([seed, 2]))
    share = float(rng.choice([0.0, 0.0, 0.01, 0.03, 0.05]))
    quantised = bool(rng.random() < 0.3)
    sig = rng.random()
    declared = NOISE_UM if sig < 0.4 else (None if sig < 0.7 else float(NOISE_UM * np.exp(rng.uniform(np.log(0.3), np.log(3)))))
    share = share if misread_share is None else misread_share
    declared = declared if sigma == "draw" else sigma
    sc = Scenario(seed, layout, name, order, hidden, share, quantised, declared, jitter_um, marks_mm=marks_mm,
                  fixed_kinds=fixed_kinds)
    return sc, text, tm, readings, labels, t_s, errors, rng


def run(seed: int, layout: str | None = None, kinds=None, *, max_steps: int = 6, **fixed) -> Scenario:
    from kinid.identification import default_model, fit, forward_select
    from kinid.identification.model.machine import machine_from_urdf
    from kinid.identification.data.observations import Observations
    from kinid.identification.fitting.residuals import design, residuals

    sc, text, tm, readings, labels, t_s, errors, rng = draw(seed, layout, kinds, **fixed)
    n = len(t_s)
    hidden_vals = {}
    instruments = [h for h in sc.hidden if isinstance(h, families.Instrument)]
    machine_hidden = [h for h in sc.hidden if h not in instruments]
    for h in machine_hidden:
        hidden_vals[h.joint] = hidden_vals.get(h.joint, 0.0) + h(readings, t_s)
    all_errors = {k: v + hidden_vals.get(k, 0.0) for k, v in errors.items()}
    for k, v in hidden_vals.items():
        all_errors.setdefault(k, v)
    # (an instrument's own offset moves the tool point a user can know: where it reads 0)
    true_p = families.zero_point_mm(tm, readings, all_errors, instruments)
    base_p = truth.tool_point_mm(tm, readings, errors, n)  # the same machine without the hidden effects
    noise = rng.normal(0.0, NOISE_UM, (n, 3)) * 1e-3  # mm
    held = np.zeros(n, bool)
    held[rng.choice(n, int(HELD_OUT_SHARE * n), replace=False)] = True
    misread = np.zeros((n, 3))
    bad = rng.choice(np.flatnonzero(~held), int(round(sc.misread_share * (~held).sum())), replace=False)
    for i in bad:
        d = rng.normal(size=3)
        misread[i] = d / np.linalg.norm(d) * rng.uniform(10.0, 40.0) * 1e-3  # mm

    machine = machine_from_urdf(text, f"{sc.layout}.urdf")
    names = [a.name for a in machine.axes]
    axes = np.column_stack([readings[a] for a in names])
    if sc.quantised:
        step = np.full(len(names), 1e-4)  # 0.1 µm and 0.0001°: a fine linear scale and rotary encoder
        axes_seen = np.round(axes / step) * step
    else:
        axes_seen = axes

    def rows(index, w, offsets=None):
        return Observations(tuple(f"M{labels[i]}" for i in index), w[index], axes_seen[index], t_s[index], {},
                            tuple(int(i) + 2 for i in index), "<proving ground>",
                            None if offsets is None else offsets[index])

    # where the marks are for the user: on the tool point (an alignment), or near it with the offset read
    seen_p, offsets_true, offsets_read = true_p, None, None
    if instruments:
        seen_p = sc.marks_mm
        offsets_read = families.offsets_true_mm(tm, readings, all_errors, seen_p)
        for h in instruments:
            offsets_read = h.read(offsets_read)
        # the oracle reads the offsets from the instrument's zero, its shape undone (known exactly)
        offsets_true = families.offsets_true_mm(tm, readings, all_errors, seen_p) - np.sum(
            [np.asarray(h.zero_mm, float) for h in instruments], axis=0)
    fit_rows = np.flatnonzero(~held)
    data = rows(fit_rows, seen_p + noise + misread, offsets_read)
    default = list(default_model(machine))
    started = time.perf_counter()
    try:
        steps = forward_select(machine, data, default, noise_um=sc.sigma_declared, max_steps=max_steps)
    except Exception as exc:  # a crash is a failure of the scenario, recorded, not the end of the run
        sc.result = {"verdict": f"crash: {type(exc).__name__}: {exc}", "added": [], "stopped": "", "set_aside": 0,
                     "misreads": int(len(bad)), "held_out_um": float("inf"), "default_um": float("nan"),
                     "oracle_um": float("nan"), "floor_um": float("nan"), "plan_um": float("inf"),
                     "default_plan_um": float("nan"), "worse_z": float("inf"), "named": [], "wanted": [],
                     "seconds": time.perf_counter() - started}
        return sc
    seconds = time.perf_counter() - started
    final = steps[-1]

    held_idx = np.flatnonzero(held)
    held_obs = Observations(tuple("H" for _ in held_idx), true_p[held_idx], axes[held_idx], t_s[held_idx], {},
                            (), "<held out>")

    def pose_errors_um2(result, effects, against=held_obs):
        r = residuals(machine, design(machine, effects, against), against, result.theta, jacobian=False)
        return np.sum(r**2, axis=1)

    def held_out_um(result, effects, against=held_obs):
        return float(np.sqrt(np.mean(pose_errors_um2(result, effects, against))))

    # every pose of the plan, the fit's own rows included, against the noise-free truth: what the model gets wrong
    # where the plan measured (for a fixed design its expectation is the held-out error less the noise), from 5×
    # the rows of the held-out share — the lower-variance figure on a small plan
    every = np.arange(n)
    plan_obs = Observations(tuple("P" for _ in every), true_p, axes, t_s, {}, (), "<every pose>")

    # the floor without the hidden effects: the default model on the same rows had the machine none of them
    floor_fit = fit(machine, rows(fit_rows, base_p + noise), default, noise_um=NOISE_UM)
    floor_obs = Observations(held_obs.marks, base_p[held_idx], axes[held_idx], t_s[held_idx], {}, (), "<held out>")
    r = residuals(machine, design(machine, default, floor_obs), floor_obs, floor_fit.theta, jacobian=False)
    floor = float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
    # the oracle: the true structure (the default model and each hidden effect's exact shape, its size free)
    # fitted on the rows the user has, the misreads known and left out
    # (an error of the instrument: the offsets read as they truly are)
    truth_effects = default + _truth_effects(machine, machine_hidden, readings, t_s)
    clean = np.setdiff1d(fit_rows, bad)
    oracle_fit = fit(machine, rows(clean, seen_p + noise, offsets_true), truth_effects, noise_um=NOISE_UM)
    oracle = held_out_um(oracle_fit, truth_effects)
    added = [s.added for s in steps[1:] if s.added]
    dg = final.diagnosis
    # what the verdict names: the error joints whose period the selection says it could not determine, the best
    # candidate when it is significant, else where the neighbour test found the residual most structured
    if final.undetermined and dg.verdict == "missing-effect":
        named = set().union(*(_named_axes(code, machine) for code in final.undetermined))
    elif dg.live and dg.live[0].p_value < dg.threshold:
        named = _named_axes(dg.live[0].effect, machine)
        if dg.inseparable and " is not added: " in final.stopped:  # the selection stopped naming a pair: both
            named |= _named_axes(dg.inseparable.split(" and ", 1)[1].split(" ", 1)[0], machine)
    else:
        named = {dg.structure.axis} if dg.structure is not None and dg.structure.axis else set()
    # the instrument's errors the selection stopped for (rows with offsets): the camera's, the laser's
    named |= {term.split("-")[0] for term in getattr(final, "instrument", ())}
    wanted = {a for h in sc.hidden for a in h.axes}
    # how surely the final model is more than 5 % worse than the default one on these held-out poses: the paired
    # difference of their squared errors pose by pose (final − 1.05² × default) in its standard errors — a dozen
    # poses of a small plan hold a 5 % difference only when it is far larger than the spread between the poses
    final_um2 = pose_errors_um2(final.fit, final.fit.effects)
    default_um2 = pose_errors_um2(steps[0].fit, steps[0].fit.effects)
    d = final_um2 - 1.05**2 * default_um2
    spread = float(np.std(d, ddof=1) / np.sqrt(len(d))) if len(d) > 1 else 0.0
    if spread > 0:
        worse_z = float(np.mean(d) / spread)
    else:  # one pose, or poses alike: as sure as the sign of the difference (none: no evidence either way)
        worse_z = float(np.copysign(np.inf, np.mean(d))) if len(d) and np.mean(d) != 0 else 0.0
    sc.result = {
        "verdict": dg.verdict, "added": added, "stopped": final.stopped, "set_aside": len(final.fit.set_aside),
        "misreads": int(len(bad)), "held_out_um": float(np.sqrt(np.mean(final_um2))),
        "default_um": float(np.sqrt(np.mean(default_um2))), "oracle_um": oracle, "floor_um": floor,
        "plan_um": held_out_um(final.fit, final.fit.effects, plan_obs),
        "default_plan_um": held_out_um(steps[0].fit, steps[0].fit.effects, plan_obs),
        "worse_z": worse_z, "named": sorted(named), "wanted": sorted(wanted), "seconds": seconds,
    }
    return sc


#: The hidden effects' values by time (each row's time is its own): what the truth basis reads.
_TRUTH_VALUES: dict = {}


def _truth_basis():
    """A basis of kinid's registry for the oracle: ``CODE:truth:<k>`` is the k-th hidden effect's exact shape
    (its value in the truth, read by each row's time), with one free size. It lists no candidate, so kinid's
    diagnosis never tries it."""
    from kinid.identification.model.bases import BASES, Basis, register_basis

    if "truth" in BASES:
        return

    def values(e, q, t, s):
        times, v = _TRUTH_VALUES[e.args[0]]
        i = np.clip(np.searchsorted(times, t), 0, len(times) - 1)
        if not np.allclose(times[i], t):
            raise ValueError("a row's time is not one the truth was drawn at")
        return v[i].reshape(-1, 1)

    register_basis(Basis(kind="truth", grammar=r"truth:(?P<k>[0-9]+)", syntax="truth:<k>", driver="time",
                         parse=lambda m, ctx: {"args": (int(m.group("k")),)}, n_params=lambda e: 1,
                         param_names=lambda e: [e.name], param_units=lambda e, u, q: [u], values=values,
                         describe=lambda e, u: "the hidden effect's exact shape"))


def _truth_effects(machine, hidden, readings, t_s) -> list:
    """The hidden effects as effects of the truth basis (their shapes at every row, sizes to fit)."""
    from kinid.identification.model.effects import parse_effect

    _truth_basis()
    order = np.argsort(t_s)
    out = []
    for k, h in enumerate(hidden):
        _TRUTH_VALUES[k] = (t_s[order], np.asarray(h(readings, t_s), float)[order])
        out.append(parse_effect(f"{h.joint}:truth:{k}", machine))
    return out


def _named_axes(effect: str, machine) -> set:
    """The axes a candidate effect names: its joint's axis letter(s), time for a drift, and the other axis its basis
    names (``on:A``, ``with:Z``, ``step:Y:40``: the error changes with that axis, and the words say so)."""
    code, _, basis = effect.partition(":")
    out = set()
    if basis.startswith("drift") or basis.startswith("warmup"):
        out.add("time")
    tail = code[2:]
    axes = {a.name for a in machine.axes}
    kind, _, rest = basis.partition(":")
    if kind in ("on", "with", "step") and rest.split(":")[0] in axes:
        out.add(rest.split(":")[0])
    for a in axes:
        if tail.endswith(a) or tail == a or f"@{a}" in basis:
            out.add(a)
    return out


def verdict_of(sc: Scenario) -> dict:
    r = sc.result
    if r["verdict"].startswith("crash"):
        return {"pass": False, "ratio": float("inf"), "worse_than_default": True, "worse_on_plan": True,
                "worse_beyond_sampling": True, "pass_floor": False, "floor_ratio": float("inf")}
    ratio = r["held_out_um"] / max(r["oracle_um"], 1e-9)
    floor_ratio = r["held_out_um"] / max(r["floor_um"], 1e-9)
    worse = r["held_out_um"] > 1.05 * r["default_um"] and r["held_out_um"] > 1.05 * r["oracle_um"]
    worse_plan = r["plan_um"] > 1.05 * r["default_plan_um"]
    surely = worse and r["worse_z"] > 2.0  # more than 5 % worse by more than two standard errors of the poses
    named = r["verdict"] == "missing-effect" and bool(set(r["named"]) & set(r["wanted"]))

    def ok(x):
        if sc.hidden:
            return x <= 1.5 or named
        return not (sc.sigma_declared == NOISE_UM and r["added"]) and x <= 1.5

    return {"pass": bool(ok(ratio)), "ratio": ratio, "worse_than_default": bool(worse),
            "worse_on_plan": bool(worse_plan), "worse_beyond_sampling": bool(surely),
            "pass_floor": bool(ok(floor_ratio)), "floor_ratio": floor_ratio}


def record(sc: Scenario) -> dict:
    """One scenario as the JSON keeps it: what was drawn, what kinid did and how it is judged."""
    return {"seed": sc.seed, "layout": sc.layout, "plan": sc.plan, "order": sc.order,
            "hidden": [f"{h.kind} {h.joint}" + (f" ({h.how})" if getattr(h, "how", "") else "") for h in sc.hidden], "misread_share": sc.misread_share,
            "quantised": sc.quantised, "sigma_declared": sc.sigma_declared, "jitter_um": sc.jitter_um,
            "kinds": sc.fixed_kinds,
            **sc.result, **verdict_of(sc)}


def class_of(rec: dict) -> str:
    """The hidden effect's kind, "none", or "combination" when there are several."""
    hidden = rec["hidden"]
    return hidden[0].split(" ", 1)[0] if len(hidden) == 1 else "combination" if hidden else "none"


def summarise(scenarios) -> dict:
    """The rates per class of scenarios (:class:`Scenario` objects or their JSON records, of one run or several)."""
    records = [record(sc) if isinstance(sc, Scenario) else sc for sc in scenarios]
    classes = {}
    for rec in records:
        sigma = rec["sigma_declared"]
        for key in {class_of(rec), "all", f"layout {rec['layout']}", f"order {rec['order']}",
                    "misreads" if rec["misread_share"] else "no misreads",
                    "σ " + ("given" if sigma == NOISE_UM else "none" if sigma is None else "wrong"),
                    "readings jittered" if rec["jitter_um"] else "readings as planned"}:
            classes.setdefault(key, []).append(rec)
    out = {}
    for key, items in sorted(classes.items()):
        ratios = np.array([v["ratio"] for v in items])
        none_given = [v for v in items if not v["hidden"] and v["sigma_declared"] == NOISE_UM]
        out[key] = {"n": len(items), "pass": float(np.mean([v["pass"] for v in items])),
                    "pass_floor": float(np.mean([v["pass_floor"] for v in items])),
                    "median_ratio": float(np.median(ratios)), "worst_ratio": float(ratios.max()),
                    "worse_than_default": float(np.mean([v["worse_than_default"] for v in items])),
                    "worse_on_plan": float(np.mean([v["worse_on_plan"] for v in items])),
                    "worse_beyond_sampling": float(np.mean([v["worse_beyond_sampling"] for v in items])),
                    "false_add": (float(np.mean([bool(v["added"]) for v in none_given])) if none_given else None)}
    return out


def print_findings(records) -> None:
    """The figures the docs quote from a run (or several): hidden-effect passes, held-out within 1.5× the oracle's,
    the scenarios worse than the default model and the additions with no hidden effect."""
    def name(v):
        seed, k = divmod(v["seed"], 100003)
        return f"seed {seed} #{k}"

    hidden = [v for v in records if v["hidden"]]
    none_given = [v for v in records if not v["hidden"] and v["sigma_declared"] == NOISE_UM]
    passed = sum(v["pass"] for v in hidden)
    within = sum(v["ratio"] <= 1.5 for v in hidden)
    print(f"\nwith a hidden effect: {passed} of {len(hidden)} pass ({passed / max(len(hidden), 1):.1%}), "
          f"held-out within 1.5× the oracle's in {within} ({within / max(len(hidden), 1):.1%})")
    print(f"with none: {sum(bool(v['added']) for v in records if not v['hidden'])} of "
          f"{sum(not v['hidden'] for v in records)} add anything; σ given right: "
          f"{sum(bool(v['added']) for v in none_given)} of {len(none_given)}")
    for key, label in (("worse_than_default", "held-out"), ("worse_beyond_sampling", "beyond 2 SE"),
                       ("worse_on_plan", "on plan")):
        worse = [name(v) for v in records if v[key]]
        print(f"more than 5 % worse than the default model, {label}: {', '.join(worse) or 'none'}")


def print_table(summary: dict) -> None:
    print(f"{'class':<26} {'n':>4} {'pass':>6} {'median':>7} {'worst':>7} {'worse':>6} {'> 2 SE':>6} {'on plan':>7} "
          f"{'false add':>9} {'pass/floor':>10}   (worse: how many scenarios)")
    for key, s in summary.items():
        fa = "" if s["false_add"] is None else f"{s['false_add']:.0%}"
        print(f"{key:<26} {s['n']:>4} {s['pass']:>6.0%} {s['median_ratio']:>7.2f} {s['worst_ratio']:>7.2f} "
              f"{round(s['worse_than_default'] * s['n']):>6} {round(s['worse_beyond_sampling'] * s['n']):>6} "
              f"{round(s['worse_on_plan'] * s['n']):>7} {fa:>9} {s['pass_floor']:>10.0%}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--kinds", nargs="+", choices=[k for k in KINDS if k != "none"] + list(families.FAMILIES),
                    help="one hidden effect per scenario, of these kinds in turn (default: drawn, 0–3 of the listed "
                         "classes); the families of benchmarks/proving_families.py are drawn only when named here")
    ap.add_argument("--rerun", metavar="JSON",
                    help="run again the scenarios this JSON recorded (of the classes --kinds names, or all), as drawn "
                         "then: the same scenarios before and after a change to kinid")
    ap.add_argument("--json", help="write every scenario's record here")
    ap.add_argument("--figure", help="write the held-out/oracle ratios per class as a PNG")
    ap.add_argument("--merge", nargs="+", metavar="JSON",
                    help="run nothing: the table, the findings and the figure of the runs these JSONs recorded")
    args = ap.parse_args(argv)
    if args.rerun:
        recorded = json.loads(Path(args.rerun).read_text())["scenarios"]
        chosen = [rec for rec in recorded if not args.kinds or class_of(rec) in args.kinds]
        records = [record(sc) for sc in _run_all(0, 0, each=lambda recs: args.json and _write_json(args.json, recs),
                                                 again=chosen)]
        title = f"{len(records)} scenarios of {args.rerun} again"
    elif args.merge:
        records = [rec for f in args.merge for rec in json.loads(Path(f).read_text())["scenarios"]]
        seeds = sorted({rec["seed"] // 100003 for rec in records})
        title = f"seed{'s' if len(seeds) > 1 else ''} {', '.join(map(str, seeds))}"
    else:
        def keep(records):  # the records so far, written whole after every scenario: a run stopped early keeps them
            if args.json:
                _write_json(args.json, records)

        records = [record(sc) for sc in _run_all(args.scenarios, args.seed, args.kinds, keep)]
        title = f"seed {args.seed}"
    summary = summarise(records)
    print_table(summary)
    print_findings(records)
    if args.json:
        _write_json(args.json, records)
    if args.figure:
        _figure(records, summary, title, args.figure)


def _write_json(path, records) -> None:
    """The run's summary and records, written whole (to a temporary file, then renamed)."""
    tmp = Path(f"{path}.partial")
    tmp.write_text(json.dumps({"summary": summarise(records), "scenarios": records}, indent=1))
    tmp.replace(path)


def _drawn_kinds(rec: dict):
    """The kinds a recorded scenario was drawn with: fixed for the families (drawn only when named), else drawn."""
    kind = class_of(rec)
    return rec.get("kinds", [kind] if kind in families.FAMILIES else None)


def _run_all(count: int, seed: int, kinds=None, each=None, again=()) -> list:
    from threadpoolctl import threadpool_limits

    scenarios = []
    started = time.perf_counter()
    with threadpool_limits(1):
        todo = [(rec["seed"], _drawn_kinds(rec)) for rec in again] or [
            (seed * 100003 + k, None if not kinds else [kinds[k % len(kinds)]]) for k in range(count)]
        for k, (scenario_seed, drawn) in enumerate(todo):
            sc = run(scenario_seed, kinds=drawn)
            scenarios.append(sc)
            if each is not None:
                each([record(s) for s in scenarios])
            v = verdict_of(sc)
            r = sc.result
            print(f"{k:4d} {sc.layout:<18} {sc.plan:<18} {sc.order:<11} {sc.kinds:<28} σ {sc.sigma_declared!s:<6.5} "
                  f"mis {r['misreads']:>2}/{r['set_aside']:<2} {r['verdict']:<15} held-out {r['held_out_um']:7.3f} "
                  f"oracle {r['oracle_um']:6.3f} floor {r['floor_um']:6.3f} default {r['default_um']:7.3f} "
                  f"plan {r['plan_um']:6.3f}/{r['default_plan_um']:6.3f} {'PASS' if v['pass'] else 'FAIL'} "
                  f"added {r['added']}", flush=True)
    print(f"\n{len(scenarios)} scenarios in {time.perf_counter() - started:.0f} s"
          f"{'' if again else f' (seed {seed})'}\n")
    return scenarios


def _figure(records, summary, title: str, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullLocator

    keys = [k for k in summary
            if not k.startswith(("layout", "order", "σ", "misreads", "no misreads", "all", "readings"))]
    fig, ax = plt.subplots(figsize=(9, 4.8), dpi=120)
    colours = plt.get_cmap("turbo")(np.linspace(0.05, 0.95, len(keys)))  # one hue per class, however many
    failed_label = "failed"
    for i, key in enumerate(keys):
        items = [(v["ratio"], v["pass"]) for v in records if class_of(v) == key and np.isfinite(v["ratio"])]
        x = np.full(len(items), i) + np.random.default_rng(i).uniform(-0.2, 0.2, len(items))
        ratio, ok = np.array([r for r, _ in items]), np.array([p for _, p in items], bool)
        ax.scatter(x[ok], ratio[ok], s=12 if len(records) < 1000 else 6, color=colours[i],
                   alpha=1.0 if len(records) < 1000 else 0.5, lw=0)  # thousands of points: the density shows
        if (~ok).any():
            ax.scatter(x[~ok], ratio[~ok], s=28, marker="x", color="k", lw=1.2, label=failed_label)
            failed_label = None
    ax.axhline(1.5, color="k", lw=0.8, ls="--", label="1.5 × oracle (above it a scenario passes only by a\n"
                                                      "missing-effect verdict naming the right axis)")
    ax.set_yscale("log")
    ax.yaxis.set_major_locator(FixedLocator([0.1, 0.2, 0.5, 1, 1.5, 2, 3, 5, 10, 20]))
    ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.yaxis.set_minor_locator(NullLocator())
    ax.set_xticks(range(len(keys)), [f"{k} ({summary[k]['n']})" for k in keys], rotation=35, ha="right",
                  rotation_mode="anchor")
    ax.set_ylabel("held-out error / oracle's")
    ax.set_title(f"identify --auto on {len(records)} drawn scenarios\n({title})", fontsize=10)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.4), ncol=2, fontsize=8, frameon=False)
    fig.tight_layout()
    fig.savefig(path, bbox_inches="tight")


if __name__ == "__main__":
    main()
