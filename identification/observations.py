"""Alignment observations: the CSV of docs/formats.md, read and written.

One row per alignment: the mark, its coordinates in the workpiece frame (mm)
and the reading of every motion axis (mm / deg) at which the tool point
coincided with it; optionally ``t_s`` and ``dir_<axis>`` columns, and the
offset columns ``mark_dx_mm``, ``mark_dy_mm``, ``mark_dz_mm``: where the mark
was seen relative to the tool point, in the tool frame (a row with offsets
says "at these readings the mark was at this offset"; without them it is an
alignment, offset 0).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from kinid.files import write_text
from kinid.errors import DataError
from kinid.files import csv_number, read_csv_rows
from .machine import Machine, axis_limits

__all__ = ["OFFSET_COLUMNS", "Observations", "read_observations", "write_observations", "observations_text", "exact_duplicates", "check_observations",
           "read_csv_rows"]

_MARK_COLUMNS = ("wx_mm", "wy_mm", "wz_mm")
#: Offset of the mark from the tool point in the tool frame, mm (optional columns).
OFFSET_COLUMNS = ("mark_dx_mm", "mark_dy_mm", "mark_dz_mm")


@dataclass(frozen=True)
class Observations:
    """Alignment observations in machine-axis order.

    Attributes
    ----------
    marks : tuple of str
    w_mm : array (N, 3)
        Mark coordinates in the workpiece frame, mm.
    axes : array (N, n_axes)
        Readings in ``machine.axes`` order, mm / deg (NaN for axes not given).
    t_s : array (N,) or None
    directions : dict axis name -> array (N,) of ±1
    lines : tuple of int
        Source line of each row (1-based), for messages.
    source : str
        File name, for messages.
    offsets_mm : array (N, 3) or None
        Where the mark was seen relative to the tool point, in the ``tool`` frame, mm
        (camera x, y and laser stand-off deviation); None for alignments (offset 0).
    """

    marks: tuple
    w_mm: np.ndarray
    axes: np.ndarray
    t_s: np.ndarray | None = None
    directions: dict = field(default_factory=dict)
    lines: tuple = ()
    source: str = "<memory>"
    offsets_mm: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.marks)

    def subset(self, index) -> "Observations":
        """Rows ``index`` (array of ints or booleans)."""
        idx = np.arange(len(self))[index]
        return replace(
            self,
            marks=tuple(self.marks[i] for i in idx),
            w_mm=self.w_mm[idx],
            axes=self.axes[idx],
            t_s=None if self.t_s is None else self.t_s[idx],
            directions={k: v[idx] for k, v in self.directions.items()},
            lines=tuple(self.lines[i] for i in idx) if self.lines else (),
            offsets_mm=None if self.offsets_mm is None else self.offsets_mm[idx],
        )


def _column_for(machine: Machine, header: str):
    """Which axis a ``<axis>_mm``/``<axis>_deg`` header names, else None; DataError on a wrong unit."""
    stem, _, unit = header.rpartition("_")
    for a in machine.axes:
        if stem == a.name.lower():
            if header != a.column:
                raise DataError(f"axis {a.name} is {a.kind}: expected column {a.column!r}", column=header)
            return a
    return None


def read_observations(path, machine: Machine, *, optional_axes=(), check_limits: bool = True) -> Observations:
    """Read an observation CSV.

    Parameters
    ----------
    path : str or Path
    machine : Machine
    optional_axes : iterable of str
        Axes that may be absent (``predict`` solves them); their readings are NaN.
    check_limits : bool
        Refuse a reading outside its axis's travel in the URDF (the joint
        limits), which is almost always a unit or column mistake.

    Raises
    ------
    DataError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    rows = read_csv_rows(path)
    if not rows:
        raise DataError("no header row and no data", path=path)
    header_line, header = rows[0]
    header = [h.strip() for h in header]
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise DataError("duplicate column", path=path, line=header_line, column=dup)
    for col in ("mark",) + _MARK_COLUMNS:
        if col not in header:
            raise DataError(f"missing required column {col!r} (header: {', '.join(header)})", path=path, line=header_line)
    axis_cols = {}
    directions_cols = {}
    for h in header:
        try:
            a = _column_for(machine, h)
        except DataError as exc:
            raise DataError(exc.message, path=path, line=header_line, column=h) from None
        if a is not None:
            axis_cols[a.name] = header.index(h)
        if h.startswith("dir_"):
            name = h[4:]
            match = [a for a in machine.axes if a.name.lower() == name]
            if not match:
                raise DataError(f"'dir_' column for unknown axis {name!r}; axes: {', '.join(a.name.lower() for a in machine.axes)}", path=path, line=header_line, column=h)
            directions_cols[match[0].name] = header.index(h)
    offset_cols = [header.index(c) if c in header else None for c in OFFSET_COLUMNS]
    optional = set(optional_axes)
    for a in machine.axes:
        if a.name not in axis_cols and a.name not in optional:
            raise DataError(f"missing column {a.column!r} for axis {a.name}", path=path, line=header_line)
    data = rows[1:]
    if not data:
        raise DataError("no data rows after the header", path=path, line=header_line)

    def number(lineno, cells, col):
        idx = header.index(col) if isinstance(col, str) else col
        return csv_number(cells, idx, path=path, line=lineno, column=header[idx])

    n = len(data)
    marks, lines = [], []
    w = np.empty((n, 3))
    axes = np.full((n, len(machine.axes)), np.nan)
    t_s = np.empty(n) if "t_s" in header else None
    dirs = {k: np.empty(n) for k in directions_cols}
    offsets = np.zeros((n, 3)) if any(c is not None for c in offset_cols) else None
    for i, (lineno, cells) in enumerate(data):
        if len(cells) != len(header):
            raise DataError(f"{len(cells)} cells but the header has {len(header)} columns", path=path, line=lineno)
        mark = cells[header.index("mark")].strip()
        if not mark:
            raise DataError("empty mark label", path=path, line=lineno, column="mark")
        marks.append(mark)
        lines.append(lineno)
        w[i] = [number(lineno, cells, c) for c in _MARK_COLUMNS]
        for j, a in enumerate(machine.axes):
            if a.name in axis_cols:
                axes[i, j] = number(lineno, cells, axis_cols[a.name])
        if t_s is not None:
            t_s[i] = number(lineno, cells, "t_s")
        if offsets is not None:
            offsets[i] = [0.0 if c is None else number(lineno, cells, c) for c in offset_cols]
        for name, idx in directions_cols.items():
            v = number(lineno, cells, idx)
            if v not in (1.0, -1.0):
                raise DataError(f"approach direction must be +1 or -1, found {cells[idx].strip()!r}", path=path, line=lineno, column=header[idx])
            dirs[name][i] = v
    if check_limits:
        limits = axis_limits(machine)
        for j, a in enumerate(machine.axes):
            lo, hi = limits[j]
            margin = 1e-9 * max(1.0, abs(lo), abs(hi))
            bad = np.flatnonzero((axes[:, j] < lo - margin) | (axes[:, j] > hi + margin))
            if bad.size:
                i = int(bad[0])
                unit = "mm" if a.kind == "prismatic" else "deg"
                raise DataError(f"{axes[i, j]:g} {unit} is outside the travel of axis {a.name} in the URDF "
                                f"({lo:g} .. {hi:g} {unit}); check the units and the column, or pass "
                                f"--allow-outside-limits if the URDF's limits are wrong",
                                path=path, line=lines[i], column=a.column)
    return Observations(tuple(marks), w, axes, t_s, dirs, tuple(lines), str(path), offsets)


