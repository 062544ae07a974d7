"""SINUMERIK swivel data for CYCLE800: one record of the ``$TC_CARR`` toolholder parameters as a part program.

The record's chain, as the SINUMERIK manuals define it (kinid writes the vectors in this sense, every
vector in the machine frame at the home position, mm; axis vectors unit, a + reading turning
right-handed about its vector):

- kinematic type T (the tool turns): l1 from the reference point to the pivot of the 1st rotary
  axis, l2 from there to the pivot of the 2nd, l3 from there back to the tool reference point; the
  tool point is ``l1 + R(v1, α1)·(l2 + R(v2, α2)·l3)`` from the reference point, l1 = −(l2 + l3);
- type P (the part turns): l2 from the reference point to the pivot of the 1st rotary axis, l3 from
  there to the pivot of the 2nd, l4 closing the chain; a point ``p`` of the table is at
  ``l2 + R(v1, α1)·(l3 + R(v2, α2)·(l4 + p))``, l4 = −(l2 + l3);
- type M (one of each): the head's axis is v1 (l1 to its pivot, l2 back, l1 = −l2), the table's v2
  (l3 to its pivot, l4 back, l4 = −l3).

The reference point is kinid's tool point with every axis at 0; ``$TC_CARR21/22`` name the axes.
"""
from __future__ import annotations

from .formats import KinematicsFit, KinematicsFormat, check_geometry, number, register_kinematics_format

__all__ = ["sinumerik_swivel_text", "swivel_vectors", "SWIVEL_RECORD"]

#: The swivel data record kinid writes (the ``n`` of ``$TC_CARR1[n]``); set another in the file if the machine
#: has several.
SWIVEL_RECORD = 1

_TYPE = {"head-head": "T", "head": "T", "table-table": "P", "table": "P", "head-table": "M"}


def _neg(v):
    return tuple(-x for x in v)


def _minus(a, b):
    return tuple(x - y for x, y in zip(a, b))


def swivel_vectors(geometry) -> dict:
    """The record's vectors ``l1 l2 l3 l4 v1 v2`` (mm, unit) and kinematic type ``T``/``P``/``M`` of ``geometry``."""
    g = check_geometry(geometry)
    zero = (0.0, 0.0, 0.0)
    axes = g.axes
    p = [a.pivot_mm for a in axes]
    v = [a.direction for a in axes] + [zero] * (2 - len(axes))
    kind = _TYPE[g.kind]
    if g.kind == "head-head":
        ls = (p[0], _minus(p[1], p[0]), _neg(p[1]), zero)
    elif g.kind == "head":
        ls = (p[0], _neg(p[0]), zero, zero)
    elif g.kind == "table-table":
        ls = (zero, p[0], _minus(p[1], p[0]), _neg(p[1]))
    elif g.kind == "table":
        ls = (zero, p[0], _neg(p[0]), zero)
    else:  # head-table: the head's axis is v1
        ls = (p[0], _neg(p[0]), p[1], _neg(p[1]))
    return {"type": kind, "l1": ls[0], "l2": ls[1], "l3": ls[2], "l4": ls[3], "v1": v[0], "v2": v[1],
            "axes": tuple(a.name for a in axes)}


def sinumerik_swivel_text(geometry, comment: str = "") -> str:
    """The ``$TC_CARR`` assignments of swivel data record :data:`SWIVEL_RECORD` as a part program (MPF)."""
    s = swivel_vectors(geometry)
    n = SWIVEL_RECORD
    lines = ["%_N_KINID_CYCLE800_MPF", ";$PATH=/_N_MPF_DIR"]
    if comment:
        lines.append(f"; {comment}")
    lines += [f"; swivel data record {n} of {geometry.machine}: kinematic type {s['type']} "
              f"({ {'T': 'the tool turns', 'P': 'the part turns', 'M': 'tool and part turn'}[s['type']]}); "
              f"rotary axes {' then '.join(s['axes'])}",
              "; vectors in mm in the machine frame with every axis at 0, the reference point at the tool point; "
              "axis vectors unit, + turning right-handed about them",
              f"; linear axes: {geometry.mapping_words()} (the controller's coordinates of the tool relative to the "
              f"part)"]
    slots = (("l1", 1), ("l2", 4), ("v1", 7), ("v2", 10), ("l3", 15), ("l4", 18))
    for key, first in slots:
        digits = 9 if key.startswith("v") else 6
        lines += [f"$TC_CARR{first + i}[{n}]={number(x, digits)}" for i, x in enumerate(s[key])]
    lines.append(f"$TC_CARR21[{n}]={s['axes'][0]}")
    if len(s["axes"]) > 1:
        lines.append(f"$TC_CARR22[{n}]={s['axes'][1]}")
    lines += [f'$TC_CARR23[{n}]="{s["type"]}"', "M30"]
    return "\n".join(lines) + "\n"


def _fit(geometry) -> KinematicsFit:
    g = check_geometry(geometry)
    if len(g.axes) not in (1, 2):
        return KinematicsFit(False, (f"a swivel data record holds one or two rotary axes, {g.machine} has "
                                     f"{len(g.axes)}",))
    return KinematicsFit(True)


SINUMERIK_SWIVEL = register_kinematics_format(KinematicsFormat(
    name="sinumerik", title="SINUMERIK swivel data record for CYCLE800 ($TC_CARR)", file_name="KINID_CYCLE800.MPF",
    fit=_fit, write=sinumerik_swivel_text))
