"""A CSV table read column by column: numbers into arrays at the speed of ``np.loadtxt``, texts only where asked.

A million-row observation file held as rows of Python strings takes about a kilobyte a row; as one array of
floats per column, eight bytes a cell. The checks and messages are those of :func:`kinid.files.read_csv_table`
(header, no column twice, every required column, rows as long as the header); a bad cell is remembered, not
raised, until its column is asked for (:meth:`CsvColumns.numbers`), with the message ``csv_number`` gives.

Two readers, one result. The fast one takes the text a few megabytes at a time: lines split on ``\n``, the
comment and blank lines found, the row widths counted, and the numeric columns parsed by ``np.loadtxt`` at once
(whose numbers are a subset of those ``float()`` reads, with the same values); a column ``np.loadtxt`` refuses or
finds a non-finite number in is read again with ``float()`` cell by cell, so its first bad cell is the one the
row-by-row reader names. Whatever the fast reader cannot judge as the ``csv`` module would — a quote, a NUL, a
lone CR, a line longer than a cell may be, a row of another width — sends the whole table to the row-by-row
reader (:func:`kinid.files.iter_csv_rows`), whose messages are those of every check.
"""
from __future__ import annotations

import math
from array import array
from dataclasses import dataclass
from itertools import repeat
from pathlib import Path

import numpy as np

from .errors import DataError
from .files import MAX_CSV_CELL, check_row_width, checked_header, csv_number, iter_csv_rows, read_csv_text

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
        The numbers of each column; NaN throughout a column with a cell that is not a finite number.
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
        out = list(map(str.strip, self.text[column]))
        if not all(out):
            raise DataError(f"empty {what}", path=self.path, line=self.lines[out.index("")], column=column)
        return out


#: Characters of the text the fast reader splits into cells at a time (its Python strings live only that long).
FAST_CHUNK_CHARS = 1 << 22


def read_csv_columns(path, *, what: str = "CSV file", required=(), texts=(), known=()) -> CsvColumns:
    """Read a CSV table with a header row into columns (module docstring); ``texts``: columns kept as text;
    ``known``: other columns the reader uses (never suggested for a missing required one).

    Raises
    ------
    DataError
        Naming the file, and the line or column, of the first problem with the table's shape.
    """
    path = Path(path)
    text = read_csv_text(path, what=what)
    rows = iter_csv_rows(path, what=what, text=text)
    header_line, header = checked_header(path, next(rows, None), required, known)
    fast = _fast_columns(path, text, header_line, header, texts)
    if fast is not None:
        return fast
    return _slow_columns(path, rows, header_line, header, texts)


def _slow_columns(path, rows, header_line, header, texts) -> CsvColumns:
    """The table row by row from ``rows`` (after the header), each cell through ``float()``: every check's message."""
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
    columns = {h: np.frombuffer(values[k], dtype=float) if len(values[k]) else np.zeros(0)
               for k, h in enumerate(header)}
    for h in bad:
        columns[h] = np.full(len(lines), np.nan)
    return CsvColumns(path, header_line, header, tuple(lines), columns, bad, text)


