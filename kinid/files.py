"""Files: outputs written whole or not at all, and the readers of CSV and JSON (with size limits); the image
reader (kinid.images), the opener of untrusted file names (kinid.untrusted) and the JSON reader (kinid.untrusted) are
re-exported here."""
from __future__ import annotations

import contextlib
import fnmatch
import os
import tempfile
from pathlib import Path

from .images import MAX_IMAGE_BYTES, MAX_IMAGE_PIXELS, image_size, read_image  # noqa: F401 (re-exported)
from .untrusted import (MAX_JSON_BYTES, MAX_JSON_DEPTH, read_json, read_limited_text,  # noqa: F401 (re-exported)
                        read_untrusted_bytes, shown_path)

__all__ = ["atomic_write", "write_text", "write_json", "read_json", "read_csv_rows", "iter_csv_rows", "read_csv_text", "csv_number", "read_limited_text", "captured_stderr", "check_output_target", "check_outputs", "read_image",
           "image_size", "MAX_IMAGE_PIXELS", "MAX_IMAGE_BYTES", "json_text", "read_untrusted_bytes",
           "shown_path", "strict_json", "json_finite"]


@contextlib.contextmanager
def atomic_write(path, mode: str = "w", **kwargs):
    """Open a temporary file beside ``path``; on success rename it onto ``path``.

    If the body raises, the temporary file is removed and ``path`` is left as
    it was (absent or with its old content). ``path`` must be a regular file
    or not exist yet: a folder, a device or a FIFO is refused, never replaced.

    Examples
    --------
    >>> with atomic_write("fit.json") as f:   # doctest: +SKIP
    ...     f.write("{}")
    """
    from .errors import DataError

    if str(path) == "-":
        raise DataError("this output cannot go to standard output ('-'); give a file name")
    path = Path(path)
    if not str(path) or str(path) == ".":
        raise DataError("the output path is empty", path=path)
    check_output_target(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise DataError(f"output folder {str(directory)!r} does not exist", path=path)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise DataError(f"cannot write in folder {str(directory)!r} ({exc.strerror or exc})", path=path) from None
    try:
        # mkstemp makes the file private (0600); give it the mode open() would: the existing
        # file's, else 0666 less the umask
        try:
            file_mode = os.stat(path).st_mode & 0o777
        except FileNotFoundError:
            umask = os.umask(0)
            os.umask(umask)
            file_mode = 0o666 & ~umask
        os.chmod(tmp, file_mode)
        with os.fdopen(fd, mode, **kwargs) as f:
            try:
                yield f
            except OSError as exc:  # ENOSPC, EDQUOT, EIO while writing: one line naming the file
                raise DataError(f"cannot write the file ({exc.strerror or exc})", path=path) from None
            try:
                f.flush()
                os.fsync(f.fileno())
            except OSError as exc:  # a full disk often shows only here
                raise DataError(f"cannot write the file ({exc.strerror or exc})", path=path) from None
        try:
            os.replace(tmp, path)
        except OSError as exc:
            raise DataError(f"cannot write the file ({exc.strerror or exc})", path=path) from None
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp)
        raise


def write_together(contents: dict) -> None:
    """Write several files as one unit: each ``path -> str or bytes`` (text as UTF-8) to a temporary file beside it,
    and only when every one is written whole, each renamed onto its path (``"-"``: standard output, last). A failure on any (a missing folder, a full
    disk) leaves all of them as they were — not a new board file beside an old drawing of it."""
    files = {path: content for path, content in contents.items() if str(path) != "-"}
    with contextlib.ExitStack() as stack:
        streams = [(stack.enter_context(atomic_write(path, "wb")), content) for path, content in files.items()]
        for f, content in streams:
            f.write(content.encode("utf-8") if isinstance(content, str) else content)
    for path, content in contents.items():
        if str(path) == "-":  # standard output, once the files are in place
            write_text(path, content if isinstance(content, str) else content.decode("utf-8"))


