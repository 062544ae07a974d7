"""An error of a rotary axis that follows the weight it carries: ``EB0J2:sag:J4`` (basis kind ``sag``).

An arm's joints and links give under the weight beyond them: the joint turns by its compliance times the gravity
torque about its axis, and that torque changes with the pose (cos of the upper arm's angle to the horizontal, cos
of the forearm's …). Its shape needs no masses: the torque of a weight hanging at a point P of the chain about the
axis through the joint, ``a · ((p − o) × ĝ)`` (m: a unit weight's lever), with ``o``, ``a`` the joint's origin and
direction, ``p`` the point and ``ĝ`` straight down (−z of the URDF's root frame), all on the nominal machine at the
pose's readings. The effect's value is one parameter (µrad per m of lever: compliance × weight) times that lever::

    value = c · a_J · ((p_P − o_J) × ĝ),   P = the origin of a later axis, or T (the tool point)

A weight spread along a link is a weight at the link's end and one at its start, so a few points carry the whole
arm: the upper arm and forearm of a UR arm are ``EB0J2:sag:J3``, ``EB0J2:sag:J4`` and ``EB0J3:sag:J4``. The basis
is driven by the whole pose (driver ``pose``: ``q`` is ``(machine, axes (N, n_axes))``); its values depend only on
the joint's axis and the point, so every location joint of that axis shares them. It is registered when
:mod:`~kinid.identification.model.effects` imports it; its candidates are the rotational location joints of every
rotary axis carried by another, with the weight at each axis it carries and, where it carries the tool (an arm's
joint, not a table's axis), at the tool point.

The arm's gravity compliance as one effect (basis kind ``gravity``, ``EB0J2:gravity`` on a UR arm): every joint whose
axis stays horizontal (:func:`loaded_axes`: J2, J3, J4 of a UR arm) turns by its own compliance times the gravity torque
it carries, the torque of the whole chain beyond it (:func:`gravity_torques`): the links' masses at their centres from
the URDF's ``<inertial>`` where the machine has them, else a unit weight at the origin of each axis it carries and at
the tool point. The compliances are the effect's parameters, one per loaded joint, each on that joint's location
rotation about its own axis (``EB0J2``, ``EB0J3``, ``EB0J4``): one effect spread over several error joints
(:attr:`~kinid.identification.model.bases.Basis.joints`). An arm droops under its weight, so a compliance below zero
beyond twice its standard deviation is a size no arm has (:attr:`~kinid.identification.model.bases.Basis.sign`).
It is added by name (``--add EB0J2:gravity``), not among ``--auto``'s candidates: listed, it changed nothing on the
UR10 tracker series (docs/identification.md, "A real arm").

References: the joint-compliance (elastostatic) model of robot calibration, e.g. Dumas, Caro, Garnier & Furet,
"Joint stiffness identification of six-revolute industrial serial robots", Robotics and Computer-Integrated
Manufacturing 27 (2011) 881–888.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .bases import Basis, BasisInput, register_basis

__all__ = ["DOWN", "levers_m", "sag_points", "loaded_axes", "gravity_torques"]

#: Gravity's direction in the URDF's root frame (ROS: z up).
DOWN = np.array([0.0, 0.0, -1.0])


def sag_points(machine, axis: str) -> list:
    """The points a weight may hang at for a sag of ``axis``: the axes it carries (in chain order), then T where
    ``axis`` carries the tool (an arm's joint; a table's axis carries the workpiece, not the tool point)."""
    model = machine.model
    jid = model.getJointId(machine.axis(axis).joint)
    later = [a.name for a in machine.axes if a.name != axis and jid in model.supports[model.getJointId(a.joint)]]
    return later + (["T"] if machine.axis(axis).chain == "tool" else [])


def _parse(m, ctx: BasisInput) -> dict:
    machine, point = ctx.machine, m.group("point")
    if ctx.axis_kind == "prismatic" or ctx.joint.direction not in "ABC":
        raise ctx.fail(f"a sag is a turn of a rotary axis under the weight it carries; {ctx.code} is not a "
                       f"rotation of a rotary axis")
    points = sag_points(machine, ctx.axis)
    if point not in points:
        where = f"the weight may hang at {', '.join(points)}" if points else "it carries no axis nor the tool point"
        raise ctx.fail(f"{point!r} is not carried by {ctx.axis}; {where}")
    return {"args": (point,)}


def levers_m(machine, axes_user: np.ndarray, axis: str, point: str) -> np.ndarray:
    """(N,) the torque about ``axis`` of a unit weight at ``point`` (an axis's origin or ``T``), m, per pose."""
    from .machine import _configurations, axes_to_si

    model = machine.model
    data = model.createData()
    jid = model.getJointId(machine.axis(axis).joint)
    pid = None if point == "T" else model.getJointId(machine.axis(point).joint)
    v = machine.axis(axis).v_index
    errors = np.zeros((len(axes_user), len(machine.configuration_parts[1])))
    out = np.zeros(len(axes_user))
    for i, q in enumerate(_configurations(machine, axes_to_si(machine, np.asarray(axes_user, float)), errors)):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        direction = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.WORLD)[3:, v]
        origin = data.oMi[jid].translation
        p = data.oMf[machine.tool_frame].translation if pid is None else data.oMi[pid].translation
        out[i] = direction @ np.cross(p - origin, DOWN)
    return out


