"""One HTML page layout for every kinid report: provenance, a summary, tables, figures, details.

The page comes from a Jinja2 template (``kinid/templates/report.html``); the same content is also written
as one self-contained HTML file and as a PDF (:func:`write_report`). A report is made of a
title, provenance rows (what was measured, with which files and checksums, when, by which kinid),
a summary of a few sentences, and sections holding paragraphs, tables and figures (PNG files beside
the page), with the full text output folded away at the end.

A report folder is written whole or not at all (:func:`report_folder`): a run stopped at any moment leaves
the earlier report or the new one, never a mix, and replaces only an empty folder or an earlier report —
a folder whose ``index.html`` kinid wrote and which holds only the files that page lists.
"""
from __future__ import annotations

import contextlib
import hashlib
import html
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path

__all__ = ["Table", "Figure", "Section", "report_page", "write_report", "file_provenance", "now_utc", "report_folder",
           "write_one_file", "check_report_folder", "not_earlier_report", "ONE_FILE", "PDF_FILE"]


@dataclass(frozen=True)
class Table:
    """A table: header cells and rows of cells (str); columns in ``numeric`` are right-aligned."""

    header: tuple
    rows: tuple
    numeric: tuple = ()
    caption: str = ""


@dataclass(frozen=True)
class Figure:
    """A PNG beside the page and its caption."""

    file: str
    caption: str


@dataclass(frozen=True)
class Section:
    """A heading with paragraphs, tables, figures and an optional folded block of plain text."""

    heading: str
    paragraphs: tuple = ()
    tables: tuple = ()
    figures: tuple = ()
    details: str = ""
    details_title: str = "Full text output"


def now_utc() -> str:
    """The date and time, UTC, to the second."""
    return datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M:%S UTC")


def file_provenance(path) -> str:
    """``name (sha256 abcd…, N bytes)`` of a file, or its name alone when it cannot be read."""
    p = Path(path)
    try:
        data = p.read_bytes()
    except OSError:
        return p.name
    return f"{p.name} (SHA-256 {hashlib.sha256(data).hexdigest()}, {len(data):,} bytes)"


_STYLE = """
body{font-family:-apple-system,"Segoe UI",Helvetica,Arial,sans-serif;color:#1d2327;max-width:1080px;margin:2em auto;
padding:0 1.5em;line-height:1.45;font-size:15px}
h1{font-size:1.6em;margin-bottom:.2em}h2{font-size:1.2em;margin-top:1.8em;border-bottom:1px solid #d0d7de;padding-bottom:.2em}
.sub{color:#57606a;margin-top:0}
table{border-collapse:collapse;margin:.6em 0 1em 0;font-size:14px}
th,td{padding:3px 10px;border-bottom:1px solid #e5e8eb;text-align:left;vertical-align:top}
th{background:#f4f6f8;font-weight:600}td.num,th.num{text-align:right;font-variant-numeric:tabular-nums;white-space:nowrap}
table.prov td:first-child{color:#57606a;white-space:nowrap}table.prov td{border:none;padding:1px 12px 1px 0;word-break:break-all}
.summary{background:#f0f6ff;border-left:4px solid #2f6fbf;padding:.6em 1em;margin:1em 0}
.summary p{margin:.3em 0}
figure{margin:1em 0 1.6em 0}figure img{max-width:100%;border:1px solid #e5e8eb}
figcaption{color:#57606a;font-size:13px;margin-top:.3em}
caption{caption-side:bottom;text-align:left;color:#57606a;font-size:13px;padding-top:.3em}
details{margin:1em 0}summary{cursor:pointer;color:#2f6fbf}
pre{background:#f6f8fa;padding:10px;font-size:12px;overflow-x:auto;line-height:1.3}
"""


