"""Effect bases: how an error joint's value may vary — one :class:`Basis` per kind, in one registry.

An effect is an error joint plus a basis (docs/formats.md, "Effects"): ``EX0C`` (constant),
``EXX:poly2``, ``EXX:periodic:10`` … Everything kinid does with an effect asks its basis here: how its
name is written and parsed, how many parameters it has and their names and units, its values at
given readings, what drives it (an axis's position, the approach direction, time, nothing), how it
is described in words, how large a candidate of it is, which candidates the diagnosis tries, and
whether a compensation table holds it.

=====================  ==============================================  ==========
name                   value of the error joint                        parameters
=====================  ==============================================  ==========
``EX0C``               constant                                        1
``EXX:poly<k>``        Σ_j θ_j q^j, j = 1..k, q = position of axis X    k
``EXX:periodic:<P>``   a·sin(2πq/P) + b·cos(2πq/P), P in mm or deg     2
``EXX:reversal``       β·s/2, s = approach direction (column dir_x)    1
``<code>:drift``       γ·t, t = column ``t_s``                          1
``EXX:map:<h>``        piecewise linear, knots every h (constant        knots
                       beyond the ends)
``EXX:local:<h>:<a>:<b>``  cubic B-splines every h whose support lies    knots − 4
                       in [a, b]: smooth, zero outside: a local error
``EA0C:on:A[:<k>]``    Σ a_n(cos nα − 1) + b_n sin nα, α = angle of A  2k
                       (:mod:`~kinid.identification.model.rotary_on`, registered when effects load)
``EB0J2:sag:J4``       c · the torque about J2 of a unit weight at J4   1
                       (:mod:`~kinid.identification.model.sag`)
``EB0J2:gravity``      cₖ · the gravity torque on each horizontal       one per
                       joint k, on EB0J2, EB0J3 … (``sag`` too)          joint
``EZZ:step:Y:40``      a jump of s where Y passes 40 (zero at Y = 0)    1
                       (:mod:`~kinid.identification.model.step`)
=====================  ==============================================  ==========

A new kind is one :func:`register_basis` call with a :class:`Basis`; parsing, the fit, the
diagnosis, the reports, the simulator and the compensation tables take it from :data:`BASES`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable

import numpy as np

from kinid.errors import DataError
from kinid.registry import Registry

from .bsplines import _local_values, _map_values, local_grid

__all__ = ["Basis", "BasisInput", "BASES", "register_basis", "basis_of", "LINEAR_PERIODS_MM", "ROTARY_PERIODS_DEG",
           "MIN_PERIOD_MM", "MIN_PERIOD_DEG", "MAX_PERIODS_OVER_TRAVEL", "MAX_MAP_KNOTS", "NUMBER", "parse_name",
           "DRIFT_HORIZON_S", "basis_of_name", "chosen_of"]

#: Periods the diagnosis tries on every position-dependent joint (mm for linear, deg for rotary axes).
LINEAR_PERIODS_MM = (2, 4, 5, 8, 10, 16, 20)
ROTARY_PERIODS_DEG = (360, 180, 120, 90)
#: Shortest period a periodic effect may have: below this no axis is sampled finely enough.
MIN_PERIOD_MM = 0.01
MIN_PERIOD_DEG = 0.01
#: Longest period, in travels of the axis: beyond it a sine over the travel is a polynomial.
MAX_PERIODS_OVER_TRAVEL = 20.0
#: Knots a map effect may have at most.
MAX_MAP_KNOTS = 200
#: A number in an effect name.
NUMBER = r"[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?"
_SUPERSCRIPT = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")


@dataclass(frozen=True)
class BasisInput:
    """What a basis's parser may use: the effect's name, its joint, the machine, where the name came from."""

    name: str
    code: str
    joint: object
    machine: object
    source: str

    @property
    def axis(self) -> str:
        return self.joint.axis

    @property
    def axis_kind(self) -> str:
        return self.machine.axis(self.joint.axis).kind

    @property
    def axis_unit(self) -> str:
        return "mm" if self.axis_kind == "prismatic" else "deg"

    def fail(self, why: str) -> DataError:
        return DataError(f"{self.source} {self.name!r}: {why}")


def _last_size(effect, beta, cov):
    return float(beta[-1]), float(np.sqrt(max(cov[-1, -1], 0.0)))


def _no_candidates(joint, axis_kind, *, varying, has_directions, has_time, **_):
    return []


def _largest_value(effect, theta) -> float:
    return float(np.max(np.abs(theta))) if np.size(theta) else 0.0


#: Drift sizes are judged over this time, s.
DRIFT_HORIZON_S = 3600.0


@dataclass(frozen=True)
class Basis:
    """One kind of effect basis.

    Attributes
    ----------
    kind : str
        ``Effect.basis`` of its effects.
    grammar : str
        Regular expression of the name after ``CODE:`` (named groups for :attr:`parse`); None for the
        bare code (constant).
    syntax : str
        The name as users write it, for messages: ``periodic:<P>``.
    driver : {"none", "position", "direction", "time", "positions", "mark", "pose"}
        What the value varies with: nothing, the position of the joint's axis, the approach
        direction of that axis, time (column ``t_s``), the positions of the joint's axis and of
        the other axis the effect names (``q`` is then (N, 2)), or the row's mark (``q`` is then the
        marks, (N,) of str: one of several targets measured at each pose), or the whole pose on the nominal
        machine (``q`` is then ``(machine, axes (N, n_axes))``: a weight's lever, ``sag``).
    parse : callable (re.Match, BasisInput) -> dict
        The effect's fields beyond name, code, basis, axis and unit (``degree``, ``period``,
        ``knots``, ``args``); raises ``BasisInput.fail(...)`` for a bad value.
    n_params : callable (effect) -> int
    param_names : callable (effect) -> list of str
    param_units : callable (effect, joint unit "µm"/"µrad", axis unit "mm"/"deg") -> list of str
    values : callable (effect, q, t_s, direction) -> array (N, n_params)
        ``q`` the axis readings (mm / deg), ``t_s`` times (s), ``direction`` ±1 of the axis; each None
        where the basis's driver does not need it. The values depend on the effect's axis and its name after the
        joint's code only (the score test computes them once for all the joints of an axis).
    describe : callable (effect, " mm" or "") -> str
        How the effect varies, in words.
    size : callable (effect, beta, cov) -> (value, std)
        One number for a candidate's size (the amplitude of a periodic term, the peak of a map …).
    candidates : callable (joint, axis_kind, varying=, has_directions=, has_time=, linear_axes=, **) -> list of str
        Effect names of this kind the diagnosis tries on ``joint`` (``linear_axes``: the names of the machine's
        linear axes; further keywords may come, so accept ``**_``).
    note : callable (effect, beta, axis_unit) -> str, or None
        A sentence for a scored candidate (where a map's error is).
    knots_plot : bool
        Reports plot its identified values at knots (maps) rather than as a curve only.
    chosen : str
        What of the name the diagnosis chooses from the data among many (``period``, ``window``, ``time
        constant``), which the held-out check chooses again on each turn's training blocks; empty for none.
    window_grid : callable (effect) -> tuple, or None
        The grid of B-splines the effect's columns are a window of (local errors): the score test computes
        the grid's columns once for every window on it.
    extent : callable (effect, theta) -> float
        The largest value the effect reaches (its size judged against what a machine can have); a drift,
        per second, over :data:`DRIFT_HORIZON_S`.
    axis_named : bool
        The name says which axis drives it, any error joint's, set-up joints' too (``step:<axis>:<at>``):
        :attr:`parse` returns it as ``axis``, the effect's :attr:`Effect.axis`.
    joints : callable (effect, machine) -> list of str, or None
        The error joint of each parameter, for an effect spread over several (``gravity``: a compliance per loaded
        joint); None: every parameter on the effect's own joint.
    sign : {0, 1, -1}
        The sign every parameter must have (a compliance: +1); one of the other sign beyond twice its standard
        deviation is a size no machine has. 0: any.
    """

    kind: str
    grammar: str | None
    syntax: str
    driver: str
    parse: Callable
    n_params: Callable
    param_names: Callable
    param_units: Callable
    values: Callable
    describe: Callable
    size: Callable = _last_size
    candidates: Callable = _no_candidates
    note: Callable | None = None
    knots_plot: bool = False
    chosen: str = ""
    window_grid: Callable | None = None
    extent: Callable = _largest_value
    axis_named: bool = False
    joints: Callable | None = None
    sign: int = 0

    @property
    def tabulated(self) -> bool:
        """A compensation table over the axis holds it (driven by the axis's position or direction)."""
        return self.driver in ("position", "direction")

    @property
    def constant(self) -> bool:
        """Does not vary: one value (a location error, a set-up)."""
        return self.driver == "none"

    @property
    def positional(self) -> bool:
        """Varies with the position of the joint's axis."""
        return self.driver == "position"


#: Basis kind -> :class:`Basis`, in the order names are tried and candidates listed.
BASES = Registry("effect basis", Basis, key="kind", parameter="kind", variant_parameter="basis")


def register_basis(basis: Basis) -> Basis:
    """Add ``basis`` to :data:`BASES` (replacing one of the same kind) and return it."""
    if isinstance(basis, Basis) and basis.driver not in ("none", "position", "direction", "time", "positions", "mark",
                                                         "pose"):
        raise DataError(f"must be none, position, direction, time, positions, mark or pose, got {basis.driver!r}",
                        parameter="driver")
    return BASES.register(basis)


def basis_of_name(name: str):
    """The registered basis an effect name is written with (``EXX:periodic:10`` -> periodic; a bare code ->
    constant), without parsing it against a machine; None for a name no basis reads."""
    rest = name.strip().partition(":")[2]
    for basis in BASES.values():
        if (basis.grammar is None and not rest) or (basis.grammar is not None and rest
                                                     and re.fullmatch(basis.grammar, rest)):
            return basis
    return None


def chosen_of(name: str) -> str:
    """What of effect ``name`` the diagnosis chose from the data among many (:attr:`Basis.chosen`), or ``""``."""
    basis = basis_of_name(name)
    return basis.chosen if basis is not None else ""


def basis_of(effect) -> Basis:
    """The registered basis of ``effect`` (an Effect or a kind)."""
    return BASES.look_up(effect if isinstance(effect, str) else effect.basis)


def _one(effect):
    return 1


def _own_name(effect):
    return [effect.name]


def _unit(effect, u, q):
    return [u]


# --- constant ---------------------------------------------------------------------------------

register_basis(Basis(
    kind="constant", grammar=None, syntax="(the bare code)", driver="none", parse=lambda m, ctx: {},
    n_params=_one, param_names=_own_name, param_units=_unit,
    values=lambda e, q, t, s: np.ones((_rows(q, t, s), 1)),
    describe=lambda e, u: "constant",
    candidates=lambda j, kind, *, varying, has_directions, has_time, **_: [j.code] if j.location else []))


def _rows(*arrays) -> int:
    for a in arrays:
        if a is not None:
            return len(a)
    raise DataError("no readings to evaluate a basis at")


# --- polynomial ---------------------------------------------------------------------------------

register_basis(Basis(
    kind="poly", grammar=r"poly(?P<deg>[1-9])", syntax="poly<k> (k=1..9)", driver="position",
    parse=lambda m, ctx: {"degree": int(m.group("deg"))},
    n_params=lambda e: e.degree,
    param_names=lambda e: [f"{e.name}[q{str(j).translate(_SUPERSCRIPT)}]" for j in range(1, e.degree + 1)],
    param_units=lambda e, u, q: [f"{u}/{q}" + (str(j).translate(_SUPERSCRIPT) if j > 1 else "")
                                 for j in range(1, e.degree + 1)],
    values=lambda e, q, t, s: np.stack([q ** j for j in range(1, e.degree + 1)], axis=1),
    describe=lambda e, u: f"polynomial of degree {e.degree} in {e.axis}",
    candidates=lambda j, kind, *, varying, has_directions, has_time, **_:
        [f"{j.code}:poly{k}" for k in (1, 2, 3)] if varying else []))


# --- periodic -----------------------------------------------------------------------------------

def _parse_period(m, ctx: BasisInput) -> dict:
    from .machine import axis_limits

    period = float(m.group("period"))
    machine, axis, kind, unit = ctx.machine, ctx.axis, ctx.axis_kind, ctx.axis_unit
    smallest = MIN_PERIOD_MM if kind == "prismatic" else MIN_PERIOD_DEG
    lo, hi = axis_limits(machine)[machine.axis_names.index(axis)]
    span = hi - lo if np.isfinite(hi - lo) else (None if kind == "prismatic" else 360.0)
    if not (np.isfinite(period) and period >= smallest):
        raise ctx.fail(f"the period must be at least {smallest:g} {unit} (a shorter one is below any sampling of "
                       f"the axis), got {m.group('period')}")
    if span is not None and period > MAX_PERIODS_OVER_TRAVEL * max(span, 360.0 if kind != "prismatic" else 0.0):
        raise ctx.fail(f"a period of {period:g} {unit} is more than {MAX_PERIODS_OVER_TRAVEL:g} times the travel of "
                       f"{axis} ({span:g} {unit}); over the travel it is a polynomial: use {ctx.code}:poly2 instead")
    return {"period": period}


def _periodic_values(e, q, t, s):
    phase = 2 * np.pi * q / e.period
    return np.stack([np.sin(phase), np.cos(phase)], axis=1)


def _amplitude(e, beta, cov):
    amp = float(np.hypot(*beta))
    g = beta / amp if amp > 0 else np.array([1.0, 0.0])
    return amp, float(np.sqrt(max(g @ cov @ g, 0.0)))


register_basis(Basis(
    kind="periodic", grammar=rf"periodic:(?P<period>{NUMBER})", syntax="periodic:<P>", driver="position",
    parse=_parse_period, n_params=lambda e: 2, param_names=lambda e: [f"{e.name}[sin]", f"{e.name}[cos]"],
    param_units=lambda e, u, q: [u, u], values=_periodic_values,
    describe=lambda e, u: f"periodic in {e.axis}, period {e.period:g}{u}", size=_amplitude, chosen="period",
    candidates=lambda j, kind, *, varying, has_directions, has_time, **_:
        [f"{j.code}:periodic:{p}" for p in (LINEAR_PERIODS_MM if kind == "prismatic" else ROTARY_PERIODS_DEG)]
        if varying else []))


# --- reversal and drift ---------------------------------------------------------------------------

register_basis(Basis(
    kind="reversal", grammar=r"reversal", syntax="reversal", driver="direction", parse=lambda m, ctx: {},
    n_params=_one, param_names=_own_name, param_units=_unit,
    values=lambda e, q, t, s: (np.asarray(s, float) / 2.0).reshape(-1, 1),
    describe=lambda e, u: f"reversal with the approach direction of {e.axis}",
    candidates=lambda j, kind, *, varying, has_directions, has_time, **_:
        [f"{j.code}:reversal"] if varying and has_directions else []))

register_basis(Basis(
    kind="drift", grammar=r"drift", syntax="drift", driver="time", parse=lambda m, ctx: {},
    n_params=_one, param_names=_own_name, param_units=lambda e, u, q: [f"{u}/s"],
    values=lambda e, q, t, s: np.asarray(t, float).reshape(-1, 1),
    describe=lambda e, u: "drift with time",
    extent=lambda e, theta: _largest_value(e, theta) * DRIFT_HORIZON_S,
    candidates=lambda j, kind, *, varying, has_directions, has_time, **_: [f"{j.code}:drift"] if has_time else []))


# --- warm-up ------------------------------------------------------------------------------------

#: Time constants (s) of the warm-up candidates: a log grid a factor 3 apart (a fit at the nearest
#: one keeps ≥ 90 % of a first-order growth of any τ between them over a run of a few τ).
WARMUP_TAUS_S = (600, 1800, 5400)


def _parse_tau(m, ctx):
    tau = float(m.group("tau"))
    if not (np.isfinite(tau) and tau > 0):
        raise ctx.fail(f"the time constant must be > 0 s, got {m.group('tau')}")
    return {"args": (tau,)}


register_basis(Basis(
    kind="warmup", grammar=rf"warmup:(?P<tau>{NUMBER})", syntax="warmup:<tau_s>", driver="time", parse=_parse_tau,
    chosen="time constant",
    n_params=_one, param_names=_own_name, param_units=_unit,
    values=lambda e, q, t, s: (1.0 - np.exp(-np.maximum(np.asarray(t, float), 0.0) / e.args[0])).reshape(-1, 1),
    describe=lambda e, u: f"thermal growth levelling off, A·(1 − e^(−t/τ)) with τ = {e.args[0]:g} s from t = 0",
    candidates=lambda j, kind, *, varying, has_directions, has_time, **_:
        [f"{j.code}:warmup:{tau}" for tau in WARMUP_TAUS_S] if has_time and j.location else []))


# --- maps and local errors ------------------------------------------------------------------------

def map_knots(ctx: BasisInput, step_text, lo_text, hi_text) -> tuple:
    """Knots every ``step`` from ``from`` to ``to`` (default: the URDF travel)."""
    from .machine import axis_limits

    machine, axis, unit = ctx.machine, ctx.axis, ctx.axis_unit
    step = float(step_text)
    if lo_text is None:
        lo, hi = axis_limits(machine)[machine.axis_names.index(axis)]
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise ctx.fail(f"axis {axis} has no travel in the URDF; give the range as {ctx.name}:<from>:<to> ({unit})")
    else:
        lo, hi = float(lo_text), float(hi_text)
    if not (np.isfinite(step) and step > 0 and np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        raise ctx.fail("a map needs a positive step and a range from < to")
    n = int(np.ceil((hi - lo) / step - 1e-9)) + 1
    if n > MAX_MAP_KNOTS:
        raise ctx.fail(f"{n} knots, more than {MAX_MAP_KNOTS}; use a larger step or give the measured range as "
                       f"{ctx.name.split(':map:')[0]}:map:{step_text}:<from>:<to> ({unit})")
    return tuple(float(lo + step * k) for k in range(max(n, 2)))


def _peak(e, beta, cov):
    """The peak value of the map (the part the model does not already hold)."""
    i = int(np.argmax(np.abs(beta)))
    return float(beta[i]), float(np.sqrt(max(cov[i, i], 0.0)))


def _where_note(knots_of):
    def note(e, beta, axis_unit) -> str:
        """In words: where a map candidate's error is, and how large at its peak."""
        i = int(np.argmax(np.abs(beta)))
        width = e.knots[1] - e.knots[0]
        knots = knots_of(e)
        big = np.flatnonzero(np.abs(beta) > 0.5 * abs(beta[i]))
        extent = (big.max() - big.min() + 1) * width
        return (f"a local error of {e.axis} near {e.axis.lower()} = {knots[i]:+g} {axis_unit}, "
                f"{abs(beta[i]):.2g} {'µm' if e.unit == 'um' else 'µrad'} peak over about {extent:g} {axis_unit}, "
                f"not described by any parametric effect")
    return note


def _parse_local(m, ctx: BasisInput) -> dict:
    knots = map_knots(ctx, m.group("lstep"), m.group("llo"), m.group("lhi"))
    if len(knots) < 5:
        raise ctx.fail("a local error needs at least four steps between from and to")
    return {"knots": knots}


register_basis(Basis(
    kind="map", grammar=rf"map:(?P<step>{NUMBER})(?::(?P<lo>[-+]?{NUMBER}):(?P<hi>[-+]?{NUMBER}))?",
    syntax="map:<step>[:<from>:<to>]", driver="position",
    parse=lambda m, ctx: {"knots": map_knots(ctx, m.group("step"), m.group("lo"), m.group("hi"))},
    n_params=lambda e: len(e.knots), param_names=lambda e: [f"{e.name}[{k:g}]" for k in e.knots],
    param_units=lambda e, u, q: [u] * len(e.knots), values=_map_values,
    describe=lambda e, u: f"map in {e.axis}, knots every {e.knots[1] - e.knots[0]:g}{u}",
    size=_peak, note=_where_note(lambda e: e.knots), knots_plot=True))

register_basis(Basis(
    kind="local", grammar=rf"local:(?P<lstep>{NUMBER}):(?P<llo>[-+]?{NUMBER}):(?P<lhi>[-+]?{NUMBER})",
    syntax="local:<step>:<from>:<to>", driver="position", parse=_parse_local,
    n_params=lambda e: len(e.knots) - 4, param_names=lambda e: [f"{e.name}[{k:g}]" for k in e.knots[2:-2]],
    param_units=lambda e, u, q: [u] * (len(e.knots) - 4), values=_local_values,
    describe=lambda e, u: (f"local error of {e.axis} between {e.knots[0]:g} and {e.knots[-1]:g}{u}, knots every "
                           f"{e.knots[1] - e.knots[0]:g}{u}"),
    size=_peak, note=_where_note(lambda e: e.knots[2:-2]), chosen="window", window_grid=local_grid))


# --- errors of one axis that vary with another axis's position (the last candidates listed) ---

def _parse_cross(m, ctx: BasisInput) -> dict:
    other = m.group("other")
    if other not in ctx.machine.axis_names:
        raise ctx.fail(f"{other!r} is not an axis of this machine; axes: {', '.join(ctx.machine.axis_names)}")
    if other == ctx.axis:
        raise ctx.fail(f"the other axis must differ from the joint's own axis {ctx.axis}; use poly<k> for that")
    return {"args": (other,)}


register_basis(Basis(
    kind="with", grammar=r"with:(?P<other>[A-Za-z][A-Za-z0-9]*)", syntax="with:<other axis>", driver="positions",
    parse=_parse_cross, n_params=lambda e: 2,
    param_names=lambda e: [f"{e.name}[{e.args[0]}]", f"{e.name}[{e.axis}·{e.args[0]}]"],
    param_units=lambda e, u, q: [f"{u}/mm", f"{u}/mm²"],
    values=lambda e, q, t, s: np.stack([q[:, 1], q[:, 0] * q[:, 1]], axis=1),
    describe=lambda e, u: (f"varies with the position of {e.args[0]}, and its slope along {e.axis} too "
                           f"(a thermal gradient, a twist)"),
    # a translation error of a linear axis that varies with another linear axis's position
    candidates=lambda j, kind, *, varying, linear_axes=(), **_:
        [f"{j.code}:with:{b}" for b in linear_axes if b != j.axis]
        if varying and kind == "prismatic" and not j.location and j.kind == "prismatic" else []))


# --- one of several targets -----------------------------------------------------------------------

def _parse_target(m, ctx: BasisInput) -> dict:
    if ctx.joint.axis != "T" or not ctx.joint.location:
        raise ctx.fail(f"a target basis is a tool point's set-up (E?0T); {ctx.code} is not one")
    return {"args": (m.group("label"),)}


register_basis(Basis(
    kind="target", grammar=r"target:(?P<label>[A-Za-z0-9_.-]+)", syntax="target:<mark>", driver="mark",
    parse=_parse_target, n_params=_one, param_names=_own_name, param_units=_unit,
    # the tool point's set-up of one target of several measured at each pose: the value on its rows, 0 elsewhere
    values=lambda e, q, t, s: (np.asarray(q) == e.args[0]).astype(float).reshape(-1, 1),
    describe=lambda e, u: f"constant on the rows of target {e.args[0]}"))


def parse_name(name: str, joint, machine, source: str) -> tuple:
    """(basis, fields) of the part of ``name`` after ``CODE:``; raises naming what is wrong."""
    code, _, rest = name.strip().partition(":")
    ctx = BasisInput(name, code, joint, machine, source)
    for basis in BASES.values():
        if (basis.grammar is None) != (not rest):
            continue
        m = None if basis.grammar is None else re.fullmatch(basis.grammar, rest)
        if basis.grammar is not None and m is None:
            continue
        if basis.driver in ("position", "direction", "positions") and not basis.axis_named and (
                joint.axis in ("W", "T") or joint.axis not in machine.axis_names):
            raise ctx.fail(f"a {rest.split(':')[0]} basis needs the position of an axis; {code} is a set-up error")
        return basis, basis.parse(m, ctx)
    syntaxes = [b.syntax for b in BASES.values() if b.grammar is not None]
    raise ctx.fail(f"unknown basis {rest!r}; expected {', '.join(syntaxes[:-1])} or {syntaxes[-1]}")
