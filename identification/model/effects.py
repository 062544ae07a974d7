"""Effects: an error joint plus a basis that says how its value varies (docs/formats.md, "Effects").

The kinds of basis (constant, poly<k>, periodic:<P>, reversal, drift, map, local …) and everything
about each — its name, parameters, values, description, candidates — are the registry of
:mod:`~kinid.identification.model.bases`; this module holds the :class:`Effect` (a joint plus a basis),
parses names against a machine, and lists the default model and the candidate library.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError
from .bases import BASES, LINEAR_PERIODS_MM, ROTARY_PERIODS_DEG, basis_of, parse_name
from .derived import axis_dependent_joints
from .machine import Machine
from .rotary_on import rotary_carriers  # registers the on:<rotary axis> basis, after those of bases
from . import sag as _sag  # noqa: F401  registers the sag:<point> basis
from . import step as _step  # noqa: F401  registers the step:<axis>:<at> basis

__all__ = ["Effect", "parse_effect", "local_effect", "check_effects", "default_model", "model_effects", "candidate_library", "axis_dependent_joints",
           "basis_values", "param_codes", "LINEAR_PERIODS_MM", "ROTARY_PERIODS_DEG"]


@dataclass(frozen=True)
class Effect:
    """One error joint plus a basis.

    Attributes
    ----------
    name : str
        As written by users: ``EXX:periodic:10``.
    code : str
        The error joint.
    basis : str
        The kind of basis, a key of :data:`~kinid.identification.model.bases.BASES` ("constant", "poly",
        "periodic", "reversal", "drift", "map", "local", …).
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
    args : tuple
        Values of a basis kind that none of the fields above holds.
    """

    name: str
    code: str
    basis: str
    degree: int = 0
    period: float = 0.0
    axis: str = ""
    unit: str = "um"
    knots: tuple = ()
    args: tuple = ()

    @property
    def n_params(self) -> int:
        return basis_of(self).n_params(self)

    def param_names(self) -> list[str]:
        return basis_of(self).param_names(self)

    def param_units(self, machine: Machine) -> list[str]:
        u = "µm" if self.unit == "um" else "µrad"
        q = "" if not self.axis else ("mm" if machine.axis(self.axis).kind == "prismatic" else "deg")
        return basis_of(self).param_units(self, u, q)


def parse_effect(name: str, machine: Machine, *, source: str = "effect") -> Effect:
    """Parse an effect name against a machine.

    Raises
    ------
    DataError
        Naming the effect and what is wrong (unknown joint, bad basis, a
        position basis on a set-up joint ...).
    """
    known = machine.parsed_effects.get(name)
    if known is not None and known.basis in BASES:  # (a basis taken out of the registry parses no more)
        return known
    code = name.strip().partition(":")[0]
    if code not in machine.error_codes:
        close = [c for c in machine.error_codes if c[:2] == code[:2]][:6]
        hint = f"; joints starting {code[:2]!r}: {', '.join(close)}" if close else ""
        raise DataError(f"{source} {name!r}: {code!r} is not an error joint of this machine{hint}")
    joint = machine.error_joint(code)
    basis, fields = parse_name(name, joint, machine, source)
    axis = fields.pop("axis", joint.axis if basis.driver in ("position", "direction", "positions", "pose") else "")
    effect = machine.parsed_effects[name] = Effect(name, code, basis.kind, axis=axis, unit=joint.unit, **fields)
    return effect


def local_effect(joint, step: float, lo: float, hi: float):
    """The local error ``CODE:local:<step>:<lo>:<hi>`` of the error joint ``joint`` (its numbers written ``:g``),
    as :func:`parse_effect` makes it from that name — the knots of ``map_knots``, the joint's axis and
    unit — without writing the name out and parsing it back (a diagnosis tries thousands of windows); None where
    parse_effect would refuse it (fewer than four steps from ``lo`` to ``hi``)."""
    name = f"{joint.code}:local:{step:g}:{lo:g}:{hi:g}"
    step, lo, hi = (float(v) for v in name.split(":")[2:])
    n = int(np.ceil((hi - lo) / step - 1e-9)) + 1
    if not (step > 0 and hi > lo and n >= 5):
        return None
    return Effect(name, joint.code, "local", axis=joint.axis, unit=joint.unit,
                  knots=tuple(float(lo + step * k) for k in range(n)))


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


def default_model(machine: Machine) -> list[Effect]:
    """Every location error (E?0?, set-up joints W and T included) as a constant, in URDF order."""
    return [Effect(e.code, e.code, "constant", unit=e.unit) for e in machine.error_joints if e.location]


#: A linear axis read at this many distinct positions (too few for a map) has its error at each as a candidate.
TABLE_POSITIONS = range(5, 11)


def candidate_library(machine: Machine, model, *, has_directions: bool, has_time: bool, positions=None) -> list[Effect]:
    """The default candidate library of docs/formats.md, minus effects already in ``model``.

    Each registered basis names its candidates per error joint: for every position-dependent joint
    poly1, poly2, poly3, periodic at the standard periods, reversal (when the data have ``dir_``
    columns); drift on every error joint (when the data have ``t_s``); every constant location
    error the model lacks; with ``positions`` (axis name → distinct positions its readings visit), the error at
    each position of an axis read at too few for a map (:func:`position_tables`), and ``on:<B>`` only on a rotary axis
    carried by the rotary axis B, read at 3 angles or more (:mod:`~kinid.identification.model.rotary_on`).
    """
    have = {e.name for e in model}
    varying = {code for code, _ in axis_dependent_joints(machine)}
    out = []
    linear = [a.name for a in machine.axes if a.kind == "prismatic"]
    carriers = rotary_carriers(machine)
    for j in machine.error_joints:
        kind = machine.axis(j.axis).kind if j.code in varying else ""
        for basis in BASES.values():
            out += basis.candidates(j, kind, varying=j.code in varying, has_directions=has_directions,
                                    has_time=has_time, linear_axes=linear, carriers=carriers,
                                    positions=positions, machine=machine)
    out += position_tables(machine, positions or {})
    return [parse_effect(n, machine) for n in out if n not in have]


def position_tables(machine: Machine, positions) -> list[str]:
    """The error at each position measured, as candidates: for the joints of a linear axis read at
    :data:`TABLE_POSITIONS` distinct positions (``positions``: axis name → how many), the polynomial through every
    position (degree positions − 1). It is what a map is where there are too few positions for one: a bump at one
    position is no period and no low polynomial."""
    return [f"{code}:poly{positions[axis] - 1}" for code, axis in axis_dependent_joints(machine)
            if machine.axis(axis).kind == "prismatic" and positions.get(axis, 0) in TABLE_POSITIONS]


def param_codes(effect: Effect, machine: Machine) -> list:
    """The error joint of each of ``effect``'s parameters: its own joint's code, or, for an effect spread over
    several (:attr:`~kinid.identification.model.bases.Basis.joints`: the arm's gravity compliance), theirs."""
    joints = basis_of(effect).joints
    return [effect.code] * effect.n_params if joints is None else list(joints(effect, machine))


def basis_values(effect: Effect, machine: Machine, axes_user: np.ndarray, *, t_s=None, directions=None,
                 marks=None) -> np.ndarray:
    """Basis values (N, n_params) of ``effect`` for N poses.

    Parameters
    ----------
    axes_user : array (N, n_axes)
        Axis readings in machine order, mm / deg.
    t_s : array (N,) or None
        Times, s (drift).
    directions : mapping axis name -> array (N,) of ±1, or None (reversal).
    marks : sequence (N,) of str, or None
        The rows' marks (a target's set-up, ``E?0T:target:T2``).

    Raises
    ------
    DataError
        If the data lack the column the basis needs (``t_s``, ``dir_<axis>``, the marks).
    """
    basis = basis_of(effect)
    n = axes_user.shape[0]
    q = t = s = None
    if basis.driver == "time":
        if t_s is None:
            raise DataError(f"effect {effect.name!r} needs the column 't_s' in the data")
        t = np.asarray(t_s, float).reshape(n)
    elif basis.driver == "position":
        q = axes_user[:, machine.axis_names.index(effect.axis)]
    elif basis.driver == "positions":  # the joint's own axis, then the other axis the effect names
        q = axes_user[:, [machine.axis_names.index(effect.axis), machine.axis_names.index(effect.args[0])]]
    elif basis.driver == "direction":
        if directions is None or effect.axis not in directions:
            raise DataError(f"effect {effect.name!r} needs the column 'dir_{effect.axis.lower()}' in the data")
        s = np.asarray(directions[effect.axis], float).reshape(n)
    elif basis.driver == "mark":
        if marks is None or len(marks) != n:
            raise DataError(f"effect {effect.name!r} needs the rows' marks (the target each row measured)")
        q = np.asarray(marks, dtype=object)
    elif basis.driver == "pose":  # the whole pose on the nominal machine (a weight's lever: sag)
        q = (machine, axes_user)
    else:
        q = np.zeros(n)
    return np.asarray(basis.values(effect, q, t, s), float).reshape(n, -1)


def model_effects(machine: Machine, add=(), *, base=None, targets=()) -> list[Effect]:
    """The default model (or ``base`` effect names) plus the effects named in ``add``.

    With two or more ``targets`` (the marks of the targets measured at each pose, ``T1``, ``T2`` …), each
    constant translation of the tool point's set-up (``EX0T``, ``EY0T``, ``EZ0T``) becomes one per target
    (``EX0T:target:T1`` …): every target its own point on the tool, the machine's errors and the measurement
    frame shared. DataError where the model has none of them.
    """
    effects = default_model(machine) if base is None else [parse_effect(n, machine) for n in base]
    names = {e.name for e in effects}
    for n in add:
        e = parse_effect(n, machine, source="added effect")
        if e.name in names:
            raise DataError(f"is already in the model: {n!r}", parameter="add")
        names.add(e.name)
        effects.append(e)
    if len(targets) > 1:
        tool = [e for e in effects if basis_of(e).constant and machine.error_joint(e.code).axis == "T"
                and machine.error_joint(e.code).location and machine.error_joint(e.code).direction in "XYZ"]
        if not tool:
            raise DataError(f"{len(targets)} targets per pose ({', '.join(targets)}): fitting them together gives "
                            f"each its own point on the tool, the set-up joints EX0T, EY0T, EZ0T, which the model "
                            f"lacks (add them to the URDF, or fit one with --target {targets[0]})")
        effects = [t for e in effects for t in ([parse_effect(f"{e.code}:target:{m}", machine) for m in targets]
                                                if e in tool else [e])]
    return effects
