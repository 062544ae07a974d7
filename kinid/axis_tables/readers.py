"""Controller compensation files read back as their controllers read them (docs/compensation.md).

Each reader takes the text a writer of :mod:`kinid.axis_tables` made and returns the
:class:`FileTable` the controller holds: its points, the error it compensates at each in kinid's
sign convention (actual − commanded, µm or µrad, per approach direction), and whether it wraps
one turn. :func:`applied` then evaluates it as the controller interpolates: linearly between points,
the end values held beyond the first and last point, a modulo table wrapped onto its turn.

``kinid compensate`` uses them to check its own files before it writes them (a file set that would
leave more error than none is refused). The tests read the same files with an implementation that
shares no code with these (tests/controller_consumers.py).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..errors import DataError

if TYPE_CHECKING:
    import numpy as np

__all__ = ["FileTable", "applied", "linuxcnc_table", "twincat_table", "sinumerik_table", "csv_tables"]


@dataclass(frozen=True)
class FileTable:
    """What a controller holds after loading one axis's file.

    Attributes
    ----------
    positions : array (n,)
        Commanded positions of the points, ascending, mm or deg.
    forward, backward : array (n,)
        The error the controller compensates there, actual − commanded, µm (linear) or µrad (rotary),
        approaching in the + and − direction (the same array for a one-table format).
    modulo : bool
        The controller wraps positions onto ``positions[0] .. positions[-1]`` (one turn).
    """

    positions: np.ndarray
    forward: np.ndarray
    backward: np.ndarray
    modulo: bool = False


def applied(table: FileTable, x, forward: bool = True) -> np.ndarray:
    """The error ``table`` compensates at commanded positions ``x`` (mm / deg), µm / µrad: linear between
    points, end values held beyond the ends, wrapped onto the table's turn where it is modulo."""
    import numpy as np

    x = np.asarray(x, float)
    q = table.positions
    if table.modulo:
        x = q[0] + np.mod(x - q[0], q[-1] - q[0])
    return np.interp(x, q, table.forward if forward else table.backward)


def _from_machine_units(values, rotary: bool):
    """mm or degrees -> µm or µrad."""
    import numpy as np

    values = np.asarray(values, float)
    return np.radians(values) * 1e6 if rotary else values * 1e3


def _fail(fmt: str, why: str) -> DataError:
    return DataError(f"{fmt} file: {why}", parameter="text")


def linuxcnc_table(text: str, rotary: bool) -> FileTable:
    """LinuxCNC ``COMP_FILE_TYPE 0``: "nominal forward reverse" per line, the actual positions reached; no modulo."""
    import numpy as np

    try:
        rows = np.array([line.split() for line in text.splitlines() if line.strip()], float)
    except ValueError:
        raise _fail("LinuxCNC", "a line is not three numbers") from None
    if rows.ndim != 2 or rows.shape[1] != 3 or rows.shape[0] < 2:
        raise _fail("LinuxCNC", "needs at least two lines of three numbers")
    q = rows[:, 0]
    return FileTable(q, _from_machine_units(rows[:, 1] - q, rotary), _from_machine_units(rows[:, 2] - q, rotary))


def twincat_table(text: str, rotary: bool) -> FileTable:
    """TwinCAT CNC ``kw.ssfk`` list: setpoints and actual − setpoint in 0.1 µm (0.0001° for a rotary axis)."""
    import numpy as np

    kv = dict(line.split(None, 1) for line in text.splitlines() if line.strip() and not line.startswith("#"))
    try:
        n = int(kv["kw.ssfk.kw_nr_max"])
        column = lambda key: np.array([int(kv[f"kw.ssfk.table[{i}].{key}"]) for i in range(n)]) * 1e-4  # noqa: E731
        q, pos, neg = column("setpoint"), column("pos"), column("neg")
    except (KeyError, ValueError) as exc:
        raise _fail("TwinCAT", f"missing or not a whole number: {exc}") from None
    return FileTable(q, _from_machine_units(pos, rotary), _from_machine_units(neg, rotary),
                     kv.get("kw.ssfk.modulo", "0").strip() == "1")


def sinumerik_table(text: str, rotary: bool) -> FileTable:
    """SINUMERIK ``%_N_AX_EEC_INI``: ``$AA_ENC_COMP`` values (the error, mm or degrees) at equal steps from
    ``_MIN`` to ``_MAX``; one table for both directions."""
    import numpy as np

    values = {int(m.group(1)): float(m.group(2)) for m in
              (re.match(r"\$AA_ENC_COMP\[0,(\d+),[^\]]+\]=(\S+)", line) for line in text.splitlines()) if m}

    def get(key):
        m = re.search(rf"\${key}\[0,[^\]]+\]=(\S+)", text)
        if m is None:
            raise _fail("SINUMERIK", f"no ${key}")
        return float(m.group(1))

    step, lo, hi = get("AA_ENC_COMP_STEP"), get("AA_ENC_COMP_MIN"), get("AA_ENC_COMP_MAX")
    k = round((hi - lo) / step) if step > 0 and math.isfinite((hi - lo) / step) else -1
    if k < 1 or sorted(values) != list(range(k + 1)):
        raise _fail("SINUMERIK", "the points are not every N from 0 to (MAX - MIN) / STEP")
    v = _from_machine_units([values[i] for i in range(k + 1)], rotary)
    return FileTable(lo + step * np.arange(k + 1), v, v, get("AA_ENC_COMP_IS_MODULO") == 1)


def csv_tables(text: str, modulo: bool = False) -> dict:
    """A plain CSV table (:func:`kinid.axis_tables.neutral_csv_text`): column name -> :class:`FileTable` of that
    column (values as written, both directions the same)."""
    import csv
    import io

    import numpy as np

    rows = list(csv.reader(io.StringIO(text)))
    try:
        data = np.array(rows[1:], float)
    except (ValueError, IndexError):
        raise _fail("CSV", "a row is not numbers") from None
    return {name: FileTable(data[:, 0], data[:, k], data[:, k], modulo) for k, name in enumerate(rows[0]) if k}
