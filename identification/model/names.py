"""Plain names of ISO 230-1 error codes and of effects, for reports ("EXX" -> "positioning error of X").

ISO 230-1 names the errors of a linear axis as its positioning error, two straightness errors and three
angular errors (one of them its roll); those of a rotary axis as its angular positioning error, two
radial motions, an axial motion and two tilt motions; the location errors of an axis line as its
position and orientation (squareness); kinid adds the set-up of the workpiece (W) and of the
tool/sensor (T).
"""
from __future__ import annotations

import re

import numpy as np

__all__ = ["plain_name", "effect_description", "axis_directions"]

_CODE = re.compile(r"^E([XYZABC])(0?)([A-Z][A-Z0-9]*)$")
_ABOUT = {"A": "X", "B": "Y", "C": "Z"}
#: ISO 841 axis letters: (kind, the direction it moves along or turns about).
ISO_AXES = {"X": ("linear", "X"), "Y": ("linear", "Y"), "Z": ("linear", "Z"), "U": ("linear", "X"),
            "V": ("linear", "Y"), "W": ("linear", "Z"), "A": ("rotary", "X"), "B": ("rotary", "Y"),
            "C": ("rotary", "Z")}


def axis_directions(machine) -> dict:
    """axis name -> (kind, direction letter) from a machine: the joint's axis in its own frame."""
    from .machine import joint_kind

    out = {}
    for a in machine.axes:
        _, direction = joint_kind(machine.model.joints[machine.model.getJointId(a.joint)])
        letter = "XYZ"[int(np.argmax(np.abs(direction)))]
        out[a.name] = ("linear" if a.kind == "prismatic" else "rotary", letter)
    return out


def plain_name(code: str, axes=None) -> str:
    """A plain-language name of an error code; the code itself if it is not one.

    Parameters
    ----------
    code : str
        ``EXX``, ``EYX``, ``EC0Y``, ``EX0W``, ``EB0J2`` …
    axes : dict, optional
        Axis name -> (``"linear"`` or ``"rotary"``, direction letter it moves along or turns about),
        e.g. from :func:`axis_directions`; default the ISO 841 letters.

    Examples
    --------
    >>> plain_name("EXX"), plain_name("EZX"), plain_name("ECC"), plain_name("EC0Y")
    ('positioning error of X', 'straightness of X in Z', 'angular positioning error of C', 'squareness of Y about Z')
    """
    m = _CODE.match(code)
    if not m:
        return code
    d, zero, k = m.group(1), m.group(2) == "0", m.group(3)
    if k in ("W", "T"):
        what = "workpiece (board)" if k == "W" else "tool (sensor)"
        return f"{what} set-up offset in {d}" if d in "XYZ" else f"{what} set-up rotation about {_ABOUT[d]}"
    kind, along = (axes or ISO_AXES).get(k, ISO_AXES.get(k, ("linear", None)))
    if zero:
        if d in "XYZ":
            return f"position of the {k} axis line in {d}"
        if kind == "linear":
            return f"squareness of {k} about {_ABOUT[d]}"
        return f"zero offset of {k}" if _ABOUT[d] == along else f"tilt of the {k} axis line about {_ABOUT[d]}"
    if kind == "linear":
        if d in "XYZ":
            return f"positioning error of {k}" if d == along else f"straightness of {k} in {d}"
        return f"roll of {k}" if _ABOUT[d] == along else f"angular error of {k} about {_ABOUT[d]}"
    if d in "ABC":
        return f"angular positioning error of {k}" if _ABOUT[d] == along else f"tilt motion of {k} about {_ABOUT[d]}"
    return f"axial motion of {k}" if d == along else f"radial motion of {k} in {d}"


def effect_description(effect, unit_of_axis: str = "") -> str:
    """How an effect varies, in words: "constant", "periodic in X, period 10 mm" … (its basis says)."""
    from .bases import basis_of

    return basis_of(effect).describe(effect, f" {unit_of_axis}" if unit_of_axis else "")
