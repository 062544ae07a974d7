"""The certificate's one A4 page: the PDF laid out by reportlab, the HTML from a Jinja2 template.

reportlab's Platypus flows the text: paragraphs and table cells break lines only between words (a word longer
than a line, a SHA-256, is the only one split), so no word is cut mid-line as a hand-made wrapper does. The page
is one frame: the content is measured at the full size (9 pt text) and, where it is too tall, at smaller scales
down to :data:`MIN_SCALE`; beyond that it is refused, never spilled onto a second page. The fonts are
DejaVu Sans from matplotlib's data (µ, σ, ±, ↑, ², ⁻¹ drawn as themselves), embedded in the PDF.
"""
from __future__ import annotations

import io
from xml.sax.saxutils import escape

from dataclasses import dataclass

from kinid.errors import DataError

__all__ = ["Certificate", "CertTable", "certificate_pdf", "certificate_html", "fits_scale", "MIN_SCALE"]

#: The smallest scale of the page's content (1 = 9 pt text) before the certificate is refused as too long.
MIN_SCALE = 0.72


@dataclass(frozen=True)
class CertTable:
    """A small table of the page: header cells, rows of cells (str), the numeric columns, a caption."""

    header: tuple
    rows: tuple
    numeric: tuple = ()
    caption: str = ""


@dataclass(frozen=True)
class Certificate:
    """The content of the page, the same for the PDF and the HTML (every text plain, escaped where drawn)."""

    title: str
    number: str
    identification: tuple          # (label, value)
    conditions: tuple              # (label, value)
    results: tuple                 # sentences: the results in plain words
    tables: tuple                  # CertTable
    uncertainty: tuple             # sentences: the uncertainty statement
    traceability: tuple            # (label, value)
    warnings: tuple                # sentences shown boxed on the page
    signatures: tuple = ("Measured by (operator)", "Approved by", "Accepted by (customer)")
    issued_by: str = ""


_MARGIN_MM = 14.0
_GREY, _BLUE, _RED_BG = "#57606a", "#2f6fbf", "#fbeaea"


def _fonts() -> tuple:
    """Register DejaVu Sans (regular, bold) once; their reportlab names."""
    from pathlib import Path

    import matplotlib
    from reportlab.pdfbase import pdfmetrics
    from reportlab.pdfbase.ttfonts import TTFont

    if "KinidSans" not in pdfmetrics.getRegisteredFontNames():
        ttf = Path(matplotlib.get_data_path()) / "fonts" / "ttf"
        pdfmetrics.registerFont(TTFont("KinidSans", str(ttf / "DejaVuSans.ttf")))
        pdfmetrics.registerFont(TTFont("KinidSans-Bold", str(ttf / "DejaVuSans-Bold.ttf")))
        pdfmetrics.registerFontFamily("KinidSans", normal="KinidSans", bold="KinidSans-Bold",
                                      italic="KinidSans", boldItalic="KinidSans-Bold")
    return "KinidSans", "KinidSans-Bold"


def _styles(s: float) -> dict:
    from reportlab.lib.styles import ParagraphStyle

    regular, bold = _fonts()
    body = ParagraphStyle("body", fontName=regular, fontSize=9 * s, leading=11.6 * s, spaceAfter=2.5 * s)
    return {"body": body,
            "small": ParagraphStyle("small", parent=body, fontSize=7.4 * s, leading=9.2 * s, textColor=_GREY),
            "cell": ParagraphStyle("cell", parent=body, fontSize=8.4 * s, leading=10 * s, spaceAfter=0),
            "num": ParagraphStyle("num", parent=body, fontSize=8.4 * s, leading=10 * s, spaceAfter=0, alignment=2),
            "head": ParagraphStyle("head", parent=body, fontName=bold, fontSize=8.4 * s, leading=10 * s, spaceAfter=0),
            "headnum": ParagraphStyle("headnum", parent=body, fontName=bold, fontSize=8.4 * s, leading=10 * s,
                                      spaceAfter=0, alignment=2),
            "label": ParagraphStyle("label", parent=body, fontSize=8.4 * s, leading=10 * s, spaceAfter=0,
                                    textColor=_GREY),
            "h1": ParagraphStyle("h1", parent=body, fontName=bold, fontSize=15 * s, leading=18 * s, spaceAfter=2 * s),
            "h2": ParagraphStyle("h2", parent=body, fontName=bold, fontSize=10.5 * s, leading=13 * s,
                                 spaceBefore=6 * s, spaceAfter=3 * s, textColor=_BLUE),
            "warn": ParagraphStyle("warn", parent=body, backColor=_RED_BG, borderPadding=3 * s, textColor="#8a1f11")}


