"""A report as A4 pages (PDF), drawn with matplotlib's PDF backend from the same content as the HTML page.

Why matplotlib: it is already how kinid draws, its PDF backend embeds subsets of the fonts (µ, σ, ±, ² and
the rest print as on screen) and writes the same bytes for the same report, and an HTML-to-PDF converter
(WeasyPrint, a headless browser) would add a large dependency for one file.

The page flows top to bottom: title, provenance, summary, then each section's paragraphs, tables (split
over pages with the header repeated), figures (the report's PNGs, scaled to the text width; an opaque one's
compressed rows embedded as they are) and the folded text output in a fixed-width font. Every page carries the
report's title and ``page n of N``.
"""
from __future__ import annotations

import io
from pathlib import Path

__all__ = ["write_pdf", "A4_MM"]

#: Page size, millimetres (ISO 216 A4, portrait).
A4_MM = (210.0, 297.0)

_PT_PER_MM = 72 / 25.4
_MARGIN_MM = 18.0
_GREY = "#57606a"
_RULE = "#d0d7de"


def write_pdf(path, title: str, subtitle: str, provenance, summary, sections, *, folder) -> None:
    """Write the report to ``path`` as A4 pages; figures are read from ``folder`` (files missing are skipped)."""
    from matplotlib.backends.backend_pdf import PdfPages

    from kinid import __version__

    from ..files import atomic_write

    flow = _Flow()
    flow.text(title, 17, weight="bold")
    flow.text(subtitle, 10, color=_GREY, after=8)
    for label, value in list(provenance) + [("report made by", f"kinid {__version__}")]:
        flow.labelled(label, str(value))
    flow.space(8)
    for sentence in summary or ():
        flow.text(sentence, 10, bar="#2f6fbf", after=4)
    for s in sections:
        flow.heading(s.heading)
        for p in s.paragraphs:
            flow.text(p, 9.5, after=5)
        for t in s.tables:
            flow.table(t)
        for f in s.figures:
            flow.figure(Path(folder) / f.file, f.caption)
        if s.details:
            flow.text(s.details_title, 9, weight="bold", after=3)
            flow.preformatted(s.details)
    buf = io.BytesIO()
    with PdfPages(buf, metadata={"Title": title, "Creator": f"kinid {__version__}", "CreationDate": None}) as pdf:
        for n, page in enumerate(flow.pages, 1):
            page.text(_MARGIN_MM / A4_MM[0], 9 / A4_MM[1], f"{title} — page {n} of {len(flow.pages)}", fontsize=7.5,
                      color=_GREY, parse_math=False)
            pdf.savefig(page)
    with atomic_write(path, "wb") as out:
        out.write(buf.getvalue())


#: A line's width predicted from its words' is measured whole when it is this close to the limit, pt: the prediction
#: is off by the rounding of glyph positions only (hundredths of a point; the tests compare it with every line
#: measured whole).
_UNSURE_PT = 0.5

#: A page holding at most this many lines of a text block alone is avoided by setting the block's lines closer.
_FEW_LINES = 8


