"""The rotary axes' geometry a controller's kinematics holds (docs/compensation.md, "Rotary axes into the
controller's kinematics").

Plain tuples of floats: the kinematics formats' registry loads without numpy.

Frame: the machine's frame (x, y, z along the machine's linear axes, as in the URDF's base), its origin at
the tool point with every axis at 0 (the controller's machine zero with the measuring tool's length
at 0). Lengths in mm, directions as unit vectors, all at the home position (every axis at 0).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["RotaryAxisGeometry", "LinearAxisMapping", "RotaryGeometry", "KINDS"]

#: Kinematic types: rotary axes carried by the table (the part turns), by the head (the tool turns) or one of each.
KINDS = ("table-table", "head-head", "head-table", "table", "head")


def _sub(a, b):
    return tuple(x - y for x, y in zip(a, b))


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


@dataclass(frozen=True)
class RotaryAxisGeometry:
    """Where one rotary axis turns, nominal and calibrated, at the home position.

    Attributes
    ----------
    name : str
        The axis (``B``, ``C``).
    carrier : {"table", "head"}
        What it turns: the part (a table axis) or the tool (a head axis).
    pivot_mm, direction : tuple of 3 float
        The calibrated axis line: a point on it (the point nearest the nominal pivot), mm, and its unit
        direction. A + reading turns what the axis carries right-handed about ``direction``.
    nominal_pivot_mm, nominal_direction : tuple of 3 float
        The same of the nominal machine (the URDF without errors).
    """

    name: str
    carrier: str
    pivot_mm: tuple
    direction: tuple
    nominal_pivot_mm: tuple
    nominal_direction: tuple

    @property
    def pivot_shift_um(self) -> tuple:
        """The calibrated pivot minus the nominal one (perpendicular to the axis), µm."""
        return tuple(1e3 * v for v in _sub(self.pivot_mm, self.nominal_pivot_mm))

    @property
    def tilt_urad(self) -> float:
        """Angle between the calibrated and the nominal direction, µrad."""
        a, b = self.direction, self.nominal_direction
        cross = (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])
        return 1e6 * math.atan2(math.sqrt(_dot(cross, cross)), _dot(a, b))


@dataclass(frozen=True)
class LinearAxisMapping:
    """A linear axis as the controller's coordinate of the tool relative to the part.

    Attributes
    ----------
    axis : str
        The machine's axis (``Y``).
    coordinate : {"X", "Y", "Z"}
        The machine frame's direction it moves along.
    sign : int
        +1 where a + reading moves the tool along + ``coordinate`` relative to the part (the axis carries
        the tool), -1 where it moves the part along + ``coordinate`` (so the tool moves along −).
    """

    axis: str
    coordinate: str
    sign: int


@dataclass(frozen=True)
class RotaryGeometry:
    """The rotary axes' geometry of a machine for its controller's kinematics.

    Attributes
    ----------
    machine : str
        The machine's name (its URDF file's stem).
    kind : str
        One of :data:`KINDS`.
    axes : tuple of RotaryAxisGeometry
        In the controller's order: head axes from the machine towards the tool, then table axes from the
        machine towards the part (the 1st axis carries the 2nd; with one of each, the head's is the 1st).
    linear : tuple of LinearAxisMapping
    location_errors : tuple of (code, value, unit)
        The significant location errors the geometry holds (µm / µrad).
    left_out : tuple of (code, reason)
        Location errors that are no part of the rotary axes' geometry (a linear axis's squareness: the
        controller's squareness compensation), and the set-up (work and tool offsets).
    """

    machine: str
    kind: str
    axes: tuple
    linear: tuple
    location_errors: tuple = ()
    left_out: tuple = ()

    def axis(self, name: str) -> RotaryAxisGeometry:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(name)

    def mapping_words(self) -> str:
        """The linear axes' mapping in one line: ``X -> +X, Y -> -Y, Z -> +Z``."""
        return ", ".join(f"{m.axis} -> {'+' if m.sign > 0 else '-'}{m.coordinate}" for m in self.linear)
