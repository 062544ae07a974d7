"""An error joint's value that jumps where an axis passes a position: ``EZZ:step:Y:40`` (basis kind ``step``).

Two glass scales that meet at Y = 40 mm, a rail's joint, a cover or a cable chain that seats as an axis passes: an
error joint holds one constant on one side of a position of an axis — the joint's own axis or any other — and
another constant on the other side. The effect has one parameter, the jump ``s`` (the value beyond the position
minus the value before it)::

    value = s · (H(q − p) − H(−p)),   H(x) = 1 for x > 0, else 0,   q = the reading of the axis named, p = its position

zero at the axis's zero like every other basis (the joint's constant stays its value there). The axis named drives
the effect (:attr:`Effect.axis` is that axis, whichever the joint's own: a set-up joint's too, a sensor that shifts
as an axis passes a position). No candidate is listed: the diagnosis searches the position between the readings
(:mod:`~kinid.identification.diagnosis.steps`). Between two neighbouring readings of the axis a step anywhere fits
the data alike: the data place it only within that interval, and the name carries a point of it (the middle).

A compensation table of the joint's own axis holds a step of that axis (the table's check says how closely its
controller's interpolation between grid points follows the jump); a step at another axis's position is a cross
compensation, left out (:mod:`~kinid.identification.compensation.compensate`).
"""
from __future__ import annotations

import numpy as np

from .bases import NUMBER, Basis, BasisInput, register_basis

__all__ = ["step_values"]


def _parse(m, ctx: BasisInput) -> dict:
    machine, axis = ctx.machine, m.group("axis")
    if axis not in machine.axis_names:
        raise ctx.fail(f"{axis!r} is not an axis of this machine; axes: {', '.join(machine.axis_names)}")
    at = float(m.group("at"))
    if not np.isfinite(at):
        raise ctx.fail(f"the step's position must be a finite number, got {m.group('at')}")
    # not checked against the URDF's travel: the diagnosis places a step between readings, which may lie beyond a
    # travel the URDF states too short (a step beyond every reading is a constant, which the fit holds as aliased)
    return {"axis": axis, "args": (at,)}


def step_values(e, q, t=None, s=None) -> np.ndarray:
    """(N, 1) values of the step ``e`` at readings ``q`` (N,) of its axis: 1 beyond its position, 0 before it, less
    its value at the axis's zero."""
    at = float(e.args[0])
    q = np.asarray(q, float)
    return ((q > at).astype(float) - float(0.0 > at)).reshape(-1, 1)


def _describe(e, u) -> str:
    return (f"a step where {e.axis} passes {e.args[0]:g}{u}: one constant before, another beyond "
            f"(zero at {e.axis} = 0)")


register_basis(Basis(
    kind="step", grammar=rf"step:(?P<axis>[A-Za-z][A-Za-z0-9]*):(?P<at>[-+]?{NUMBER})", syntax="step:<axis>:<at>",
    driver="position", parse=_parse, n_params=lambda e: 1, param_names=lambda e: [e.name],
    param_units=lambda e, u, q: [u], values=step_values, describe=_describe, chosen="step position",
    axis_named=True))
