"""An existing URDF (a ROS robot, a machine drawn elsewhere) -> a machine kinid can identify (``kinid model``).

A robot's URDF describes its nominal kinematics only. To identify its errors kinid needs error joints
(docs/machines.md): the location errors ``E<d>0<axis>`` before every motion joint, the set-up of the
measured target on the tool (``E?0T``) and of the measurement frame on the base (``E?0W``), and links
``workpiece`` and ``tool``. :func:`identification_urdf` walks the chain from the base link to the tool
link (and, for a machine tool, from the root to the workpiece link), keeps every joint's origin as a
fixed joint and every motion joint with its name, axis and limits (and each link's ``<inertial>``, where given, on
the link of the same frame: the gravity compliance's masses), inserts the error joints, and can
put a measured marker offset on the tool. With every error joint at zero the result has exactly the
source's kinematics: the tool link's origin (plus the marker offset) in the workpiece frame.

Joints whose names are already ISO 230-1 codes (a machine written for kinid) are dropped: their
origin is zero and their value is the error kinid puts back. A motion joint whose name kinid's loader
reads back as an axis name (capital letters and digits, not starting with E: ``X``, ``B``, ``A1``) keeps
it; any other (``shoulder_pan_joint``, ``j1``, ``elbow``) keeps its name in the URDF and gets a short
name ``J<n>`` (n its place among the motion joints) in a ``<kinid>`` element, which Pinocchio and ROS
ignore. The source is read by :func:`read_source`: the checks of kinid's own machine loader (size, no
DOCTYPE or entities, XML errors with their line and column, no loop, no xacro).
"""
from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from kinid.errors import DataError
from kinid.untrusted import shown_path as shown

from .urdf_checks import check_urdf_limits

__all__ = ["ChainJoint", "identification_urdf", "read_chain", "read_source"]

_ISO_CODE = re.compile(r"E[XYZABC](0?)[A-Za-z][A-Za-z0-9]*")
#: A motion joint's name that kinid's loader reads back as the axis name (its error joints E?0<name>).
_KEPT = re.compile(r"[A-DF-Z][A-Z0-9]*")
#: A name written into the identification machine as it is (else a made-up one).
_PLAIN = re.compile(r"[A-Za-z0-9_.\-]+")
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


def read_source(text: str, *, path="<urdf>") -> ET.Element:
    """The parsed XML root of a source URDF, through the checks of kinid's machine loader (size, no DOCTYPE or
    entities, XML errors with line and column, a robot element, no joint loop, no chain deeper than a machine's,
    no xacro macro): every refusal a one-line :class:`~kinid.errors.MachineError` naming ``path``."""
    return check_urdf_limits(text, path)


