"""Files with axis columns — observations, plans and poses, run logs: one reader of their header and
readings (docs/formats.md), one travel check with one margin.

Every such file is a CSV table (:func:`kinid.files.read_csv_table`: header, no column twice, rows as
long as the header) with a column per axis named ``<axis>_mm`` or ``<axis>_deg`` after the axis's
kind, optional ``dir_<axis>`` approach directions (±1) and an optional ``t_s``. The readers of the
observation CSV and the run log take their own columns (marks, offsets; image names, laser) from
the :class:`AxisTable` this module returns.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinid.errors import DataError
from kinid.files import csv_number, read_csv_table
from .machine import Machine, axis_limits

__all__ = ["AxisTable", "read_axis_table", "check_travel", "warn_if_metres", "TRAVEL_MARGIN", "TRAVEL_TOLERANCE"]

#: Readings beyond the URDF travel by less than this share of the limit (or 1e-9 mm / deg) are on it.
TRAVEL_MARGIN = 1e-9
#: Readings beyond the travel by at most this share of its span (at least TRAVEL_TOLERANCE_MIN mm / deg)
#: are accepted with a warning naming them: a stop past a soft limit, a limit written a little tight.
TRAVEL_TOLERANCE = 0.005
TRAVEL_TOLERANCE_MIN = 0.5


@dataclass(frozen=True)
class AxisTable:
    """A CSV table with axis columns, read.

    Attributes
    ----------
    path : Path
    header_line : int
    header : list of str
    rows : list of (line, cells)
    axes : array (N, n_axes)
        Readings in ``machine.axes`` order, mm / deg (NaN for an optional axis without a column).
    directions : dict axis name -> array (N,) of ±1
    t_s : array (N,) or None
    lines : tuple of int
    """

    path: Path
    header_line: int
    header: list
    rows: list
    axes: np.ndarray
    directions: dict
    t_s: np.ndarray | None
    lines: tuple

    def numbers(self, column: str) -> np.ndarray:
        """The finite numbers of ``column``, one per row; DataError naming the line of a bad cell."""
        k = self.header.index(column)
        return np.array([csv_number(cells, k, path=self.path, line=line, column=column) for line, cells in self.rows])

    def texts(self, column: str, what: str) -> list:
        """The stripped, non-empty texts of ``column``; DataError naming the line of an empty one."""
        k = self.header.index(column)
        out = []
        for line, cells in self.rows:
            value = cells[k].strip()
            if not value:
                raise DataError(f"empty {what}", path=self.path, line=line, column=column)
            out.append(value)
        return out


def _axis_of(machine: Machine, header: str):
    """Which axis a ``<axis>_mm``/``<axis>_deg`` header names, else None; DataError on a wrong unit."""
    stem = header.rpartition("_")[0]
    for a in machine.axes:
        if stem == a.name.lower():
            if header != a.column:
                raise DataError(f"axis {a.name} is {a.kind}: expected column {a.column!r}", column=header)
            return a
    return None


def read_axis_table(path, machine: Machine, *, what: str, required=(), optional_axes=(),
                    check_limits: bool = True) -> AxisTable:
    """Read a CSV table with axis columns.

    Parameters
    ----------
    what : str
        The kind of file, for messages ("observation file", "run log").
    required : sequence of str
        Other columns the file must have.
    optional_axes : iterable of str
        Axes that may be absent (their readings are NaN).
    check_limits : bool
        Refuse a reading outside its axis's URDF travel (:func:`check_travel`).

    Raises
    ------
    DataError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    header_line, header, rows = read_csv_table(path, what=what, required=required)
    axis_cols, dir_cols = {}, {}
    for h in header:
        try:
            a = _axis_of(machine, h)
        except DataError as exc:
            raise DataError(exc.message, path=path, line=header_line, column=h) from None
        if a is not None:
            axis_cols[a.name] = header.index(h)
        if h.startswith("dir_"):
            match = [a for a in machine.axes if a.name.lower() == h[4:]]
            if not match:
                raise DataError(f"'dir_' column for unknown axis {h[4:]!r}; axes: "
                                f"{', '.join(a.name.lower() for a in machine.axes)}", path=path, line=header_line,
                                column=h)
            dir_cols[match[0].name] = header.index(h)
    optional = set(optional_axes)
    for a in machine.axes:
        if a.name not in axis_cols and a.name not in optional:
            raise DataError(f"missing column {a.column!r} for axis {a.name}", path=path, line=header_line)
    if not rows:
        raise DataError("no data rows after the header", path=path, line=header_line)
    n = len(rows)
    axes = np.full((n, len(machine.axes)), np.nan)
    dirs = {k: np.empty(n) for k in dir_cols}
    t_s = np.empty(n) if "t_s" in header else None
    for i, (line, cells) in enumerate(rows):
        for j, a in enumerate(machine.axes):
            if a.name in axis_cols:
                axes[i, j] = csv_number(cells, axis_cols[a.name], path=path, line=line, column=a.column)
        if t_s is not None:
            t_s[i] = csv_number(cells, header.index("t_s"), path=path, line=line, column="t_s")
        for name, k in dir_cols.items():
            v = csv_number(cells, k, path=path, line=line, column=header[k])
            if v not in (1.0, -1.0):
                raise DataError(f"approach direction must be +1 or -1, found {cells[k].strip()!r}", path=path,
                                line=line, column=header[k])
            dirs[name][i] = v
    lines = tuple(line for line, _ in rows)
    if check_limits:
        check_travel(machine, axes, lines, path)
    warn_if_metres(machine, axes, path)
    return AxisTable(path, header_line, header, rows, axes, dirs, t_s, lines)


