"""The report's PDF (kinid.reports.pdf): the text output breaks lines between words, and no last page holds a few
lines alone. Checked on the page's text as poppler's pdftotext extracts it."""
import re
import shutil
import subprocess

import pytest

from kinid.reports.html import Section
from kinid.reports.pdf import write_pdf

pytestmark = pytest.mark.skipif(shutil.which("pdftotext") is None, reason="poppler-utils not installed")

#: Words no two of which share a long prefix, so that a word cut in two leaves fragments that are not words.
WORDS = ("alignment", "lookalike", "spindle", "reversal", "periodic", "backlash", "gantry", "straightness",
         "squareness", "trunnion", "pitch", "rotary", "workpiece", "tracker", "camera", "residual")


def _pdf(tmp_path, details: str):
    path = tmp_path / "report.pdf"
    write_pdf(path, "Wrap check", "kinid test", [("run", "synthetic")], ["One sentence."],
              [Section("Details", paragraphs=("A paragraph.",), details=details)], folder=tmp_path)
    return path


def _pages(path) -> list:
    text = subprocess.run(["pdftotext", "-layout", str(path), "-"], capture_output=True, text=True, check=True).stdout
    return text.split("\f")[:-1] if text.endswith("\f") else text.split("\f")


def test_long_lines_of_the_text_output_break_between_words(tmp_path):
    # lines of 300+ characters with indentation, as a diagnosis's verdict line, in the fixed-width block
    lines = ["  " + " ".join(WORDS[(i + k) % len(WORDS)] for k in range(30)) for i in range(12)]
    text = " ".join(_pages(_pdf(tmp_path, "\n".join(lines)))).replace("\u00a0", " ")
    tokens = [t.lower() for t in re.findall(r"[A-Za-z]+", text)]
    assert {t for t in tokens} >= set(WORDS)
    broken = sorted({t for t in tokens if t not in WORDS} - {"wrap", "check", "kinid", "test", "run", "synthetic",
                                                              "one", "sentence", "details", "a", "paragraph",
                                                              "full", "text", "output", "page", "of", "report",
                                                              "made", "by"})
    assert not broken, f"fragments of words on the page: {broken}"
    # every word of the input appears as often on the page as in the input: none split over two lines
    for w in WORDS:
        assert tokens.count(w) == sum(line.split().count(w) for line in lines), w


def test_no_last_page_with_a_few_lines_alone(tmp_path):
    # find a length of the text output whose last lines would spill onto a page of their own at the normal spacing
    counts = []
    for n in range(70, 200, 4):
        pages = _pages(_pdf(tmp_path, "\n".join(f"line {i} residual" for i in range(n))))
        last = [x for x in pages[-1].splitlines() if "residual" in x]
        counts.append((n, len(pages), len(last)))
        # the last page holds no block of 1..8 lines of the text output alone (its title line only is not a page)
        assert not (len(pages) > 1 and 0 < len(last) <= 8 and not any("A paragraph" in x for x in pages[-1].splitlines())), \
            (n, len(pages), len(last))
    assert max(p for _, p, _ in counts) >= 2  # the lengths tried do reach a second page
