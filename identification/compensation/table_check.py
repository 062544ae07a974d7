"""Never worse than none: every table of a compensation applied as its controller applies it, before the
folder is written (docs/compensation.md, "Checked before writing").

A file is read back from its text (:mod:`kinid.axis_tables.readers`: the controller's points, the sign rule of its
format, modulo or not, end values held beyond the ends) and evaluated at the measured readings of its axis
and densely over the measured range. There, what it leaves of the fitted error, |error − compensation|, may
not exceed the error itself, |error|, by more than a tolerance (the interpolation bound of the table, or the
format's resolution). Beyond the data, at the ends of the travel, the compensation may not be larger than
the largest error inside the data (the hold or zero policy, never an extrapolated model).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from kinid.errors import DataError

__all__ = ["TableCheck", "check_table", "check_tables", "check_positions", "WORSE_SHARE"]

#: At any measured position a table may leave more than the error itself by at most this share of the error's RMS
#: over the measured range (a table's linear interpolation departs from the model by up to about that much).
WORSE_SHARE = 0.10
#: Points over the measured range at which each table is checked, besides the measured readings.
_DENSE = 2001


@dataclass(frozen=True)
class TableCheck:
    """One file's table (or one column of a CSV table) to check.

    Attributes
    ----------
    file : str
        The file's name (and the column, for a CSV table), as messages name it.
    axis : str
    units : tuple (position unit, value unit)
        ``("mm", "µm")`` or ``("deg", "µrad")``.
    error_at : callable q (n,) -> (k, n)
        The fitted error the table compensates, per row (a direction, or their mean), µm / µrad.
    applied_at : callable q (n,) -> (k, n)
        What the controller applies, read back from the file, the same rows.
    floor : float
        The tolerance's least value (the format's resolution), µm / µrad.
    """

    file: str
    axis: str
    units: tuple
    error_at: Callable
    applied_at: Callable
    floor: float = 0.0


def check_positions(readings, measured) -> np.ndarray:
    """The positions at which a table is checked: the distinct measured ``readings`` and :data:`_DENSE` points over
    the ``measured`` range (low, high)."""
    dense = np.linspace(measured[0], measured[1], _DENSE)
    r = np.asarray(readings if readings is not None else (), float)
    return np.union1d(dense, r[(r >= measured[0]) & (r <= measured[1])])


def check_table(check: TableCheck, inside: np.ndarray, ends=()) -> dict:
    """Check one table at the positions ``inside`` (the measured range) and ``ends`` (the travel's ends beyond the
    data). Returns the largest share of the error it leaves there (``left_max``, ``error_max`` µm / µrad, and the
    positions checked).

    Raises
    ------
    DataError
        Naming the file, the axis's position and the figures, where the table leaves more error than none.
    """
    q_unit, unit = check.units
    e = np.atleast_2d(check.error_at(inside))
    c = np.atleast_2d(check.applied_at(inside))
    error_rms = float(np.sqrt(np.mean(e ** 2))) if e.size else 0.0
    tol = max(WORSE_SHARE * error_rms, check.floor, 1e-9)
    left = np.abs(e - c)
    excess = left - np.abs(e) - tol
    k, i = np.unravel_index(int(np.argmax(excess)), excess.shape)
    if excess[k, i] > 0:
        raise DataError(f"{check.file}: applied as the controller applies it, it would leave {left[k, i]:.3g} {unit} "
                        f"at {check.axis} = {inside[i]:g} {q_unit}, where no compensation leaves {abs(e[k, i]):.3g} "
                        f"{unit} (more error than none inside the measured range); nothing written — the format's "
                        f"points or resolution cannot follow the error there: try --table-range data, a finer step or "
                        f"another --format")
    largest = float(np.max(np.abs(e))) if e.size else 0.0
    ends = np.asarray(ends, float)
    if ends.size:
        at_ends = np.abs(np.atleast_2d(check.applied_at(ends)))
        k, i = np.unravel_index(int(np.argmax(at_ends)), at_ends.shape)
        if at_ends[k, i] > largest + tol:
            raise DataError(f"{check.file}: applied as the controller applies it, it would compensate "
                            f"{at_ends[k, i]:.3g} {unit} at the travel's end {check.axis} = {ends[i]:g} {q_unit}, more "
                            f"than the largest error inside the measured range ({largest:.3g} {unit}): beyond the "
                            f"data a table must hold its end values or return to zero; nothing written")
    return {"checked_positions": int(inside.size + ends.size), "error_max": largest,
            "left_max": float(np.max(left)) if left.size else 0.0}


def check_tables(checks, *, by_name: bool) -> tuple:
    """Each ``(check, inside, ends)`` by :func:`check_table`: ``({file: outcome}, [(file, why left out)])``.

    A table that would leave more error than none is refused (DataError) where its format was asked for by name
    (``by_name``) or where no table would do; otherwise its format is left out, the others written, and the reason
    given for a note.
    """
    outcome, worse = {}, []
    for check, inside, ends in checks:
        try:
            outcome[check.file] = check_table(check, inside, ends)
        except DataError as exc:
            if by_name or len(worse) + 1 == len(checks):
                raise
            why = exc.message.split("; nothing written")[0].split(": ", 1)[-1]
            worse.append((check.file, f"{why}; the other formats' tables are written (--format names the formats to "
                                      f"write, and refuses one that cannot follow)"))
    return outcome, worse