#: A linear axis whose readings all lie within this share of its travel's larger end looks like metres in mm.
METRES_SHARE = 0.002


def warn_if_metres(machine: Machine, axes: np.ndarray, path) -> None:
    """A warning when every reading of a linear axis with a travel of 100 mm or more lies within ±0.2 % of it
    (±1.2 mm of ±600 mm) and yet they vary: metres written in a ``_mm`` column."""
    import warnings

    limits = axis_limits(machine)
    for j, a in enumerate(machine.axes):
        lo, hi = limits[j]
        v = axes[:, j][np.isfinite(axes[:, j])]
        reach = max(abs(lo), abs(hi)) if np.isfinite(hi - lo) else np.inf
        if a.kind != "prismatic" or v.size < 3 or not np.isfinite(reach) or hi - lo < 100.0:
            continue
        if np.abs(v).max() <= METRES_SHARE * reach and np.ptp(v) > 0:
            warnings.warn(f"{path}: every reading of {a.column} is within ±{np.abs(v).max():.3g} mm of a travel of "
                          f"{lo:g} .. {hi:g} mm; if they are metres, multiply by 1000", stacklevel=3)


def check_travel(machine: Machine, axes: np.ndarray, lines, path) -> None:
    """Refuse the first reading outside its axis's URDF travel by more than the tolerance (``TRAVEL_TOLERANCE``
    of the span, at least ``TRAVEL_TOLERANCE_MIN`` mm / deg): almost always a unit or column mistake. Readings
    beyond it by less are accepted with a warning naming their lines. NaN readings (absent axes) pass."""
    import warnings

    limits = axis_limits(machine)
    for j, a in enumerate(machine.axes):
        lo, hi = limits[j]
        margin = TRAVEL_MARGIN * max(1.0, abs(lo) if np.isfinite(lo) else 1.0, abs(hi) if np.isfinite(hi) else 1.0)
        outside = (axes[:, j] < lo - margin) | (axes[:, j] > hi + margin)
        if not outside.any():
            continue
        unit = "mm" if a.kind == "prismatic" else "deg"
        span = hi - lo if np.isfinite(hi - lo) else 0.0
        tol = max(TRAVEL_TOLERANCE * span, TRAVEL_TOLERANCE_MIN)
        far = np.flatnonzero((axes[:, j] < lo - tol) | (axes[:, j] > hi + tol))
        if far.size:
            i = int(far[0])
            raise DataError(f"{axes[i, j]:g} {unit} is outside the travel of axis {a.name} in the URDF "
                            f"({lo:g} .. {hi:g} {unit}) by more than {tol:.3g} {unit}; check the units and the column, "
                            f"or pass --allow-outside-limits if the URDF's limits are wrong",
                            path=path, line=lines[i], column=a.column)
        near = np.flatnonzero(outside)
        worst = float(np.max(np.maximum(lo - axes[near, j], axes[near, j] - hi)))
        shown = ", ".join(str(lines[i]) for i in near[:8]) + (" …" if near.size > 8 else "")
        warnings.warn(f"{path}: {near.size} reading(s) of {a.column} beyond the URDF travel ({lo:g} .. {hi:g} {unit}) "
                      f"by up to {worst:.3g} {unit}, within the tolerance of {tol:.3g} {unit}; used (lines {shown})",
                      stacklevel=2)
