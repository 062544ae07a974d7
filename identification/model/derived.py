"""What follows from a machine's model alone (its axes' travel, its joints' geometry), computed once per machine.

A :class:`~kinid.identification.model.machine.Machine` is frozen and its Pinocchio model is not changed after loading,
so a value derived from them is kept on the machine, under a key, the first time it is asked for.
"""
from __future__ import annotations

import numpy as np

from .urdf_checks import joint_kind

__all__ = ["derived", "axis_dependent_joints"]


def derived(machine, key, make):
    """The value ``make()`` derives from ``machine``'s model, made on the first call with ``key`` and kept."""
    store = machine.__dict__.setdefault("_derived", {})
    if key not in store:
        store[key] = make()
    return store[key]


def axis_dependent_joints(machine) -> list:
    """(code, axis) of the error joints whose value may vary with the position of their axis.

    Every position-dependent joint ``E<d><k>``; and a location joint ``E<d>0<k>``
    whose motion is the same as axis ``k``'s own — a translation along the
    direction of a linear axis, or a rotation about the same line as a rotary
    axis — because it commutes with the axis, so that its value varying with
    the axis's position is the position-dependent error the URDF has no joint
    for (an arm's gear error of J2 is ``EB0J2`` varying with J2 when J2 turns
    about y).
    """
    # asked by the library, the period search and the maps alike: found once per machine
    return list(derived(machine, "axis_dependent_joints", lambda: tuple(_axis_dependent_joints(machine))))


def _axis_dependent_joints(machine) -> list:
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
        dk = data.oMi[jk].rotation @ joint_kind(machine.model.joints[jk])[1]
        if np.linalg.norm(np.cross(de, dk)) > 1e-9:
            continue  # not parallel
        offset = data.oMi[jk].translation - data.oMi[je].translation
        if e.kind == "revolute" and np.linalg.norm(np.cross(offset, dk)) > 1e-9:
            continue  # parallel rotation axes on different lines do not commute
        out.append((e.code, e.axis))
    return out
