"""Files with axis columns — observations, plans and poses, run logs: one reader of their header and
readings (docs/formats.md), one travel check with one margin.

Every such file is a CSV table (:func:`kinid.csv_columns.read_csv_columns`: header, no column twice, rows as
long as the header) with a column per axis named ``<axis>_mm`` or ``<axis>_deg`` after the axis's
kind, optional ``dir_<axis>`` approach directions (±1) and an optional ``t_s``. The readers of the
observation CSV and the run log take their own columns (marks, offsets; image names, laser) from
the :class:`AxisTable` this module returns.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import warnings

import numpy as np

from kinid.errors import DataError
from kinid.csv_columns import CsvColumns, read_csv_columns
from kinid.files import column_hint
from ..model import Machine, axis_limits

__all__ = ["AxisTable", "read_axis_table", "check_travel", "warn_if_metres", "metres_columns", "TRAVEL_MARGIN",
           "TRAVEL_TOLERANCE"]

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
    columns : CsvColumns
        The table by columns (numbers as arrays; the text columns asked for).
    axes : array (N, n_axes)
        Readings in ``machine.axes`` order, mm / deg (NaN for an optional axis without a column).
    directions : dict axis name -> array (N,) of ±1
    t_s : array (N,) or None
    lines : tuple of int
    """

    path: Path
    header_line: int
    header: list
    columns: CsvColumns
    axes: np.ndarray
    directions: dict
    t_s: np.ndarray | None
    lines: tuple

    def numbers(self, column: str) -> np.ndarray:
        """The finite numbers of ``column``, one per row; DataError naming the line of a bad cell."""
        return self.columns.numbers(column)

    def texts(self, column: str, what: str) -> list:
        """The stripped, non-empty texts of ``column``; DataError naming the line of an empty one."""
        return self.columns.texts(column, what)


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
                    check_limits: bool = True, texts=(), warn_metres: bool = True) -> AxisTable:
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
    texts : sequence of str
        Columns read as text (marks, image names); every other is read as numbers.
    warn_metres : bool
        Warn of readings that look like metres (:func:`warn_if_metres`); a reader that checks the units
        of its rows as a whole (the observation CSV) warns itself.

    Raises
    ------
    DataError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    known = [a.column for a in machine.axes] + [f"dir_{a.name.lower()}" for a in machine.axes] + ["t_s", "run"]
    table = read_csv_columns(path, what=what, required=required, texts=texts, known=known)
    header_line, header = table.header_line, table.header
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
                hint = column_hint(h, [f"dir_{a.name.lower()}" for a in machine.axes if f"dir_{a.name.lower()}"
                                       not in header]).replace("? ", "?; ")
                raise DataError(f"'dir_' column for unknown axis {h[4:]!r}; {hint}axes: "
                                f"{', '.join(a.name.lower() for a in machine.axes)}", path=path, line=header_line,
                                column=h)
            dir_cols[match[0].name] = header.index(h)
    optional = set(optional_axes)
    for a in machine.axes:
        if a.name not in axis_cols and a.name not in optional:
            known = set(required) | {header[k] for k in axis_cols.values()} | {"t_s", "mark"}
            hint = column_hint(a.column, [h for h in header if h not in known and not h.startswith("dir_")])
            raise DataError(f"missing column {a.column!r} for axis {a.name}{' (' + hint.strip() + ')' if hint else ''}",
                            path=path, line=header_line)
    lines = table.lines
    if not lines:
        raise DataError("no data rows after the header", path=path, line=header_line)
    n = len(lines)
    # the first bad cell in reading order among the columns read here, as a row-by-row reader would meet it
    read = [a.column for a in machine.axes if a.name in axis_cols] + (["t_s"] if "t_s" in header else []) + \
        (["run"] if "t_s" in header and "run" in header else []) + [header[k] for k in dir_cols.values()]
    first = table.first_bad(read)
    if first is not None:
        raise first
    axes = np.full((n, len(machine.axes)), np.nan)
    for j, a in enumerate(machine.axes):
        if a.name in axis_cols:
            axes[:, j] = table.numbers(a.column)
    t_s = table.numbers("t_s").copy() if "t_s" in header else None
    if t_s is not None:
        t_s = run_clock(t_s, table.numbers("run") if "run" in header else None, lines, path)
    dirs = {}
    for name, k in dir_cols.items():
        v = table.numbers(header[k])
        wrong = np.flatnonzero((v != 1.0) & (v != -1.0))
        if wrong.size:
            i = int(wrong[0])
            raise DataError(f"approach direction must be +1 or -1, found {v[i]:g}", path=path, line=lines[i],
                            column=header[k])
        dirs[name] = v.copy()
    if check_limits:
        check_travel(machine, axes, lines, path)
    if warn_metres:
        warn_if_metres(machine, axes, path)
    return AxisTable(path, header_line, header, table, axes, dirs, t_s, lines)


def run_clock(t_s: np.ndarray, runs, lines, path) -> np.ndarray:
    """Times from each run's start, as the time-driven effects take them (a warm-up, a drift restart with each run).

    With a ``run`` column (a number per row): ``t_s`` less the earliest ``t_s`` of the row's run, so a file that
    joins two runs timed by one clock gives each run's rows their time since that run began. Without one, ``t_s``
    as written; where it goes back (a second run appended, timed from its own start) that row starts a new run,
    and a warning says so.
    """
    t_s = np.asarray(t_s, float).copy()
    if runs is not None:
        runs = np.asarray(runs, float)
        for r in np.unique(runs):
            rows = runs == r
            t_s[rows] -= np.min(t_s[rows])
        return t_s
    back = np.flatnonzero(np.diff(t_s) < 0)
    if back.size:
        i = int(back[0]) + 1
        warnings.warn(f"{path}: t_s goes back at line {lines[i]} ({t_s[i - 1]:g} -> {t_s[i]:g} s): read as the start "
                      f"of another run ({back.size + 1} runs), a warm-up or drift restarting with each; give a 'run' "
                      f"column where the runs share one clock", stacklevel=3)
    return t_s


#: A linear axis whose readings all lie within this share of its travel's larger end looks like metres in mm.
METRES_SHARE = 0.002


def metres_columns(machine: Machine, axes: np.ndarray) -> list:
    """(column, largest |reading| mm, low, high) of each linear axis with a travel of 100 mm or more whose every
    reading lies within ±0.2 % of it (±1.2 mm of ±600 mm) and yet they vary: metres written in a ``_mm`` column."""
    limits = axis_limits(machine)
    out = []
    for j, a in enumerate(machine.axes):
        lo, hi = limits[j]
        v = axes[:, j][np.isfinite(axes[:, j])]
        reach = max(abs(lo), abs(hi)) if np.isfinite(hi - lo) else np.inf
        if a.kind != "prismatic" or v.size < 3 or not np.isfinite(reach) or hi - lo < 100.0:
            continue
        if np.abs(v).max() <= METRES_SHARE * reach and np.ptp(v) > 0:
            out.append((a.column, float(np.abs(v).max()), lo, hi))
    return out


def warn_if_metres(machine: Machine, axes: np.ndarray, path) -> list:
    """A warning for each column of :func:`metres_columns`; returns their names."""
    import warnings

    found = metres_columns(machine, axes)
    for column, largest, lo, hi in found:
        warnings.warn(f"{path}: every reading of {column} is within ±{largest:.3g} mm of a travel of "
                      f"{lo:g} .. {hi:g} mm; if they are metres, multiply by 1000", stacklevel=3)
    return [c for c, *_ in found]


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