def _values(e, q, t=None, s=None) -> np.ndarray:
    machine, axes_user = q
    return levers_m(machine, axes_user, e.axis, e.args[0]).reshape(-1, 1)


def _candidates(j, kind, *, carriers=None, machine=None, **_) -> list:
    """Every rotational location joint of a rotary axis carried by another, the weight at each point it carries."""
    if machine is None or not j.location or j.direction not in "ABC" or j.axis not in (carriers or {}):
        return []
    return [f"{j.code}:sag:{p}" for p in sag_points(machine, j.axis)]


def _extent(e, theta) -> float:
    """The largest value at a lever of 1 m (the lever of an arm's links is about that)."""
    return float(np.max(np.abs(theta))) if np.size(theta) else 0.0


register_basis(Basis(
    kind="sag", grammar=r"sag:(?P<point>[A-Za-z][A-Za-z0-9]*)", syntax="sag:<axis or T>", driver="pose",
    parse=_parse, n_params=lambda e: 1, param_names=lambda e: [e.name], param_units=lambda e, u, q: [f"{u}/m"],
    values=_values, extent=_extent, candidates=_candidates,
    describe=lambda e, u: (f"follows the torque about {e.axis} of a weight at "
                           f"{'the tool point' if e.args[0] == 'T' else e.args[0]}: a joint that gives under the "
                           f"weight it carries")))


# --- the arm's gravity compliance: one effect, a compliance per loaded joint -------------------------

#: An axis is horizontal when the cosine of its angle to gravity is below this (about 0.06°).
HORIZONTAL_COS = 1e-3


def loaded_axes(machine) -> list:
    """(axis, its location rotation about its own line) of every rotary axis that carries the tool and stays
    horizontal whatever the pose: horizontal at the zero pose, and every rotary axis before it turns about the
    vertical or about a line parallel to it (J2, J3, J4 of a UR arm: (``J2``, ``EB0J2``) …)."""
    from .derived import axis_dependent_joints, derived

    def find():
        model = machine.model
        data = model.createData()
        pin.forwardKinematics(model, data, pin.neutral(model))
        pin.computeJointJacobians(model, data, pin.neutral(model))
        rotary = [a for a in machine.axes if a.kind != "prismatic"]
        line = {a.name: pin.getJointJacobian(model, data, model.getJointId(a.joint),
                                             pin.ReferenceFrame.WORLD)[3:, a.v_index] for a in rotary}
        own = {}
        for code, axis in axis_dependent_joints(machine):
            if machine.error_joint(code).location and machine.error_joint(code).kind == "revolute":
                own.setdefault(axis, code)

        def before(a):
            jid = model.getJointId(a.joint)
            return [b for b in rotary if b.name != a.name and model.getJointId(b.joint) in model.supports[jid]]

        def steady(a):  # no axis before it turns its line's direction: each is parallel to it or stays vertical
            return all(np.linalg.norm(np.cross(line[b.name], line[a.name])) < HORIZONTAL_COS
                       or (abs(abs(line[b.name] @ DOWN) - 1.0) < HORIZONTAL_COS and steady(b)) for b in before(a))

        return tuple((a.name, own[a.name]) for a in rotary if a.chain == "tool" and a.name in own
                     and abs(line[a.name] @ DOWN) < HORIZONTAL_COS and steady(a))
    return list(derived(machine, "loaded_axes", find))


def _masses(machine) -> list:
    """(joint id, mass kg, centre in the joint's frame m) of the bodies with a mass; empty where the machine has
    none (a source URDF without ``<inertial>``)."""
    model = machine.model
    return [(b, float(model.inertias[b].mass), np.array(model.inertias[b].lever))
            for b in range(1, model.njoints) if model.inertias[b].mass > 0]