def _fast_columns(path, text, header_line, header, texts):
    """The table (module docstring) read vectorised, or None where the row-by-row reader must judge it."""
    if "\r" in text:
        text = text.replace("\r\n", "\n")
        if "\r" in text:  # a lone CR ends a row too: the csv module's business
            return None
    start = 0
    for _ in range(header_line):
        start = text.find("\n", start) + 1
        if start == 0:  # the header is the last line
            return None
    if text.find('"', start) >= 0 or text.find("\x00", start) >= 0:
        return None
    width = len(header)
    numeric = [k for k, h in enumerate(header) if h not in texts]
    pieces = {h: [] for h in header}
    bad, text_cells = {}, {header[k]: [] for k, h in enumerate(header) if h in texts}
    most = text.count("\n", start) + 1  # rows at most: the columns are filled in place, never concatenated
    values, lines, filled = {h: np.empty(most) for h in header}, np.empty(most, int), 0
    line = header_line + 1
    while start < len(text):
        end = text.find("\n", start + FAST_CHUNK_CHARS)
        end = len(text) if end < 0 else end + 1
        chunk = _fast_chunk(text[start:end], line, width)
        if chunk is None:
            return None
        rows, (numbers, seen) = chunk
        line += seen
        _chunk_numbers(path, header, numeric, rows, numbers, pieces, bad)
        for k, h in enumerate(header):
            if h in texts:
                cells = _cells(rows, k)
                text_cells[h] += cells
                if h not in bad:
                    _column_numbers(path, h, k, cells, numbers, pieces, bad)
        stop = filled + len(rows)
        lines[filled:stop] = numbers
        for h, got in pieces.items():
            if got:
                values[h][filled:stop] = got.pop()
        filled, start = stop, end
    for h, v in [(None, lines), *values.items()]:
        v.resize(filled, refcheck=False)  # in place: no copy of a million rows
        if h in bad:
            v[:] = np.nan
    return CsvColumns(path, header_line, header, tuple(lines.tolist()), values, bad, text_cells)


def _fast_chunk(chunk: str, line: int, width: int):
    """``(rows, (line numbers, lines in chunk))`` of a chunk of whole lines starting at file line ``line``: its rows
    without comment and blank lines; None if a row's width or a line's length is for the row-by-row reader."""
    parts = chunk.split("\n")
    if parts[-1] == "":
        parts.pop()
    n = len(parts)
    if n and max(map(len, parts)) > MAX_CSV_CELL:
        return None
    commas = np.fromiter(map(str.count, parts, repeat(",")), int, n)
    skip = np.zeros(n, bool)
    if "#" in chunk:
        skip[[i for i, p in enumerate(parts) if p.lstrip().startswith("#")]] = True
    for i in np.flatnonzero(commas == 0).tolist():
        skip[i] = skip[i] or not parts[i].strip()
    if np.any(commas[~skip] != width - 1):
        return None
    numbers = line + np.flatnonzero(~skip)
    rows = [p for p, s in zip(parts, skip.tolist()) if not s] if skip.any() else parts
    return rows, (numbers, n)


def _cells(rows, k: int) -> list:
    """The cells of column ``k`` of ``rows`` (lines of the header's width, no quotes)."""
    if k == 0:
        return [r.partition(",")[0] for r in rows]
    return [r.split(",", k + 1)[k] for r in rows]


def _chunk_numbers(path, header, numeric, rows, lines, pieces, bad) -> None:
    """Append the chunk's numbers of the ``numeric`` columns to ``pieces``; the first bad cell of a column to ``bad``."""
    todo = [k for k in numeric if header[k] not in bad]
    if not todo or not rows:
        return
    try:
        block = np.loadtxt(rows, delimiter=",", usecols=todo, comments=None, quotechar=None, ndmin=2)
    except ValueError:
        block = None
    for j, k in enumerate(todo):
        if block is not None and np.isfinite(block[:, j]).all():
            pieces[header[k]].append(block[:, j])
        else:
            _column_numbers(path, header[k], k, _cells(rows, k), lines, pieces, bad)


def _column_numbers(path, column, k, cells, lines, pieces, bad) -> None:
    """The numbers of one column's ``cells`` by ``float()`` (as the row-by-row reader reads them) into ``pieces``,
    or its first bad cell's DataError into ``bad``."""
    try:
        v = np.fromiter(map(float, cells), float, len(cells))
        if np.isfinite(v).all():
            pieces[column].append(v)
            return
    except ValueError:
        pass
    for i, cell in enumerate(cells):
        try:
            ok = math.isfinite(float(cell))
        except ValueError:
            ok = False
        if not ok:
            try:
                csv_number(cells, i, path=path, line=int(lines[i]), column=column)
            except DataError as exc:
                bad[column] = exc
            return
