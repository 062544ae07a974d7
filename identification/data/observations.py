"""Alignment observations: the CSV of docs/formats.md, read and written.

One row per alignment: the mark, its coordinates in the workpiece frame (mm)
and the reading of every motion axis (mm / deg) at which the tool point
coincided with it; optionally ``t_s`` and ``dir_<axis>`` columns, and the
offset columns ``mark_dx_mm``, ``mark_dy_mm``, ``mark_dz_mm``: where the mark
was seen relative to the tool point, in the tool frame (a row with offsets
says "at these readings the mark was at this offset"; without them it is an
alignment, offset 0). Columns ``shift_<source>_<dx|dy|dz>_mm`` name a shared (type B)
source of uncertainty of those offsets: how far the offset moves when the
source is one standard deviation off (``observe`` writes them for the laser's
offset from the camera); the fit carries them into its uncertainties.
"""
from __future__ import annotations

import csv
import io
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from kinid.files import write_text
from kinid.errors import DataError
from kinid.files import read_csv_rows
from ..model import Machine

__all__ = ["SetAside", "OFFSET_COLUMNS", "Observations", "read_observations", "write_observations", "observations_text", "exact_duplicates", "row_groups", "check_observations",
           "read_csv_rows"]

_MARK_COLUMNS = ("wx_mm", "wy_mm", "wz_mm")
#: Offset of the mark from the tool point in the tool frame, mm (optional columns).
OFFSET_COLUMNS = ("mark_dx_mm", "mark_dy_mm", "mark_dz_mm")
#: A shared source's shift of the offsets for one standard deviation: shift_<source>_<dx|dy|dz>_mm.
_SHIFT_COLUMN = re.compile(r"shift_([a-z][a-z0-9_]*)_(dx|dy|dz)_mm")


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
    shifts_mm : dict source -> array (N, 3)
        For each shared source of uncertainty of the offsets (e.g. ``laser_offset_x``): how far the
        offsets move, tool frame, mm, when the source is one standard deviation off.
    rotations : array (N, 3, 3) or None
        On a row of a measured orientation (an instrument export's, docs/formats.md): the tool frame's measured
        orientation in the workpiece (measurement) frame, its columns the tool's x, y, z; NaN on the other rows.
        Such a row's residual is the small-angle vector of the model's orientation against it, in the workpiece
        frame, µrad, times ``rotation_um_per_urad`` (its σ's ratio to the points'): three rows in µm like a point's.
    rotation_um_per_urad : array (N,) or None
        That factor (µm per µrad) on the orientation rows, 0 on the points' rows.
    """

    marks: tuple
    w_mm: np.ndarray
    axes: np.ndarray
    t_s: np.ndarray | None = None
    directions: dict = field(default_factory=dict)
    lines: tuple = ()
    source: str = "<memory>"
    offsets_mm: np.ndarray | None = None
    shifts_mm: dict = field(default_factory=dict)
    rotations: np.ndarray | None = None
    rotation_um_per_urad: np.ndarray | None = None

    @property
    def rotation_rows(self) -> np.ndarray:
        """(N,) bool: the rows of a measured orientation (``rotations``), not of a point."""
        if self.rotation_um_per_urad is None:
            return np.zeros(len(self), bool)
        return self.rotation_um_per_urad > 0

    def __len__(self) -> int:
        return len(self.marks)

    def subset(self, index) -> "Observations":
        """Rows ``index`` (array of ints or booleans); the observations themselves when that is every row in order."""
        idx = np.arange(len(self))[index]
        if len(idx) == len(self) and np.array_equal(idx, np.arange(len(self))):
            return self  # frozen: nothing to copy
        return replace(
            self,
            marks=_take(self.marks, idx),
            w_mm=self.w_mm[idx],
            axes=self.axes[idx],
            t_s=None if self.t_s is None else self.t_s[idx],
            directions={k: v[idx] for k, v in self.directions.items()},
            lines=_take(self.lines, idx) if self.lines else (),
            offsets_mm=None if self.offsets_mm is None else self.offsets_mm[idx],
            shifts_mm={k: v[idx] for k, v in self.shifts_mm.items()},
            rotations=None if self.rotations is None else self.rotations[idx],
            rotation_um_per_urad=None if self.rotation_um_per_urad is None else self.rotation_um_per_urad[idx],
        )


def _take(items: tuple, idx: np.ndarray) -> tuple:
    """``items`` at ``idx`` as a tuple, gathered in C (``operator.itemgetter``), not a Python loop over rows."""
    from operator import itemgetter

    return tuple(itemgetter(*idx.tolist())(items)) if len(idx) > 1 else tuple(items[i] for i in idx)


def read_observations(path, machine: Machine, *, optional_axes=(), check_limits: bool = True,
                      check_units: bool = True) -> Observations:
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
    check_units : bool
        Warn of columns in a likely wrong unit (:func:`~kinid.identification.data.units.warn_units`: marks
        or readings in metres or inches, angles in radians). ``kinid identify`` checks them itself, after
        the fit, to name them in its refusal of a fit that failed instead.

    Raises
    ------
    DataError
        Naming the file, line and column of the first problem.
    """
    from .axis_columns import read_axis_table

    t = read_axis_table(path, machine, what="CSV file", required=("mark",) + _MARK_COLUMNS, texts=("mark",),
                        optional_axes=optional_axes, check_limits=check_limits, warn_metres=False)
    marks = t.texts("mark", "mark label")
    w = np.column_stack([t.numbers(c) for c in _MARK_COLUMNS])
    offsets = None
    if any(c in t.header for c in OFFSET_COLUMNS):
        offsets = np.column_stack([t.numbers(c) if c in t.header else np.zeros(len(marks)) for c in OFFSET_COLUMNS])
    shifts = {}
    for h in t.header:
        m = _SHIFT_COLUMN.fullmatch(h)
        if m:
            if offsets is None:
                raise DataError("a shift column needs the offset columns (mark_dx_mm, mark_dy_mm, mark_dz_mm)",
                                path=t.path, line=t.header_line, column=h)
            shifts.setdefault(m[1], np.zeros((len(marks), 3)))[:, "xyz".index(m[2][1])] = t.numbers(h)
    obs = Observations(tuple(marks), w, t.axes, t.t_s, t.directions, t.lines, str(t.path), offsets, shifts)
    if check_units:
        from .units import warn_units

        warn_units(machine, obs)
    return obs


#: The fewest observation rows each computation is made from (below them a fit's SVD, the replicate noise and the
#: score test's degrees of freedom fail with numpy's errors instead of a message): a fit 2, a verification 3, a
#: diagnosis (kinid diagnose, identify --auto) 4.
MIN_ROWS = {"a fit": 2, "a verification": 3, "a diagnosis": 4}


def check_row_count(obs, what: str) -> None:
    """Refuse observations with fewer rows than :data:`MIN_ROWS` ``[what]``: one DataError naming the file."""
    need = MIN_ROWS[what]
    if len(obs) < need:
        raise DataError(f"{len(obs)} observation row(s); {what} needs at least {need}: measure more alignments",
                        path=getattr(obs, "source", None))


def check_observations(obs, name: str = "obs") -> Observations:
    """``obs`` if it is :class:`Observations`; DataError naming the argument otherwise."""
    if not isinstance(obs, Observations):
        hint = " (read a CSV with kinid.identification.read_observations(path, machine))" if isinstance(obs, (str, Path)) else ""
        raise DataError(f"must be Observations{hint}, got {type(obs).__name__}", parameter=name)
    return obs


def exact_duplicates(obs: Observations) -> list:
    """(row, first row) pairs where a row repeats an earlier one exactly: same mark, mark position,
    every reading, time and direction. Such copies are one measurement, not replicates."""
    group, first = row_groups(obs.marks, obs.w_mm, obs.axes, () if obs.t_s is None else obs.t_s,
                              *(obs.directions[a] for a in sorted(obs.directions)),
                              () if obs.offsets_mm is None else obs.offsets_mm)
    return [(int(i), int(first[group[i]])) for i in np.flatnonzero(first[group] != np.arange(len(obs)))]


#: The multiplier of the rows' hash in :func:`row_groups` (the golden ratio's 64-bit fraction, Fibonacci hashing).
ROW_HASH = 0x9E3779B97F4A7C15


def row_groups(*columns) -> tuple:
    """(group (N,), first (groups,)): rows equal in every one of ``columns`` (each (N,) or (N, k), of numbers or
    strings; an empty one is left out) share a group, ``first[g]`` is the first row of group ``g``; groups are
    numbered in the order of their first rows. NaN equals NaN and −0 equals 0, as values read from a file would.

    Rows are ordered by a 64-bit hash of their bits (one sort, not one per column); rows of one hash are then
    compared whole, and a hash shared by rows that differ is sorted out by their values."""
    parts = []
    for c in columns:
        if isinstance(c, (tuple, list)) and c and all(isinstance(v, str) for v in c[:1]):
            c = _codes(c)  # marks as read: no array of texts made on the way
        c = np.asarray(c)
        if c.size == 0:
            continue
        parts.append((_codes(c) if c.dtype.kind not in "biuf" else c).reshape(len(c), -1))
    if not parts:
        return np.zeros(0, int), np.zeros(0, int)
    # each column's bits, −0 as 0 and one NaN: hashed and compared a column at a time (no (N, k) table of them made)
    key = [_bits(p[:, k]) for p in parts for k in range(p.shape[1])]
    n = len(key[0])
    h = np.zeros(n, np.uint64)
    with np.errstate(over="ignore"):
        for column in key:
            h = (h ^ column.view(np.uint64)) * np.uint64(ROW_HASH)
            h ^= h >> np.uint64(29)
    order = np.argsort(h, kind="stable")  # equal rows in the order they come
    ordered_h = h[order]
    same_row = ordered_h[1:] == ordered_h[:-1]
    pairs = np.flatnonzero(same_row)  # neighbours of one hash: compared whole
    a, b = order[pairs], order[pairs + 1]
    equal = np.logical_and.reduce([column[a] == column[b] for column in key])
    same_row[pairs] = equal
    if not equal.all():  # rows of one hash that differ (or come interleaved): sort those by value
        order = np.lexsort([h.view(np.int64), *key[::-1]])
        same_row = np.logical_and.reduce([column[order[1:]] == column[order[:-1]] for column in key])
    starts = np.r_[True, ~same_row]
    label = np.empty(n, int)
    label[order] = np.cumsum(starts) - 1
    first_of_row = order[starts][label]
    is_first = np.zeros(n, bool)
    is_first[first_of_row] = True
    number = np.cumsum(is_first) - 1
    return number[first_of_row], np.flatnonzero(is_first)


def _bits(column) -> np.ndarray:
    """The bits (int64) of a column of numbers as floats, −0 as 0 and every NaN one NaN: equal bits, equal values
    as read from a file."""
    c = np.asarray(column, dtype=float) + 0.0  # a copy; −0 is 0
    nan = np.isnan(c)
    if nan.any():
        c[nan] = np.nan
    return c.view(np.int64)


def _codes(texts) -> np.ndarray:
    """An integer per text (an array, or a list or tuple of str), equal for equal texts."""
    seen = {}
    values = texts if isinstance(texts, (tuple, list)) else np.asarray(texts).astype(str).ravel().tolist()
    codes = np.fromiter(map(seen.setdefault, values, range(len(values))), int, len(values))
    return codes if isinstance(texts, (tuple, list)) else codes.reshape(np.shape(texts))


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
    shift_columns = [(f"shift_{k}_{c}_mm", v[:, j]) for k, v in obs.shifts_mm.items() for j, c in enumerate(("dx", "dy", "dz"))
                     if np.any(v[:, j] != 0)]
    header += [name for name, _ in shift_columns]
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
        row += [f"{v[i]:.6g}" for _, v in shift_columns]
        row += [f"{extra[k][i]:.6g}" if isinstance(extra[k][i], (float, np.floating)) else str(extra[k][i]) for k in extra]
        writer.writerow(row)
    return buf.getvalue()


def write_observations(path, obs: Observations, machine: Machine, *, extra: dict | None = None) -> None:
    """Write ``obs`` as CSV, atomically."""
    write_text(path, observations_text(obs, machine, extra=extra))


@dataclass(frozen=True)
class SetAside:
    """One alignment set aside as a gross error.

    Attributes
    ----------
    row : int
        0-based row in the data as read.
    line : int or None
        Its line in the CSV file.
    mark : str
    residual_um : float
        Length of its residual (tool point − mark) when it was set aside, µm.
    sigmas : float
        Its studentized residual, in σ (the χ²₃ statistic's square root).
    """

    row: int
    line: int | None
    mark: str
    residual_um: float
    sigmas: float

    def describe(self) -> str:
        where = f"line {self.line}" if self.line is not None else f"row {self.row + 1}"
        return f"{where} (mark {self.mark}): residual {self.residual_um:.2f} µm, {self.sigmas:.1f} σ"
