"""Where an axis's compensation tables go: where the data are (docs/compensation.md, "Where the tables go").

- :func:`axis_range` — the range of an axis's tables: the measured readings (default) or, on request,
  the URDF travel where it is finite and the model is defined there; one turn as a modulo table only
  where the readings go all the way round;
- :func:`largest_gap_deg` — the widest stretch of a turn without a reading (the seam from the last
  reading round to the first included);
- :func:`turn_change` — how much a model changes over one turn (a scale error of a rotary axis,
  which a modulo table cannot hold);
- :func:`unwrapped_range` — where a one-turn table goes for a format that does not wrap (LinuxCNC): the turn
  that holds the readings as the data give them (−180 … 180° for readings in −180 … 175°), or all of them.
"""
from __future__ import annotations

import numpy as np

from kinid.errors import DataError
from ..fitting import FitResult
from ..model import axis_limits
from .table_grids import AxisRange

__all__ = ["axis_range", "largest_gap_deg", "full_turn", "turn_change", "not_one_turn", "unwrapped_range",
           "FULL_TURN_GAP_DEG", "TURN_TOLERANCE"]

#: A rotary axis's readings go all the way round when no stretch of the turn wider than this is without a
#: reading, the seam from the last reading round to the first included (12 positions 30° apart qualify, a
#: tilt over −60 … 60° does not).
FULL_TURN_GAP_DEG = 60.0


def largest_gap_deg(readings_deg) -> float:
    """The widest arc of one turn with no reading in ``readings_deg`` (deg, any range), seam included; 360
    for fewer than two distinct angles."""
    r = np.unique(np.mod(np.round(np.asarray(readings_deg, float), 6), 360.0))
    if r.size < 2:
        return 360.0
    return float(max(np.max(np.diff(r)), 360.0 - (r[-1] - r[0])))


def full_turn(result: FitResult, axis: str) -> bool:
    """The fit's readings of rotary ``axis`` go all the way round (no gap over :data:`FULL_TURN_GAP_DEG`). A fit
    saved without its readings counts its measured range instead: a full turn when it spans all but that gap."""
    readings = result.axis_readings.get(axis)
    if readings is not None and len(readings):
        return largest_gap_deg(readings) <= FULL_TURN_GAP_DEG
    measured = result.axis_ranges.get(axis)
    return measured is not None and measured[1] - measured[0] >= 360.0 - FULL_TURN_GAP_DEG


def turn_change(values_at, low: float) -> np.ndarray:
    """Per column of ``values_at`` (callable q (n,) -> (k, n)): the largest change of the model over one turn,
    |f(q + 360°) − f(q)|, for q over one turn from ``low``. Zero (to rounding) for a model that repeats every
    turn (constants, periodic terms with a whole number of periods per turn)."""
    q = np.linspace(low, low + 360.0, 721)
    return np.max(np.abs(np.atleast_2d(values_at(q + 360.0)) - np.atleast_2d(values_at(q))), axis=1)