def read_chain(text, start: str, end: str, *, path="<urdf>", options=("base", "tool")) -> list:
    """The joints from link ``start`` to link ``end`` of the URDF (text, or a root of :func:`read_source`), root side
    first. ``options`` name the arguments that gave ``start`` and ``end``, for messages."""
    root = read_source(text, path=path) if isinstance(text, str) else text
    by_child = {}
    links = {link.get("name") for link in root.findall("link")}
    for j in root.findall("joint"):
        parent, child = j.find("parent"), j.find("child")
        name = repr(j.get("name"))
        if parent is None or child is None:
            raise DataError(f"joint {name} has no parent or child link", path=path)
        if child.get("link") in by_child:
            raise DataError(f"link {child.get('link')!r} is the child of two joints "
                            f"({by_child[child.get('link')][1].name!r} and {name}); a URDF is a tree", path=path)
        origin, axis, lim = j.find("origin"), j.find("axis"), j.find("limit")
        kind = j.get("type", "")
        if kind not in ("fixed", "prismatic", "revolute", "continuous"):
            raise DataError(f"joint {name} is of type {kind!r}; kinid models fixed, prismatic, revolute "
                            f"and continuous joints", path=path)
        limit = None
        if lim is not None and kind in ("prismatic", "revolute"):
            try:
                limit = (float(lim.get("lower", "nan")), float(lim.get("upper", "nan")))
            except ValueError:
                raise DataError(f"joint {name}: limits are not numbers", path=path) from None
        by_child[child.get("link")] = (parent.get("link"), ChainJoint(
            j.get("name"), kind,
            _floats(origin.get("xyz") if origin is not None else None, (0, 0, 0), f"joint {name} origin xyz", path),
            _floats(origin.get("rpy") if origin is not None else None, (0, 0, 0), f"joint {name} origin rpy", path),
            _floats(axis.get("xyz") if axis is not None else None, (1, 0, 0), f"joint {name} axis", path),
            limit))
    for name, option in ((start, options[0]), (end, options[1])):
        if name not in links:
            close = [shown(n) for n in sorted(links, key=str)[:12]]
            raise DataError(f"names no link {name!r} in the URDF; links: {', '.join(close)}"
                            f"{' …' if len(links) > 12 else ''}", path=path, parameter=option)
    chain, link = [], end
    while link != start:
        if link not in by_child or len(chain) > len(by_child):
            raise DataError(f"names link {end!r}, which is not below link {start!r} in the URDF", path=path,
                            parameter=options[1])
        link, joint = by_child[link]
        chain.append(joint)
    return chain[::-1]


def _root(root, path) -> str:
    children = {j.find("child").get("link") for j in root.findall("joint") if j.find("child") is not None}
    roots = [link.get("name") for link in root.findall("link") if link.get("name") not in children]
    if not roots:
        raise DataError("the URDF has no root link (every link is some joint's child)", path=path)
    return roots[0]


def _comment(text: str) -> str:
    """``text`` fit for an XML comment and a terminal: unprintable characters escaped, no ``--``."""
    return shown(text).replace("--", "- -")


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

    from xml.sax.saxutils import quoteattr

    root = read_source(text, path=path)
    base = base or _root(root, path)
    workpiece = workpiece or base
    tool_chain = read_chain(root, base, tool, path=path, options=("base", "tool"))
    work_chain = read_chain(root, base, workpiece, path=path, options=("base", "workpiece"))
    # a segment both chains share moves both ends alike: the relative pose does not see it
    shared = 0
    while shared < min(len(tool_chain), len(work_chain)) and tool_chain[shared] == work_chain[shared]:
        shared += 1
    moving = [shown(j.name) for j in tool_chain[:shared] if j.kind != "fixed" and not _ISO_CODE.fullmatch(j.name)]
    if moving:
        raise DataError(f"the workpiece and tool chains share motion joint(s) {', '.join(moving)}: give as --base a "
                        f"link below them", path=path)
    motion = [j for j in work_chain[shared:] + tool_chain[shared:] if j.kind != "fixed"
              and not (_ISO_CODE.fullmatch(j.name) and j.xyz == (0.0, 0.0, 0.0) and j.rpy == (0.0, 0.0, 0.0))]
    short_names = _short_names([j.name for j in motion])
    renamed = {}
    child_of = {j.get("name"): j.find("child").get("link") for j in root.findall("joint")}
    carried = {}  # identification link -> the source link whose <inertial> it carries (the same frame)

    def elements(chain):
        out = []
        for j in chain:
            if _ISO_CODE.fullmatch(j.name) and j.xyz == (0.0, 0.0, 0.0) and j.rpy == (0.0, 0.0, 0.0):
                continue  # an error joint of a machine written for kinid: zero, and put back below
            if j.xyz != (0.0, 0.0, 0.0) or j.rpy != (0.0, 0.0, 0.0) or j.kind == "fixed":
                label = j.name if _PLAIN.fullmatch(j.name) else f"joint{len(out) + 1}_{len(renamed) + 1}"
                out.append(Fixed(f"{label}_origin", j.xyz, j.rpy))  # (a kept name could clash with the mounts)
            if j.kind == "fixed":
                carried[f"{out[-1].name}_link"] = child_of[j.name]
                continue
            carried[f"{short_names[j.name].lower()}_link"] = child_of[j.name]
            short = short_names[j.name]
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
    robot = name or root.get("name", "machine")
    robot = robot if _PLAIN.fullmatch(robot) else "machine"
    out = machine_urdf(f"{robot}_kinid", work, tool_elements, _comment(
        f"Identification machine of {robot} (kinid model): chains {base} -> {workpiece} and {base} -> {tool}, "
        f"location errors before every motion joint, set-up joints at both ends."))
    out = _with_inertials(out, root, carried, path)
    # motion joints keep the source's names; their short names go into the <kinid> element
    mapping = []
    for short, original in renamed.items():
        if short != original:
            out = out.replace(f'<joint name="{short}" type=', f'<joint name={quoteattr(original)} type=', 1)
            mapping.append(f'    <axis joint={quoteattr(original)} name="{short}"/>')
    if mapping:
        out = out.replace("</robot>", "  <kinid>\n" + "\n".join(mapping) + "\n  </kinid>\n</robot>")
    return out


