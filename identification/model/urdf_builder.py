"""Write machine URDFs with ISO 230-1 error joints (docs/machines.md).

A machine is described as two chains from the root: the workpiece chain
(ending at link ``workpiece``) and the tool chain (ending at link ``tool``).
Each chain is a list of elements:

- :class:`Fixed` — nominal structure (an offset and/or rotation, SI units);
- :class:`Axis` — a motion axis with, optionally, its six position-dependent
  error joints ``E<d><k>`` after it and the named location error joints
  ``E<d>0<k>`` before it;
- :func:`setup` adds the six set-up joints of pseudo-axis ``W`` or ``T``.

Used to generate the shipped machines in ``urdf/`` and the machine variants of
the tests, so that every URDF follows the same convention.

Examples
--------
>>> text = machine_urdf("tiny", [Axis("Y", "prismatic", (0, 1, 0))], [Axis("X", "prismatic", (1, 0, 0))])
>>> "<joint name=\\"EXY\\" type=\\"prismatic\\">" in text
True
"""
from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["Fixed", "Axis", "machine_urdf", "DIRECTIONS"]

#: Error direction letter -> (joint type, unit axis in the parent frame).
DIRECTIONS = {
    "X": ("prismatic", (1, 0, 0)),
    "Y": ("prismatic", (0, 1, 0)),
    "Z": ("prismatic", (0, 0, 1)),
    "A": ("revolute", (1, 0, 0)),
    "B": ("revolute", (0, 1, 0)),
    "C": ("revolute", (0, 0, 1)),
}


@dataclass(frozen=True)
class Fixed:
    """Nominal structure: a fixed joint with origin ``xyz_m`` (metres) and ``rpy_rad`` (radians)."""

    name: str
    xyz_m: tuple = (0.0, 0.0, 0.0)
    rpy_rad: tuple = (0.0, 0.0, 0.0)
    comment: str = ""


@dataclass(frozen=True)
class Axis:
    """A motion axis.

    Parameters
    ----------
    name : str
        ISO 841 letter (``X``..``W``, ``A``..``C``) or another name not starting with ``E``.
    kind : {"prismatic", "revolute"}
    direction : tuple of 3 floats
        Unit axis in the parent frame.
    location_errors : tuple of str
        Direction letters of the location errors ``E<d>0<name>`` placed before the axis.
    pdge : bool
        Whether the six position-dependent error joints ``E<d><name>`` follow the axis.
    limit : tuple of 2 floats
        Travel, metres or radians.
    comment : str
        Nominal geometry, written into the URDF as an XML comment.
    """

    name: str
    kind: str
    direction: tuple
    location_errors: tuple = ()
    pdge: bool = True
    limit: tuple = (-1.0, 1.0)
    comment: str = ""


@dataclass(frozen=True)
class _Setup:
    name: str  # "W" or "T"
    comment: str = ""


def setup(name: str, comment: str = "") -> _Setup:
    """The six set-up joints ``E?0W`` (workpiece) or ``E?0T`` (tool)."""
    if name not in ("W", "T"):
        raise ValueError(f"set-up pseudo-axis must be 'W' or 'T', got {name!r}")
    return _Setup(name, comment)


@dataclass
class _Writer:
    lines: list = field(default_factory=list)
    parent: str = "base"
    links: set = field(default_factory=lambda: {"base"})

    def link(self, name):
        if name not in self.links:
            self.links.add(name)
            self.lines.append(f'  <link name="{name}"/>')

    def joint(self, name, kind, child, xyz=(0, 0, 0), rpy=(0, 0, 0), axis=None, limit=None, comment=""):
        self.link(child)
        if comment:
            self.lines.append(f"  <!-- {comment} -->")
        self.lines.append(f'  <joint name="{name}" type="{kind}">')
        self.lines.append(f'    <parent link="{self.parent}"/>')
        self.lines.append(f'    <child link="{child}"/>')
        self.lines.append(f'    <origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>')
        if axis is not None:
            self.lines.append(f'    <axis xyz="{_fmt(axis)}"/>')
        if limit is not None:
            self.lines.append(
                f'    <limit lower="{limit[0]:g}" upper="{limit[1]:g}" effort="1000" velocity="1"/>'
            )
        self.lines.append("  </joint>")
        self.parent = child

    def error_joint(self, code, letter, comment=""):
        kind, axis = DIRECTIONS[letter]
        limit = (-0.1, 0.1) if kind == "prismatic" else (-0.5, 0.5)
        self.joint(code, kind, f"{code}_link", axis=axis, limit=limit, comment=comment)


def _fmt(v):
    # nine digits where they read back as the same number, else every digit (a converted URDF's π)
    return " ".join(f"{float(x):.9g}" if float(f"{float(x):.9g}") == float(x) else repr(float(x)) for x in v)


def _chain(w: _Writer, elements, end_link: str):
    w.parent = "base"
    for el in elements:
        if isinstance(el, Fixed):
            w.joint(el.name, "fixed", f"{el.name}_link", el.xyz_m, el.rpy_rad, comment=el.comment)
        elif isinstance(el, Axis):
            for d in el.location_errors:
                w.error_joint(f"E{d}0{el.name}", d, comment=f"location error of {el.name}" if d == el.location_errors[0] else "")
            w.joint(el.name, el.kind, f"{el.name.lower()}_link", axis=el.direction, limit=el.limit, comment=el.comment)
            if el.pdge:
                for i, d in enumerate("XYZABC"):
                    w.error_joint(f"E{d}{el.name}", d, comment=f"position-dependent errors of {el.name}" if i == 0 else "")
        elif isinstance(el, _Setup):
            for i, d in enumerate("XYZABC"):
                w.error_joint(f"E{d}0{el.name}", d, comment=el.comment if i == 0 else "")
        else:
            raise TypeError(f"unknown chain element {el!r}")
    w.joint(f"{end_link}_mount", "fixed", end_link)


def machine_urdf(name: str, workpiece_chain, tool_chain, description: str = "") -> str:
    """URDF text of a machine with the given workpiece and tool chains.

    Parameters
    ----------
    name : str
        Robot name.
    workpiece_chain, tool_chain : list
        Elements from the root outwards (:class:`Fixed`, :class:`Axis`, :func:`setup`).
    description : str
        Free text (nominal geometry) written as a comment at the top.

    Returns
    -------
    str
        The URDF document.
    """
    w = _Writer()
    head = ['<?xml version="1.0"?>']
    if description:
        head.append("<!--\n" + description.rstrip() + "\n-->")
    head.append(f'<robot name="{name}">')
    w.lines.append('  <link name="base"/>')
    w.lines.append("  <!-- ===== workpiece chain: base -> ... -> workpiece ===== -->")
    _chain(w, workpiece_chain, "workpiece")
    w.lines.append("  <!-- ===== tool chain: base -> ... -> tool ===== -->")
    _chain(w, tool_chain, "tool")
    return "\n".join(head + w.lines + ["</robot>", ""])
