"""One validator for every JSON file kinid reads: types, finite numbers, physical ranges, ordered ranges.

A schema is built from small pieces: :class:`Number`, :class:`Text`, :class:`Flag`, :class:`Items`
(a list), :class:`Row` (a list of fixed length, each item its own schema), :class:`Fields` (an object)
and :class:`Table` (an object whose keys are the user's, such as axis names). :func:`validate` walks the data and the schema together and raises one
:class:`~kinid.errors.DataError` naming the file and where in it the value is, in the spelling a user
would look for (``parameters[3].std``), and what was expected. Physical ranges are wide on purpose — a
value outside them is no machine's — and each loader states them where it declares its schema.

Examples
--------
>>> schema = Fields({"pitch_mm": Number(low=0, open_low=True)}, optional={"note": Text()})
>>> validate({"pitch_mm": 5.0}, schema, path="board.json")
{'pitch_mm': 5.0}
>>> validate({"pitch_mm": -5}, schema, path="board.json")
Traceback (most recent call last):
...
kinid.errors.DataError: board.json: pitch_mm: must be a number > 0, got -5
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from .errors import DataError

__all__ = ["Number", "Text", "Flag", "Items", "Row", "Fields", "Table", "Either", "validate"]


@dataclass(frozen=True)
class Number:
    """A finite JSON number in [low, high] (``open_low``: > low); ``integer`` for whole numbers; ``null`` allows null."""

    low: float | None = None
    high: float | None = None
    open_low: bool = False
    integer: bool = False
    null: bool = False


@dataclass(frozen=True)
class Text:
    """A string, one of ``choices`` when given; ``null`` allows null."""

    choices: tuple = ()
    null: bool = False


@dataclass(frozen=True)
class Flag:
    """true or false."""


@dataclass(frozen=True)
class Items:
    """A list of ``item``: exactly ``length`` long, or within [min_length, max_length]; ``ordered``: each number
    no smaller than the one before (a range [start, stop]); ``null`` allows null."""

    item: object
    length: int | None = None
    min_length: int = 0
    max_length: int | None = None
    ordered: bool = False
    null: bool = False


@dataclass(frozen=True)
class Row:
    """A list of fixed length whose items have each their own schema (``[name, coefficient]``)."""

    items: tuple
    null: bool = False


@dataclass(frozen=True)
class Fields:
    """An object with ``required`` and ``optional`` keys (name -> schema); other keys are refused unless
    ``other`` is True."""

    required: dict
    optional: dict = field(default_factory=dict)
    other: bool = False
    null: bool = False


@dataclass(frozen=True)
class Table:
    """An object whose keys are the user's (axis names, effect names), every value of schema ``value``."""

    value: object
    null: bool = False


@dataclass(frozen=True)
class Either:
    """A value any of ``options`` accepts (tried in order; the message is the first one's)."""

    options: tuple


def validate(data, schema, *, path=None, at: str = ""):
    """``data`` if it matches ``schema``; else a DataError naming ``path`` and the place in the data.

    Parameters
    ----------
    data : object
        Parsed JSON (:func:`kinid.files.read_json`).
    schema : Number, Text, Flag, Items, Fields, Table or Either
    path : str or Path, optional
        The file, named in the message.
    at : str
        Where ``data`` sits in the file (for nested calls).

    Returns
    -------
    object
        ``data`` itself (numbers are not converted: the loader converts what it reads).
    """
    problem = _problem(data, schema, at)
    if problem is not None:
        where, message = problem
        raise DataError(f"{where}: {message}" if where else message, path=path)
    return data


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _shown(v) -> str:
    text = repr(v)
    return text if len(text) <= 60 else text[:57] + "..."


