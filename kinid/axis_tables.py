"""Axis error tables and the controller files that load them (docs/compensation.md).

One writer for every method that ends in a bidirectional table of one axis's
positioning error against its position — the five-axis compensation
(``kinid compensate``) and the stage methods alike.

Sign convention everywhere in kinid: an axis error is *actual − commanded*
(where the axis is, minus where it was told to be), in µm for a linear axis
and µrad for a rotary one, for the approach direction + (``forward``) and −
(``reverse``). Each controller format below states how it takes that.

Formats
-------
``linuxcnc``
    LinuxCNC joint compensation file (``[JOINT_n] COMP_FILE``,
    ``COMP_FILE_TYPE = 0``): one line per point, "nominal forward reverse",
    separated by a space, ascending nominal, machine units (mm, or degrees for
    an angular joint); forward and reverse are the *actual* positions reached
    when travelling in the positive and negative direction; at most 256 lines
    per joint. Reference: LinuxCNC documentation, "INI Configuration",
    section [JOINT_<num>], entries COMP_FILE and COMP_FILE_TYPE.
``twincat``
    Beckhoff TwinCAT CNC (ISG kernel) compensation value list for leadscrew
    error compensation (``kw.ssfk.*``), bilateral, metric unit
    (``kw.ssfk.unit 1``: lengths in 0.1 µm; rotary axes in 0.0001°), explicit
    interpolation points (``kw.ssfk.interval 0``, ``table[i].setpoint``) and the
    compensation values ``table[i].pos`` / ``table[i].neg`` = actual − setpoint,
    integers; at most 1500 points by default (P-COMP-00059). Reference:
    Beckhoff Information System, TF5200 "Axis compensation", leadscrew error
    compensation (kw.ssfk.*, P-COMP-00017 to P-COMP-00025) and its example
    compensation value list.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass

import numpy as np

from .errors import DataError

__all__ = ["AxisErrorTable", "FORMATS", "neutral_csv_text", "linuxcnc_text", "twincat_text", "format_text",
           "LINUXCNC_MAX_POINTS", "TWINCAT_MAX_POINTS", "points_for"]

#: LinuxCNC reads at most this many triplets per joint.
LINUXCNC_MAX_POINTS = 256
#: TwinCAT CNC's default table size (P-COMP-00059).
TWINCAT_MAX_POINTS = 1500


@dataclass(frozen=True)
class AxisErrorTable:
    """The positioning error of one axis against its commanded position.

    Attributes
    ----------
    axis : str
        Axis name (``X``, ``C``).
    rotary : bool
        True for a rotary axis: positions in degrees, errors in µrad; else mm and µm.
    positions : array (n,)
        Commanded positions, ascending, mm or deg.
    forward : array (n,)
        Error actual − commanded approaching in the + direction, µm or µrad.
    reverse : array (n,) or None
        The same approaching in the − direction; None: the same as ``forward``.
    """

    axis: str
    rotary: bool
    positions: np.ndarray
    forward: np.ndarray
    reverse: np.ndarray | None = None

    def __post_init__(self):
        pos = np.asarray(self.positions, float)
        fwd = np.asarray(self.forward, float)
        rev = None if self.reverse is None else np.asarray(self.reverse, float)
        if pos.ndim != 1 or pos.size < 2:
            raise DataError(f"needs at least two positions, got {pos.size}", parameter="positions")
        if fwd.shape != pos.shape or (rev is not None and rev.shape != pos.shape):
            raise DataError(f"forward and reverse must have the shape of positions {pos.shape}", parameter="forward")
        for name, a in (("positions", pos), ("forward", fwd), ("reverse", rev)):
            if a is not None and not np.all(np.isfinite(a)):
                raise DataError("must be finite numbers", parameter=name)
        if np.any(np.diff(pos) <= 0):
            raise DataError("must be strictly ascending", parameter="positions")
        object.__setattr__(self, "positions", pos)
        object.__setattr__(self, "forward", fwd)
        object.__setattr__(self, "reverse", rev)

    @property
    def unit(self) -> str:
        return "urad" if self.rotary else "um"

    @property
    def backward(self) -> np.ndarray:
        """The − direction errors (``forward`` where the table is one-sided)."""
        return self.forward if self.reverse is None else self.reverse


def neutral_csv_text(position_column: str, positions, columns: dict) -> str:
    """A plain CSV table: ``position_column`` then one column per entry of ``columns`` (name -> values)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([position_column, *columns])
    values = [np.asarray(v, float) for v in columns.values()]
    for i, q in enumerate(np.asarray(positions, float)):
        w.writerow([_num(q, 9), *(_num(v[i], 6) for v in values)])
    return buf.getvalue()