def gravity_torques(machine, axes_user: np.ndarray) -> np.ndarray:
    """(N, n_loaded) the gravity torque each axis of :func:`loaded_axes` carries, per pose: Σ m · a · ((p − o) × ĝ)
    over the chain beyond it, in kg·m (masses from the URDF, at their centres) or, where the machine has no
    masses, in unit weights × m (a unit weight at the origin of every axis it carries and at the tool point)."""
    from .machine import _configurations, axes_to_si

    model = machine.model
    data = model.createData()
    loaded = [machine.axis(a) for a, _ in loaded_axes(machine)]
    jids = [model.getJointId(a.joint) for a in loaded]
    masses = _masses(machine)
    errors = np.zeros((len(axes_user), len(machine.configuration_parts[1])))
    out = np.zeros((len(axes_user), len(loaded)))
    for i, q in enumerate(_configurations(machine, axes_to_si(machine, np.asarray(axes_user, float)), errors)):
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        for k, (a, jid) in enumerate(zip(loaded, jids)):
            direction = pin.getJointJacobian(model, data, jid, pin.ReferenceFrame.WORLD)[3:, a.v_index]
            origin = data.oMi[jid].translation
            if masses:
                weights = [(m, data.oMi[b].act(c)) for b, m, c in masses if jid in model.supports[b]]
            else:
                weights = [(1.0, data.oMi[model.getJointId(machine.axis(p).joint)].translation if p != "T" else
                            data.oMf[machine.tool_frame].translation) for p in sag_points(machine, a.name)]
            out[i, k] = sum(m * (direction @ np.cross(p - origin, DOWN)) for m, p in weights)
    return out


def _parse_gravity(m, ctx: BasisInput) -> dict:
    loaded = loaded_axes(ctx.machine)
    if not loaded or ctx.code != loaded[0][1]:
        where = (f"write it on {loaded[0][1]}, the rotation of {loaded[0][0]}, the first of them" if loaded else
                 "this machine has none")
        raise ctx.fail(f"the gravity compliance is one effect of every joint whose axis stays horizontal and "
                       f"carries the tool; {where}")
    # the loaded axes, what the torque is counted in (kg·m: the URDF's masses; m: unit weights) and its largest
    return {"args": (tuple(a for a, _ in loaded), "kg·m" if _masses(ctx.machine) else "m",
                     _largest_torques(ctx.machine))}


def _largest_torques(machine) -> tuple:
    """The largest gravity torque each loaded axis can carry (the unit of :func:`gravity_torques`): every weight
    beyond it at the full length of the chain between them (the links' lengths added: no pose reaches more)."""
    model = machine.model
    data = model.createData()
    pin.forwardKinematics(model, data, pin.neutral(model))
    pin.updateFramePlacements(model, data)

    def reach(jid, b, extra):  # the chain's length from joint jid's origin to a point ``extra`` beyond joint b's
        length = extra
        while b != jid:
            length += float(np.linalg.norm(data.oMi[b].translation - data.oMi[model.parents[b]].translation))
            b = model.parents[b]
        return length

    masses = _masses(machine)
    tool = model.frames[machine.tool_frame]
    out = []
    for a, _ in loaded_axes(machine):
        jid = model.getJointId(machine.axis(a).joint)
        if masses:
            out.append(sum(m * reach(jid, b, float(np.linalg.norm(c))) for b, m, c in masses
                           if jid in model.supports[b]))
        else:
            out.append(sum(reach(jid, model.getJointId(machine.axis(p).joint), 0.0) if p != "T" else
                           reach(jid, tool.parentJoint, float(np.linalg.norm(tool.placement.translation)))
                           for p in sag_points(machine, a)))
    return tuple(out)


def _deflection_extent(e, theta) -> float:
    """The largest turn of a loaded joint: its compliance times the largest torque it can carry."""
    return float(np.max(np.abs(np.asarray(theta, float) * np.asarray(e.args[2])))) if np.size(theta) else 0.0


register_basis(Basis(
    kind="gravity", grammar=r"gravity", syntax="gravity", driver="pose", parse=_parse_gravity,
    n_params=lambda e: len(e.args[0]), param_names=lambda e: [f"{e.name}[{a}]" for a in e.args[0]],
    param_units=lambda e, u, q: [f"{u}/{e.args[1]}" if e.args[1] == "m" else f"{u}/({e.args[1]})"] * len(e.args[0]),
    values=lambda e, q, t=None, s=None: gravity_torques(q[0], q[1]), extent=_deflection_extent,
    sign=1,
    joints=lambda e, machine: [dict(loaded_axes(machine))[a] for a in e.args[0]],
    describe=lambda e, u: (f"turns {', '.join(e.args[0])} each by its compliance times the gravity torque it carries: "
                           f"an arm that gives under its weight")))
