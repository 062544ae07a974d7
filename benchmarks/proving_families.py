"""Hidden effects nobody named, for the diagnosis proving ground: random shapes, not kinid's list.

Each family draws its truth in plain numpy (and scipy's cubic spline), sharing no code with kinid:

- ``smooth-1``: a random smooth function of ONE variable of the machine state — any motion axis, rotary or
  linear, or time — on a random error joint: a Fourier series of 1–3 harmonics with random coefficients (whole
  turns on a rotary axis that turns all the way round, else half-periods over the visited range), or a natural
  cubic spline through 4–6 random values at equally spaced knots;
- ``smooth-2``: the same of TWO variables, a sum of one or two products of such functions, the pair drawn among
  the kinds the machine has (rotary × rotary, linear × rotary, linear × linear, axis × time);
- ``step``: a step at a random position of an axis (uniform between the 20th and 80th percentile of its readings,
  so that it lies between two positions the plan visits, not on one);
- ``instrument``: an error of the instrument, not of the machine — the camera's scale (0.3–2 %) or rotation
  (0.5–5 mrad) on the mark offsets ``mark_dx_mm``/``mark_dy_mm``, the laser's scale (0.3–2 %) on ``mark_dz_mm``,
  or a constant offset of the tool point in the tool frame. The machine stops near the mark, not on it (its linear
  axes a few mm off, an arm's joints a few hundredths of a degree), and the offset is read.

Sizes: each effect is scaled so that the tool point moves by 5–40 µm RMS about its mean over the plan (an
instrument's offsets spread so that its error is that size at the tool), well above the 1 µm noise.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline

import proving_truth as truth

FAMILIES = ("smooth-1", "smooth-2", "step", "instrument")
SIZE_UM = (5.0, 40.0)


@dataclass(frozen=True)
class Instrument:
    """An error of the instrument: how the offsets (tool frame, mm) are read from the true ones."""

    kind: str
    joint: str  # what errs: camera-scale, camera-rotation, laser-scale, tool-offset
    axes: tuple  # what a right verdict names (kinid has no word for it: passes by the held-out error only)
    spread_mm: float  # the machine stops up to this far from the mark along each linear axis
    read: object  # callable(d_true (N, 3) mm) -> d_read (N, 3) mm
    zero_mm: tuple = (0.0, 0.0, 0.0)  # where the instrument reads 0, tool frame: the tool point the user has

    def __call__(self, r, t):  # no error joint moves
        return 0.0


def _variables(tm, readings, t_s):
    """Each variable that changes over the plan: name -> (kind, values, turns all the way round)."""
    out = {}
    for a in tm.motion:
        v = np.asarray(readings[a], float)
        if np.ptp(v) < 1e-3:
            continue
        kind = "linear" if tm.kind(a) == "prismatic" else "rotary"
        lo, hi = tm.limits[a]
        out[a] = (kind, v, kind == "rotary" and (not np.isfinite(lo) or hi - lo >= 359.0))
    out["time"] = ("time", np.asarray(t_s, float), False)
    return out


def _shape_1d(rng, values, whole_turns: bool):
    """A random smooth function of one variable, as a callable of its values, and its description."""
    if whole_turns:  # a function of the angle that closes on itself
        theta = np.radians(values)
        k = int(rng.integers(1, 4))
        a, b = rng.normal(size=k), rng.normal(size=k)
        return (lambda x: sum(a[i] * np.cos((i + 1) * np.radians(x)) + b[i] * np.sin((i + 1) * np.radians(x))
                              for i in range(k))), f"Fourier {k} turn harmonics", theta
    lo, hi = float(np.min(values)), float(np.max(values))

    def unit(x):
        return (np.asarray(x, float) - lo) / max(hi - lo, 1e-9)

    if rng.random() < 0.5:
        k = int(rng.integers(1, 4))
        a, b = rng.normal(size=k), rng.normal(size=k)
        return (lambda x: sum(a[i] * np.cos((i + 1) * np.pi * unit(x)) + b[i] * np.sin((i + 1) * np.pi * unit(x))
                              for i in range(k))), f"Fourier {k} half-periods", None
    knots = int(rng.integers(4, 7))
    spline = CubicSpline(np.linspace(0, 1, knots), rng.normal(size=knots), bc_type="natural")
    return (lambda x: spline(np.clip(unit(x), 0, 1))), f"cubic spline {knots} knots", None


def _joint_axis(tm, code: str) -> set:
    """The motion axis an error joint belongs to (its code's tail), if any."""
    tail = code[2:]
    return {a for a in tm.motion if tail.endswith(a)}


def _tool_spread_um(tm, readings, code: str, values) -> float:
    """How far the tool point moves, RMS about its mean over the plan, µm, when joint ``code`` takes ``values``
    (µm / µrad)."""
    n = len(values)
    moved = truth.tool_point_mm(tm, readings, {code: values}, n) - truth.tool_point_mm(tm, readings, {}, n)
    moved = moved - moved.mean(axis=0)
    return float(np.sqrt(np.mean(np.sum(moved**2, axis=1)))) * 1e3


def _scaled(tm, readings, code, raw, rng):
    """The factor that makes ``raw`` (values at the plan's poses) move the tool point 5–40 µm RMS."""
    spread = _tool_spread_um(tm, readings, code, raw)
    return rng.uniform(*SIZE_UM) / spread if spread > 1e-9 else None


def family_effects(tm, kind: str, rng, readings: dict, t_s) -> list:
    """One hidden effect of family ``kind`` on this machine, as ``proving_ground.Hidden`` objects (or an
    :class:`Instrument`); empty when the machine has no place for it."""
    if kind == "instrument":
        return [_instrument(tm, rng, readings)]
    if kind not in FAMILIES:
        return []
    for _ in range(20):  # a joint that does not move the tool point over this plan is drawn again
        out = _machine_effect(tm, kind, rng, readings, t_s)
        if out:
            return out
    return []


def _machine_effect(tm, kind, rng, readings, t_s) -> list:
    from proving_ground import Hidden

    variables = _variables(tm, readings, t_s)
    joints = list(tm.errors)
    code = joints[rng.integers(len(joints))]
    if kind == "smooth-1":
        name = str(list(variables)[rng.integers(len(variables))])
        f, how, _ = _shape_1d(rng, variables[name][1], variables[name][2])
        args, how = (name,), f"{how} of {name}"

        def raw_of(r, t):
            return f(t if name == "time" else r[name])
    elif kind == "smooth-2":
        kinds = {k: [n for n, v in variables.items() if v[0] == k] for k in ("linear", "rotary", "time")}
        axes = kinds["linear"] + kinds["rotary"]
        pairs = [p for p in ((kinds["rotary"], kinds["rotary"]), (kinds["linear"], kinds["rotary"]),
                             (kinds["linear"], kinds["linear"]), (axes, kinds["time"]))
                 if p[0] and p[1] and len(set(p[0]) | set(p[1])) >= 2]
        first, second = pairs[rng.integers(len(pairs))]
        u = str(first[rng.integers(len(first))])
        v = str(next(iter(w for w in rng.permutation(second) if w != u)))
        terms = []
        for _ in range(int(rng.integers(1, 3))):
            fu = _shape_1d(rng, variables[u][1], variables[u][2])[0]
            fv = _shape_1d(rng, variables[v][1], variables[v][2])[0]
            terms.append((fu, fv))
        args, how = (u, v), f"{len(terms)} product(s) of {u} × {v}"

        def raw_of(r, t):
            def val(name):
                return t if name == "time" else r[name]
            return sum(fu(val(u)) * fv(val(v)) for fu, fv in terms)
    elif kind == "step":
        axes = [n for n in variables if n != "time"]
        name = str(axes[rng.integers(len(axes))])
        # anywhere between the 20th and 80th percentiles, not at a percentile: a percentile of a plan that visits
        # each position many times is one of its readings, and rows read there alike (to 1e-13 mm, or within the
        # µm of a solved reading) would fall either side by rounding — a step no reading can place
        low, high = np.percentile(variables[name][1], [20.0, 80.0])
        at = float(low + (high - low) * (rng.uniform(20, 80) - 20.0) / 60.0)  # (the draw it always was)
        args, how = (name,), f"step at {name} = {at:.3g}"

        def raw_of(r, t):
            return np.where(np.asarray(r[name]) > at, 0.5, -0.5)
    factor = _scaled(tm, readings, code, np.asarray(raw_of(readings, t_s), float) * np.ones(len(t_s)), rng)
    if factor is None:
        return []
    wanted = tuple(sorted(set(args) | _joint_axis(tm, code)))
    return [Hidden(kind, code, wanted, lambda r, t: factor * np.asarray(raw_of(r, t), float) * np.ones(len(t)),
                   how)]


def _instrument(tm, rng, readings) -> Instrument:
    what = ("camera-scale", "camera-rotation", "laser-scale", "tool-offset")[rng.integers(4)]
    size_um = rng.uniform(*SIZE_UM)
    if what == "tool-offset":
        d = rng.normal(size=3)
        d = d / np.linalg.norm(d) * size_um * 1e-3
        return Instrument("instrument", what, ("tool",), 1.0, lambda x: x + d, tuple(-d))
    if what == "camera-rotation":
        angle = rng.uniform(0.5e-3, 5e-3) * rng.choice([-1, 1])
        c, s = np.cos(angle), np.sin(angle)
        spread = float(np.clip(size_um * 1e-3 / angle * np.sqrt(3 / 2), 0.5, 10.0))
        return Instrument("instrument", what, ("camera",), abs(spread),
                          lambda x: np.column_stack([c * x[:, 0] - s * x[:, 1], s * x[:, 0] + c * x[:, 1], x[:, 2]]))
    scale = rng.uniform(0.003, 0.02) * rng.choice([-1, 1])
    spread = float(np.clip(size_um * 1e-3 / abs(scale) * np.sqrt(3 / (2 if what == "camera-scale" else 1)), 0.5, 10.0))
    factor = np.array([1 + scale, 1 + scale, 1.0]) if what == "camera-scale" else np.array([1.0, 1.0, 1 + scale])
    return Instrument("instrument", what, ("camera" if what == "camera-scale" else "laser",), spread,
                      lambda x: x * factor)


def stop_near(tm, readings: dict, spread_mm: float, rng) -> dict:
    """Readings where the machine stops near each mark rather than on it: each linear axis up to ``spread_mm``
    off (uniformly), or, on a machine without linear axes, each joint by as much at a 500 mm reach."""
    n = len(next(iter(readings.values())))
    linear = [a for a in tm.motion if tm.kind(a) == "prismatic"]
    out = dict(readings)
    for a in (linear or tm.motion):
        step = spread_mm if linear else np.degrees(spread_mm / 500.0)
        out[a] = np.asarray(readings[a], float) + rng.uniform(-step, step, n)
    return out


def zero_point_mm(tm, readings: dict, errors: dict, instruments) -> np.ndarray:
    """Where the instruments read 0 (the tool point a user can know, which the held-out error is judged at) in
    the workpiece frame, mm (N, 3): the true tool point moved by the instruments' zero in the tool frame."""
    n = len(next(iter(readings.values())))
    R, p = truth.tool_pose_mm(tm, readings, errors, n)
    zero = np.sum([np.asarray(h.zero_mm, float) for h in instruments], axis=0) if instruments else np.zeros(3)
    return p + R @ zero


def offsets_true_mm(tm, readings: dict, errors: dict, marks_mm) -> np.ndarray:
    """Where each mark is relative to the true tool point, in the tool frame, mm (N, 3)."""
    n = len(marks_mm)
    R, p = truth.tool_pose_mm(tm, readings, errors, n)
    return np.einsum("nji,nj->ni", R, marks_mm - p)