def _p(text: str, style):
    from reportlab.platypus import Paragraph

    return Paragraph(escape(str(text)), style)


def _story(cert: Certificate, s: float, width_pt: float) -> list:
    """The page's flowables at scale ``s``."""
    from reportlab.lib import colors
    from reportlab.lib.units import mm
    from reportlab.platypus import Spacer, Table, TableStyle

    st = _styles(s)
    pad = TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP"), ("LEFTPADDING", (0, 0), (-1, -1), 0),
                      ("RIGHTPADDING", (0, 0), (-1, -1), 4 * s), ("TOPPADDING", (0, 0), (-1, -1), 0.8 * s),
                      ("BOTTOMPADDING", (0, 0), (-1, -1), 0.8 * s)])
    head = [[_p(cert.title, st["h1"]), _p(f"No. {cert.number}" if cert.number else "", st["h2"])]]
    out = [Table(head, colWidths=[width_pt * 0.74, width_pt * 0.26], style=TableStyle(
        [("VALIGN", (0, 0), (-1, -1), "BOTTOM"), ("ALIGN", (1, 0), (1, 0), "RIGHT"),
         ("LEFTPADDING", (0, 0), (-1, -1), 0), ("RIGHTPADDING", (0, 0), (-1, -1), 0),
         ("LINEBELOW", (0, 0), (-1, 0), 1.2, colors.HexColor(_BLUE))]))]
    if cert.issued_by:
        out.append(_p(f"Issued by {cert.issued_by}", st["small"]))
    out.append(Spacer(1, 4 * s))
    half = width_pt / 2
    blocks = [[_p(k, st["label"]), _p(v, st["cell"])] for k, v in cert.identification], \
             [[_p(k, st["label"]), _p(v, st["cell"])] for k, v in cert.conditions]
    pair = [[Table(b, colWidths=[half * 0.36, half * 0.62], style=pad) for b in blocks]]
    out += [Table([[_p("Identification", st["h2"]), _p("Measurement conditions", st["h2"])]] + pair,
                  colWidths=[half, half], style=pad)]
    for w in cert.warnings:
        out += [Spacer(1, 3 * s), _p(f"Warning: {w}.", st["warn"]), Spacer(1, 2 * s)]
    out.append(_p("Results", st["h2"]))
    out += [_p(r, st["body"]) for r in cert.results]
    for t in cert.tables:
        out += [Spacer(1, 2 * s), _table(t, st, width_pt, s), _p(t.caption, st["small"])]
    out.append(_p("Uncertainty of measurement", st["h2"]))
    out += [_p(u, st["body"]) for u in cert.uncertainty]
    out.append(_p("Traceability", st["h2"]))
    out.append(Table([[_p(k, st["label"]), _p(v, st["small"])] for k, v in cert.traceability],
                     colWidths=[width_pt * 0.17, width_pt * 0.83], style=pad))
    out.append(Spacer(1, 16 * s))
    cols, gap = len(cert.signatures), 8 * mm
    names = []  # a line to sign on per column, a gap between the lines
    for i, x in enumerate(cert.signatures):
        names += ([_p("", st["small"])] if i else []) + [_p(f"{x}: name, date, signature", st["small"])]
    widths = [(width_pt - gap * (cols - 1)) / cols if i % 2 == 0 else gap for i in range(2 * cols - 1)]
    sign = Table([[""] * len(names), names], colWidths=widths, rowHeights=[10 * mm * s, None],
                 style=TableStyle([("LEFTPADDING", (0, 0), (-1, -1), 0), ("RIGHTPADDING", (0, 0), (-1, -1), 0)]
                                  + [("LINEABOVE", (i, 1), (i, 1), 0.6, colors.black) for i in range(0, len(names), 2)]))
    out.append(sign)
    return out