def _problem(v, s, at):
    """(where, message) of the first value that does not match, or None."""
    if isinstance(s, Either):
        problems = [_problem(v, option, at) for option in s.options]
        if any(p is None for p in problems):
            return None
        same_kind = [p for p, option in zip(problems, s.options) if _kind(option) == _kind_of(v)]
        return same_kind[0] if same_kind else (at, f"must be {_wanted(s)}, got {_shown(v)}")
    if v is None:
        return None if getattr(s, "null", False) else (at, f"must not be null ({_wanted(s)})")
    if isinstance(s, Number):
        return None if _number_ok(v, s) else (at, f"must be {_wanted(s)}, got {_shown(v)}")
    if isinstance(s, Text):
        if not isinstance(v, str) or (s.choices and v not in s.choices):
            return at, f"must be {_wanted(s)}, got {_shown(v)}"
        return None
    if isinstance(s, Flag):
        return None if isinstance(v, bool) else (at, f"must be true or false, got {_shown(v)}")
    if isinstance(s, Items):
        return _items_problem(v, s, at)
    if isinstance(s, Row):
        if not isinstance(v, list) or len(v) != len(s.items):
            return at, f"must be {_wanted(s)}, got {_shown(v)}"
        for i, (item, schema) in enumerate(zip(v, s.items)):
            p = _problem(item, schema, f"{at}[{i}]")
            if p is not None:
                return p
        return None
    if isinstance(s, Table):
        if not isinstance(v, dict):
            return at, f"must be an object (name: value), got {_shown(v)}"
        for key, value in v.items():
            p = _problem(value, s.value, _join(at, key))
            if p is not None:
                return p
        return None
    if isinstance(s, Fields):
        if not isinstance(v, dict):
            return at, f"must be an object with {', '.join(s.required) or 'keys'}, got {_shown(v)}"
        for key in s.required:
            if key not in v:
                return _join(at, key), "missing"
        known = {**s.required, **s.optional}
        for key, value in v.items():
            if key not in known:
                if s.other:
                    continue
                return _join(at, key), f"unknown key; known keys: {', '.join(sorted(known))}"
            p = _problem(value, known[key], _join(at, key))
            if p is not None:
                return p
        return None
    raise TypeError(f"not a schema: {s!r}")


def _items_problem(v, s: Items, at):
    if not isinstance(v, list):
        return at, f"must be {_wanted(s)}, got {_shown(v)}"
    n = len(v)
    if s.length is not None and n != s.length:
        return at, f"must be {_wanted(s)}, got {n} item(s)"
    if n < s.min_length or (s.max_length is not None and n > s.max_length):
        return at, f"must be {_wanted(s)}, got {n} item(s)"
    for i, item in enumerate(v):
        p = _problem(item, s.item, f"{at}[{i}]")
        if p is not None:
            return p
    if s.ordered and any(_is_number(a) and _is_number(b) and b < a for a, b in zip(v, v[1:])):
        return at, f"must be in increasing order (start, stop), got {_shown(v)}"
    return None


def _kind(s) -> str:
    """The JSON type a schema wants: number, string, bool, list or object."""
    return {Number: "number", Text: "string", Flag: "bool", Items: "list", Row: "list"}.get(type(s), "object")


def _kind_of(v) -> str:
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, (int, float)):
        return "number"
    return {str: "string", list: "list", dict: "object"}.get(type(v), "other")


def _number_ok(v, s: Number) -> bool:
    if not _is_number(v) or not math.isfinite(v):
        return False
    if s.integer and not float(v).is_integer():
        return False
    if s.low is not None and (v < s.low or (s.open_low and v == s.low)):
        return False
    return s.high is None or v <= s.high


def _wanted(s) -> str:
    if isinstance(s, Number):
        kind = "an integer" if s.integer else "a number"
        if s.low is not None and s.high is not None:
            return f"{kind} in {'(' if s.open_low else '['}{s.low:g}, {s.high:g}]"
        if s.low is not None:
            return f"{kind} {'>' if s.open_low else '>='} {s.low:g}"
        if s.high is not None:
            return f"{kind} <= {s.high:g}"
        return f"a finite {kind[2:] if kind.startswith('a ') else kind[3:]}"
    if isinstance(s, Text):
        return "one of " + ", ".join(map(repr, s.choices)) if s.choices else "a string"
    if isinstance(s, Flag):
        return "true or false"
    if isinstance(s, Items):
        size = (f"{s.length} " if s.length is not None
                else f"{s.min_length}..{s.max_length} " if s.max_length is not None
                else f"at least {s.min_length} " if s.min_length else "")
        return f"a list of {size}{_plural(s.item)}"
    if isinstance(s, Row):
        return "[" + ", ".join(_wanted(i) for i in s.items) + "]"
    if isinstance(s, (Fields, Table)):
        return "an object"
    if isinstance(s, Either):
        return " or ".join(_wanted(o) for o in s.options)
    return "a value"


def _plural(s) -> str:
    return {Number: "numbers", Text: "strings", Flag: "flags", Items: "lists"}.get(type(s), "objects")


def _join(at: str, key) -> str:
    return f"{at}.{key}" if at else str(key)
