"""A CSV table read column by column: numbers into arrays as the rows stream by, texts only where asked.

A million-row observation file held as rows of Python strings takes about a kilobyte a row; as one array of
floats per column, eight bytes a cell. The checks and messages are those of :func:`kinid.files.read_csv_table`
(header, no column twice, every required column, rows as long as the header); a bad cell is remembered, not
raised, until its column is asked for (:meth:`CsvColumns.numbers`), with the message ``csv_number`` gives.
"""
from __future__ import annotations

from array import array
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import DataError
from .files import check_row_width, checked_header, csv_number, iter_csv_rows

__all__ = ["CsvColumns", "read_csv_columns"]


@dataclass(frozen=True)
class CsvColumns:
    """A CSV table by columns.

    Attributes
    ----------
    path : Path
    header_line : int
    header : list of str
    lines : tuple of int
        File line of each row.
    values : dict column -> array (N,)
        The numbers of each column (NaN where a cell is not a finite number).
    bad : dict column -> DataError
        The first cell of the column that is not a finite number.
    text : dict column -> list of str
        The raw cells of the text columns asked for.
    """

    path: Path
    header_line: int
    header: list
    lines: tuple
    values: dict
    bad: dict
    text: dict

    def numbers(self, column: str) -> np.ndarray:
        """The finite numbers of ``column``; the DataError of its first bad cell (file, line, column)."""
        if column in self.bad:
            raise self.bad[column]
        return self.values[column]

    def first_bad(self, columns):
        """The DataError of the earliest bad cell among ``columns`` (by line, then by the order given), or None."""
        found = [(self.bad[c].line, k, self.bad[c]) for k, c in enumerate(columns) if c in self.bad]
        return min(found)[2] if found else None

    def texts(self, column: str, what: str) -> list:
        """The stripped, non-empty texts of ``column``; DataError naming the line of an empty one."""
        out = []
        for line, cell in zip(self.lines, self.text[column]):
            value = cell.strip()
            if not value:
                raise DataError(f"empty {what}", path=self.path, line=line, column=column)
            out.append(value)
        return out


def read_csv_columns(path, *, what: str = "CSV file", required=(), texts=(), known=()) -> CsvColumns:
    """Read a CSV table with a header row into columns (module docstring); ``texts``: columns kept as text;
    ``known``: other columns the reader uses (never suggested for a missing required one).

    Raises
    ------
    DataError
        Naming the file, and the line or column, of the first problem with the table's shape.
    """
    path = Path(path)
    rows = iter_csv_rows(path, what=what)
    header_line, header = checked_header(path, next(rows, None), required, known)
    kept = [k for k, h in enumerate(header) if h in texts]
    values = [array("d") for _ in header]
    text = {header[k]: [] for k in kept}
    bad = {}
    lines = array("q")
    nan = float("nan")
    for line, cells in rows:
        check_row_width(path, line, cells, header)
        lines.append(line)
        for k, cell in enumerate(cells):
            try:
                v = float(cell)
                if v != v or v in (float("inf"), float("-inf")):
                    raise ValueError
            except ValueError:
                v = nan
                if header[k] not in bad:
                    try:
                        csv_number(cells, k, path=path, line=line, column=header[k])
                    except DataError as exc:
                        bad[header[k]] = exc
            values[k].append(v)
        for k in kept:
            text[header[k]].append(cells[k])
    return CsvColumns(path, header_line, header, tuple(lines),
                      {h: np.frombuffer(values[k], dtype=float) if len(values[k]) else np.zeros(0)
                       for k, h in enumerate(header)}, bad, text)
