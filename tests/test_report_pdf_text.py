"""The report's PDF writes its text lines itself (kinid.reports.pdf._pdf_text_writer) as matplotlib's PDF renderer's
``draw_text`` writes them: the same file, byte for byte, on text that takes every branch of that code — kerned pairs,
bold and fixed-width fonts, characters beyond Latin-1 (Type 3 fonts hold 256 characters a subset: σ, µ, ±, −, ², →
go into further subsets), characters the first font lacks (drawn from a fallback font), a table's right-aligned
cells and a page break."""
import pytest

from kinid.reports import pdf
from kinid.reports.html import Section, Table

TEXT = ("AVATAR WAVE Ta Yo kerned: fi ffl; σ = 1.2 µm ± 0.3 µm², −4.5 → 7 (k = 2); ✓ ∑ ∞ ≤ ≥ Ω Å é ß ñ "
        "«quoted» — “smart” ‘quotes’ … and ★ ♥ ⚠ outside the first font")


def _write(path, *, ours: bool):
    rows = tuple((f"EXX:periodic:{k}", f"{k * 1.234:.3f}", "µm" if k % 2 else "µrad", TEXT[: 10 + 7 * k])
                 for k in range(40))
    sections = [Section("Text σ µ ± → ✓", paragraphs=(TEXT, TEXT.upper()),
                        tables=(Table(("error", "value", "unit", "note"), rows, numeric=(1,), caption=TEXT),),
                        details="\n".join(f"  {k:3d}  {TEXT}" for k in range(60)))]
    real, used = pdf._pdf_text_writer, []

    def writer(renderer):
        used.append(real(renderer) if ours else None)  # None: matplotlib's draw_text, line by line
        return used[-1]

    try:
        pdf._pdf_text_writer = writer
        pdf.write_pdf(path, "Text check — σ µ ±", "kinid test: ✓", [("run", TEXT)], [TEXT], sections,
                      folder=path.parent)
    finally:
        pdf._pdf_text_writer = real
    assert used and all(w is not None for w in used) == ours  # every page drawn by the writer asked for
    return path.read_bytes()


def test_text_lines_are_written_as_matplotlibs_draw_text_writes_them(tmp_path):
    import io

    from matplotlib.backends.backend_pdf import PdfFile, RendererPdf

    if pdf._pdf_text_writer(RendererPdf(PdfFile(io.BytesIO()), 72, 100, 100)) is None:
        pytest.skip("this matplotlib's PDF renderer has another shape: the report draws with its draw_text")
    ours = _write(tmp_path / "ours.pdf", ours=True)
    theirs = _write(tmp_path / "theirs.pdf", ours=False)
    assert ours.count(b"/Type /Page ") > 1  # a page break: the fonts' subsets carry over to the next page
    assert ours == theirs
