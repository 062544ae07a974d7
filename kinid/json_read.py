"""The reader of JSON files kinid is given: limits on size, nesting and digits, no duplicate key, every refusal one
:class:`~kinid.errors.DataError` naming the file (and the line and column where it can). Re-exported by kinid.files."""
from __future__ import annotations

from .untrusted import read_limited_text

#: Limits on JSON files kinid reads (fit, error set, board, camera files).
MAX_JSON_BYTES = 64 * 1024 * 1024
MAX_JSON_DEPTH = 32


def read_json(path, *, what: str = "JSON file", max_bytes: int = MAX_JSON_BYTES, max_depth: int = MAX_JSON_DEPTH):
    """Read a JSON file with limits on its size and nesting; every problem a DataError naming the file.

    Parameters
    ----------
    what : str
        What the file is, for messages ("fit file", "board file").
    """
    import json

    from .errors import DataError

    text = read_limited_text(path, what=what, max_bytes=max_bytes)
    depth, in_string, escaped = 0, False, False
    for ch in text:
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > max_depth:
                raise DataError(f"{what} nests deeper than {max_depth} levels", path=path)
        elif ch in "]}":
            depth -= 1
    try:
        return json.loads(text, parse_constant=lambda c: _reject_constant(c, path, what),
                          parse_int=lambda t: _json_int(t, text, path, what),
                          parse_float=lambda t: _json_float(t, text, path, what),
                          object_pairs_hook=lambda pairs: _unique_keys(pairs, text, path, what))
    except json.JSONDecodeError as exc:
        raise DataError(f"not valid JSON: {exc.msg} (column {exc.colno})", path=path, line=exc.lineno) from None
    except (ValueError, RecursionError) as exc:  # any other refusal of the decoder: one line, never a traceback
        raise DataError(f"not valid JSON: {str(exc).splitlines()[0][:200]}", path=path) from None


#: The most digits an integer in a JSON file kinid reads may have (a count, an index, a seed: 20 digits hold 2**64).
MAX_JSON_INT_DIGITS = 20


def _reject_constant(name, path, what):
    from .errors import DataError

    raise DataError(f"{what} holds {name}, which is not a JSON number", path=path)


def _json_int(token: str, text: str, path, what: str) -> int:
    """An integer of a JSON file; one of more than MAX_JSON_INT_DIGITS digits is refused where it stands (Python's
    own limit of 4 300 digits would raise a ValueError naming nothing)."""
    from .errors import DataError

    if len(token.lstrip("-")) > MAX_JSON_INT_DIGITS:
        line, column = _json_position(text, token)
        raise DataError(f"{what} holds an integer of {len(token.lstrip('-')):,} digits (at most "
                        f"{MAX_JSON_INT_DIGITS} are read; column {column})", path=path, line=line)
    return int(token)


def _json_float(token: str, text: str, path, what: str) -> float:
    """A number of a JSON file; one too large for a float (``1e400``, read as infinity) is refused where it stands."""
    import math

    from .errors import DataError

    value = float(token)
    if not math.isfinite(value):
        line, column = _json_position(text, token)
        shown = token if len(token) <= 30 else token[:27] + "..."
        raise DataError(f"{what} holds {shown}, which is too large for a number (column {column})", path=path,
                        line=line)
    return value


def _unique_keys(pairs, text: str, path, what: str) -> dict:
    """A JSON object as a dict; a key given twice is refused (json takes the last value without a word)."""
    from .errors import DataError

    seen = set()
    for key, _ in pairs:
        if key in seen:
            import json
            import re

            spots = [m.start() for m in re.finditer(re.escape(json.dumps(key, ensure_ascii=False)) + r"\s*:", text)]
            line = text.count("\n", 0, spots[1]) + 1 if len(spots) > 1 else None
            shown = key if len(key) <= 60 else key[:57] + "..."
            raise DataError(f"{what} gives the key {shown!r} twice in one object; each key once (which value is "
                            f"meant?)", path=path, line=line)
        seen.add(key)
    return dict(pairs)


def _json_position(text: str, token: str) -> tuple:
    """(line, column), 1-based, of the first place ``token`` stands as a number in ``text`` (None, None if not
    found: the number was written another way)."""
    import re

    m = re.search(r"(?<![\w.+\-\"])" + re.escape(token) + r"(?![\w.])", text)
    if m is None:
        return None, None
    line_start = text.rfind("\n", 0, m.start()) + 1
    return text.count("\n", 0, m.start()) + 1, m.start() - line_start + 1