def _table(t, st, width_pt: float, s: float):
    from reportlab.lib import colors
    from reportlab.platypus import Table, TableStyle

    rows = [[_p(h, st["headnum"] if i in t.numeric else st["head"]) for i, h in enumerate(t.header)]]
    rows += [[_p(c, st["num"] if i in t.numeric else st["cell"]) for i, c in enumerate(r)] for r in t.rows]
    first = 0.22 if len(t.header) > 4 else 0.34
    rest = (1 - first) / (len(t.header) - 1)
    return Table(rows, colWidths=[width_pt * first] + [width_pt * rest] * (len(t.header) - 1), repeatRows=0,
                 style=TableStyle([("VALIGN", (0, 0), (-1, -1), "TOP"),
                                   ("BACKGROUND", (0, 0), (-1, 0), colors.HexColor("#f4f6f8")),
                                   ("LINEBELOW", (0, 0), (-1, -1), 0.3, colors.HexColor("#d0d7de")),
                                   ("TOPPADDING", (0, 0), (-1, -1), 1.2 * s),
                                   ("BOTTOMPADDING", (0, 0), (-1, -1), 1.6 * s)]))


def _frame_pt() -> tuple:
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm

    return A4[0] - 2 * _MARGIN_MM * mm, A4[1] - 2 * _MARGIN_MM * mm - 8 * mm  # the footer's band


def _height(story, width_pt: float) -> float:
    total = 0.0
    for f in story:
        _, h = f.wrap(width_pt, 1e6)
        total += h + f.getSpaceBefore() + f.getSpaceAfter()
    return total


def fits_scale(cert: Certificate) -> float:
    """The largest scale (1, 0.96, ... down to MIN_SCALE) at which the page's content fits the frame.

    Raises
    ------
    DataError
        It does not fit even at MIN_SCALE: the line says how much content there is.
    """
    width, height = _frame_pt()
    s = 1.0
    while s >= MIN_SCALE - 1e-9:
        if _height(_story(cert, s, width), width) <= height * 0.985:  # the frame's own padding
            return s
        s = round(s - 0.04, 2)
    rows = sum(len(t.rows) for t in cert.tables)
    raise DataError(f"the certificate does not fit one A4 page even with its text at {MIN_SCALE:.0%} size "
                    f"({rows} table rows, {len(cert.results)} result sentences): give fewer --iso axes, or "
                    f"shorter remarks in the metadata file")


def certificate_pdf(cert: Certificate) -> tuple:
    """The PDF (bytes, one A4 page) and the scale its content was drawn at."""
    from reportlab.lib.pagesizes import A4
    from reportlab.lib.units import mm
    from reportlab.platypus import Frame, PageTemplate, BaseDocTemplate

    from kinid import __version__

    scale = fits_scale(cert)
    width, height = _frame_pt()
    regular, _ = _fonts()
    pages = []

    def footer(canvas, doc):
        pages.append(doc.page)
        canvas.saveState()
        canvas.setFont(regular, 7)
        canvas.setFillColor(_GREY)
        number = f"certificate {cert.number}, " if cert.number else ""
        canvas.drawString(_MARGIN_MM * mm, _MARGIN_MM * mm - 2 * mm,
                          f"{number}page 1 of 1; to be reproduced only in full. Made with kinid {__version__}.")
        canvas.restoreState()

    buffer = io.BytesIO()
    doc = BaseDocTemplate(buffer, pagesize=A4, leftMargin=_MARGIN_MM * mm, rightMargin=_MARGIN_MM * mm,
                          topMargin=_MARGIN_MM * mm, bottomMargin=_MARGIN_MM * mm + 8 * mm, title=cert.title,
                          author=cert.issued_by or "kinid", subject=f"certificate {cert.number}".strip(),
                          creator=f"kinid {__version__}", invariant=1)
    frame = Frame(doc.leftMargin, doc.bottomMargin, width, height, leftPadding=0, rightPadding=0, topPadding=0,
                  bottomPadding=0, id="page")
    doc.addPageTemplates([PageTemplate(id="one", frames=[frame], onPage=footer)])
    doc.build(_story(cert, scale, width))
    if len(pages) != 1:  # pragma: no cover - fits_scale measured it: a layout bug, not a user's error
        raise RuntimeError(f"the certificate took {len(pages)} pages at scale {scale}")
    return buffer.getvalue(), scale


def certificate_html(cert: Certificate, *, scale: float = 1.0) -> str:
    """The page as HTML (the template ``kinid/templates/certificate.html``, every value escaped), with a print
    stylesheet for one A4 page at the PDF's ``scale``."""
    from importlib.resources import files

    import jinja2

    from kinid import __version__

    text = (files("kinid") / "templates" / "certificate.html").read_text(encoding="utf-8")
    env = jinja2.Environment(autoescape=True, trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True,
                             undefined=jinja2.StrictUndefined)
    return env.from_string(text).render(c=cert, version=__version__, scale=scale)
