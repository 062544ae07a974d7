"""Move plans of the backlash calibration (CN105547173, figures 4 and 6, re-designed).

Every photographed position of the pixel-equivalent path is approached from
the *same* side on every axis (here: from the negative side). The lead-screw
play is then taken up the same way at every photo, so the actual distance
between any two photos equals the commanded one, however large the backlash:
that is why the patent's paths first move past a point and come back before a
photo ("take out the backlash"). A photo pair is what the patent calls a
non-reversal move.

The reversal path photographs the same commanded position twice, approached
from opposite sides (4 moves per cycle, two reversals): the two images differ
by exactly one full backlash. Each excursion must be longer than the backlash.

All positions are offsets from the start position (x_mm, y_mm, theta_deg) and
stay within ``±travel`` of it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.checks import check_int, check_positive

__all__ = ["PlannedMove", "plan_moves"]


@dataclass(frozen=True)
class PlannedMove:
    """One commanded move of the plan.

    Attributes
    ----------
    offset : tuple of float
        (dx_mm, dy_mm, dtheta_deg) from the start position.
    role : str
        ``"preload"`` (no photo), ``"scale"`` (photo of the pixel-equivalent
        path, approached from the negative side), ``"up"`` / ``"down"`` (photo
        of a reversal cycle approached from the negative / positive side), or
        ``"centre"`` (θ photo approached from the negative side, used with the
        ``"up"`` photos to find the rotation centre).
    axis : str
        ``"xy"`` for the pixel-equivalent path, else ``"x"``, ``"y"`` or ``"theta"``.
    cycle : int
        Index of the reversal cycle on its axis (-1 for the pixel-equivalent path).
    target : float
        Commanded target of the reversal cycle (offset, mm or deg); NaN otherwise.
    """

    offset: tuple
    role: str
    axis: str
    cycle: int = -1
    target: float = float("nan")

    @property
    def photo(self) -> bool:
        """True when an image is taken after this move."""
        return self.role != "preload"


def _check_count(name, value):
    return check_int(name, value, minimum=1)


def plan_moves(travel_mm, travel_deg, *, repeats=1, n_targets=1) -> list:
    """The full move plan: pixel equivalent, then X, Y and θ reversal cycles.

    Parameters
    ----------
    travel_mm : float
        Every X and Y command stays within ``±travel_mm`` of the start, mm.
    travel_deg : float
        Every θ command stays within ``±travel_deg`` of the start, degrees.
    repeats : int
        Reversal cycles per target position and axis (1: the patent's 4 moves
        per axis).
    n_targets : int
        Target positions per linear axis, spread over ``±travel_mm / 2`` (the
        ISO 230-2 reversal value B needs several); θ uses the start angle only.

    Returns
    -------
    list of PlannedMove
        9 pixel-equivalent moves + 4 · repeats · (2 · n_targets + 1) reversal moves.

    Raises
    ------
    DataError
        On a non-positive travel or count.

    Notes
    -----
    Pixel-equivalent path (a = travel/2, T = travel), X-Y offsets::

        1 (-T,-T) preload   2 (-a,-a) photo   3 (+a,-a) photo [X]   4 (+a,+a) photo [Y]
        5 (-T,+a) preload   6 (-a,+a) photo [X]   7 (-a,-T) preload   8 (-a,-a) photo [Y]
        9 ( 0, 0) photo [XY]

    Photos 2, 3, 4, 6, 8, 9 are all approached from the negative side on X and
    Y, giving five non-reversal pairs (two along X, two along Y, one oblique).
    A reversal cycle at target t with excursion e = travel/2:
    ``t - e`` (preload), ``t`` (photo "up"), ``t + e`` (θ: photo "centre"),
    ``t`` (photo "down").
    """
    t_mm = check_positive("travel_mm", travel_mm)
    t_deg = check_positive("travel_deg", travel_deg)
    repeats = _check_count("repeats", repeats)
    n_targets = _check_count("n_targets", n_targets)
    a = 0.5 * t_mm
    plan = [
        PlannedMove((-t_mm, -t_mm, 0.0), "preload", "xy"),
        PlannedMove((-a, -a, 0.0), "scale", "xy"),
        PlannedMove((a, -a, 0.0), "scale", "xy"),
        PlannedMove((a, a, 0.0), "scale", "xy"),
        PlannedMove((-t_mm, a, 0.0), "preload", "xy"),
        PlannedMove((-a, a, 0.0), "scale", "xy"),
        PlannedMove((-a, -t_mm, 0.0), "preload", "xy"),
        PlannedMove((-a, -a, 0.0), "scale", "xy"),
        PlannedMove((0.0, 0.0, 0.0), "scale", "xy"),
    ]
    targets = [0.0] if n_targets == 1 else list(np.linspace(-0.5 * t_mm, 0.5 * t_mm, n_targets))
    e = 0.5 * t_mm
    for axis, k in (("x", 0), ("y", 1)):
        cycle = 0
        for t in targets:
            for _ in range(repeats):
                for off, role in ((t - e, "preload"), (t, "up"), (t + e, "preload"), (t, "down")):
                    o = [0.0, 0.0, 0.0]
                    o[k] = float(off)
                    plan.append(PlannedMove(tuple(o), role, axis, cycle, float(t)))
                cycle += 1
    e_deg = 0.5 * t_deg
    for cycle in range(repeats):
        for off, role in ((-e_deg, "preload"), (0.0, "up"), (e_deg, "centre"), (0.0, "down")):
            plan.append(PlannedMove((0.0, 0.0, float(off)), role, "theta", cycle, 0.0))
    return plan
