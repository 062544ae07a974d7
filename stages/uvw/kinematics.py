"""Kinematics of a UVW (X-Y-θ) alignment stage.

Three actuators push the table: ``X1`` and ``X2`` along X, at y = +a and
y = −a from the table centre, and ``Y`` along Y, at x = b. Each actuator is a
lead-screw slide carrying a cross-roller slide (free perpendicular to the
drive) and a pivot (free rotation) on which the table rests. The stroke of an
actuator is the displacement of its pivot along its drive direction from home.

With the pivot ``p`` of an actuator given in the table frame at home and the
table pose (t, θ), the pivot sits at ``R(θ) p + t``; the stroke is the
component of ``R(θ) p + t − p`` along the drive direction. This is exact for
any angle (inverse kinematics in closed form); the forward kinematics solves
one scalar equation for θ by Newton's method.

References
----------
The CN patent ("error compensation method of an alignment platform"):
a rotation of the table decomposes into two first-direction (X) moves and one
second-direction (Y) move, each compensated separately.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from kinid.checks import check_positive
from kinid.errors import DataError, StageError

__all__ = ["ACTUATORS", "UVWGeometry", "Pose", "Strokes", "inverse_kinematics", "forward_kinematics",
           "decompose_move", "check_actuator", "check_lead"]

#: Actuator names of the UVW protocol (docs/hardware.md).
ACTUATORS = ("X1", "X2", "Y")


def check_actuator(actuator) -> str:
    """Return ``actuator`` if it is one of :data:`ACTUATORS`, else raise :class:`StageError`."""
    if actuator not in ACTUATORS:
        raise StageError(f"unknown actuator {actuator!r}; expected one of 'X1', 'X2', 'Y'")
    return actuator


def check_lead(lead_um) -> float:
    """Return the screw lead as a float if it is a finite positive number (µm), else raise :class:`DataError`."""
    return check_positive("lead_um", lead_um)


@dataclass(frozen=True)
class UVWGeometry:
    """Where the actuators push the table (table frame at home, mm).

    Parameters
    ----------
    a_mm : float
        Distance of the X1 and X2 pivots from the table centre along Y
        (X1 at y = +a, X2 at y = −a), mm. Must be positive.
    b_mm : float
        X coordinate of the Y pivot, mm. Must be non-zero.
    x1_offset_mm, x2_offset_mm : float
        X coordinate of the X1 / X2 pivot, mm (0 for the symmetric stage).
    y_offset_mm : float
        Y coordinate of the Y pivot, mm (0 for the symmetric stage).
    """

    a_mm: float = 50.0
    b_mm: float = 50.0
    x1_offset_mm: float = 0.0
    x2_offset_mm: float = 0.0
    y_offset_mm: float = 0.0

    def __post_init__(self):
        for name in ("a_mm", "b_mm", "x1_offset_mm", "x2_offset_mm", "y_offset_mm"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise DataError(f"UVWGeometry.{name} must be a finite number, got {value!r}")
        if self.a_mm <= 0:
            raise DataError(f"UVWGeometry.a_mm must be positive (X pivots at y = ±a), got {self.a_mm!r}")
        if self.b_mm == 0:
            raise DataError("UVWGeometry.b_mm must be non-zero (Y pivot off the centre along X), got 0")


@dataclass(frozen=True)
class Pose:
    """Table pose relative to home: translation in µm, rotation in degrees (counter-clockwise)."""

    x_um: float
    y_um: float
    theta_deg: float


@dataclass(frozen=True)
class Strokes:
    """Actuator strokes (µm from home) of the three actuators."""

    x1_um: float
    x2_um: float
    y_um: float

    def as_dict(self) -> dict:
        """``{"X1": x1_um, "X2": x2_um, "Y": y_um}``, keyed as the ``move`` protocol expects."""
        return {"X1": self.x1_um, "X2": self.x2_um, "Y": self.y_um}


def inverse_kinematics(geometry: UVWGeometry, x_um: float, y_um: float, theta_deg: float) -> Strokes:
    """Exact actuator strokes for a table pose.

    Parameters
    ----------
    geometry : UVWGeometry
        Pivot positions.
    x_um, y_um : float
        Translation of the table centre from home, µm.
    theta_deg : float
        Rotation of the table from home, degrees, counter-clockwise.

    Returns
    -------
    Strokes
        ``x1_um = x + c1 (cos θ − 1) − a sin θ``, ``x2_um = x + c2 (cos θ − 1) + a sin θ``,
        ``y_um = y + b sin θ + e (cos θ − 1)`` (lengths in µm).

    Examples
    --------
    >>> s = inverse_kinematics(UVWGeometry(a_mm=50, b_mm=50), 0.0, 0.0, 0.01)
    >>> round(s.x1_um, 3), round(s.x2_um, 3), round(s.y_um, 3)
    (-8.727, 8.727, 8.727)
    """
    from kinid.checks import check_instance, check_number

    check_instance("geometry", geometry, UVWGeometry)
    th = math.radians(check_number("theta_deg", theta_deg))
    check_number("x_um", x_um), check_number("y_um", y_um)
    s, c1 = math.sin(th), math.cos(th) - 1.0
    g = geometry
    return Strokes(
        x1_um=x_um + 1e3 * (g.x1_offset_mm * c1 - g.a_mm * s),
        x2_um=x_um + 1e3 * (g.x2_offset_mm * c1 + g.a_mm * s),
        y_um=y_um + 1e3 * (g.b_mm * s + g.y_offset_mm * c1),
    )


def forward_kinematics(geometry: UVWGeometry, strokes: Strokes, *, tol_rad: float = 1e-15,
                       max_iter: int = 50) -> Pose:
    """Table pose from the actuator strokes (Newton's method on θ).

    Parameters
    ----------
    geometry : UVWGeometry
        Pivot positions.
    strokes : Strokes
        Actuator strokes, µm.
    tol_rad : float
        Stop when the Newton step in θ is below this, radians.
    max_iter : int
        Newton iterations at most.

    Returns
    -------
    Pose
        The pose whose :func:`inverse_kinematics` gives ``strokes``.

    Raises
    ------
    StageError
        If the X1 and X2 strokes differ by more than the pivot distance 2a
        allows (no pose reaches them).
    """
    g = geometry
    a_um, dc_um = 1e3 * g.a_mm, 1e3 * (g.x2_offset_mm - g.x1_offset_mm)
    diff = strokes.x2_um - strokes.x1_um  # = dc (cos θ − 1) + 2 a sin θ
    ratio = diff / (2.0 * a_um)
    if abs(ratio) >= 1.0:
        raise StageError(f"X1 and X2 strokes differ by {diff:g} µm, more than the pivot distance 2a = "
                         f"{2 * a_um:g} µm allows")
    th = math.asin(ratio)
    for _ in range(max_iter):
        f = dc_um * (math.cos(th) - 1.0) + 2.0 * a_um * math.sin(th) - diff
        df = -dc_um * math.sin(th) + 2.0 * a_um * math.cos(th)
        step = f / df
        th -= step
        if abs(step) < tol_rad:
            break
    s, c1 = math.sin(th), math.cos(th) - 1.0
    x_um = strokes.x1_um - 1e3 * (g.x1_offset_mm * c1 - g.a_mm * s)
    y_um = strokes.y_um - 1e3 * (g.b_mm * s + g.y_offset_mm * c1)
    return Pose(x_um=x_um, y_um=y_um, theta_deg=math.degrees(th))


def decompose_move(geometry: UVWGeometry, start: Pose, end: Pose) -> Strokes:
    """Split a table move into actuator moves, as the patent does.

    A pure translation along X is one first-direction move (X1 and X2 alike),
    one along Y is one second-direction move; a rotation becomes two
    first-direction moves (X1 and X2 by different strokes) and one
    second-direction move (Y), each compensated on its own.

    Parameters
    ----------
    geometry : UVWGeometry
        Pivot positions.
    start, end : Pose
        Table pose before and after the move.

    Returns
    -------
    Strokes
        Signed stroke of each actuator for the move, µm (positive: forward).
    """
    a = inverse_kinematics(geometry, start.x_um, start.y_um, start.theta_deg)
    b = inverse_kinematics(geometry, end.x_um, end.y_um, end.theta_deg)
    return Strokes(x1_um=b.x1_um - a.x1_um, x2_um=b.x2_um - a.x2_um, y_um=b.y_um - a.y_um)