def check_observations(obs, name: str = "obs") -> Observations:
    """``obs`` if it is :class:`Observations`; DataError naming the argument otherwise."""
    if not isinstance(obs, Observations):
        hint = " (read a CSV with kinid.identification.read_observations(path, machine))" if isinstance(obs, (str, Path)) else ""
        raise DataError(f"must be Observations{hint}, got {type(obs).__name__}", parameter=name)
    return obs


def exact_duplicates(obs: Observations) -> list:
    """(row, first row) pairs where a row repeats an earlier one exactly: same mark, mark position,
    every reading, time and direction. Such copies are one measurement, not replicates."""
    seen, out = {}, []
    for i in range(len(obs)):
        key = (obs.marks[i], *obs.w_mm[i], *obs.axes[i], None if obs.t_s is None else obs.t_s[i],
               *(obs.directions[a][i] for a in sorted(obs.directions)),
               *(() if obs.offsets_mm is None else obs.offsets_mm[i]))
        key = tuple("nan" if isinstance(v, float) and v != v else v for v in key)
        if key in seen:
            out.append((i, seen[key]))
        else:
            seen[key] = i
    return out


def _ordered_axes(machine: Machine):
    """Axes for output columns: prismatic first, then revolute, each alphabetical."""
    return sorted(machine.axes, key=lambda a: (a.kind != "prismatic", a.name))


def observations_text(obs: Observations, machine: Machine, *, extra: dict | None = None) -> str:
    """CSV text of ``obs`` (docs/formats.md, "Observation CSV"); ``extra`` adds columns name -> array (N,)."""
    axes = _ordered_axes(machine)
    header = ["mark", *_MARK_COLUMNS, *[a.column for a in axes]]
    if obs.t_s is not None:
        header.append("t_s")
    dir_axes = [a for a in axes if a.name in obs.directions]
    header += [f"dir_{a.name.lower()}" for a in dir_axes]
    if obs.offsets_mm is not None:
        header += list(OFFSET_COLUMNS)
    extra = extra or {}
    header += list(extra)
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(header)
    index = {a.name: i for i, a in enumerate(machine.axes)}
    for i in range(len(obs)):
        row = [obs.marks[i], *(f"{v:.6f}" for v in obs.w_mm[i])]
        row += [f"{obs.axes[i, index[a.name]]:.9f}" for a in axes]
        if obs.t_s is not None:
            row.append(f"{obs.t_s[i]:.3f}")
        row += [f"{int(obs.directions[a.name][i]):d}" for a in dir_axes]
        if obs.offsets_mm is not None:
            row += [f"{v:.6f}" for v in obs.offsets_mm[i]]
        row += [f"{extra[k][i]:.6g}" if isinstance(extra[k][i], (float, np.floating)) else str(extra[k][i]) for k in extra]
        writer.writerow(row)
    return buf.getvalue()


def write_observations(path, obs: Observations, machine: Machine, *, extra: dict | None = None) -> None:
    """Write ``obs`` as CSV, atomically."""
    write_text(path, observations_text(obs, machine, extra=extra))
