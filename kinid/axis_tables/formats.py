"""Axis error tables and the controller files that load them (docs/compensation.md).

One writer for every method that ends in a bidirectional table of one axis's
positioning error against its position — the five-axis compensation
(``kinid compensate``) and the stage methods alike.

Sign convention everywhere in kinid: an axis error is *actual − commanded*
(where the axis is, minus where it was told to be), in µm for a linear axis
and µrad for a rotary one, for the approach direction + (``forward``) and −
(``reverse``). Each controller format states how it takes that.

Controller formats are a registry (:data:`CONTROLLER_FORMATS`) of
:class:`ControllerFormat` objects with one interface: a name, a file-name
pattern, the most points the controller reads, whether it needs equal steps,
whether it has a modulo (one-turn) table, the smallest value it stores, the
sign rule, what the controller does beyond the table's ends, and
``write(table, options) -> text``. A new format is one :func:`register_format`
call; ``kinid compensate``, the stage commands and :func:`write_tables` take it
from the registry.
"""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

from .readers import linuxcnc_table, sinumerik_table, twincat_table
from ..errors import DataError
from ..registry import Registry

if TYPE_CHECKING:  # numpy is imported by the functions that compute: the format registry loads without it
    import numpy as np

__all__ = ["AxisErrorTable", "TableOptions", "ControllerFormat", "CONTROLLER_FORMATS", "register_format",
           "controller_format", "default_formats", "format_text", "write_tables", "neutral_csv_text",
           "linuxcnc_text", "twincat_text", "sinumerik_text", "points_for",
           "LINUXCNC_MAX_POINTS", "TWINCAT_MAX_POINTS", "SINUMERIK_MAX_POINTS"]

#: LinuxCNC reads at most this many triplets per joint.
LINUXCNC_MAX_POINTS = 256
#: TwinCAT CNC: ``kw.ssfk.kw_nr_max`` must be smaller than ``kw.ssfk.max_points`` (P-COMP-00059, default 1500).
TWINCAT_MAX_POINTS = 1499
#: SINUMERIK: kinid writes at most this many points; MD38000 $MA_MM_ENC_COMP_MAX_POINTS must reserve at least
#: as many (small controls such as the 808D take 200).
SINUMERIK_MAX_POINTS = 5000


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
        import numpy as np

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


@dataclass(frozen=True)
class TableOptions:
    """What a controller file needs besides the table.

    Attributes
    ----------
    axis_number : int or None
        The controller's number of the axis (TwinCAT logical axis ``kopf.achs_nr``, SINUMERIK machine
        axis ``AX<n>``); None: 1, with a note in the file to set it.
    axis_name : str or None
        Name written into the file where the format has one (default: the table's axis).
    modulo : bool
        The table covers one turn of a rotary axis, first and last points one position apart by 360°
        with equal values; the controller wraps it.
    comment : str
        One line of provenance, written where the format takes comments.
    """

    axis_number: int | None = None
    axis_name: str | None = None
    modulo: bool = False
    comment: str = ""


@dataclass(frozen=True)
class ControllerFormat:
    """One controller's axis compensation file.

    Attributes
    ----------
    name : str
        Registry key and ``--format`` value.
    title : str
        What the file is, in the controller's words.
    file_pattern : str
        File name, ``{axis}`` replaced by the axis name.
    max_points : int
        Most points the controller reads per axis.
    equidistant : bool
        The controller takes a start, a step and values (points at equal steps only).
    bidirectional : bool
        The file holds a table per approach direction; else one table (the mean of both), the reversal
        going to the controller's backlash compensation.
    modulo : bool
        The format marks a one-turn table of a rotary axis as modulo.
    resolution_um, resolution_urad : float
        The smallest step of a stored value (linear, rotary axes).
    sign : str
        How a value in the file relates to kinid's error (actual − commanded).
    beyond : str
        What the controller applies beyond the table's first and last points.
    write : callable (AxisErrorTable, TableOptions) -> str
    default : bool
        Written by ``kinid compensate`` when no ``--format`` is given.
    read : callable (text, rotary) -> kinid.axis_tables.readers.FileTable, or None
        The file read back as the controller holds it (points, the error compensated in kinid's sign
        convention, modulo); ``kinid compensate`` checks every file it writes through it. None: the
        command checks the table it gave ``write`` instead, and says so.
    """

    name: str
    title: str
    file_pattern: str
    max_points: int
    equidistant: bool
    bidirectional: bool
    modulo: bool
    resolution_um: float
    resolution_urad: float
    sign: str
    beyond: str
    write: Callable
    default: bool = True
    read: Callable | None = None

    def file_name(self, axis: str) -> str:
        return self.file_pattern.format(axis=axis)

    def resolution(self, rotary: bool) -> float:
        """Smallest stored step of a value, µm (linear) or µrad (rotary)."""
        return self.resolution_urad if rotary else self.resolution_um