def report_page(title: str, subtitle: str, provenance, summary, sections) -> str:
    """The HTML text of a report, from the page template ``kinid/templates/report.html`` (Jinja2, every value
    escaped).

    Parameters
    ----------
    title, subtitle : str
    provenance : sequence of (label, value)
        Shown under the title: what, with which files, when, by which version.
    summary : sequence of str
        A few sentences: what is wrong, how much it matters, what to do next.
    sections : sequence of Section
    """
    from kinid import __version__

    prov = [(k, str(v)) for k, v in provenance] + [("report made by", f"kinid {__version__}")]
    tables = [[Table(t.header, tuple(tuple(str(c) for c in row) for row in t.rows), t.numeric, t.caption)
               for t in s.tables] for s in sections]
    return _template().render(version=__version__, title=title, subtitle=subtitle, provenance=prov,
                              summary=list(summary or ()), style=_STYLE,
                              sections=[{**s.__dict__, "tables": t} for s, t in zip(sections, tables)])


def _template():
    """The page template, loaded once."""
    global _TEMPLATE
    if _TEMPLATE is None:
        from importlib.resources import files

        import jinja2

        text = (files("kinid") / "templates" / "report.html").read_text(encoding="utf-8")
        env = jinja2.Environment(autoescape=True, trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                                 undefined=jinja2.StrictUndefined)
        _TEMPLATE = env.from_string(text)
    return _TEMPLATE


_TEMPLATE = None


def write_report(folder, title: str, subtitle: str, provenance, summary, sections) -> Path:
    """Write a report's pages into ``folder``, whose figures and linked files are already there; returns
    the path of ``index.html``.

    Three forms of the same report: ``index.html`` (:func:`report_page`, figures beside it),
    :data:`ONE_FILE` (the page with its figures inside, :func:`write_one_file`) and :data:`PDF_FILE`
    (A4 pages, :func:`kinid.reports.pdf.write_pdf`): one file to send, to open or to print.
    """
    from ..files import write_text
    from .pdf import write_pdf

    folder = Path(folder)
    page = folder / "index.html"
    write_text(page, report_page(title, subtitle, provenance, summary, sections))
    write_one_file(folder)
    write_pdf(folder / PDF_FILE, title, subtitle, provenance, summary, sections, folder=folder)
    return page


#: The mark of a page kinid wrote (in its head), and the list of the report folder's files that
#: :func:`report_folder` adds beside it once every file is written: what :func:`not_earlier_report` reads.
_GENERATOR = "<meta name='generator' content='kinid "
_FILES_META = "<meta name='kinid-report-files' content='"

#: A page larger than this is not read to learn whether it is a kinid report (it is not one).
_MAX_PAGE_BYTES = 64 * 1024 * 1024


@contextlib.contextmanager
def report_folder(path):
    """Write a report folder whole or not at all: yield a new folder that replaces ``path`` at the end.

    The body writes the report's figures and files and then its pages (:func:`write_report`) into the
    yielded folder; when it ends, the page is given the list of the folder's files and the folder takes the place
    of ``path`` in one step (:func:`kinid.folders.staged_folder`). A run killed or interrupted (Ctrl-C)
    at any moment leaves at ``path`` the earlier report or the new one, whole. ``path`` is replaced only
    if it does not exist, is empty or holds an earlier kinid report and nothing else
    (:func:`not_earlier_report`).

    Raises
    ------
    DataError
        Naming the folder: it holds files that are not an earlier report's, another kinid is writing
        it, or it cannot be written.

    Examples
    --------
    >>> with report_folder("report") as d:   # doctest: +SKIP
    ...     write_report(d, "Title", "kinid verb", provenance, summary, sections)
    """
    from ..folders import staged_folder

    with staged_folder(path, foreign=not_earlier_report) as stage:
        yield stage
        _list_files(stage)


def check_report_folder(path) -> None:
    """Refuse early what :func:`report_folder` would refuse to replace (before a command computes its report)."""
    from ..folders import check_output_folder

    check_output_folder(path, foreign=not_earlier_report)


