"""The one opener of files named by untrusted input (a run log naming images, the command line): regular
files only, names that print on one line, sizes known before reading; and the reader of the JSON files kinid is
given: limits on size, nesting and digits, no duplicate key, every refusal one
:class:`~kinid.errors.DataError` naming the file (and the line and column where it can). Re-exported by
kinid.files."""
from __future__ import annotations

import os

#: Characters refused in a file name kinid is asked to read: they cannot be shown on one line as they are
#: (C0/C1 controls, DEL, line and paragraph separators, bidirectional overrides and isolates).
_BIDI_CONTROLS = frozenset("\u202a\u202b\u202c\u202d\u202e\u2066\u2067\u2068\u2069")


def shown_path(path) -> str:
    """A file name as messages print it: as it is when every character prints, else its ``repr`` (quoted, with
    control characters, NUL and other unprintable ones escaped as ``\\x1b``, ``\\x00``, ``\\u202e``).

    Never returns raw escape sequences, so a name from a run log cannot colour, move or clear the terminal.
    """
    name = os.fsdecode(os.fspath(path)) if isinstance(path, (str, bytes, os.PathLike)) else str(path)
    return name if name.isprintable() else repr(name)


def _bad_name_character(name: str):
    """The first character of ``name`` that a file name kinid reads may not hold, or None."""
    import unicodedata

    for ch in name:
        if ch in _BIDI_CONTROLS or unicodedata.category(ch) in ("Cc", "Zl", "Zp"):
            return ch
    return None


_FILE_KINDS = (("S_ISFIFO", "a FIFO (named pipe)"), ("S_ISCHR", "a character device"),
               ("S_ISBLK", "a block device"), ("S_ISSOCK", "a socket"))


def read_untrusted_bytes(path, *, what: str, max_bytes: int, error=None, missing: str | None = None) -> bytes:
    """The bytes of a file named by untrusted input (the command line, a run log), read only if it is safe to.

    The one opener for such names. Refused, with one ``error`` naming the file (shown by :func:`shown_path`),
    before anything is read:

    - a name holding a NUL byte or a control character (C0, C1, DEL, a line separator, a bidirectional override);
    - anything that is not a regular file once links are followed: a folder, a FIFO (whose ``open`` would wait
      for ever for a writer), a device (``/dev/zero`` never ends), a socket;
    - a file larger than ``max_bytes`` by its ``os.stat`` size.

    The file is opened with ``O_NONBLOCK`` and checked again with ``fstat``, so a FIFO swapped in after the
    check cannot block either; at most ``max_bytes`` + 1 bytes are read (a file that grows is refused too).

    Parameters
    ----------
    what : str
        What the file is, for messages ("CSV file", "image file").
    max_bytes : int
        Largest file accepted.
    error : type, optional
        The KinidError subclass to raise (default DataError).
    missing : str, optional
        The message for a file that does not exist (default ``"<what> not found"``).
    """
    import stat

    from .errors import DataError

    error = error or DataError
    try:
        name = os.fsdecode(os.fspath(path))
    except TypeError:
        raise error(f"a {what} name must be a path, got {type(path).__name__}") from None
    shown = shown_path(name)
    if "\x00" in name:
        raise error(f"the {what} name holds a NUL byte; kinid reads no such file", path=shown)
    bad = _bad_name_character(name)
    if bad is not None:
        raise error(f"the {what} name holds the control character {bad!r}; kinid reads no such file "
                    f"(rename the file)", path=shown)

    def refuse_kind(mode):
        if stat.S_ISDIR(mode):
            raise error(f"is a folder, not {_article(what)} {what}", path=shown)
        if not stat.S_ISREG(mode):
            kind = next((k for test, k in _FILE_KINDS if getattr(stat, test)(mode)), "not a regular file")
            raise error(f"is {kind}, not {_article(what)} {what}; kinid reads only regular files", path=shown)

    def too_large(size):
        return error(f"{what} is larger than {max_bytes:,} bytes ({size:,} bytes)", path=shown)

    try:
        st = os.stat(name)  # follows links: a link to /dev/zero is the device
    except (FileNotFoundError, NotADirectoryError):
        raise error(missing or f"{what} not found", path=shown) from None
    except (OSError, ValueError) as exc:  # a link loop, a name too long, no permission on a folder
        raise error(f"cannot read {what}: {getattr(exc, 'strerror', None) or exc}", path=shown) from None
    refuse_kind(st.st_mode)
    if st.st_size > max_bytes:
        raise too_large(st.st_size)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0) | getattr(os, "O_NOCTTY", 0)
    try:
        fd = os.open(name, flags)
    except (FileNotFoundError, NotADirectoryError):
        raise error(missing or f"{what} not found", path=shown) from None
    except OSError as exc:
        raise error(f"cannot read {what}: {exc.strerror or exc}", path=shown) from None
    try:
        st = os.fstat(fd)  # what was opened, if the name changed since the check
        refuse_kind(st.st_mode)
        if st.st_size > max_bytes:
            raise too_large(st.st_size)
        chunks, total, size = [], 0, st.st_size + 1  # the size first, in one read: no copy joining the pieces
        while total <= max_bytes:
            chunk = os.read(fd, min(max_bytes + 1 - total, size or 16 * 1024 * 1024))
            size = 0
            if not chunk:
                break
            chunks.append(chunk)
            total += len(chunk)
    except OSError as exc:
        raise error(f"cannot read {what}: {exc.strerror or exc}", path=shown) from None
    finally:
        os.close(fd)
    if total > max_bytes:
        raise error(f"{what} is larger than {max_bytes:,} bytes", path=shown)
    return chunks[0] if len(chunks) == 1 else b"".join(chunks)


def read_limited_text(path, *, what: str, max_bytes: int, error=None) -> str:
    """The UTF-8 text of a file of at most ``max_bytes``; every problem one ``error`` naming the file.

    The file is opened by :func:`read_untrusted_bytes`: a FIFO, a device, a socket, a folder or a name
    with a control character is refused before anything is read.

    Parameters
    ----------
    what : str
        What the file is, for messages ("CSV file", "machine file").
    error : type, optional
        The KinidError subclass to raise (default DataError).
    """
    from .errors import DataError

    error = error or DataError
    raw = read_untrusted_bytes(path, what=what, max_bytes=max_bytes, error=error)
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{what} is not UTF-8 text (byte {exc.start})", path=shown_path(path),
                    line=raw[:exc.start].count(b"\n") + 1) from None


def _article(what: str) -> str:
    return "an" if what[:1].lower() in "aeiou" else "a"


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