#: Controller format name -> :class:`ControllerFormat`.
CONTROLLER_FORMATS = Registry("controller format", ControllerFormat, parameter="fmt", variant_parameter="fmt")


def register_format(fmt: ControllerFormat) -> ControllerFormat:
    """Add ``fmt`` to :data:`CONTROLLER_FORMATS` (replacing one of the same name) and return it."""
    return CONTROLLER_FORMATS.register(fmt)


def controller_format(name) -> ControllerFormat:
    """The registered format ``name`` (or ``name`` itself when it is a :class:`ControllerFormat`)."""
    return CONTROLLER_FORMATS.look_up(name)


def default_formats() -> tuple:
    """Names of the formats written when none is asked for."""
    return CONTROLLER_FORMATS.defaults()


def neutral_csv_text(position_column: str, positions, columns: dict) -> str:
    """A plain CSV table: ``position_column`` then one column per entry of ``columns`` (name -> values)."""
    import numpy as np

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
    import numpy as np

    values = np.asarray(values, float)
    return values * 1e-3 if not table.rotary else np.degrees(values * 1e-6)


def _check_points(fmt: ControllerFormat, table: AxisErrorTable) -> None:
    n = table.positions.size
    if n > fmt.max_points:
        raise DataError(f"axis {table.axis}: {n} points, but {fmt.title} holds at most {fmt.max_points} per axis; "
                        f"use a coarser step", parameter="positions")


# --- LinuxCNC ----------------------------------------------------------------------------------

def linuxcnc_text(table: AxisErrorTable, options: TableOptions = TableOptions()) -> str:
    """LinuxCNC ``COMP_FILE_TYPE = 0`` text: "nominal forward reverse" per line, machine units (mm / deg).

    Forward and reverse are the actual positions reached approaching in the + and − direction:
    nominal + error. Numbers with 6 decimals (0.001 µm, 0.000001°). The loader takes no comments.

    Raises
    ------
    DataError
        If the table has more points than LinuxCNC reads (256): use a coarser step.
    """
    _check_points(LINUXCNC, table)
    fwd = table.positions + _to_machine_units(table, table.forward)
    rev = table.positions + _to_machine_units(table, table.backward)
    return "".join(f"{q:.6f} {f:.6f} {r:.6f}\n" for q, f, r in zip(table.positions, fwd, rev))


LINUXCNC = register_format(ControllerFormat(
    name="linuxcnc", title="LinuxCNC joint compensation file (COMP_FILE_TYPE 0)", file_pattern="{axis}.comp",
    max_points=LINUXCNC_MAX_POINTS, equidistant=False, bidirectional=True, modulo=False,
    resolution_um=0.001, resolution_urad=math.radians(1e-6) * 1e6,
    sign="forward/reverse columns are the actual positions reached: nominal + error",
    beyond="the first and last points' values are held (the loader's end entries have zero slope)",
    write=linuxcnc_text, read=linuxcnc_table))


# --- Beckhoff TwinCAT CNC ----------------------------------------------------------------------