def _list_files(folder) -> None:
    """Add to the kinid page ``folder/index.html`` the list of the folder's files (the report's own)."""
    import json
    import os

    from ..files import write_text

    page = Path(folder) / "index.html"
    if not page.is_file():
        return
    text = page.read_text(encoding="utf-8")
    head_end = text.find("</head>")
    if head_end < 0 or _GENERATOR not in text[:head_end]:
        return
    names = sorted(os.listdir(folder))
    meta = f"{_FILES_META}{html.escape(json.dumps(names, ensure_ascii=False), quote=True)}'>"
    write_text(page, text[:head_end] + meta + text[head_end:])


def not_earlier_report(folder) -> list:
    """Names in ``folder`` that are not an earlier kinid report's (the ``foreign=`` of :func:`report_folder`).

    An earlier report holds ``index.html`` written by kinid (:func:`report_page`) and only the files its
    page lists, each a regular file. A kinid page that lists none (an earlier version's, or one written
    in place) owns the figures it shows and ``residuals.csv``. Anything else — the user's files, a sub-folder, a link, or
    no kinid page at all — keeps the folder from being replaced.
    """
    import json
    import os
    import re

    from ..errors import KinidError
    from ..files import read_limited_text

    folder = Path(folder)
    names = sorted(os.listdir(folder))
    page = folder / "index.html"
    if page.is_symlink() or not page.is_file():
        return names
    try:
        text = read_limited_text(page, what="report page", max_bytes=_MAX_PAGE_BYTES)
    except (KinidError, OSError):
        return names
    head = text[:max(text.find("</head>"), 0)]
    listed = re.search(re.escape(_FILES_META) + r"([^']*)'>", head) if _GENERATOR in head else None
    if listed:
        try:
            own = json.loads(html.unescape(listed.group(1)))
        except ValueError:
            return names
        if not (isinstance(own, list) and all(isinstance(n, str) for n in own)):
            return names
        own = set(own) | {"index.html"}
    elif _GENERATOR in head or "<tr><td>report made by</td><td>kinid " in text:
        # a kinid page without the list (an earlier version's, or one written in place): its figures, its CSV
        own = {"index.html", "residuals.csv", *(html.unescape(n) for n in re.findall(r'<img src="([^"]+)"', text))}
    else:
        return names
    return [n for n in names if n not in own or (folder / n).is_symlink() or not (folder / n).is_file()]


#: The report as one file to send (``--report DIR`` writes it beside ``index.html``): the same page with its
#: figures and the files it links inside it, so that it opens anywhere without the folder.
ONE_FILE = "report.html"

#: The report as A4 pages to print or send (:mod:`kinid.reports.pdf`).
PDF_FILE = "report.pdf"

#: The media types of the files a report page shows or links, put inside :data:`ONE_FILE`.
_INLINE = {".png": "image/png", ".svg": "image/svg+xml", ".csv": "text/csv"}


def write_one_file(folder) -> None:
    """Write ``folder/report.html``: the kinid page ``folder/index.html`` with every figure and linked file of
    the folder inside it (data URIs); nothing if there is no kinid page."""
    import base64
    import re

    from ..files import write_text

    folder = Path(folder)
    page = folder / "index.html"
    if not page.is_file():
        return
    text = page.read_text(encoding="utf-8")
    if _GENERATOR not in text[: max(text.find("</head>"), 0)]:
        return

    def inline(match):
        attribute, name = match.group(1), html.unescape(match.group(2))
        path = folder / name
        kind = _INLINE.get(path.suffix.lower())
        if kind is None or "/" in name or path.is_symlink() or not path.is_file():
            return match.group(0)
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        keep_name = f' download="{html.escape(name)}"' if attribute == "href" else ""
        return f'{attribute}="data:{kind};base64,{data}"{keep_name}'

    write_text(folder / ONE_FILE, re.sub(r'\b(src|href)="([^"]+)"', inline, text))
