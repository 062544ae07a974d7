"""A printable ring-coded board: SVG and PDF at true scale, with a scale bar (``kinid board``).

The drawing is the board file's geometry exactly (docs/formats.md, "Board file"): mark (row, col) at
board-frame (col·pitch, row·pitch) mm, x to the right and y down the page — the board as the camera
sees it — a filled centre circle and a ring of ``bits`` equal sectors, element k covering the angles
[k, k + 1)·360°/bits measured clockwise from the board's x axis, printed when bit ``bits − 1 − k`` of
the mark's code is set (the renderer and the locator of :mod:`kinid.vision` use the same rule).
Consecutive printed elements are drawn as one sector, so a print shows no seams between them.

Both files are vector drawings in millimetres: the SVG's width and height are given in mm with a
viewBox in mm; the PDF's page is the same size in points (mm · 72 / 25.4). Print at 100 % (no "fit to
page") and check the scale bar with a ruler.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["BoardLayout", "board_layout", "board_svg", "board_pdf", "ring_runs", "board_id", "PAGES", "MAX_PAGE_MM"]

#: White space around the marks, mm.
MARGIN_MM = 10.0
#: Height of the strip below the marks that holds the scale bar and the caption, mm.
FOOTER_MM = 22.0
#: Width of the strip left of the marks that holds the vertical scale bar, mm.
SIDE_MM = 12.0
#: Largest page kinid draws, mm a side (2 m: a wide-format plotter's roll), checked before anything is drawn.
MAX_PAGE_MM = 2000.0
#: Paper sizes, portrait (width, height) mm; ``auto`` takes the first the board fits, either way round.
PAGES = {"a4": (210.0, 297.0), "letter": (215.9, 279.4), "a3": (297.0, 420.0), "tabloid": (279.4, 431.8),
         "a2": (420.0, 594.0), "a1": (594.0, 841.0), "a0": (841.0, 1189.0)}


def board_id(board) -> str:
    """A short identifier of the board's geometry and codes (8 hex digits): printed on the page and by the
    commands, recomputed from the board file, so a print can be matched to its file."""
    import hashlib
    import json

    key = json.dumps([board.pitch_mm, board.rows, board.cols, board.center_d_mm, board.ring_inner_d_mm,
                      board.ring_outer_d_mm, board.bits, [list(r) for r in board.codes]])
    return hashlib.sha256(key.encode()).hexdigest()[:8]


@dataclass(frozen=True)
class BoardLayout:
    """Where everything goes on the page, mm (x right, y down from the page's top-left corner).

    Attributes
    ----------
    width_mm, height_mm : float
        Page size.
    origin_mm : (float, float)
        Page position of mark (0, 0), the board frame's origin.
    scale_bar_mm : float
        Length of the horizontal scale bar.
    scale_bar_at_mm : (float, float)
        Page position of its left end.
    vertical_bar_mm : float
        Length of the vertical scale bar (a printer may scale the two directions differently).
    vertical_bar_at_mm : (float, float)
        Page position of its top end.
    caption : str
        Two lines.
    page : str
        The paper size (``PAGES``), or ``"fit"`` for a page the board's own size.
    """

    width_mm: float
    height_mm: float
    origin_mm: tuple
    scale_bar_mm: float
    scale_bar_at_mm: tuple
    caption: str
    vertical_bar_mm: float = 0.0
    vertical_bar_at_mm: tuple = (0.0, 0.0)
    page: str = "fit"


def board_layout(board, page: str = "auto") -> BoardLayout:
    """The page of ``board``: a vertical scale bar left of the marks, then a scale bar and a caption below them.

    ``page``: a paper size of :data:`PAGES` (portrait, or landscape if only that fits), ``"auto"`` for the
    first of them the board fits, or ``"fit"`` for a page the board's own size.

    Raises
    ------
    DataError
        Naming ``pitch_mm``, if the page would be larger than :data:`MAX_PAGE_MM` a side; naming ``page``, if
        the board does not fit the paper asked for.
    """
    from kinid.errors import DataError

    r = board.ring_outer_d_mm / 2.0
    span_x = (board.cols - 1) * board.pitch_mm + 2 * r
    span_y = (board.rows - 1) * board.pitch_mm + 2 * r
    need_w = max(span_x, 80.0) + 2 * MARGIN_MM + SIDE_MM
    need_h = span_y + 2 * MARGIN_MM + FOOTER_MM
    if not (need_w <= MAX_PAGE_MM and need_h <= MAX_PAGE_MM):  # NaN too
        raise DataError(f"{board.pitch_mm:g} with {board.rows} x {board.cols} marks makes a page of {need_w:.4g} x "
                        f"{need_h:.4g} mm, larger than kinid draws ({MAX_PAGE_MM:g} mm a side); give a smaller pitch "
                        f"or fewer rows or columns", parameter="pitch_mm")
    if page not in ("fit", "auto") and page not in PAGES:
        raise DataError(f"must be auto, fit or one of {', '.join(PAGES)}, got {page!r}", parameter="page")
    width, height = need_w, need_h
    names = list(PAGES) if page == "auto" else ([] if page == "fit" else [page])
    chosen = "fit"
    for name in names:
        pw, ph = PAGES[name]
        fits = [(w, h) for w, h in ((pw, ph), (ph, pw)) if need_w <= w and need_h <= h]
        if fits:
            (width, height), chosen = fits[0], name
            break
    else:
        if page not in ("fit", "auto"):
            raise DataError(f"a board of {need_w:.0f} x {need_h:.0f} mm (marks, scale bars, caption) does not fit "
                            f"{page} ({PAGES[page][0]:g} x {PAGES[page][1]:g} mm) either way round; give --page "
                            f"auto or a smaller board", parameter="page")
    # the drawing centred on the page: side strip + marks across, marks + footer down
    left = (width - need_w) / 2.0 + MARGIN_MM + SIDE_MM
    top = (height - need_h) / 2.0 + MARGIN_MM
    inner = need_w - 2 * MARGIN_MM - SIDE_MM
    origin = (left + r + (inner - span_x) / 2.0, top + r)
    bar = 50.0 if inner >= 50.0 else 10.0 * math.floor(inner / 10.0)
    vbar = 50.0 if span_y >= 50.0 else 10.0 * max(1, math.floor(span_y / 10.0))
    bar_y = top + span_y + FOOTER_MM - 8.0
    caption = (f"kinid ring-coded board {board_id(board)}: {board.rows} x {board.cols} marks, pitch "
               f"{board.pitch_mm:g} mm, {board.bits}-bit codes.\nPrint at 100 % (no scaling); "
               + (f"both bars must measure {bar:g} mm." if bar == vbar else
                  f"the bars must measure {bar:g} mm across and {vbar:g} mm down."))
    return BoardLayout(width, height, origin, bar, (left, bar_y), caption, vbar, (left - SIDE_MM + 4.0, top), chosen)


def ring_runs(code: int, bits: int) -> list:
    """Printed ring elements of ``code`` as runs (first element, count), consecutive elements merged
    (a run may wrap past element ``bits − 1`` to element 0)."""
    on = [(int(code) >> (bits - 1 - k)) & 1 == 1 for k in range(bits)]
    if all(on):
        return [(0, bits)]
    start = on.index(False) + 1  # begin just after an unprinted element, so no run is split by the wrap
    runs, k = [], 0
    while k < bits:
        e = (start + k) % bits
        if on[e]:
            n = 1
            while k + n < bits and on[(start + k + n) % bits]:
                n += 1
            runs.append((e, n))
            k += n
        else:
            k += 1
    return runs


def _marks(board, layout):
    """(page centre x, y, code) of every mark, mm."""
    ox, oy = layout.origin_mm
    for r, row in enumerate(board.codes):
        for c, code in enumerate(row):
            x, y = board.mark_mm(r, c)
            yield ox + x, oy + y, int(code)


def _sector_points(cx, cy, r_in, r_out, a0, a1):
    """Outer arc a0 -> a1, inner arc back: the four corner points (angles in radians, clockwise on the page)."""
    p = lambda r, a: (cx + r * math.cos(a), cy + r * math.sin(a))  # noqa: E731  (y down: clockwise as seen)
    return p(r_out, a0), p(r_out, a1), p(r_in, a1), p(r_in, a0)


def _f(v: float) -> str:
    return f"{v:.4f}".rstrip("0").rstrip(".")


def board_svg(board, page: str = "auto") -> str:
    """The board as an SVG document, true scale (width and height in mm, viewBox in mm)."""
    lay = board_layout(board, page)
    rc, ri, ro = board.center_d_mm / 2.0, board.ring_inner_d_mm / 2.0, board.ring_outer_d_mm / 2.0
    step = 2 * math.pi / board.bits
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{_f(lay.width_mm)}mm" height="{_f(lay.height_mm)}mm" '
           f'viewBox="0 0 {_f(lay.width_mm)} {_f(lay.height_mm)}">',
           f"<title>{lay.caption.replace(chr(10), ' ')}</title>",
           f'<rect x="0" y="0" width="{_f(lay.width_mm)}" height="{_f(lay.height_mm)}" fill="#fff"/>',
           '<g fill="#000" stroke="none">']
    for cx, cy, code in _marks(board, lay):
        out.append(f'<circle cx="{_f(cx)}" cy="{_f(cy)}" r="{_f(rc)}" data-code="{code}"/>')
        for e, n in ring_runs(code, board.bits):
            a0, a1 = e * step, (e + n) * step
            large = 1 if n * step > math.pi else 0
            if n == board.bits:  # the whole ring: two half annuli
                a1 = a0 + math.pi
                large = 0
            (x0, y0), (x1, y1), (x2, y2), (x3, y3) = _sector_points(cx, cy, ri, ro, a0, a1)
            d = (f"M{_f(x0)},{_f(y0)} A{_f(ro)},{_f(ro)} 0 {large} 1 {_f(x1)},{_f(y1)} L{_f(x2)},{_f(y2)} "
                 f"A{_f(ri)},{_f(ri)} 0 {large} 0 {_f(x3)},{_f(y3)} Z")
            if n == board.bits:
                (u0, v0), (u1, v1), (u2, v2), (u3, v3) = _sector_points(cx, cy, ri, ro, a1, a1 + math.pi)
                d += (f" M{_f(u0)},{_f(v0)} A{_f(ro)},{_f(ro)} 0 0 1 {_f(u1)},{_f(v1)} L{_f(u2)},{_f(v2)} "
                      f"A{_f(ri)},{_f(ri)} 0 0 0 {_f(u3)},{_f(v3)} Z")
            out.append(f'<path d="{d}" data-code="{code}" data-first="{e}" data-count="{n}"/>')
    out.append("</g>")
    bx, by = lay.scale_bar_at_mm
    out.append(f'<g id="scale-bar"><rect x="{_f(bx)}" y="{_f(by)}" width="{_f(lay.scale_bar_mm)}" height="1.5" '
               f'fill="#000"/>')
    for k in range(int(lay.scale_bar_mm // 10) + 1):
        out.append(f'<rect x="{_f(bx + 10 * k - 0.15)}" y="{_f(by - 2)}" width="0.3" height="3.5" fill="#000"/>')
    out.append(f'<text x="{_f(bx + lay.scale_bar_mm + 3)}" y="{_f(by + 1.5)}" font-family="Helvetica, Arial, '
               f'sans-serif" font-size="4">{lay.scale_bar_mm:g} mm</text></g>')
    vx, vy = lay.vertical_bar_at_mm
    out.append(f'<g id="scale-bar-vertical"><rect x="{_f(vx)}" y="{_f(vy)}" width="1.5" '
               f'height="{_f(lay.vertical_bar_mm)}" fill="#000"/>')
    for k in range(int(lay.vertical_bar_mm // 10) + 1):
        out.append(f'<rect x="{_f(vx - 2)}" y="{_f(vy + 10 * k - 0.15)}" width="3.5" height="0.3" fill="#000"/>')
    out.append(f'<text x="{_f(vx + 5.5)}" y="{_f(vy + lay.vertical_bar_mm)}" font-family="Helvetica, Arial, '
               f'sans-serif" font-size="4" transform="rotate(-90 {_f(vx + 5.5)} {_f(vy + lay.vertical_bar_mm)})">'
               f'{lay.vertical_bar_mm:g} mm</text></g>')
    for i, line in enumerate(lay.caption.splitlines()):
        out.append(f'<text x="{_f(bx)}" y="{_f(by + 7 + 4 * i)}" font-family="Helvetica, Arial, sans-serif" '
                   f'font-size="3">{line}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"


# --- PDF ------------------------------------------------------------------------------------------

def _arc_beziers(cx, cy, r, a0, a1):
    """Cubic Bézier segments (each ≤ 90°) of the arc a0 -> a1 (either sense): list of (c1, c2, end)."""
    n = max(1, int(math.ceil(abs(a1 - a0) / (math.pi / 2) - 1e-9)))
    da = (a1 - a0) / n
    k = 4.0 / 3.0 * math.tan(da / 4.0)
    out = []
    for i in range(n):
        s, e = a0 + i * da, a0 + (i + 1) * da
        p0 = np.array([math.cos(s), math.sin(s)])
        p3 = np.array([math.cos(e), math.sin(e)])
        c1 = p0 + k * np.array([-p0[1], p0[0]])
        c2 = p3 - k * np.array([-p3[1], p3[0]])
        out.append(tuple((cx + r * q[0], cy + r * q[1]) for q in (c1, c2, p3)))
    return out


def _pdf_path(ops):
    return " ".join(ops)


def board_pdf(board, page: str = "auto") -> bytes:
    """The board as a one-page PDF, true scale: the page is the layout's size in points and the
    drawing is in mm through one transform (scale 72/25.4, y down)."""
    lay = board_layout(board, page)
    k = 72.0 / 25.4
    w_pt, h_pt = lay.width_mm * k, lay.height_mm * k
    rc, ri, ro = board.center_d_mm / 2.0, board.ring_inner_d_mm / 2.0, board.ring_outer_d_mm / 2.0
    step = 2 * math.pi / board.bits
    g = lambda v: f"{v:.4f}"  # noqa: E731
    ops = ["q", f"{g(k)} 0 0 {g(-k)} 0 {g(h_pt)} cm", "0 g"]  # millimetres, y down from the top
    for cx, cy, code in _marks(board, lay):
        path = [f"{g(cx + rc)} {g(cy)} m"]
        for c1, c2, p in _arc_beziers(cx, cy, rc, 0.0, 2 * math.pi):
            path.append(f"{g(c1[0])} {g(c1[1])} {g(c2[0])} {g(c2[1])} {g(p[0])} {g(p[1])} c")
        path.append("h f")
        ops.append(_pdf_path(path))
        for e, n in ring_runs(code, board.bits):
            a0, a1 = e * step, (e + n) * step
            pieces = [(a0, a1)] if n < board.bits else [(a0, a0 + math.pi), (a0 + math.pi, a0 + 2 * math.pi)]
            for s, t in pieces:
                start = (cx + ro * math.cos(s), cy + ro * math.sin(s))
                path = [f"{g(start[0])} {g(start[1])} m"]
                for c1, c2, p in _arc_beziers(cx, cy, ro, s, t):
                    path.append(f"{g(c1[0])} {g(c1[1])} {g(c2[0])} {g(c2[1])} {g(p[0])} {g(p[1])} c")
                inner_end = (cx + ri * math.cos(t), cy + ri * math.sin(t))
                path.append(f"{g(inner_end[0])} {g(inner_end[1])} l")
                for c1, c2, p in _arc_beziers(cx, cy, ri, t, s):
                    path.append(f"{g(c1[0])} {g(c1[1])} {g(c2[0])} {g(c2[1])} {g(p[0])} {g(p[1])} c")
                path.append("h f")
                ops.append(_pdf_path(path))
    bx, by = lay.scale_bar_at_mm
    ops.append(f"{g(bx)} {g(by)} {g(lay.scale_bar_mm)} 1.5 re f")
    for i in range(int(lay.scale_bar_mm // 10) + 1):
        ops.append(f"{g(bx + 10 * i - 0.15)} {g(by - 2)} 0.3 3.5 re f")
    vx, vy = lay.vertical_bar_at_mm
    ops.append(f"{g(vx)} {g(vy)} 1.5 {g(lay.vertical_bar_mm)} re f")
    for i in range(int(lay.vertical_bar_mm // 10) + 1):
        ops.append(f"{g(vx - 2)} {g(vy + 10 * i - 0.15)} 3.5 0.3 re f")
    ops.append("Q")
    # text in points, y up (PDF's own frame)
    def text(x_mm, y_mm, size_pt, s):
        s = s.replace("\\", "\\\\").replace("(", "\\(").replace(")", "\\)")
        return f"BT /F1 {size_pt:g} Tf {g(x_mm * k)} {g(h_pt - y_mm * k)} Td ({s}) Tj ET"
    ops.append(text(bx + lay.scale_bar_mm + 3, by + 1.5, 11, f"{lay.scale_bar_mm:g} mm"))
    tx, ty = (vx + 5.5) * k, h_pt - (vy + lay.vertical_bar_mm) * k  # rotated 90°: reads upwards beside the bar
    ops.append(f"BT /F1 11 Tf 0 1 -1 0 {g(tx)} {g(ty)} Tm ({lay.vertical_bar_mm:g} mm) Tj ET")
    for i, line in enumerate(lay.caption.splitlines()):
        ops.append(text(bx, by + 7 + 4 * i, 8, line))
    content = "\n".join(ops).encode("latin-1", "replace")
    objects = [
        b"<< /Type /Catalog /Pages 2 0 R >>",
        b"<< /Type /Pages /Kids [3 0 R] /Count 1 >>",
        (f"<< /Type /Page /Parent 2 0 R /MediaBox [0 0 {g(w_pt)} {g(h_pt)}] /Contents 4 0 R "
         f"/Resources << /Font << /F1 5 0 R >> >> >>").encode(),
        b"<< /Length " + str(len(content)).encode() + b" >>\nstream\n" + content + b"\nendstream",
        b"<< /Type /Font /Subtype /Type1 /BaseFont /Helvetica >>",
    ]
    out = bytearray(b"%PDF-1.4\n")
    offsets = []
    for i, body in enumerate(objects, start=1):
        offsets.append(len(out))
        out += f"{i} 0 obj\n".encode() + body + b"\nendobj\n"
    xref = len(out)
    out += f"xref\n0 {len(objects) + 1}\n0000000000 65535 f \n".encode()
    out += b"".join(f"{o:010d} 00000 n \n".encode() for o in offsets)
    out += f"trailer\n<< /Size {len(objects) + 1} /Root 1 0 R >>\nstartxref\n{xref}\n%%EOF\n".encode()
    return bytes(out)