def axis_range(result: FitResult, axis: str, policy: str = "data") -> AxisRange | None:
    """The range of ``axis``'s tables under ``policy`` ("data": the measured readings; "travel": the URDF's).

    A rotary axis whose readings go all the way round (:func:`full_turn`) and whose travel allows a turn gets
    one turn, 0 .. 360°, as a modulo table, under either policy; every other axis a table over its measured
    readings, whatever the URDF's travel. ``travel`` spreads the table over the URDF travel only where it is
    finite and, for a rotary axis, at most one turn (beyond, a model fitted over part of a turn is not defined).
    None where the fit has no readings of the axis (data policy).

    Raises
    ------
    DataError
        ``travel`` where the axis's travel is unbounded or more than a turn the data do not cover.
    """
    if policy not in ("data", "travel"):
        raise DataError(f"must be 'data' or 'travel', got {policy!r}", parameter="range_policy")
    machine = result.machine
    j = machine.axis_names.index(axis)
    a = machine.axes[j]
    lo, hi = (float(v) for v in axis_limits(machine)[j])
    measured = result.axis_ranges.get(axis)
    measured = tuple(measured) if measured is not None and measured[1] > measured[0] else None
    rotary = a.kind == "revolute"
    turns = rotary and (a.nq == 2 or not np.isfinite(hi - lo) or hi - lo >= 360.0 - 1e-9)
    if turns and measured is not None and full_turn(result, axis):
        return AxisRange(0.0, 360.0, "one turn (modulo)", True, (lo, hi), measured)
    if policy == "travel":
        if not np.isfinite(hi - lo):
            kind = "continuous" if a.nq == 2 else "no limits"
            raise DataError(f"travel: axis {axis} has no finite travel in the URDF ({kind}), so no table can cover it; "
                            f"give --table-range data (the measured readings)",
                            parameter="range_policy")
        if rotary and hi - lo > 360.0 + 1e-9:
            seen = "" if measured is None else f" (measured {measured[0]:g} .. {measured[1]:g}°)"
            raise DataError(f"travel: axis {axis}'s travel {lo:g} .. {hi:g}° is more than a turn and its readings do "
                            f"not go all the way round{seen}: the fitted model is not defined over that travel; give "
                            f"--table-range data (the measured readings)", parameter="range_policy")
        return AxisRange(lo, hi, "URDF travel", False, (lo, hi), measured)
    if measured is None:
        return None
    return AxisRange(measured[0], measured[1], "measured readings", False, (lo, hi), measured)


#: A rotary axis's model repeats every turn when no column changes by more than this over one (µm / µrad).
TURN_TOLERANCE = 1e-3


def not_one_turn(axis: str, names, cols_at, rng: AxisRange) -> dict | None:
    """Why a one-turn (modulo) table cannot hold the model of rotary ``axis``, or None where it can: the columns
    whose value after a turn differs from the value before by more than :data:`TURN_TOLERANCE`, and the scale
    error of the positioning column (its mean change over a turn, ppm) — a modulo table would set it to zero."""
    stack = lambda q: np.vstack([cols_at(q)[n] for n in names])  # noqa: E731
    change = turn_change(stack, rng.low)
    if not np.any(change > TURN_TOLERANCE):
        return None
    worst = int(np.argmax(change))
    own = f"E{axis}{axis}_urad"
    q = np.linspace(rng.low, rng.high, 361)
    scale = float(np.mean(cols_at(q + 360.0)[own] - cols_at(q)[own])) / (2 * np.pi) if own in names else None
    words = (f" (the axis's scale error alone is {scale:+.4g} ppm: a controller that takes the axis's scale in its "
             f"machine data can hold that part there instead)" if scale is not None and abs(scale) > 0 else "")
    return {"reason": f"the readings of {axis} go all the way round, but its model does not repeat every turn "
                      f"({names[worst]} changes by {change[worst]:.3g} over one turn"
                      + (f": a scale error of {scale:+.4g} ppm" if scale is not None and abs(scale) > 0 else "")
                      + "), which a one-turn (modulo) table cannot hold",
            "turn_change": {n: float(c) for n, c in zip(names, change)}, "scale_ppm": scale, "scale_words": words}


def unwrapped_range(rng: AxisRange) -> AxisRange:
    """Where the one-turn table ``rng`` (modulo, 0 .. 360°) goes for a format that does not wrap positions onto a
    turn: the controller compensates the reading as it is, so the table covers the readings as the data give them.

    The whole turn 360°·k .. 360°·(k + 1) that holds every measured reading (0 .. 360° for readings in 0 .. 330°);
    else, for readings in −180 … 175° or unwrapped ones (−400 … 725°), from the lowest reading over one turn or up
    to the highest, whichever is further. The model repeats every turn (:func:`not_one_turn` found nothing), so its
    values there are the one turn's. Not modulo: beyond, the format's end policy.
    """
    if not rng.modulo or rng.measured is None:
        return rng
    lo, hi = (float(v) for v in rng.measured)
    start = 360.0 * np.floor(lo / 360.0 + 1e-12)
    if hi > start + 360.0 + 1e-9:
        start = lo
    return AxisRange(start, max(start + 360.0, hi), "the measured readings' turn (no wrap)", False, rng.travel,
                     rng.measured)
