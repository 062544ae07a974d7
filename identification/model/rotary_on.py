"""An error of one rotary axis that follows another rotary axis's angle: ``EA0C:on:A`` (basis kind ``on``).

A table C carried by a trunnion A: its bearing sags as A tilts, so C's location (its tilt, its offset) varies
with A's angle. As a smooth function of an angle it is a Fourier series in that angle; the first harmonic
(the default order) holds a sag with gravity, order k the harmonics 1..k::

    value = Σ_{n=1..k} a_n·(cos(n·α) − 1) + b_n·sin(n·α),   α = angle of the other axis (deg)

Every term is zero at α = 0, so the joint's constant (in the default model) stays its value at the other axis's
zero. The effect's own axis (``Effect.axis``) is the joint's; the other axis is ``Effect.args[0]``, the order
``Effect.degree``. It is registered after the other bases (:mod:`~kinid.identification.model.bases`), when
:mod:`~kinid.identification.model.effects` (which parses every effect name) imports it; its candidates are the
location joints of each rotary axis on the rotary axis that carries it (the nearest rotary axis between it and
the base in the URDF's chain: C on the trunnion A of an A/C table), where the data read that axis at
:data:`MIN_ANGLES` distinct angles at least — order 1 only: four on a five-axis table-table machine, none where
the two rotary axes are in different chains (head and table), one per location joint of each joint of an arm but
its first. Any other pair is named with ``--add``.
"""
from __future__ import annotations

import numpy as np

from .bases import Basis, BasisInput, register_basis

__all__ = ["MAX_ORDER", "MIN_ANGLES", "on_values", "rotary_carriers"]

#: Highest harmonic an ``on:<axis>:<k>`` effect may have.
MAX_ORDER = 4
#: The other axis must be read at this many distinct angles at least for the candidates (2 parameters and the
#: joint's constant).
MIN_ANGLES = 3


def _parse(m, ctx: BasisInput) -> dict:
    other = m.group("other")
    machine = ctx.machine
    if other not in machine.axis_names:
        raise ctx.fail(f"{other!r} is not an axis of this machine; axes: {', '.join(machine.axis_names)}")
    if other == ctx.axis:
        raise ctx.fail(f"the other axis must differ from the joint's own axis {ctx.axis}; use periodic:<P> for that")
    if ctx.axis_kind == "prismatic" or machine.axis(other).kind == "prismatic":
        raise ctx.fail(f"on:<axis> is for a rotary axis's error that follows another rotary axis ({ctx.axis} and "
                       f"{other} must both be rotary); for linear axes use with:<other axis>")
    order = int(m.group("order") or 1)
    if not 1 <= order <= MAX_ORDER:
        raise ctx.fail(f"the order must be 1 to {MAX_ORDER}, got {m.group('order')}")
    return {"args": (other,), "degree": order}


def on_values(e, q, t=None, s=None) -> np.ndarray:
    """(N, 2k) values: per harmonic n = 1..k, cos(n·α) − 1 and sin(n·α); ``q`` (N, 2), α = ``q[:, 1]`` in deg."""
    alpha = np.radians(np.asarray(q, float)[:, 1])
    cols = []
    for n in range(1, e.degree + 1):
        cols += [np.cos(n * alpha) - 1.0, np.sin(n * alpha)]
    return np.stack(cols, axis=1)


def _names(e) -> list:
    out = []
    for n in range(1, e.degree + 1):
        angle = f"{n if n > 1 else ''}{e.args[0]}"
        out += [f"{e.name}[cos {angle}]", f"{e.name}[sin {angle}]"]
    return out


def _size(e, beta, cov):
    """The first harmonic's amplitude and its σ."""
    b = np.asarray(beta[:2], float)
    amp = float(np.hypot(*b))
    g = b / amp if amp > 0 else np.array([1.0, 0.0])
    return amp, float(np.sqrt(max(g @ np.asarray(cov)[:2, :2] @ g, 0.0)))


def _extent(e, theta) -> float:
    """The largest value over a whole turn of the other axis."""
    alpha = np.linspace(0.0, 360.0, 721)
    values = on_values(e, np.stack([np.zeros_like(alpha), alpha], axis=1)) @ np.asarray(theta, float)
    return float(np.max(np.abs(values))) if np.size(theta) else 0.0


def _describe(e, u) -> str:
    other = e.args[0]
    terms = "first harmonic" if e.degree == 1 else f"harmonics 1 to {e.degree}"
    return f"varies with the angle of {other} ({terms}, zero at {other} = 0): a bearing or trunnion that sags as {other} turns"


def rotary_carriers(machine) -> dict:
    """Rotary axis name -> the rotary axis that carries it: the nearest one between it and the base in the URDF's
    chain (C -> A on an A/C table; none for a head's B and a table's C, in different chains)."""
    model = machine.model
    rotary = {model.getJointId(a.joint): a.name for a in machine.axes if a.kind != "prismatic"}
    out = {}
    for jid, name in rotary.items():
        p = model.parents[jid]
        while p > 0 and p not in rotary:
            p = model.parents[p]
        if p > 0:
            out[name] = rotary[p]
    return out


def _candidates(j, kind, *, carriers=None, positions=None, **_) -> list:
    """Order 1 on every location joint of a rotary axis, on the rotary axis that carries it (``carriers``, from
    :func:`rotary_carriers`) where that axis is read at MIN_ANGLES angles or more (``positions``; where the
    angles read are not known, always)."""
    other = (carriers or {}).get(j.axis) if j.location else None
    if other is None or (positions is not None and positions.get(other, 0) < MIN_ANGLES):
        return []
    return [f"{j.code}:on:{other}"]


register_basis(Basis(
    kind="on", grammar=r"on:(?P<other>[A-Za-z][A-Za-z0-9]*)(?::(?P<order>[0-9]+))?", syntax="on:<rotary axis>[:<k>]",
    driver="positions", parse=_parse, n_params=lambda e: 2 * e.degree, param_names=_names,
    param_units=lambda e, u, q: [u] * (2 * e.degree), values=on_values, describe=_describe, size=_size,
    extent=_extent, candidates=_candidates))
