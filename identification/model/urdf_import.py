"""An existing URDF (a ROS robot, a machine drawn elsewhere) -> a machine kinid can identify (``kinid model``).

A robot's URDF describes its nominal kinematics only. To identify its errors kinid needs error joints
(docs/machines.md): the location errors ``E<d>0<axis>`` before every motion joint, the set-up of the
measured target on the tool (``E?0T``) and of the measurement frame on the base (``E?0W``), and links
``workpiece`` and ``tool``. :func:`identification_urdf` walks the chain from the base link to the tool
link (and, for a machine tool, from the root to the workpiece link), keeps every joint's origin as a
fixed joint and every motion joint with its name, axis and limits, inserts the error joints, and can
put a measured marker offset on the tool. With every error joint at zero the result has exactly the
source's kinematics: the tool link's origin (plus the marker offset) in the workpiece frame.

Joints whose names are already ISO 230-1 codes (a machine written for kinid) are dropped: their
origin is zero and their value is the error kinid puts back. Motion joints whose names are not
letters and digits (``shoulder_pan_joint``) keep their names; their short names ``J1``, ``J2`` … in
chain order go into a ``<kinid>`` element, which Pinocchio and ROS ignore.
"""
from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from kinid.errors import DataError

__all__ = ["ChainJoint", "identification_urdf", "read_chain"]

_ISO_CODE = re.compile(r"E[XYZABC](0?)[A-Za-z][A-Za-z0-9]*")
_SHORT = re.compile(r"[A-Za-z][A-Za-z0-9]*")
#: Location error directions put before each motion joint: all six (kinid holds what the data cannot
#: identify, by name, and says with what it aliases).
LOCATION_ERRORS = ("X", "Y", "Z", "A", "B", "C")


@dataclass(frozen=True)
class ChainJoint:
    """One joint of the source on a chain: its origin (m, rad), kind, axis and limits (m or rad)."""

    name: str
    kind: str  # fixed, prismatic, revolute, continuous
    xyz: tuple
    rpy: tuple
    axis: tuple
    limit: tuple | None


def _floats(text, default, what, path):
    if not text:
        return tuple(default)
    try:
        values = tuple(float(v) for v in text.split())
    except ValueError:
        raise DataError(f"{what} is not numbers: {text!r}", path=path) from None
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise DataError(f"{what} must be 3 finite numbers, got {text!r}", path=path)
    return values


def read_chain(text: str, start: str, end: str, *, path="<urdf>") -> list:
    """The joints from link ``start`` to link ``end`` of the URDF ``text`` (root side first)."""
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise DataError(f"not a URDF (XML: {exc})", path=path) from None
    by_child = {}
    links = {link.get("name") for link in root.findall("link")}
    for j in root.findall("joint"):
        parent, child = j.find("parent"), j.find("child")
        if parent is None or child is None:
            raise DataError(f"joint {j.get('name')!r} has no parent or child link", path=path)
        origin, axis, lim = j.find("origin"), j.find("axis"), j.find("limit")
        kind = j.get("type", "")
        if kind not in ("fixed", "prismatic", "revolute", "continuous"):
            raise DataError(f"joint {j.get('name')!r} is of type {kind!r}; kinid models fixed, prismatic, revolute "
                            f"and continuous joints", path=path)
        limit = None
        if lim is not None and kind in ("prismatic", "revolute"):
            try:
                limit = (float(lim.get("lower", "nan")), float(lim.get("upper", "nan")))
            except ValueError:
                raise DataError(f"joint {j.get('name')!r}: limits are not numbers", path=path) from None
        by_child[child.get("link")] = (parent.get("link"), ChainJoint(
            j.get("name"), kind,
            _floats(origin.get("xyz") if origin is not None else None, (0, 0, 0), f"joint {j.get('name')!r} origin xyz", path),
            _floats(origin.get("rpy") if origin is not None else None, (0, 0, 0), f"joint {j.get('name')!r} origin rpy", path),
            _floats(axis.get("xyz") if axis is not None else None, (1, 0, 0), f"joint {j.get('name')!r} axis", path),
            limit))
    for name in (start, end):
        if name not in links:
            close = sorted(links)[:12]
            raise DataError(f"no link {name!r} in the URDF; links: {', '.join(close)}{' …' if len(links) > 12 else ''}",
                            path=path)
    chain, link = [], end
    while link != start:
        if link not in by_child:
            raise DataError(f"link {end!r} is not below link {start!r} in the URDF", path=path)
        link, joint = by_child[link]
        chain.append(joint)
    return chain[::-1]


