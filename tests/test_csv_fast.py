"""The vectorised CSV column reader gives what the row-by-row reader gives: the same numbers, texts, line numbers
and the same first bad cell (file, line, column, message) — or hands the table to the row-by-row reader.

The truth here is the row-by-row reader itself (``csv`` module and ``float()`` per cell), run on the same file
with the fast reader switched off; each case also says whether the fast reader must have judged the file."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import kinid.csv_columns as cc
from kinid.errors import DataError

HEADER = "mark,a_mm,b_mm,note"
SETTINGS = settings(max_examples=200, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.function_scoped_fixture])


def _read(path, monkeypatch, *, fast: bool):
    """(outcome, used_fast): the table's columns as plain data, or the DataError's text."""
    used = []
    real = cc._fast_columns

    def spy(*args):
        out = real(*args) if fast else None
        used.append(out is not None)
        return out

    with monkeypatch.context() as m:
        m.setattr(cc, "_fast_columns", spy)
        try:
            t = cc.read_csv_columns(path, required=("mark",), texts=("mark",))
        except DataError as exc:
            return ("error", str(exc)), any(used)
    numbers = {}
    for h in t.header:
        try:
            numbers[h] = ("ok", t.numbers(h).tolist())
        except DataError as exc:
            numbers[h] = ("bad", str(exc), exc.line)
        assert np.array_equal(t.values[h], t.values[h], equal_nan=True) and len(t.values[h]) == len(t.lines)
    return ("table", t.header_line, t.header, t.lines, numbers, t.text, t.texts("mark", "mark") if
            all(c.strip() for c in t.text["mark"]) else None), used[-1] if used else False


def _same(path, monkeypatch):
    fast, used = _read(path, monkeypatch, fast=True)
    slow, _ = _read(path, monkeypatch, fast=False)
    assert fast == slow
    return fast, used


def _write(tmp_path, text: str):
    f = tmp_path / "t.csv"
    f.write_bytes(text.encode("utf-8"))
    return f


CASES = {
    # name: (body after the header line, whether the fast reader must judge it)
    "clean": ("M1,1.5,2,x\nM2,-0,1e-5,y\n", True),
    "no final newline": ("M1,1.5,2,x\nM2,3,4,y", True),
    "comments and blanks": ("# a, comment\nM1,1,2,x\n\n   \n  # another\n\x0c\nM2,3,4,y\n", True),
    "crlf": ("M1,1,2,x\r\nM2,3,4,y\r\n", True),
    "spaces and form feed": ("M1, 1.5 ,2\x0c,x\nM2,3,\t4,y\n", True),
    "underscore and arabic digits": ("M1,1_000,\u0663,x\nM2,3,4,y\n", True),
    "nan in a column": ("M1,1,2,x\nM2,nan,4,y\nM3,inf,5,z\n", True),
    "empty cell": ("M1,1,2,x\nM2,,4,y\n", True),
    "blank cell": ("M1,1,2,x\nM2, ,4,y\n", True),
    "not a number": ("M1,1,2,x\nM2,1.2.3,4,y\n", True),
    "numbers in the text columns": ("1,1,2,3\n2,3,4,5\n", True),
    "empty mark": ("M1,1,2,x\n ,3,4,y\n", True),
    "short row": ("M1,1,2,x\nM2,3,4\n", False),
    "long row": ("M1,1,2,x\nM2,3,4,y,z\n", False),
    "a one-cell row": ("M1,1,2,x\nM2\n", False),
    "quoted cell": ('M1,"1",2,x\nM2,3,4,y\n', False),
    "quote left open": ('M1,1,2,"x\nM2,3,4,y\n', False),
    "lone CR": ("M1,1,2,x\rM2,3,4,y\n", False),
    "NUL": ("M1,1,2,x\x00\nM2,3,4,y\n", False),
    "long cell": ("M1,1,2," + "x" * 5000 + "\nM2,3,4,y\n", False),
    "long comment": ("#" + "x" * 5000 + "\nM2,3,4,y\n", False),
    "header only": ("", True),
    "U+2028 in a cell": ("M1,1,2,x\u2028y\nM2,3,4,y\n", True),
}


@pytest.mark.parametrize("name", list(CASES))
def test_fast_reader_agrees(tmp_path, monkeypatch, name):
    body, fast = CASES[name]
    outcome, used = _same(_write(tmp_path, HEADER + "\n" + body), monkeypatch)
    assert used == fast, (name, outcome)


def test_header_last_line_without_newline(tmp_path, monkeypatch):
    outcome, _ = _same(_write(tmp_path, "# c\n" + HEADER), monkeypatch)
    assert outcome[0] == "table" and outcome[3] == ()


def test_line_numbers_across_chunks(tmp_path, monkeypatch):
    """Chunks of a few lines: line numbers run on, and the first bad cell is the earliest, across chunks."""
    rows = [f"M{i},{i}.5,{-i},n{i}" for i in range(200)]
    rows[57] = "# a comment line"
    rows[120] = "M120,oops,1,n"
    rows[150] = "M150,nan,1,n"
    rows[33] = ""
    f = _write(tmp_path, "# top\n" + HEADER + "\n" + "\n".join(rows) + "\n")
    monkeypatch.setattr(cc, "FAST_CHUNK_CHARS", 40)
    outcome, used = _same(f, monkeypatch)
    assert used
    lines, numbers = outcome[3], outcome[4]
    assert lines[:3] == (3, 4, 5) and 36 not in lines and 60 not in lines and lines[-1] == 202
    assert numbers["a_mm"][0] == "bad" and numbers["a_mm"][2] == 123 and "'oops' is not a number" in numbers["a_mm"][1]
    assert numbers["b_mm"] == ("ok", [1.0 if i in (120, 150) else float(-i) for i in range(200) if i not in (33, 57)])


cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr), st.integers(-10**6, 10**6).map(str),
                 st.text(alphabet=" \t\x0c#,_.e+-0123456789\u0663\u2028xn\"", max_size=6),
                 st.sampled_from(["", " ", "1_0", "0x10", "1e400", "-0", "# c", "nan", "\u0661.5"]))
line = st.lists(cell, min_size=1, max_size=5).map(",".join)


@SETTINGS
@given(st.lists(line, max_size=12), st.sampled_from(["\n", "\r\n"]), st.integers(8, 200))
def test_fast_reader_agrees_on_any_table(tmp_path_factory, monkeypatch, body, newline, chunk):
    f = _write(tmp_path_factory.mktemp("csv"), newline.join([HEADER, *body]) + newline)
    monkeypatch.setattr(cc, "FAST_CHUNK_CHARS", chunk)
    _same(f, monkeypatch)