class _Flow:
    """Pages being filled top to bottom; positions in points from the page's top-left corner."""

    def __init__(self):
        self.width_pt, self.height_pt = A4_MM[0] * _PT_PER_MM, A4_MM[1] * _PT_PER_MM
        self.left = self.top = _MARGIN_MM * _PT_PER_MM
        self.right = self.width_pt - self.left
        self.bottom = self.height_pt - 16 * _PT_PER_MM
        self.pages = []
        self.y = self.bottom  # no page yet: the first draw opens one
        self._measure = _pdf_measure()
        self._props = {}  # (size, weight, family) -> FontProperties
        self._metrics = {}  # (text, size, weight, family) -> (width, height, descent), pt: a table measures each cell twice

    # -- geometry -------------------------------------------------------------------------------------
    def _new_page(self):
        from matplotlib.figure import Figure

        self.pages.append(Figure(figsize=(A4_MM[0] / 25.4, A4_MM[1] / 25.4)))
        self._lines = _lines()
        self.pages[-1].add_artist(self._lines)
        self.y = self.top

    def _room(self, height_pt: float) -> None:
        """Start a new page unless ``height_pt`` fits below the cursor."""
        if not self.pages or self.y + height_pt > self.bottom:
            self._new_page()

    def space(self, pt: float) -> None:
        self.y += pt

    def _xy(self, x_pt, y_pt):
        return x_pt / self.width_pt, 1 - y_pt / self.height_pt

    def _put(self, x_pt, y_pt, s, size, *, weight="normal", family="sans-serif", color="black", ha="left"):
        """Set ``s`` with its top at ``y_pt`` and its left (``ha="right"``: right) end at ``x_pt``, where
        ``Figure.text(..., va="top")`` puts it: the baseline below the top by the height of "lp" (or of the string's
        own glyphs, if taller) less their descent, measured as the PDF renderer measures (unhinted, 72 dpi)."""
        h, d = self._height_descent(s, size, weight, family)
        _, lp_h, lp_d = self._metric("lp", size, weight, family)
        x = x_pt - self._width(s, size, weight, family) if ha == "right" else x_pt
        self._lines.add(*self._xy(x, y_pt + max(h, lp_h) - max(d, lp_d)), s, self._prop(size, weight, family), color)

    def _prop(self, size, weight, family):
        """The font properties of ``size``, ``weight`` and ``family``, made once."""
        return self._props.get((size, weight, family)) or self._props.setdefault(
            (size, weight, family), _font(size, weight, family))

    def _line(self, x0, x1, y, color=_RULE, lw=0.6):
        from matplotlib.lines import Line2D

        page = self.pages[-1]
        (a, b), (c, _) = self._xy(x0, y), self._xy(x1, y)
        page.add_artist(Line2D([a, c], [b, b], transform=page.transFigure, color=color, lw=lw))

    def _box(self, x0, y0, x1, y1, color):
        from matplotlib.patches import Rectangle

        page = self.pages[-1]
        (a, b), (c, d) = self._xy(x0, y1), self._xy(x1, y0)
        page.add_artist(Rectangle((a, b), c - a, d - b, transform=page.transFigure, color=color, lw=0, zorder=-1))

    # -- text -----------------------------------------------------------------------------------------
    def _width(self, s: str, size: float, weight="normal", family="sans-serif") -> float:
        if family == "monospace" and len(s) > 1:  # every character as wide as one: the text output's lines
            return len(s) * self._width("0", size, weight, family)
        return self._metric(s, size, weight, family)[0]

    def _metric(self, s: str, size: float, weight="normal", family="sans-serif") -> tuple:
        """Width, height and descent, pt, of ``s`` as the PDF renderer measures it (each string measured once)."""
        key = (s, size, weight, family)
        if key not in self._metrics:  # measuring shapes the text (libraqm): about 0.5 ms a string
            self._metrics[key] = self._measure.get_text_width_height_descent(s, self._prop(size, weight, family),
                                                                             False)
        return self._metrics[key]

    def _height_descent(self, s: str, size: float, weight="normal", family="sans-serif") -> tuple:
        """Height and descent, pt, of ``s`` as :meth:`_metric` measures them, from its characters' (each measured
        once): the renderer's box of a string is the union of its glyphs' boxes, all on one baseline, so its top is
        the highest glyph's and its bottom the lowest's. A line is not shaped to be placed, only to be drawn."""
        if not s:
            return self._metric(s, size, weight, family)[1:]
        top = depth = -float("inf")
        for c in set(s):
            _, h, d = self._metric(c, size, weight, family)
            top, depth = max(top, h - d), max(depth, d)
        return top + depth, depth

    def _gap(self, before: str, after: str, size: float, weight, family) -> float:
        """The room, pt, between the ink of a word ending in ``before`` and one starting with ``after`` set after it
        with one space (the space's advance, the glyphs' side bearings and any kerning)."""
        pair = f"{before} {after}"
        return (self._width(pair, size, weight, family) - self._width(before, size, weight, family)
                - self._width(after, size, weight, family))

    def wrap(self, text: str, size: float, width_pt: float, weight="normal", family="sans-serif") -> list:
        """Lines of ``text`` no wider than ``width_pt`` (words kept whole unless one alone is wider).

        Each line is the longest run of words that fits, as measuring every trial line would give; a trial's
        width is predicted from its words' widths and the gaps between them (each measured once, then cached),
        and measured whole only when the prediction falls within :data:`_UNSURE_PT` of the limit.
        """
        lines = []
        for paragraph in str(text).split("\n"):
            line, line_w = "", 0.0
            for word in paragraph.split(" "):
                trial = f"{line} {word}" if line else word
                if not line or not word:
                    trial_w = self._width(trial, size, weight, family)
                else:
                    trial_w = (line_w + self._gap(line[-1], word[0], size, weight, family)
                               + self._width(word, size, weight, family))
                    if abs(trial_w - width_pt) <= _UNSURE_PT:
                        trial_w = self._width(trial, size, weight, family)
                if trial_w <= width_pt:
                    line, line_w = trial, trial_w
                    continue
                if line:
                    lines.append(line)
                while self._width(word, size, weight, family) > width_pt and len(word) > 1:  # a hash, a path
                    cut = max(1, int(len(word) * width_pt / self._width(word, size, weight, family)) - 1)
                    lines.append(word[:cut])
                    word = word[cut:]
                line, line_w = word, self._width(word, size, weight, family)
            lines.append(line)
        return lines

    def text(self, s: str, size: float, *, weight="normal", color="black", after=2.0, bar=None) -> None:
        indent = 8 if bar else 0
        lines = self.wrap(s, size, self.right - self.left - indent, weight)
        step = size * 1.35
        for line in lines:
            self._room(step)
            if bar:
                self._box(self.left, self.y - 1, self.left + 2.5, self.y + step - 1, bar)
            self._put(self.left + indent, self.y, line, size, weight=weight, color=color)
            self.y += step
        self.y += after

    def labelled(self, label: str, value: str) -> None:
        size, label_w = 8, 34 * _PT_PER_MM
        lines = self.wrap(value, size, self.right - self.left - label_w)
        step = size * 1.35
        self._room(step * len(lines))
        self._put(self.left, self.y, label, size, color=_GREY)
        for line in lines:
            self._put(self.left + label_w, self.y, line, size)
            self.y += step

    def heading(self, s: str) -> None:
        self.space(10)
        self._room(13 * 1.4 + 150)  # keep a heading with the start of what follows it
        self._put(self.left, self.y, s, 13, weight="bold")
        self.y += 13 * 1.35
        self._line(self.left, self.right, self.y)
        self.y += 6

    def preformatted(self, s: str) -> None:
        """Monospace text, a long line broken at a space (:meth:`wrap_preformatted`); where the block would leave
        at most :data:`_FEW_LINES` lines alone on a page of their own, its lines are set up to 9 % closer instead."""
        size = 6.5
        lines = self.wrap_preformatted(s, size, self.right - self.left)
        step = size * 1.3
        pages, alone = self._pages_for(len(lines), step)
        if 0 < alone <= _FEW_LINES:
            step = next((step * f for f in (0.97, 0.94, 0.91) if self._pages_for(len(lines), step * f)[0] < pages),
                        step)
        for line in lines:
            self._room(step)
            self._put(self.left, self.y, line.replace(" ", "\u00a0"), size, family="monospace")
            self.y += step
        self.y += 6

    def _pages_for(self, n: int, step: float) -> tuple:
        """New pages ``n`` lines at ``step`` open below the cursor, and the lines alone on the last of them."""
        import math

        here = 0 if not self.pages else max(0, math.floor((self.bottom - self.y) / step + 1e-9))
        per_page = math.floor((self.bottom - self.top) / step + 1e-9)
        if n <= here:
            return 0, 0
        return math.ceil((n - here) / per_page), (n - here) % per_page or per_page

    def wrap_preformatted(self, s: str, size: float, width_pt: float) -> list:
        """Lines of monospace ``s`` no wider than ``width_pt``: a longer line breaks at its last space that fits and
        goes on two characters further in than it began; only a word longer than a line is cut."""
        per_line = max(8, int(width_pt / (self._width("M" * 20, size, family="monospace") / 20)))
        out = []
        for line in s.split("\n"):
            indent = min(len(line) - len(line.lstrip(" ")) + 2, per_line // 2)
            first = True
            while len(line) > per_line:
                start = 0 if first else indent
                cut = line.rfind(" ", start + 1, per_line + 1)
                if cut <= start or not line[start:cut].strip():
                    cut = per_line  # one word longer than a line (a hash, a path)
                out.append(line[:cut].rstrip())
                line = " " * indent + line[cut:].lstrip(" ")
                first = False
            out.append(line)
        return out

    # -- tables and figures ---------------------------------------------------------------------------
    def table(self, t) -> None:
        size, pad = 7.5, 4.0
        cells = [list(map(str, t.header))] + [list(map(str, row)) for row in t.rows]
        n = len(t.header)
        natural = [max(self._width(row[i], size, "bold" if r == 0 else "normal") for r, row in enumerate(cells))
                   + 2 * pad for i in range(n)]
        widths = _fit_widths(natural, self.right - self.left)
        wrapped = [[self.wrap(row[i], size, widths[i] - 2 * pad, "bold" if r == 0 else "normal") for i in range(n)]
                   for r, row in enumerate(cells)]
        step = size * 1.3
        xs = [self.left + sum(widths[:i]) for i in range(n + 1)]

        def draw(row_lines, header=False):
            h = max(len(c) for c in row_lines) * step + 3
            if header:
                self._box(xs[0], self.y, xs[-1], self.y + h, "#f4f6f8")
            for i, lines in enumerate(row_lines):
                for k, line in enumerate(lines):
                    right = i in t.numeric
                    x = xs[i + 1] - pad if right else xs[i] + pad
                    self._put(x, self.y + 1.5 + k * step, line, size, ha="right" if right else "left",
                              weight="bold" if header else "normal")
            self.y += h
            self._line(xs[0], xs[-1], self.y, color="#e5e8eb")

        header_h = max(len(c) for c in wrapped[0]) * step + 3
        self._room(header_h + step * 2)
        draw(wrapped[0], header=True)
        for row in wrapped[1:]:
            h = max(len(c) for c in row) * step + 3
            if self.y + h > self.bottom:
                self._new_page()
                draw(wrapped[0], header=True)
            draw(row)
        if t.caption:
            self.y += 3
            self.text(t.caption, 7.5, color=_GREY)
        self.y += 8

    def figure(self, png: Path, caption: str) -> None:
        image = _PngStream.read(png) or _opaque_pixels(png)
        if image is None:
            return
        h_px, w_px = image.shape[:2]
        width = min(self.right - self.left, w_px / 110 * 72)  # never larger than drawn (110 dpi)
        height = width * h_px / w_px
        most = self.bottom - self.top - 30
        if height > most:
            width, height = width * most / height, most
        self._room(height + 20)
        x0, y1 = self._xy(self.left, self.y + height)
        self.pages[-1].add_artist(_picture(image, (x0, y1, width / self.width_pt, height / self.height_pt)))
        self.y += height + 3
        self.text(caption, 7.5, color=_GREY, after=10)


def _font(size, weight, family):
    from matplotlib.font_manager import FontProperties

    return FontProperties(size=size, weight=weight, family=family)


def _pdf_measure():
    """A renderer measuring text as matplotlib's PDF backend does (its ``get_text_width_height_descent``: the
    font unhinted at 72 dpi, one point a unit), without a PDF file to draw into."""
    from matplotlib.backends._backend_pdf_ps import RendererPDFPSBase

    class Measure(RendererPDFPSBase):
        _use_afm_rc_name = "pdf.use14corefonts"

    return Measure(1, 1)


def _lines():
    """An artist drawing a page's lines of text, each at a given baseline (fractions of the page), in one pass:
    what ``Figure.text`` draws, without a text artist each that measures its string again to place it."""
    from matplotlib.artist import Artist

    class Lines(Artist):
        zorder = 3  # where Figure.text draws: above the rules and boxes

        def __init__(self):
            super().__init__()
            self.items = []

        def add(self, x, y, s, prop, color):
            self.items.append((x, y, s, prop, color))

        def draw(self, renderer):
            if not self.get_visible() or not self.items:
                return
            at = self.get_figure(root=True).transFigure.transform([(x, y) for x, y, *_ in self.items])
            draw_text = _pdf_text_writer(renderer) or (
                lambda gc, x, y, s, prop: renderer.draw_text(gc, x, y, s, prop, 0.0, ismath=False))
            for (x, y), (_, _, s, prop, color) in zip(at, self.items):
                gc = renderer.new_gc()
                gc.set_foreground(color)
                draw_text(gc, x, y, s, prop)
                gc.restore()
            self.stale = False

    return Lines()


def _pdf_text_writer(renderer):
    """A function ``(gc, x, y, s, prop)`` writing a line of text into the PDF of ``renderer`` as its ``draw_text(gc, x,
    y, s, prop, 0.0)`` writes it, the same bytes, at a third of its cost; None where the renderer is not matplotlib's
    PDF renderer of the shape this follows (matplotlib 3.11: text shaped by libraqm, glyphs tracked one by one), or
    it sets the 14 core fonts: the caller then uses ``draw_text``.

    ``draw_text`` looks the font up by its properties for every string, loads every glyph's outline (which the PDF's
    text does not use: the fonts are embedded at the end, from the glyphs tracked) and tracks each glyph again; here
    the font is looked up once per properties, the string is shaped without loading outlines and a glyph is tracked
    once per file. The tests compare the two PDFs byte by byte.
    """
    import itertools
    import math

    import matplotlib as mpl
    from matplotlib.backends.backend_pdf import Op, RendererPdf
    from matplotlib.font_manager import FontPath
    from matplotlib.ft2font import FT2Font, LoadFlags

    renderer = getattr(renderer, "_vector_renderer", renderer)  # savefig's MixedModeRenderer holds the PDF's
    tracker = getattr(getattr(renderer, "file", None), "_character_tracker", None)
    if (not isinstance(renderer, RendererPdf) or not hasattr(FT2Font, "_layout")
            or not hasattr(tracker, "track_glyph") or mpl.rcParams["pdf.use14corefonts"]):
        return None
    file, fonttype = renderer.file, mpl.rcParams["pdf.fonttype"]
    fonts = {}  # FontProperties -> FT2Font
    tracked = file.__dict__.setdefault("_kinid_tracked_glyphs", {})  # (font file, face, char, glyph) -> subset, code

    def chunk(kerns_or_chars, fontsize):  # as draw_text's output_singlebyte_chunk
        if kerns_or_chars:
            file.output([(-1000 * next(group) / fontsize) if tp == float else renderer._encode_glyphs(group, fonttype)
                         for tp, group in itertools.groupby(kerns_or_chars, type)], Op.showkern)
            kerns_or_chars.clear()

    def write(gc, x, y, s, prop):
        renderer.check_gc(gc, gc._rgb)
        fontsize = prop.get_size_in_points()
        font = fonts.get(prop) or fonts.setdefault(prop, renderer._get_font_ttf(prop))
        font.clear()  # as _get_font_ttf leaves it: a font file's FT2Font is shared by every size
        font.set_size(fontsize, 72)
        file.output(Op.gsave)
        a = math.radians(0.0)
        file.output(math.cos(a), math.sin(a), -math.sin(a), math.cos(a), x, y, Op.concat_matrix)
        singlebyte_chunk, prev_font, prev_start_x = [], None, 0
        file.output(Op.begin_text)
        for item in font._layout(s, LoadFlags.NO_HINTING, features=None, language=None):
            key = (item.ft_object.fname, item.ft_object.face_index, item.char, item.glyph_index)
            subset, charcode = tracked.get(key) or tracked.setdefault(
                key, tracker.track_glyph(item.ft_object, item.char, item.glyph_index))
            if (item.ft_object, subset) != prev_font:
                chunk(singlebyte_chunk, fontsize)
                file.output(file.fontName(FontPath(item.ft_object.fname, item.ft_object.face_index), subset),
                            fontsize, Op.selectfont)
                renderer._setup_textpos(item.x, 0, 0, prev_start_x, 0, 0)
                prev_font, prev_start_x = (item.ft_object, subset), item.x
            if item.y:
                chunk(singlebyte_chunk, fontsize)
                file.output(item.y, Op.textrise)
            if item.prev_kern:
                singlebyte_chunk.append(item.prev_kern)
            singlebyte_chunk.append(charcode)
            if item.y:
                chunk(singlebyte_chunk, fontsize)
                file.output(0, Op.textrise)
        chunk(singlebyte_chunk, fontsize)
        file.output(Op.end_text)
        file.output(Op.grestore)

    return write


def _picture(pixels, box):
    """An artist drawing ``pixels`` (rows top to bottom, or a :class:`_PngStream`) into ``box`` (left, bottom, width,
    height; fractions of the page) at their own resolution, as ``imshow(..., interpolation="none")`` in an axes of
    that box does, without making an axes (which costs more than the picture)."""
    from matplotlib.artist import Artist
    from matplotlib.transforms import Affine2D

    class Picture(Artist):
        def draw(self, renderer):
            if not self.get_visible():
                return
            (x0, y0), (x1, y1) = self.get_figure(root=True).transFigure.transform(
                [(box[0], box[1]), (box[0] + box[2], box[1] + box[3])])
            image = pixels
            if isinstance(image, _PngStream) and not _embeds_png_streams(getattr(renderer, "file", None)):
                image = image.pixels()
            if not isinstance(image, _PngStream):
                image = image[::-1]  # rows bottom up
            gc = renderer.new_gc()
            renderer.draw_image(gc, x0, y0, image, Affine2D().scale(x1 - x0, y1 - y0))
            gc.restore()
            self.stale = False

    return Picture()


class _PngStream:
    """An 8-bit RGB PNG's compressed rows (its IDAT data: zlib over the PNG-filtered rows), which a PDF holds as they
    are (FlateDecode with the PNG predictors, as matplotlib embeds an image after encoding it as PNG itself): the
    figure goes into the PDF without decoding its pixels and compressing them again."""

    def __init__(self, path: Path, width_px: int, height_px: int, data: bytes):
        self.path, self.width_px, self.height_px, self.data = path, width_px, height_px, data
        self.shape = (height_px, width_px, 3)  # what matplotlib's PDF renderer reads of an image it places

    @classmethod
    def read(cls, path: Path):
        """The stream of ``path`` if it is an 8-bit RGB PNG, not interlaced (kinid's opaque figures); else None."""
        import struct
        import zlib

        try:
            data = Path(path).read_bytes()
        except OSError:
            return None
        if data[:8] != b"\x89PNG\r\n\x1a\n":
            return None
        at, header, rows = 8, None, []
        while at + 12 <= len(data):
            length, kind = struct.unpack(">I4s", data[at:at + 8])
            body, crc = data[at + 8:at + 8 + length], data[at + 8 + length:at + 12 + length]
            if len(crc) != 4 or zlib.crc32(kind + body) != struct.unpack(">I", crc)[0]:
                return None
            if kind == b"IHDR":
                header = struct.unpack(">IIBBBBB", body)
            elif kind == b"IDAT":
                rows.append(body)
            elif kind == b"IEND":
                break
            at += 12 + length
        if header is None or header[2:] != (8, 2, 0, 0, 0) or not rows:  # 8 bits, RGB, deflate, PNG filters, not
            return None  # interlaced
        return cls(Path(path), header[0], header[1], b"".join(rows))

    def pixels(self):
        """The pixels, (height, width, 3) uint8, rows top to bottom (for a renderer other than the PDF's)."""
        return _opaque_pixels(self.path)


def _embeds_png_streams(pdf_file) -> bool:
    """Make matplotlib's PDF file ``pdf_file`` write each :class:`_PngStream` it is given as an image as it is (an image
    XObject of the stream, FlateDecode with the PNG predictors); False if ``pdf_file`` is not one it knows how to
    (then the picture is drawn from its pixels)."""
    if pdf_file is None:
        return False
    if getattr(pdf_file, "_kinid_png_streams", False):
        return True
    images, write_images = getattr(pdf_file, "_images", None), getattr(pdf_file, "writeImages", None)
    if not isinstance(images, dict) or write_images is None or not hasattr(pdf_file, "beginStream"):
        return False

    def write_all():
        ours = {key: entry for key, entry in images.items() if isinstance(entry[0], _PngStream)}
        for key in ours:
            del images[key]  # matplotlib writes the others, from their pixels
        write_images()
        for stream, _, ob in ours.values():
            _write_png_stream(pdf_file, stream, ob.id)

    pdf_file.writeImages = write_all
    pdf_file._kinid_png_streams = True
    return True


def _write_png_stream(pdf_file, stream: _PngStream, object_id: int) -> None:
    from matplotlib.backends.backend_pdf import Name

    pdf_file.beginStream(object_id, pdf_file.reserveObject("length of image stream"),
                         {"Type": Name("XObject"), "Subtype": Name("Image"), "Width": stream.width_px,
                          "Height": stream.height_px, "ColorSpace": Name("DeviceRGB"), "BitsPerComponent": 8},
                         png={"Predictor": 10, "Colors": 3, "Columns": stream.width_px})
    pdf_file.currentstream.write(stream.data)
    pdf_file.endStream()


def _opaque_pixels(png: Path):
    """The PNG's pixels as 8-bit RGB when it is opaque (a report's figure: the PDF then holds one image, without
    a transparency mask to compress beside it), else RGBA; None if it cannot be read."""
    import numpy as np
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(png) as im:
            if im.mode == "RGB":  # kinid's figures (kinid.reports.figures.save_figure): opaque, read as they are
                return np.asarray(im)
            pixels = np.asarray(im.convert("RGBA"))
    except (OSError, ValueError, SyntaxError, UnidentifiedImageError):
        return None
    return pixels[:, :, :3] if np.all(pixels[:, :, 3] == 255) else pixels


def _fit_widths(natural, total) -> list:
    """Column widths: each its natural width if all fit, else the narrow ones whole and the wide ones
    sharing what is left equally (their text wraps)."""
    if sum(natural) <= total:
        return list(natural)
    widths = list(natural)
    wide = set(range(len(natural)))
    while wide:
        share = (total - sum(widths[i] for i in range(len(widths)) if i not in wide)) / len(wide)
        narrow = {i for i in wide if natural[i] <= share}
        if not narrow:
            for i in wide:
                widths[i] = share
            break
        wide -= narrow
    return widths
