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

References: the joint-compliance (elastostatic) model of robot calibration, e.g. Dumas, Caro, Garnier & Furet,
"Joint stiffness identification of six-revolute industrial serial robots", Robotics and Computer-Integrated
Manufacturing 27 (2011) 881–888.
"""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from .bases import Basis, BasisInput, register_basis

__all__ = ["DOWN", "levers_m", "sag_points"]

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