def twincat_text(table: AxisErrorTable, options: TableOptions = TableOptions(), **legacy) -> str:
    """Beckhoff TwinCAT CNC leadscrew error compensation list (``kw.ssfk.*``), bilateral, metric.

    Setpoints and compensation values (actual − setpoint) as integers in 0.1 µm for a linear axis
    and 0.0001° for a rotary one; interpolation points given one by one (``interval 0``);
    ``kw.ssfk.modulo 1`` for a one-turn table of a rotary axis.

    Raises
    ------
    DataError
        If the table has more points than the list may use (``kw_nr_max`` < ``max_points`` = 1500).
    """
    import numpy as np

    if legacy:
        options = TableOptions(axis_number=legacy.get("axis_number"), axis_name=legacy.get("axis_name"))
    _check_points(TWINCAT, table)
    n = table.positions.size
    setpoint = np.rint(table.positions * 1e4).astype(np.int64)  # mm -> 0.1 µm, deg -> 0.0001°
    if table.rotary:
        pos = np.rint(np.degrees(table.forward * 1e-6) * 1e4).astype(np.int64)
        neg = np.rint(np.degrees(table.backward * 1e-6) * 1e4).astype(np.int64)
    else:
        pos = np.rint(table.forward * 10).astype(np.int64)  # µm -> 0.1 µm
        neg = np.rint(table.backward * 10).astype(np.int64)
    if np.any(np.diff(setpoint) <= 0):
        raise DataError(f"axis {table.axis}: points closer than the list's resolution", parameter="positions")
    name = options.axis_name or table.axis
    lines = [f"# {options.comment}"] if options.comment else []
    lines += [f"kopf.achs_nr                        {int(options.axis_number or 1)}",
              f"kopf.log_achs_name                  {name}",
              "kw.ssfk.interval                    0",
              f"kw.ssfk.kw_startpos                 {setpoint[0]}",
              f"kw.ssfk.kw_nr_max                   {n}",
              "kw.ssfk.unit                        1",
              "kw.ssfk.bilateral                   1",
              f"kw.ssfk.modulo                      {1 if options.modulo else 0}"]
    lines += [f"kw.ssfk.table[{i}].setpoint".ljust(36) + f"{v}" for i, v in enumerate(setpoint)]
    lines += [f"kw.ssfk.table[{i}].pos".ljust(36) + f"{v}" for i, v in enumerate(pos)]
    lines += [f"kw.ssfk.table[{i}].neg".ljust(36) + f"{v}" for i, v in enumerate(neg)]
    return "\n".join(lines) + "\n"


TWINCAT = register_format(ControllerFormat(
    name="twincat", title="Beckhoff TwinCAT CNC leadscrew error compensation list (kw.ssfk)",
    file_pattern="{axis}_ssfk.lis", max_points=TWINCAT_MAX_POINTS, equidistant=False, bidirectional=True,
    modulo=True, resolution_um=0.1, resolution_urad=math.radians(1e-4) * 1e6,
    sign="table[i].pos / .neg = actual - setpoint, 0.1 µm (0.0001° for rotary axes)",
    beyond="not stated by the list's documentation: kinid adds points at the travel's ends when the URDF has "
           "limits, so the held (or zero) value is explicit",
    write=twincat_text, read=twincat_table))


# --- Siemens SINUMERIK ---------------------------------------------------------------------------

