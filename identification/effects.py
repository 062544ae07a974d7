"""Effects: an error joint plus a basis that says how its value varies (docs/formats.md, "Effects").

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
=====================  ==============================================  ==========

Parameter units: the joint's unit u (µm for a translation, µrad for a
rotation) — times (mm or deg)^-j for a polynomial term, per second for drift.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError
from .machine import Machine, _joint_kind, axis_limits

__all__ = ["Effect", "parse_effect", "check_effects", "default_model", "candidate_library", "axis_dependent_joints", "basis_values", "LINEAR_PERIODS_MM", "ROTARY_PERIODS_DEG"]

LINEAR_PERIODS_MM = (2, 4, 5, 8, 10, 16, 20)
ROTARY_PERIODS_DEG = (360, 180, 120, 90)
_SUPERSCRIPT = str.maketrans("0123456789", "⁰¹²³⁴⁵⁶⁷⁸⁹")
_NUM = r"[0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?"
_BASIS = re.compile(rf"^(?:poly(?P<deg>[1-9])|periodic:(?P<period>{_NUM})|(?P<rev>reversal)|(?P<drift>drift)"
                    rf"|map:(?P<step>{_NUM})(?::(?P<lo>[-+]?{_NUM}):(?P<hi>[-+]?{_NUM}))?"
                    rf"|local:(?P<lstep>{_NUM}):(?P<llo>[-+]?{_NUM}):(?P<lhi>[-+]?{_NUM}))$")
#: Knots a map effect may have at most.
MAX_MAP_KNOTS = 200


@dataclass(frozen=True)
class Effect:
    """One error joint plus a basis.

    Attributes
    ----------
    name : str
        As written by users: ``EXX:periodic:10``.
    code : str
        The error joint.
    basis : {"constant", "poly", "periodic", "reversal", "drift", "map", "local"}
    degree : int
        Polynomial degree (poly only).
    period : float
        Period in mm or deg (periodic only).
    axis : str
        The axis whose position or direction drives the basis ("" for constant/drift).
    unit : {"um", "urad"}
        Unit of the error joint's value.
    knots : tuple of float
        Map only: the axis positions (mm or deg) where the map's values are the
        parameters; linear in between, constant beyond the ends.
    """

    name: str
    code: str
    basis: str
    degree: int = 0
    period: float = 0.0
    axis: str = ""
    unit: str = "um"
    knots: tuple = ()

    @property
    def n_params(self) -> int:
        if self.basis == "map":
            return len(self.knots)
        if self.basis == "local":
            return len(self.knots) - 4
        return {"poly": self.degree, "periodic": 2}.get(self.basis, 1)

    def param_names(self) -> list[str]:
        if self.basis == "poly":
            return [f"{self.name}[q{str(j).translate(_SUPERSCRIPT)}]" for j in range(1, self.degree + 1)]
        if self.basis == "periodic":
            return [f"{self.name}[sin]", f"{self.name}[cos]"]
        if self.basis == "map":
            return [f"{self.name}[{k:g}]" for k in self.knots]
        if self.basis == "local":
            return [f"{self.name}[{k:g}]" for k in self.knots[2:-2]]
        return [self.name]

    def param_units(self, machine: Machine) -> list[str]:
        u = "µm" if self.unit == "um" else "µrad"
        if self.basis == "poly":
            q = "mm" if machine.axis(self.axis).kind == "prismatic" else "deg"
            return [f"{u}/{q}" + (str(j).translate(_SUPERSCRIPT) if j > 1 else "") for j in range(1, self.degree + 1)]
        if self.basis == "drift":
            return [f"{u}/s"]
        return [u] * self.n_params


#: Shortest period a periodic effect may have: below this no axis is sampled finely enough.
MIN_PERIOD_MM = 0.01
MIN_PERIOD_DEG = 0.01
#: Longest period, in travels of the axis: beyond it a sine over the travel is a polynomial.
MAX_PERIODS_OVER_TRAVEL = 20.0


def parse_effect(name: str, machine: Machine, *, source: str = "effect") -> Effect:
    """Parse an effect name against a machine.

    Raises
    ------
    DataError
        Naming the effect and what is wrong (unknown joint, bad basis, a
        position basis on a set-up joint ...).
    """
    code, _, basis = name.strip().partition(":")
    if code not in machine.error_codes:
        close = [c for c in machine.error_codes if c[:2] == code[:2]][:6]
        hint = f"; joints starting {code[:2]!r}: {', '.join(close)}" if close else ""
        raise DataError(f"{source} {name!r}: {code!r} is not an error joint of this machine{hint}")
    joint = machine.error_joint(code)
    if not basis:
        return Effect(name, code, "constant", unit=joint.unit)
    m = _BASIS.match(basis)
    if not m:
        raise DataError(f"{source} {name!r}: unknown basis {basis!r}; expected poly<k> (k=1..9), periodic:<P>, "
                        "reversal, drift, map:<step>[:<from>:<to>] or local:<step>:<from>:<to>")
    if m.group("drift"):
        return Effect(name, code, "drift", unit=joint.unit)
    axis = joint.axis
    if axis in ("W", "T") or axis not in machine.axis_names:
        raise DataError(f"{source} {name!r}: a {basis.split(':')[0]} basis needs the position of an axis; {code} is a set-up error")
    if m.group("deg"):
        return Effect(name, code, "poly", degree=int(m.group("deg")), axis=axis, unit=joint.unit)
    if m.group("step"):
        return Effect(name, code, "map", axis=axis, unit=joint.unit,
                      knots=_map_knots(name, machine, axis, m.group("step"), m.group("lo"), m.group("hi"), source))
    if m.group("lstep"):
        knots = _map_knots(name, machine, axis, m.group("lstep"), m.group("llo"), m.group("lhi"), source)
        if len(knots) < 5:
            raise DataError(f"{source} {name!r}: a local error needs at least four steps between from and to")
        return Effect(name, code, "local", axis=axis, unit=joint.unit, knots=knots)
    if m.group("period"):
        period = float(m.group("period"))
        kind = machine.axis(axis).kind
        unit = "mm" if kind == "prismatic" else "deg"
        smallest = MIN_PERIOD_MM if kind == "prismatic" else MIN_PERIOD_DEG
        lo, hi = axis_limits(machine)[machine.axis_names.index(axis)]
        span = hi - lo if np.isfinite(hi - lo) else (None if kind == "prismatic" else 360.0)
        if not (np.isfinite(period) and period >= smallest):
            raise DataError(f"{source} {name!r}: the period must be at least {smallest:g} {unit} (a shorter one is "
                            f"below any sampling of the axis), got {m.group('period')}")
        if span is not None and period > MAX_PERIODS_OVER_TRAVEL * max(span, 360.0 if kind != "prismatic" else 0.0):
            raise DataError(f"{source} {name!r}: a period of {period:g} {unit} is more than "
                            f"{MAX_PERIODS_OVER_TRAVEL:g} times the travel of {axis} ({span:g} {unit}); over the "
                            f"travel it is a polynomial: use {code}:poly2 instead")
        return Effect(name, code, "periodic", period=period, axis=axis, unit=joint.unit)
    return Effect(name, code, "reversal", axis=axis, unit=joint.unit)


def check_effects(machine: Machine, effects, name: str = "effects") -> tuple:
    """``effects`` as a tuple of :class:`Effect`; names (``"EXX:periodic:10"``) are parsed.

    Raises
    ------
    DataError
        Naming the argument and the item that is neither an Effect nor an effect name.
    """
    if isinstance(effects, (str, Effect)):
        effects = [effects]
    try:
        items = list(effects)
    except TypeError:
        raise DataError(f"must be a sequence of effects or effect names, got {type(effects).__name__}",
                        parameter=name) from None
    out = []
    for k, e in enumerate(items):
        if isinstance(e, str):
            e = parse_effect(e, machine, source=f"{name}[{k}]")
        elif not isinstance(e, Effect):
            raise DataError(f"[{k}] must be an Effect or an effect name such as 'EXX:periodic:10', got "
                            f"{type(e).__name__}", parameter=name)
        out.append(e)
    return tuple(out)


def _map_knots(name, machine, axis, step_text, lo_text, hi_text, source) -> tuple:
    """Knots of ``CODE:map:<step>[:<from>:<to>]``: every ``step`` from ``from`` to ``to`` (default: the URDF travel)."""
    step = float(step_text)
    unit = "mm" if machine.axis(axis).kind == "prismatic" else "deg"
    if lo_text is None:
        lo, hi = axis_limits(machine)[machine.axis_names.index(axis)]
        if not (np.isfinite(lo) and np.isfinite(hi)):
            raise DataError(f"{source} {name!r}: axis {axis} has no travel in the URDF; give the range as "
                            f"{name}:<from>:<to> ({unit})")
    else:
        lo, hi = float(lo_text), float(hi_text)
    if not (np.isfinite(step) and step > 0 and np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        raise DataError(f"{source} {name!r}: a map needs a positive step and a range from < to")
    n = int(np.ceil((hi - lo) / step - 1e-9)) + 1
    if n > MAX_MAP_KNOTS:
        raise DataError(f"{source} {name!r}: {n} knots, more than {MAX_MAP_KNOTS}; use a larger step or give the "
                        f"measured range as {name.split(':map:')[0]}:map:{step_text}:<from>:<to> ({unit})")
    return tuple(float(lo + step * k) for k in range(max(n, 2)))


def default_model(machine: Machine) -> list[Effect]:
    """Every location error (E?0?, set-up joints W and T included) as a constant, in URDF order."""
    return [Effect(e.code, e.code, "constant", unit=e.unit) for e in machine.error_joints if e.location]


def candidate_library(machine: Machine, model, *, has_directions: bool, has_time: bool) -> list[Effect]:
    """The default candidate library of docs/formats.md, minus effects already in ``model``.

    For every position-dependent joint: poly1, poly2, poly3, periodic at the
    standard periods, reversal (when the data have ``dir_`` columns); drift on
    every error joint (when the data have ``t_s``); every constant location
    error the model lacks.
    """
    have = {e.name for e in model}
    varying = {code for code, _ in axis_dependent_joints(machine)}
    out = []
    for j in machine.error_joints:
        if j.location:
            out.append(f"{j.code}")
        if j.code in varying:
            kind = machine.axis(j.axis).kind
            out += [f"{j.code}:poly{k}" for k in (1, 2, 3)]
            periods = LINEAR_PERIODS_MM if kind == "prismatic" else ROTARY_PERIODS_DEG
            out += [f"{j.code}:periodic:{p}" for p in periods]
            if has_directions:
                out.append(f"{j.code}:reversal")
        if has_time:
            out.append(f"{j.code}:drift")
    return [parse_effect(n, machine) for n in out if n not in have]


def axis_dependent_joints(machine: Machine) -> list:
    """(code, axis) of the error joints whose value may vary with the position of their axis.

    Every position-dependent joint ``E<d><k>``; and a location joint ``E<d>0<k>``
    whose motion is the same as axis ``k``'s own — a translation along the
    direction of a linear axis, or a rotation about the same line as a rotary
    axis — because it commutes with the axis, so that its value varying with
    the axis's position is the position-dependent error the URDF has no joint
    for (an arm's gear error of J2 is ``EB0J2`` varying with J2 when J2 turns
    about y).
    """
    import pinocchio as pin

    data = machine.model.createData()
    pin.forwardKinematics(machine.model, data, pin.neutral(machine.model))
    out = []
    for e in machine.error_joints:
        if e.axis not in machine.axis_names:
            continue
        if not e.location:
            out.append((e.code, e.axis))
            continue
        axis = machine.axis(e.axis)
        if (e.kind == "prismatic") != (axis.kind == "prismatic"):
            continue
        je, jk = machine.model.getJointId(e.code), machine.model.getJointId(machine.axis(e.axis).joint)
        de = data.oMi[je].rotation @ np.eye(3)["XYZABC".index(e.direction) % 3]
        dk = data.oMi[jk].rotation @ _joint_kind(machine.model.joints[jk])[1]
        if np.linalg.norm(np.cross(de, dk)) > 1e-9:
            continue  # not parallel
        offset = data.oMi[jk].translation - data.oMi[je].translation
        if e.kind == "revolute" and np.linalg.norm(np.cross(offset, dk)) > 1e-9:
            continue  # parallel rotation axes on different lines do not commute
        out.append((e.code, e.axis))
    return out


def basis_values(effect: Effect, machine: Machine, axes_user: np.ndarray, *, t_s=None, directions=None) -> np.ndarray:
    """Basis values (N, n_params) of ``effect`` for N poses.

    Parameters
    ----------
    axes_user : array (N, n_axes)
        Axis readings in machine order, mm / deg.
    t_s : array (N,) or None
        Times, s (drift).
    directions : mapping axis name -> array (N,) of ±1, or None (reversal).

    Raises
    ------
    DataError
        If the data lack the column the basis needs (``t_s``, ``dir_<axis>``).
    """
    n = axes_user.shape[0]
    if effect.basis == "constant":
        return np.ones((n, 1))
    if effect.basis == "drift":
        if t_s is None:
            raise DataError(f"effect {effect.name!r} needs the column 't_s' in the data")
        return np.asarray(t_s, float).reshape(n, 1)
    q = axes_user[:, machine.axis_names.index(effect.axis)]
    if effect.basis == "poly":
        return np.stack([q**j for j in range(1, effect.degree + 1)], axis=1)
    if effect.basis == "periodic":
        phase = 2 * np.pi * q / effect.period
        return np.stack([np.sin(phase), np.cos(phase)], axis=1)
    if effect.basis == "local":  # cubic B-splines whose support lies inside [from, to]: smooth, zero outside
        knots = np.asarray(effect.knots)
        step = knots[1] - knots[0]
        t = np.abs(q[:, None] - knots[None, 2:-2]) / step
        return np.where(t < 1, 2 / 3 - t**2 + t**3 / 2, np.where(t < 2, (2 - t) ** 3 / 6, 0.0))
    if effect.basis == "map":  # hat functions: linear between knots, constant beyond the ends
        knots = np.asarray(effect.knots)
        step = knots[1] - knots[0]
        x = np.clip((q - knots[0]) / step, 0.0, len(knots) - 1.0)
        i = np.minimum(np.floor(x).astype(int), len(knots) - 2)
        t = x - i
        out = np.zeros((n, len(knots)))
        out[np.arange(n), i] = 1.0 - t
        out[np.arange(n), i + 1] += t
        return out
    column = f"dir_{effect.axis.lower()}"
    if directions is None or effect.axis not in directions:
        raise DataError(f"effect {effect.name!r} needs the column {column!r} in the data")
    return (np.asarray(directions[effect.axis], float) / 2.0).reshape(n, 1)
