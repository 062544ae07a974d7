"""Grids for compensation tables: the fewest equal steps whose linear interpolation — what a
controller does between points — follows a model within a bound, and the points that make a
table's end policy explicit (docs/compensation.md, "Where the tables go")."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinid.axis_tables import AxisErrorTable, points_for
from kinid.errors import DataError

__all__ = ["AxisRange", "interpolation_worst", "fewest_points", "table_grid", "with_ends", "extra_points", "rms",
           "directions", "left_after", "check_grid_step", "MAX_GRID_POINTS"]

#: Most points a fixed grid step may ask of one table, checked from the step and the range before anything is
#: allocated (a 1 µm step over 1 m; a controller file then holds at most its own limit of them).
MAX_GRID_POINTS = 1_000_000

#: Model samples per table interval, and at least over a range, when a grid's interpolation error is measured.
_FINE = 8
_DENSE = 20001


@dataclass(frozen=True)
class AxisRange:
    """Where an axis's tables go.

    Attributes
    ----------
    low, high : float
        mm or deg.
    source : str
        "measured readings", "URDF travel" or "one turn (modulo)".
    modulo : bool
        A one-turn table of a rotary axis (first and last points hold the same value).
    travel : tuple (low, high)
        The URDF travel (±inf where it gives none).
    measured : tuple (low, high) or None
        The readings the fit spans.
    """

    low: float
    high: float
    source: str
    modulo: bool
    travel: tuple
    measured: tuple | None


def interpolation_worst(values_at, low: float, high: float, n: int) -> np.ndarray:
    """Largest departure, per column, of the linear interpolation through ``n`` equal-step points: on a
    grid of ``_FINE`` samples per interval and at least ``_DENSE`` samples over the range (so that an
    error that repeats faster than the points cannot hide between the samples)."""
    nodes = np.linspace(low, high, n)
    fine = np.union1d(np.linspace(low, high, _FINE * (n - 1) + 1), np.linspace(low, high, _DENSE))
    v = np.atleast_2d(values_at(fine))
    at_nodes = np.atleast_2d(values_at(nodes))
    return np.array([np.max(np.abs(np.interp(fine, nodes, row) - v[k])) for k, row in enumerate(at_nodes)])


def fewest_points(values_at, low: float, high: float, bounds, most: int) -> int:
    """Fewest equal-step points from ``low`` to ``high`` whose interpolation stays within ``bounds``
    (per column), at most ``most``."""
    bounds = np.asarray(bounds, float)
    ok = lambda n: bool(np.all(interpolation_worst(values_at, low, high, n) <= bounds))  # noqa: E731
    good, bad = None, 2
    n = 2
    while n < most:
        if ok(n):
            good = n
            break
        bad = n
        n = 2 * n - 1
    if good is None:
        if not ok(most):
            return most
        good = most
    while good - bad > 1:
        mid = (good + bad) // 2
        good, bad = (mid, bad) if ok(mid) else (good, mid)
    return good


def check_grid_step(step, low: float, high: float, *, parameter: str | None = None) -> float:
    """``step`` as a float, refused unless it is a finite number > 0 giving at most :data:`MAX_GRID_POINTS`
    points from ``low`` to ``high``; checked by arithmetic alone, before any grid is allocated.

    Parameters
    ----------
    parameter : str, optional
        The argument that set the step (``"step_mm"``, ``"step_deg"``), named by the error; without it the
        message names both.

    Raises
    ------
    DataError
        Naming ``parameter`` (the command line shows ``--step-mm`` / ``--step-deg``) and the limit.
    """
    who = "" if parameter is not None else "the grid step (step_mm or step_deg) "
    try:
        value = float(step)
    except (TypeError, ValueError):
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise DataError(f"{who}must be a positive number, got {step!r}", parameter=parameter)
    span = float(high) - float(low)
    points = span / value + 1 if math.isfinite(span) else math.inf
    if points > MAX_GRID_POINTS:
        raise DataError(f"{who}{value:g} would put {points:.3g} points in the table over {float(low):g} .. "
                        f"{float(high):g}, more than the limit of {MAX_GRID_POINTS:,} points per table; give a step "
                        f"of at least {span / (MAX_GRID_POINTS - 1):.3g}", parameter=parameter)
    return value


def table_grid(values_at, rng: AxisRange, bounds, most: int, step, *, parameter: str | None = None) -> np.ndarray:
    """The grid of one table: at the fixed ``step`` (at most ``most`` points) or, without one, the fewest equal
    steps whose interpolation follows ``values_at`` within ``bounds``. A step giving more than
    :data:`MAX_GRID_POINTS` points over the range is refused before anything is allocated
    (:func:`check_grid_step`; ``parameter`` names the argument that set it)."""
    if step is not None:
        if parameter is None and rng.modulo:  # a one-turn table is a rotary axis's: its step is step_deg
            parameter = "step_deg"
        step = check_grid_step(step, rng.low, rng.high, parameter=parameter)
        return points_for(step, rng.low, rng.high, most)
    return np.linspace(rng.low, rng.high, fewest_points(values_at, rng.low, rng.high, bounds, most))


def _ends(rng: AxisRange, beyond: str, equidistant: bool) -> tuple:
    """Points added beyond the range: (one step beyond each end, the travel's ends)."""
    if rng.modulo:
        return False, ()
    lo, hi = rng.travel
    travel = () if equidistant else tuple(t for t, outside in ((lo, lo < rng.low - 1e-9), (hi, hi > rng.high + 1e-9))
                                          if np.isfinite(t) and outside)
    return beyond == "zero", travel


def with_ends(q: np.ndarray, columns: dict, rng: AxisRange, beyond: str, equidistant: bool):
    """The grid and columns with the beyond policy made explicit: a zero one step beyond each end
    (``zero``) and, for formats with free points, the travel's ends at the held or zero value."""
    step_out, travel = _ends(rng, beyond, equidistant)
    q = np.asarray(q, float)
    cols = {k: np.asarray(v, float) for k, v in columns.items()}
    if rng.modulo:  # one turn: the controller wraps 360° onto 0°
        return q, {k: np.concatenate([v[:-1], v[:1]]) for k, v in cols.items()}
    step = q[1] - q[0]
    if step_out:
        q = np.concatenate([[q[0] - step], q, [q[-1] + step]])
        cols = {k: np.concatenate([[0.0], v, [0.0]]) for k, v in cols.items()}
    lo_t, hi_t = (min(travel, default=np.inf), max(travel, default=-np.inf))
    if lo_t < q[0] - 1e-9:
        q = np.concatenate([[lo_t], q])
        cols = {k: np.concatenate([[v[0]], v]) for k, v in cols.items()}
    if hi_t > q[-1] + 1e-9:
        q = np.concatenate([q, [hi_t]])
        cols = {k: np.concatenate([v, [v[-1]]]) for k, v in cols.items()}
    return q, cols


def extra_points(rng: AxisRange, beyond: str, equidistant: bool) -> int:
    step_out, travel = _ends(rng, beyond, equidistant)
    return 2 * step_out + len(travel)


def rms(x) -> float:
    x = np.asarray(x, float)
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else 0.0


def _quantised(values, resolution: float) -> np.ndarray:
    return np.round(np.asarray(values, float) / resolution) * resolution


def directions(table: AxisErrorTable) -> np.ndarray:
    """(2, n): the forward and backward errors of a table."""
    return np.vstack([table.forward, table.backward])


def left_after(fmt, table: AxisErrorTable, values_at, inside: np.ndarray, resolution: float) -> dict:
    """What the controller's interpolation of ``table`` (values stored at ``resolution``) leaves of the
    model inside the measured range: RMS and largest, per direction pooled."""
    model = values_at(inside)
    stored = directions(table) if fmt.bidirectional else directions(table).mean(axis=0, keepdims=True)
    left = np.vstack([np.interp(inside, table.positions, _quantised(row, resolution)) for row in stored]) - model
    return {"rms": rms(left), "max": float(np.max(np.abs(left)))}
