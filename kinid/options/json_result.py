"""``--json``: a verb's result printed as one strict JSON value on standard output."""
from __future__ import annotations

import argparse
from dataclasses import dataclass

__all__ = ["add_json_option", "csv_rows", "json_file", "json_text", "WrittenJson"]


def add_json_option(parser: argparse.ArgumentParser, result, what: str) -> None:
    """``--json``: after the verb has run, its result ``result(args)`` printed as one strict JSON value on
    standard output, the verb's own text going to standard error (``what`` names the result in the help).

    For verbs whose result is the file they write (:func:`json_file`, :func:`csv_rows`): the roof
    (kinid.cli) prints it, so the verb's code is the same with or without ``--json``.
    """
    parser.add_argument("--json", action="store_true", help=f"print {what} as JSON on standard output (the "
                                                            "text goes to standard error)")
    parser.set_defaults(json_result=result)


@dataclass(frozen=True)
class WrittenJson:
    """The JSON file a verb wrote (kinid's own strict JSON, checked when it was made): printed as written."""

    path: str


def json_file(dest: str, name: str | None = None):
    """A ``result`` for :func:`add_json_option`: the JSON file the verb wrote at ``args.<dest>`` (inside it,
    ``name``, when ``args.<dest>`` is a folder)."""
    def result(args):
        from pathlib import Path

        path = Path(getattr(args, dest))
        return WrittenJson(str(path / name if name else path))
    return result


def json_text(value) -> str:
    """What ``--json`` prints for a verb's result: a :class:`WrittenJson` file's text, any other value as
    strict JSON (kinid.files.strict_json)."""
    from ..files import MAX_JSON_BYTES, strict_json
    from ..untrusted import read_limited_text

    if isinstance(value, WrittenJson):
        return read_limited_text(value.path, what="JSON file", max_bytes=MAX_JSON_BYTES).strip()
    return strict_json(value)


def csv_rows(dest: str):
    """A ``result`` for :func:`add_json_option`: the rows of the CSV the verb wrote at ``args.<dest>``, one
    object per row (numbers as numbers, empty cells as null)."""
    def result(args):
        import csv
        import io

        from ..untrusted import read_limited_text
        from ..files import MAX_CSV_BYTES

        text = read_limited_text(getattr(args, dest), what="CSV file", max_bytes=MAX_CSV_BYTES)
        return [{k: _cell(v) for k, v in row.items()}
                for row in csv.DictReader(io.StringIO(text)) if any(row.values())]
    return result


def _cell(text):
    if text is None or text.strip() == "":
        return None
    try:
        return float(text) if any(c in text for c in ".eEn") else int(text)
    except ValueError:
        return text