def write_text(path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (UTF-8); ``"-"`` writes it to standard output."""
    if str(path) == "-":
        import sys

        stream = sys.__stdout__ if sys.__stdout__ is not None else sys.stdout  # the real one, even when the
        stream.write(text)                                                      # command line sends its messages
        stream.flush()                                                          # to stderr meanwhile
        return
    from .errors import DataError

    try:
        with atomic_write(path, "w", encoding="utf-8", newline="") as f:
            f.write(text)
    except OSError as exc:  # ENOSPC, EDQUOT, EIO while writing: one line naming the file
        raise DataError(f"cannot write the file ({exc.strerror or exc})", path=path) from None


def write_json(path, data, *, indent: int | None = 1) -> None:
    """Write ``data`` as JSON (whole or not at all); a NaN or infinity anywhere is an error, never written.

    Raises
    ------
    DataError
        Naming the file, if ``data`` holds a number JSON cannot represent.
    """
    write_text(path, json_text(data, indent=indent, path=path))


def json_text(data, *, indent: int | None = 1, path=None) -> str:
    """The text :func:`write_json` writes (a DataError naming ``path`` for a NaN or infinity anywhere)."""
    import json

    from .errors import DataError

    try:
        text = json.dumps(data, indent=indent, ensure_ascii=False, allow_nan=False)
    except ValueError as exc:
        raise DataError(f"refusing to write a non-finite number into JSON ({exc})", path=path) from None
    return text + "\n"


def json_finite(data):
    """``data`` with every NaN or infinity (Python or numpy, at any depth) turned into ``None``, numpy scalars and
    arrays into Python numbers and lists: what ``--json`` outputs print, so they are strict JSON (``null``)."""
    import math

    if isinstance(data, float):
        return data if math.isfinite(data) else None
    if isinstance(data, dict):
        return {k: json_finite(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [json_finite(v) for v in data]
    if type(data).__module__ == "numpy" and hasattr(data, "tolist"):  # a numpy scalar or array
        return json_finite(data.tolist())
    return data


def strict_json(data, **kwargs) -> str:
    """Strict JSON text of ``data`` for a ``--json`` output: a NaN or infinity anywhere is ``null``, never the
    ``NaN``/``Infinity`` that ``json.dumps`` writes by default and that JSON parsers refuse."""
    import json

    return json.dumps(json_finite(data), allow_nan=False, **kwargs)


#: Limits on a CSV file kinid reads.
MAX_CSV_BYTES = 512 * 1024 * 1024
MAX_CSV_CELL = 4096


def read_csv_rows(path, *, what: str = "CSV file") -> list:
    """(line number, cells) of each row of a CSV file, comments (``#``) and blank lines skipped.

    Rows are split only where the CSV standard ends them (CR, LF, CR LF); a quoted cell that runs over a line
    end is refused (a quote left open would otherwise swallow the rows after it); a form feed or U+2028 inside a
    cell stays in the cell.

    Raises
    ------
    DataError
        Naming the file (and line): missing, a folder, not UTF-8, too large,
        a cell longer than ``MAX_CSV_CELL`` characters, or malformed quoting.
    """
    return list(iter_csv_rows(path, what=what))


def read_csv_text(path, *, what: str = "CSV file") -> str:
    """The whole text of a CSV file (UTF-8, at most ``MAX_CSV_BYTES``); DataError naming the file otherwise."""
    return read_limited_text(path, what=what, max_bytes=MAX_CSV_BYTES)


def _physical_lines(text: str):
    """The lines of ``text`` with their endings (CR LF, LF or CR), one at a time."""
    import re

    for m in re.finditer(r"[^\r\n]*(?:\r\n|\r|\n)|[^\r\n]+$", text):
        yield m.group()


def iter_csv_rows(path, *, what: str = "CSV file", text: str | None = None):
    """:func:`read_csv_rows` one row at a time (the file's text is read whole, its rows are not held); ``text``:
    the file's text, already read (:func:`read_csv_text`)."""
    import csv

    from .errors import DataError

    path = Path(path)
    if text is None:
        text = read_csv_text(path, what=what)
    reader = csv.reader(_physical_lines(text), strict=False)
    start = 1
    try:
        for cells in reader:
            lineno, start = start, reader.line_num + 1
            if reader.line_num > lineno:
                raise DataError(f"a quoted cell runs over lines {lineno} to {reader.line_num} (a quote not closed?); "
                                f"a cell of a measurement file is one line", path=path, line=lineno)
            if not cells or (len(cells) == 1 and not cells[0].strip()) or cells[0].lstrip().startswith("#"):
                continue
            for c in cells:
                if len(c) > MAX_CSV_CELL:
                    raise DataError(f"a cell of {len(c):,} characters, more than the limit of {MAX_CSV_CELL:,}",
                                    path=path, line=lineno)
            yield lineno, cells
    except csv.Error as exc:
        raise DataError(f"malformed CSV ({exc})", path=path, line=start) from None


def read_csv_table(path, *, what: str = "CSV file", required=()) -> tuple:
    """``(header_line, header, rows)`` of a CSV file with a header row: the header's cells stripped, every
    ``required`` column present, no column twice, and every row as long as the header.

    Raises
    ------
    DataError
        Naming the file, and the line or column, of the first problem.
    """
    rows = read_csv_rows(path, what=what)
    header_line, header = checked_header(path, rows[0] if rows else None, required)
    for line, cells in rows[1:]:
        check_row_width(path, line, cells, header)
    return header_line, header, rows[1:]


def checked_header(path, first, required=(), known=()) -> tuple:
    """``(header_line, header)`` of a CSV table's first row ``(line, cells)`` (None: an empty file), the cells
    stripped; DataError for an empty file, a column given twice or a ``required`` one missing (with the
    closest column neither required nor ``known`` as a likely typo of it)."""
    from .errors import DataError

    if first is None:
        raise DataError("no header row and no data", path=path)
    header_line, header = first
    header = [h.strip() for h in header]
    if len(set(header)) != len(header):
        raise DataError("duplicate column", path=path, line=header_line,
                        column=next(h for h in header if header.count(h) > 1))
    for col in required:
        if col not in header:
            hint = column_hint(col, [h for h in header if h not in required and h not in known])
            raise DataError(f"missing column {col!r} ({hint}header: {', '.join(header)})", path=path,
                            line=header_line)
    return header_line, header


def column_hint(wanted: str, unused) -> str:
    """``"did you mean 'x_m'? "`` when one of the columns a reader did not use (``unused``) is a likely typo of
    the column ``wanted`` it misses (difflib's ratio at least 0.6), else ``""``."""
    import difflib

    close = difflib.get_close_matches(wanted, list(unused), n=1, cutoff=0.6)
    return f"did you mean {close[0]!r}? " if close else ""


def check_row_width(path, line, cells, header) -> None:
    """DataError when a row has another number of cells than the header has columns."""
    from .errors import DataError

    if len(cells) != len(header):
        raise DataError(f"{len(cells)} cells but the header has {len(header)} columns", path=path, line=line)


def csv_number(cells, index: int, *, path, line, column) -> float:
    """The finite number in ``cells[index]`` of a CSV row; DataError naming the file, line and column."""
    import math

    from .errors import DataError

    cell = cells[index].strip() if index < len(cells) else ""
    if not cell:
        raise DataError("empty cell; a number is needed", path=path, line=line, column=column)
    try:
        value = float(cell)
    except ValueError:
        raise DataError(f"{cell!r} is not a number", path=path, line=line, column=column) from None
    if not math.isfinite(value):
        raise DataError(f"{cell!r} is not a finite number", path=path, line=line, column=column)
    return value


class _Captured:
    text = ""


@contextlib.contextmanager
def captured_stderr():
    """Capture what C libraries (the URDF parser, libpng) write to file descriptor 2.

    Their lines would otherwise appear before kinid's own one-line message;
    the caller decides whether to pass them on (``.text`` after the block).
    """
    import sys

    result = _Captured()
    try:
        fd = sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # no real stderr (a notebook): nothing to capture
        yield result
        return
    sys.stderr.flush()
    saved = os.dup(fd)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), fd)
        try:
            yield result
        finally:
            sys.stderr.flush()
            os.dup2(saved, fd)
            os.close(saved)
            tmp.seek(0)
            result.text = tmp.read().decode("utf-8", "replace")


def check_output_target(path) -> None:
    """Refuse an output path that exists and is not a regular file (a folder, a device, a FIFO, a socket)."""
    import stat

    from .errors import DataError

    try:
        st = os.stat(path)
    except (FileNotFoundError, NotADirectoryError):
        return
    except OSError as exc:
        raise DataError(f"cannot use as output ({exc.strerror or exc})", path=path) from None
    if stat.S_ISDIR(st.st_mode):
        raise DataError("is a folder; give a file name to write", path=path)
    if not stat.S_ISREG(st.st_mode):
        raise DataError("exists and is not a regular file (a device, FIFO or socket); kinid writes only regular "
                        "files", path=path)


def check_outputs(outputs, inputs) -> None:
    """Refuse outputs that would overwrite an input, whatever the spelling or link, or each other.

    Parameters
    ----------
    outputs : iterable of (option, path, kind)
        ``kind`` is ``"file"``, ``"folder"`` (a report folder: files of the names in ``REPORT_FILES``
        in it are outputs) or ``"replaced folder"`` (a folder written whole by :func:`staged_folder`:
        no input may lie anywhere in it).
    inputs : iterable of (option, path)
        Existing files or folders the command reads.

    Raises
    ------
    DataError
        Naming the output and the input it would overwrite.
    """
    from .errors import DataError

    inputs = [(opt, Path(p)) for opt, p in inputs if p and str(p) != "-" and os.path.exists(p)]
    seen = []
    for opt, path, kind in outputs:
        if path is None or str(path) == "-":
            continue
        if not str(path).strip():
            raise DataError(f"{opt} is empty; give a path to write")
        path = Path(path)
        if kind == "file":
            check_output_target(path)
            for in_opt, src in inputs:
                if path.exists() and src.is_file() and os.path.samefile(path, src):
                    raise DataError(f"{opt} names the input file given as {in_opt}; kinid never overwrites an input: "
                                    f"choose another {opt}", path=path)
                if src.is_dir() and _inside(path, src):
                    raise DataError(f"{opt} lies inside the input folder given as {in_opt}; kinid never writes into "
                                    f"an input folder (a frame there would be changed, or read next time): choose "
                                    f"another {opt}", path=path)
        else:
            if path.exists() and not path.is_dir():
                raise DataError(f"{opt} must be a folder, and this is a file", path=path)
            for in_opt, src in inputs:
                if src.is_dir() and _inside(path, src) and os.path.realpath(path) == os.path.realpath(src):
                    raise DataError(f"{opt} is the input folder given as {in_opt}; choose another {opt} folder",
                                    path=path)
                if kind == "replaced folder" and _inside(src, path):
                    raise DataError(f"the {opt} folder holds {src.name}, an input ({in_opt}); kinid replaces the whole "
                                    f"{opt} folder and never writes over its inputs: choose another {opt} folder",
                                    path=path)
                if src.is_file() and _inside(src, path) and any(fnmatch.fnmatch(src.name, p) for p in REPORT_FILES):
                    raise DataError(f"the {opt} folder holds the input given as {in_opt} ({src.name}), a name a "
                                    f"report may write; kinid never writes over its inputs: choose another {opt} "
                                    f"folder", path=path)
        for other_opt, other in seen:
            if os.path.realpath(other) == os.path.realpath(path):
                raise DataError(f"{opt} and {other_opt} name the same path; give each its own", path=path)
        seen.append((opt, path))


#: Names a report folder may hold (``--report DIR``, ``kinid demo --out DIR``).
REPORT_FILES = ("*.html", "*.png", "*.svg", "*.csv")


def _inside(src: Path, folder: Path) -> bool:
    """True if ``src`` is ``folder`` or lies inside it (through any spelling or link)."""
    try:
        real_src, real_folder = os.path.realpath(src), os.path.realpath(folder)
    except OSError:  # pragma: no cover
        return False
    return real_src == real_folder or real_src.startswith(real_folder.rstrip(os.sep) + os.sep)