def _num(x: float, digits: int) -> str:
    s = f"{x:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _to_machine_units(table: AxisErrorTable, values) -> np.ndarray:
    """Errors in mm (linear) or degrees (rotary)."""
    values = np.asarray(values, float)
    return values * 1e-3 if not table.rotary else np.degrees(values * 1e-6)


def linuxcnc_text(table: AxisErrorTable) -> str:
    """LinuxCNC ``COMP_FILE_TYPE = 0`` text: "nominal forward reverse" per line, machine units (mm / deg).

    Forward and reverse are the actual positions reached approaching in the + and − direction:
    nominal + error. Numbers with 6 decimals (0.001 µm, 0.000001°).

    Raises
    ------
    DataError
        If the table has more points than LinuxCNC reads (256): use a coarser step.
    """
    n = table.positions.size
    if n > LINUXCNC_MAX_POINTS:
        raise DataError(f"axis {table.axis}: {n} points, but LinuxCNC reads at most {LINUXCNC_MAX_POINTS} per joint; "
                        f"use a coarser step", parameter="positions")
    fwd = table.positions + _to_machine_units(table, table.forward)
    rev = table.positions + _to_machine_units(table, table.backward)
    return "".join(f"{q:.6f} {f:.6f} {r:.6f}\n" for q, f, r in zip(table.positions, fwd, rev))


def twincat_text(table: AxisErrorTable, *, axis_number: int = 1, axis_name: str | None = None) -> str:
    """Beckhoff TwinCAT CNC leadscrew error compensation list (``kw.ssfk.*``), bilateral, metric.

    Setpoints and compensation values (actual − setpoint) as integers in 0.1 µm for a linear axis
    and 0.0001° for a rotary one; interpolation points given one by one (``interval 0``).

    Raises
    ------
    DataError
        If the table has more points than the default list size (1500).
    """
    n = table.positions.size
    if n > TWINCAT_MAX_POINTS:
        raise DataError(f"axis {table.axis}: {n} points, more than the {TWINCAT_MAX_POINTS} a TwinCAT list holds by "
                        f"default; use a coarser step", parameter="positions")
    if table.rotary:
        setpoint = np.rint(table.positions * 1e4).astype(np.int64)  # 0.0001°
        pos = np.rint(np.degrees(table.forward * 1e-6) * 1e4).astype(np.int64)
        neg = np.rint(np.degrees(table.backward * 1e-6) * 1e4).astype(np.int64)
    else:
        setpoint = np.rint(table.positions * 1e4).astype(np.int64)  # mm -> 0.1 µm
        pos = np.rint(table.forward * 10).astype(np.int64)  # µm -> 0.1 µm
        neg = np.rint(table.backward * 10).astype(np.int64)
    if np.any(np.diff(setpoint) <= 0):
        raise DataError(f"axis {table.axis}: points closer than the list's resolution", parameter="positions")
    name = axis_name or table.axis
    lines = [f"kopf.achs_nr                        {int(axis_number)}",
             f"kopf.log_achs_name                  {name}",
             "kw.ssfk.interval                    0",
             f"kw.ssfk.kw_startpos                 {setpoint[0]}",
             f"kw.ssfk.kw_nr_max                   {n}",
             "kw.ssfk.unit                        1",
             "kw.ssfk.bilateral                   1"]
    lines += [f"kw.ssfk.table[{i}].setpoint".ljust(36) + f"{v}" for i, v in enumerate(setpoint)]
    lines += [f"kw.ssfk.table[{i}].pos".ljust(36) + f"{v}" for i, v in enumerate(pos)]
    lines += [f"kw.ssfk.table[{i}].neg".ljust(36) + f"{v}" for i, v in enumerate(neg)]
    return "\n".join(lines) + "\n"


#: Controller format name -> (file name pattern, writer, most points).
FORMATS = {
    "linuxcnc": ("{axis}.comp", linuxcnc_text, LINUXCNC_MAX_POINTS),
    "twincat": ("{axis}_ssfk.lis", twincat_text, TWINCAT_MAX_POINTS),
}


def format_text(fmt: str, table: AxisErrorTable, **options) -> str:
    """The text of ``table`` in controller format ``fmt`` (a key of :data:`FORMATS`)."""
    if fmt not in FORMATS:
        raise DataError(f"unknown controller format {fmt!r}; known: {', '.join(FORMATS)}", parameter="fmt")
    writer = FORMATS[fmt][1]
    return writer(table, **options) if fmt == "twincat" else writer(table)


def points_for(step: float, low: float, high: float, most: int | None = None) -> np.ndarray:
    """Grid from ``low`` to ``high`` (both included) at ``step`` or finer, at most ``most`` points."""
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise DataError(f"no finite range {low:g} .. {high:g}", parameter="range")
    n = int(math.ceil((high - low) / step - 1e-9)) + 1
    if most is not None:
        n = min(n, most)
    return np.linspace(low, high, max(n, 2))