def _root(text: str) -> str:
    root = ET.fromstring(text)
    children = {j.find("child").get("link") for j in root.findall("joint")}
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    return roots[0]


def identification_urdf(text: str, *, tool: str, base: str | None = None, workpiece: str | None = None,
                        tool_offset_m=(0.0, 0.0, 0.0), position_errors: bool = False, name: str | None = None,
                        path="<urdf>") -> str:
    """The identification machine of the URDF ``text`` (see the module docstring).

    Parameters
    ----------
    tool : str
        The link the measured point is fixed to (an arm's flange, a machine's spindle or camera).
    base : str, optional
        The link both chains start from (default: the URDF's root).
    workpiece : str, optional
        The link the measurement frame is fixed to (a machine tool's table); default ``base`` (a robot
        measured by a tracker standing by it).
    tool_offset_m : (3,)
        The measured point in the ``tool`` link's frame, metres (a marker on the flange).
    position_errors : bool
        Also the six position-dependent error joints ``E?<axis>`` after every motion joint (a machine
        tool's straightness, positioning and angular errors; not needed for an arm's gear errors, which
        the location joint about the same line takes).
    """
    from .urdf_builder import Axis, Fixed, machine_urdf, setup

    base = base or _root(text)
    workpiece = workpiece or base
    tool_chain = read_chain(text, base, tool, path=path)
    work_chain = read_chain(text, base, workpiece, path=path)
    # a segment both chains share moves both ends alike: the relative pose does not see it
    shared = 0
    while shared < min(len(tool_chain), len(work_chain)) and tool_chain[shared] == work_chain[shared]:
        shared += 1
    moving = [j.name for j in tool_chain[:shared] if j.kind != "fixed" and not _ISO_CODE.fullmatch(j.name)]
    if moving:
        raise DataError(f"the workpiece and tool chains share motion joint(s) {', '.join(moving)}: give as --base a "
                        f"link below them", path=path)
    renamed = {}

    def elements(chain):
        out = []
        for j in chain:
            if _ISO_CODE.fullmatch(j.name) and j.xyz == (0.0, 0.0, 0.0) and j.rpy == (0.0, 0.0, 0.0):
                continue  # an error joint of a machine written for kinid: zero, and put back below
            if j.xyz != (0.0, 0.0, 0.0) or j.rpy != (0.0, 0.0, 0.0) or j.kind == "fixed":
                out.append(Fixed(f"{j.name}_origin", j.xyz, j.rpy))  # (a kept name could clash with the mounts)
            if j.kind == "fixed":
                continue
            short = j.name if _SHORT.fullmatch(j.name) and not j.name.startswith("E") else f"J{len(renamed) + 1}"
            renamed[short] = j.name
            kind = "prismatic" if j.kind == "prismatic" else "revolute"
            limit = j.limit if j.limit is not None and all(math.isfinite(v) for v in j.limit) else (
                (-2 * math.pi, 2 * math.pi) if kind == "revolute" else (-10.0, 10.0))
            norm = math.sqrt(sum(v * v for v in j.axis))
            if not norm > 0:
                raise DataError(f"joint {j.name!r} has a zero axis", path=path)
            out.append(Axis(short, kind, tuple(v / norm for v in j.axis), location_errors=LOCATION_ERRORS,
                            pdge=position_errors, limit=limit))
        return out

    work = elements(work_chain[shared:]) + [setup("W", "set-up of the measurement frame")]
    tool_elements = elements(tool_chain[shared:])
    offset = tuple(float(v) for v in tool_offset_m)
    if any(v != 0.0 for v in offset):
        tool_elements.append(Fixed("measured_point", offset))
    tool_elements.append(setup("T", "set-up of the measured point on the tool"))
    robot = name or ET.fromstring(text).get("name", "machine")
    out = machine_urdf(f"{robot}_kinid", work, tool_elements,
                       f"Identification machine of {robot} (kinid model): chains {base} -> {workpiece} and "
                       f"{base} -> {tool}, location errors before every motion joint, set-up joints at both ends.")
    # motion joints keep the source's names; their short names go into the <kinid> element
    mapping = []
    for short, original in renamed.items():
        if short != original:
            out = out.replace(f'<joint name="{short}" type=', f'<joint name="{original}" type=', 1)
            mapping.append(f'    <axis joint="{original}" name="{short}"/>')
    if mapping:
        out = out.replace("</robot>", "  <kinid>\n" + "\n".join(mapping) + "\n  </kinid>\n</robot>")
    return out