def sinumerik_text(table: AxisErrorTable, options: TableOptions = TableOptions()) -> str:
    """SINUMERIK measuring-system error compensation (LEC) table: the ``%_N_AX_EEC_INI`` part program.

    ``$AA_ENC_COMP[0,N,AX<n>]`` holds the compensation value of point N in mm (degrees for a rotary
    axis), points at equal steps ``$AA_ENC_COMP_STEP`` from ``$AA_ENC_COMP_MIN`` to
    ``$AA_ENC_COMP_MAX``; ``$AA_ENC_COMP_IS_MODULO`` for a one-turn table of a rotary axis. One table
    for both directions: the mean of forward and reverse (the reversal belongs in the backlash machine
    data, MD32450). Values to 0.000001 mm / degree. A positive value moves the axis in the negative
    direction, so the value is the error itself (actual − commanded). Reference: SINUMERIK Extended
    Functions function manual, K3 Compensations, "Measuring system error compensation" and its example;
    MD38000 $MA_MM_ENC_COMP_MAX_POINTS must be at least the number of points, MD32700
    $MA_ENC_COMP_ENABLE = 1 after loading.

    Raises
    ------
    DataError
        If the points are not equally spaced, or there are more than 5000.
    """
    import numpy as np

    _check_points(SINUMERIK, table)
    q = table.positions
    step = (q[-1] - q[0]) / (q.size - 1)
    if not np.allclose(np.diff(q), step, rtol=1e-9, atol=1e-9):
        raise DataError(f"axis {table.axis}: SINUMERIK needs points at equal steps", parameter="positions")
    values = _to_machine_units(table, 0.5 * (table.forward + table.backward))
    ax = options.axis_name or f"AX{int(options.axis_number or 1)}"
    lines = ["%_N_AX_EEC_INI", "CHANDATA(1)"]
    if options.comment:
        lines.append(f"; {options.comment}")
    lines += [f"$AA_ENC_COMP[0,{i},{ax}]={_num(v, 6)}" for i, v in enumerate(values)]
    lines += [f"$AA_ENC_COMP_STEP[0,{ax}]={_num(step, 6)}",
              f"$AA_ENC_COMP_MIN[0,{ax}]={_num(q[0], 6)}",
              f"$AA_ENC_COMP_MAX[0,{ax}]={_num(q[-1], 6)}",
              f"$AA_ENC_COMP_IS_MODULO[0,{ax}]={1 if options.modulo else 0}",
              "M17"]
    return "\n".join(lines) + "\n"


SINUMERIK = register_format(ControllerFormat(
    name="sinumerik", title="Siemens SINUMERIK measuring-system error compensation (%_N_AX_EEC_INI)",
    file_pattern="{axis}_EEC_INI.spf", max_points=SINUMERIK_MAX_POINTS, equidistant=True, bidirectional=False,
    modulo=True, resolution_um=0.001, resolution_urad=math.radians(1e-6) * 1e6,
    sign="$AA_ENC_COMP = actual - commanded (the error), mm or degrees; one table, the mean of both directions",
    beyond="the values at $AA_ENC_COMP_MIN and $AA_ENC_COMP_MAX are held",
    write=sinumerik_text, read=sinumerik_table))


def format_text(fmt, table: AxisErrorTable, options: TableOptions | None = None, **keywords) -> str:
    """The text of ``table`` in controller format ``fmt`` (a name in :data:`CONTROLLER_FORMATS` or a format)."""
    fmt = controller_format(fmt)
    if options is None:
        options = TableOptions(**keywords)
    return fmt.write(table, options)


def write_tables(folder, tables, formats=None, *, axis_numbers=None, modulo=(), comment: str = "") -> list:
    """Write every table in every format into ``folder`` (created if missing).

    Parameters
    ----------
    tables : sequence of AxisErrorTable
    formats : sequence of str or ControllerFormat, optional
        Default: :func:`default_formats`.
    axis_numbers : dict axis -> int, optional
        The controller's axis numbers; default: the table's place in ``tables`` (1, 2, …).
    modulo : collection of str
        Axes whose table covers one turn (written as modulo tables where the format has them).

    Returns
    -------
    list of (file name, format name, axis)
    """
    from pathlib import Path

    from ..files import write_text

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    fmts = [controller_format(f) for f in (default_formats() if formats is None else formats)]
    numbers = dict(axis_numbers or {})
    written = []
    for k, table in enumerate(tables, start=1):
        options = TableOptions(axis_number=numbers.get(table.axis, k), modulo=table.axis in modulo, comment=comment)
        for fmt in fmts:
            name = fmt.file_name(table.axis)
            write_text(folder / name, fmt.write(table, options))
            written.append((name, fmt.name, table.axis))
    return written


def points_for(step: float, low: float, high: float, most: int | None = None) -> np.ndarray:
    """Grid from ``low`` to ``high`` (both included) at ``step`` or finer, at most ``most`` points."""
    import numpy as np

    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise DataError(f"no finite range {low:g} .. {high:g}", parameter="range")
    n = int(math.ceil((high - low) / step - 1e-9)) + 1
    if most is not None:
        n = min(n, most)
    return np.linspace(low, high, max(n, 2))
