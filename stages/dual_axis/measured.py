"""One round of the dual-axis method measured on a gantry: the offset table from a CSV (docs/dual_axis.md).

A round: both Y axes step together from the start, the head making the moves of the table in use (zero
in the first round), and at each stop the camera measures where the plate has gone in the image. The
measurement CSV holds, per stop, the camera Y, the plate's shift in the image from where it was at the
start (px), and optionally the table entries in use during the round. The new table is the entries in
use plus the head move that cancels each shift (``-pixel_to_mm @ shift``), the method's update rule.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from kinid.errors import DataError
from kinid.files import csv_number, read_csv_table

from .calibrate import _check_matrix
from .table import OffsetTable, RoundRecord

__all__ = ["read_round", "table_from_round", "MEASUREMENT_COLUMNS"]

MEASUREMENT_COLUMNS = ("camera_y_mm", "shift_x_px", "shift_y_px")


def read_round(path):
    """(camera_y_mm (n,), shift_px (n, 2), table in use (n, 2) mm) from a measurement CSV."""
    path = Path(path)
    header_line, header, rows = read_csv_table(path, what="measurement file", required=MEASUREMENT_COLUMNS)
    in_use = [c for c in ("table_dx_mm", "table_dy_mm") if c in header]
    if len(in_use) == 1:
        raise DataError("give both table_dx_mm and table_dy_mm (the table in use), or neither", path=path,
                        line=header_line)
    y, shift, used = [], [], []
    for line, cells in rows:
        num = lambda c: csv_number(cells, header.index(c), path=path, line=line, column=c)  # noqa: E731
        y.append(num("camera_y_mm"))
        shift.append((num("shift_x_px"), num("shift_y_px")))
        used.append((num("table_dx_mm"), num("table_dy_mm")) if in_use else (0.0, 0.0))
        if len(y) > 1 and not y[-1] > y[-2]:
            raise DataError(f"camera Y must increase from row to row ({y[-2]:g} then {y[-1]:g} mm)", path=path,
                            line=line, column="camera_y_mm")
    if len(y) < 2:
        raise DataError("a round needs the start and at least one step", path=path)
    return np.array(y), np.array(shift), np.array(used)


def table_from_round(y_mm, shift_px, in_use_mm, pixel_to_mm, spec_um: float) -> OffsetTable:
    """The offset table after this round (entries in use + the measured correction), with its record."""
    m = _check_matrix(pixel_to_mm)
    change = -(np.asarray(shift_px, float) @ m.T)  # head move that cancels each shift, mm
    change = change - change[0]  # the start is the reference
    largest = float(np.max(np.abs(change)) * 1e3)
    done = largest <= spec_um
    record = RoundRecord(1, change * 1e3, largest)
    msg = (f"largest change {largest:.3f} µm {'<=' if done else '>'} {spec_um:g} µm: "
           + ("the table in use was good" if done else "run a round with the new table"))
    table = OffsetTable(np.asarray(y_mm, float), np.asarray(in_use_mm, float) + change, rounds=1, converged=done,
                        spec_um=float(spec_um), history=(record,), message=msg)
    return table
