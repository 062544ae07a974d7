"""The output a page shows after an ``<!-- output of: COMMAND -->`` marker is what COMMAND prints.

The convention (the marker, excerpts with ``...``, exact text or numbers to a
stated number of units in their last shown digit) is stated in
``tests/docs_output.py``, which also rewrites the blocks
(``.venv/bin/python tests/docs_output.py --write``). Each page's commands run
once, in order, in a fresh copy of the repository, as
``tests/test_docs_commands.py`` runs them; every comparison is also shown to
fail on a deliberately altered block, so that it cannot pass vacuously.
"""
from __future__ import annotations

import re

import pytest

from docs_output import main, marked_blocks, malformed_markers, matches, rewritten, run_page
from test_docs_commands import ROOT, _fresh_clone, _pages

MARKED = [p for p in _pages() if marked_blocks(p.read_text(encoding="utf-8"))]

PRINTED = ["plan: 84 alignments", "tool point: U = 0.491 µm (k = 2)", "  expected 3-D RMS 0.426 µm",
           "order: 3 blocks", "plan written to plan.csv", ""]


def _altered(shown, digits):
    """The shown block with one line altered beyond what the comparison accepts: a figure or, without one, a word."""
    shown = list(shown)
    for i, line in enumerate(shown):
        number = re.search(r"\d+(?:\.(\d+))?", line)
        if number and line.strip() != "...":
            step = (digits or 0) + 5  # five units beyond the tolerance, in the last shown digit
            value = int(number.group(0).replace(".", "")) + step
            text = str(value).rjust(len(number.group(0).replace(".", "")), "0")
            if number.group(1):
                text = text[:-len(number.group(1))] + "." + text[-len(number.group(1)):]
            shown[i] = line[:number.start()] + text + line[number.end():]
            return shown
    for i, line in enumerate(shown):
        if line.strip() and line.strip() != "...":
            shown[i] = line + " altered"
            return shown
    raise AssertionError("a block with nothing to alter")


def test_a_whole_block_is_the_whole_output():
    assert matches(PRINTED[:-1], PRINTED)
    assert not matches(PRINTED[:-2], PRINTED)  # a line missing at the end
    assert not matches(PRINTED[1:-1], PRINTED)  # a line missing at the start
    assert not matches([PRINTED[1], PRINTED[0]] + PRINTED[2:-1], PRINTED)  # order


def test_an_excerpt_keeps_order_and_its_lines_consecutive():
    assert matches(["...", PRINTED[1], PRINTED[2], "..."], PRINTED)
    assert matches([PRINTED[0], "...", PRINTED[4]], PRINTED)
    assert matches(["...", PRINTED[4]], PRINTED)
    assert matches(["  ...", PRINTED[3], PRINTED[4]], PRINTED)  # indented gap, as in a table
    assert not matches(["...", PRINTED[4], PRINTED[1], "..."], PRINTED)  # order
    assert not matches(["...", PRINTED[1], PRINTED[3], "..."], PRINTED)  # a line left out without "..."
    assert not matches(["...", PRINTED[1]], PRINTED)  # not the end
    assert not matches([PRINTED[1], "..."], PRINTED)  # not the start
    assert not matches(["...", "plan: 85 alignments", "..."], PRINTED)


def test_numbers_to_the_stated_units_of_the_last_digit():
    line = "  expected 3-D RMS 0.426 µm, -1.5e-3 ppm, 12 marks"
    assert matches([line], ["  expected 3-D RMS 0.428 µm, -1.7e-3 ppm, 12 marks"], digits=2)
    assert not matches([line], ["  expected 3-D RMS 0.428 µm, -1.5e-3 ppm, 12 marks"])  # exact by default
    assert not matches([line], ["  expected 3-D RMS 0.429 µm, -1.5e-3 ppm, 12 marks"], digits=2)
    assert not matches([line], ["  expected 3-D RMS 0.426 µm, -1.5e-3 ppm, 13 marks"], digits=2)  # counts exact
    assert matches(["X.comp: 116 points from -67.6 to 67.6"], ["X.comp: 116 points from -67.564 to 67.581"], digits=2)
    assert not matches(["X.comp: 116 points from -67.6 to 67.6"], ["X.comp: 114 points from -67.564 to 67.581"],
                       digits=2)
    assert not matches([line], ["  expected 3-D RMS 0.426 mm, -1.5e-3 ppm, 12 marks"], digits=2)  # words exact
    assert not matches([line], ["  expected 3-D RMS 0.426 µm, -1.5e-3 ppm, 12 marks, 3 held"], digits=2)


def test_rewriting_keeps_a_matching_block_and_updates_an_excerpt_line_by_line():
    assert rewritten(["...", "tool point: U = 0.492 µm (k = 2)", "..."], PRINTED, digits=2) == \
        ["...", "tool point: U = 0.492 µm (k = 2)", "..."]  # within tolerance: left as written
    assert rewritten(["...", "tool point: U = 0.5 µm (k = 2)", "..."], PRINTED) == \
        ["...", PRINTED[1], "..."]
    assert rewritten(["plan: 80 alignments", "plan written to plan.csv"], PRINTED) == PRINTED[:-1]
    assert rewritten(["...", "a line no longer printed", "..."], PRINTED) is None


def test_the_docs_mark_their_output_blocks_and_every_marker_binds_a_block():
    assert {p.name for p in MARKED} >= {"README.md", "plan.md", "compensation.md", "history.md"}
    for page in _pages():
        assert malformed_markers(page.read_text(encoding="utf-8")) == [], page.name


@pytest.mark.parametrize("page", MARKED, ids=[p.name for p in MARKED])
def test_marked_blocks_show_what_their_commands_print(page, tmp_path):
    results = run_page(page, _fresh_clone(tmp_path / "clone"))
    assert len(results) == len(marked_blocks(page.read_text(encoding="utf-8")))
    for mark, printed, status in results:
        lines = printed.splitlines()
        assert status in (0, 2), f"{page.name}:{mark.line}: `{mark.command}` exited {status}:\n{printed[-2000:]}"
        assert matches(mark.shown, lines, mark.digits), (
            f"{page.name}:{mark.line}: the block differs from what `{mark.command}` prints "
            f"(.venv/bin/python tests/docs_output.py --write docs/{page.name} rewrites it):\n{printed}")
        # not vacuous: the same block with one figure (or word) altered fails
        assert not matches(_altered(mark.shown, mark.digits), lines, mark.digits), (page.name, mark.line)


def test_the_script_reports_an_altered_page_and_rewrites_it(tmp_path, capsys):
    page = ROOT / "docs" / "machines.md"
    text = page.read_text(encoding="utf-8")
    (mark,) = marked_blocks(text)
    assert len(mark.shown) > 1  # the block to alter: the whole output of `kinid model`
    altered = text[:mark.body_start] + mark.shown[0].replace("48 error joints", "47 error joints") + "\n" \
        + "".join(line + "\n" for line in mark.shown[2:]) + text[mark.body_end:]
    copy = tmp_path / "machines.md"
    copy.write_text(altered, encoding="utf-8")
    assert main(["--check", str(copy)]) == 1
    report = capsys.readouterr().out
    assert f"machines.md:{mark.line}:" in report and "-" + mark.shown[0].replace("48", "47") in report, report
    assert copy.read_text(encoding="utf-8") == altered  # --check changes nothing
    assert main(["--write", str(copy)]) == 0
    assert copy.read_text(encoding="utf-8") == text