def _with_inertials(out: str, root, carried: dict, path) -> str:
    """``out`` with each source link's mass and centre (its ``<inertial>``: the gravity compliance's torques,
    docs/formats.md) on the identification link of the same frame, where the source gives a mass."""
    links = {link.get("name"): link for link in root.findall("link")}
    for link, source in carried.items():
        inertial = links[source].find("inertial") if source in links else None
        mass = inertial.find("mass") if inertial is not None else None
        if mass is None:
            continue
        what = f"link {shown(source)!r} <inertial>"
        try:
            kg = float(mass.get("value", "nan"))
        except ValueError:
            raise DataError(f"{what} mass is not a number: {mass.get('value')!r}", path=path) from None
        if not (math.isfinite(kg) and kg >= 0):
            raise DataError(f"{what} mass must be a finite number ≥ 0 kg, got {mass.get('value')!r}", path=path)
        origin = inertial.find("origin")
        xyz = _floats(origin.get("xyz") if origin is not None else None, (0, 0, 0), f"{what} origin xyz", path)
        rpy = _floats(origin.get("rpy") if origin is not None else None, (0, 0, 0), f"{what} origin rpy", path)
        tensor = inertial.find("inertia")
        moments = {}
        for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
            try:
                moments[k] = float(tensor.get(k, "0") if tensor is not None else "0")
            except ValueError:
                moments[k] = math.nan
            if not math.isfinite(moments[k]):
                raise DataError(f"{what} inertia {k} must be a finite number, got {tensor.get(k)!r}", path=path)
        attrs = " ".join(f'{k}="{v!r}"' for k, v in moments.items())
        xyz_text, rpy_text = " ".join(map(repr, xyz)), " ".join(map(repr, rpy))
        text = (f'<inertial><mass value="{kg!r}"/><origin xyz="{xyz_text}" rpy="{rpy_text}"/><inertia {attrs}/>'
                f'</inertial>')
        out = out.replace(f'  <link name="{link}"/>', f'  <link name="{link}">{text}</link>', 1)
    return out


def _short_names(joints) -> dict:
    """Motion joint name -> its axis name in kinid: the name itself where kinid's loader reads it back as one
    (:data:`_KEPT`, not W or T), else ``J<n>`` with n its place among ``joints`` (the next free number where a
    kept name took it)."""
    kept = {n for n in joints if _KEPT.fullmatch(n) and n not in ("W", "T")}
    out, taken = {}, set(kept)
    for n, joint in enumerate(joints, start=1):
        if joint in kept:
            out[joint] = joint
            continue
        while f"J{n}" in taken:
            n += 1
        out[joint] = f"J{n}"
        taken.add(f"J{n}")
    return out
