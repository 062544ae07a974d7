"""The report's PDF holds each opaque figure's PNG rows as they are (kinid.reports.pdf._PngStream): not decoded and
compressed again. These tests read the images back out of the PDF with poppler's pdfimages, a decoder that shares
no code with kinid or matplotlib, and compare them with the PNG files' pixels."""
import shutil
import subprocess

import numpy as np
import pytest
from PIL import Image

from kinid.reports.figures import fixed_layout, new_figure, save_figure
from kinid.reports.html import Figure, Section
from kinid.reports.pdf import _PngStream, write_pdf

needs_poppler = pytest.mark.skipif(shutil.which("pdfimages") is None, reason="poppler-utils not installed")


def _figures(folder):
    """An opaque figure as kinid writes it (RGB) and one with transparent pixels (RGBA), as PNG files."""
    fig = new_figure((4.0, 2.5))
    ax = fig.subplots()
    x = np.linspace(0.0, 10.0, 200)
    ax.plot(x, np.sin(x), lw=0.8)
    ax.scatter(x[::10], np.cos(x[::10]), s=12, color="tab:orange")
    ax.set_xlabel("X position (mm)")
    fixed_layout(fig)
    save_figure(fig, folder / "opaque.png", tight=False)
    rgba = np.zeros((40, 60, 4), np.uint8)
    rgba[..., 0] = np.arange(60, dtype=np.uint8)[None, :] * 4
    rgba[..., 3] = 255
    rgba[:10, :10, 3] = 0  # a transparent corner: drawn from its pixels, with a mask
    Image.fromarray(rgba).save(folder / "clear.png")
    return ("opaque.png", "clear.png")


def _pdf(folder, names):
    sections = [Section("Figures", figures=tuple(Figure(n, f"figure {n}") for n in names))]
    write_pdf(folder / "r.pdf", "Title", "sub", [("made", "now")], ["One sentence."], sections, folder=folder)
    return (folder / "r.pdf").read_bytes()


def test_only_an_opaque_8_bit_rgb_png_is_taken_as_a_stream(tmp_path):
    opaque, clear = _figures(tmp_path)
    stream = _PngStream.read(tmp_path / opaque)
    with Image.open(tmp_path / opaque) as im:
        assert im.mode == "RGB" and stream.shape == (im.height, im.width, 3)
    assert _PngStream.read(tmp_path / clear) is None  # RGBA
    (tmp_path / "cut.png").write_bytes((tmp_path / opaque).read_bytes()[:-30])  # a file cut short: no IEND, bad CRC
    data = bytearray((tmp_path / opaque).read_bytes())
    data[40] ^= 0xFF  # a damaged byte inside a chunk
    (tmp_path / "damaged.png").write_bytes(bytes(data))
    assert _PngStream.read(tmp_path / "cut.png") is None
    assert _PngStream.read(tmp_path / "damaged.png") is None
    assert _PngStream.read(tmp_path / "missing.png") is None


def test_the_pdf_holds_the_png_rows_as_they_are(tmp_path):
    opaque, clear = _figures(tmp_path)
    pdf = _pdf(tmp_path, (opaque, clear))
    assert _PngStream.read(tmp_path / opaque).data in pdf  # the same compressed bytes: not encoded again


@needs_poppler
def test_the_images_read_back_from_the_pdf_are_the_figures_pixels(tmp_path):
    names = _figures(tmp_path)
    _pdf(tmp_path, names)
    subprocess.run(["pdfimages", "-png", str(tmp_path / "r.pdf"), str(tmp_path / "out")], check=True)
    read = sorted(tmp_path.glob("out-*.png"))
    assert len(read) == 3  # the opaque figure; the other and its transparency mask
    opaque = np.asarray(Image.open(tmp_path / names[0]))
    assert np.array_equal(np.asarray(Image.open(read[0]).convert("RGB")), opaque)
    clear = np.asarray(Image.open(tmp_path / names[1]))
    assert np.array_equal(np.asarray(Image.open(read[1]).convert("RGB")), clear[..., :3])
