"""``kinid board``: the printable board is the board file's geometry at true scale, and it decodes.

The SVG is read back as geometry (circles and annular sectors from their coordinates, not from kinid's
renderer), drawn with OpenCV at 8 px/mm, and the ring-code locator must find every mark with its code
where the board file puts it.
"""
from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from kinid.cli import main
from kinid.vision import detect_markers, load_board
from kinid.vision.board_print import board_layout, ring_runs

PX_PER_MM, SS = 8, 4


@pytest.fixture(scope="module")
def printed(tmp_path_factory):
    d = tmp_path_factory.mktemp("board")
    assert main(["board", "--out", str(d / "b.json"), "--svg", str(d / "b.svg"), "--pdf", str(d / "b.pdf"),
                 "--rows", "4", "--cols", "5"]) == 0
    return d, load_board(d / "b.json")


def _svg(d):
    return ET.parse(d / "b.svg").getroot()


def test_svg_is_true_scale(printed):
    d, board = printed
    root = _svg(d)
    lay = board_layout(board)
    assert root.get("width") == f"{lay.width_mm:g}mm" and root.get("height") == f"{lay.height_mm:g}mm"
    assert [float(v) for v in root.get("viewBox").split()] == [0, 0, lay.width_mm, lay.height_mm]
    ns = "{http://www.w3.org/2000/svg}"
    circles = [(float(c.get("cx")), float(c.get("cy")), float(c.get("r"))) for c in root.iter(ns + "circle")]
    assert len(circles) == board.rows * board.cols
    ox, oy = lay.origin_mm
    for (cx, cy, r), (row, col) in zip(circles, [(r, c) for r in range(board.rows) for c in range(board.cols)]):
        assert (cx - ox, cy - oy) == pytest.approx(board.mark_mm(row, col), abs=1e-4)
        assert r == pytest.approx(board.center_d_mm / 2)
    bar = next(g for g in root.iter(ns + "g") if g.get("id") == "scale-bar")
    assert float(bar.find(ns + "rect").get("width")) == lay.scale_bar_mm == 50.0


def _raster(d, board):
    """The SVG's circles and sectors drawn by OpenCV (4x supersampled, area-averaged), 8 px/mm."""
    import cv2

    root, ns = _svg(d), "{http://www.w3.org/2000/svg}"
    lay = board_layout(board)
    h, w = int(lay.height_mm * PX_PER_MM), int(lay.width_mm * PX_PER_MM)
    canvas = np.full((h * SS, w * SS), 230, np.uint8)
    k = PX_PER_MM * SS
    shift = 4
    P = lambda x, y: (int(round((x * k - 0.5) * 2 ** shift)), int(round((y * k - 0.5) * 2 ** shift)))  # noqa: E731
    R = lambda r: int(round(r * k * 2 ** shift))  # noqa: E731
    circles = {}
    for c in root.iter(ns + "circle"):
        circles[c.get("data-code")] = (float(c.get("cx")), float(c.get("cy")), float(c.get("r")))
    for path in root.iter(ns + "path"):
        nums = [float(v) for v in re.findall(r"-?\d+\.?\d*", path.get("d"))]
        cx, cy, _ = circles[path.get("data-code")]
        # each sub-path: M x0,y0 A ro,ro 0 large 1 x1,y1 L x2,y2 A ri,ri 0 large 0 x3,y3 Z
        for j in range(0, len(nums), 18):
            x0, y0, ro = nums[j], nums[j + 1], nums[j + 2]
            x1, y1, ri = nums[j + 7], nums[j + 8], nums[j + 11]
            a0 = math.degrees(math.atan2(y0 - cy, x0 - cx))
            a1 = math.degrees(math.atan2(y1 - cy, x1 - cx))
            a1 += 360 if a1 <= a0 else 0
            cv2.ellipse(canvas, P(cx, cy), (R(ro), R(ro)), 0, a0, a1, 20, -1, cv2.LINE_AA, shift)
            cv2.ellipse(canvas, P(cx, cy), (R(ri), R(ri)), 0, a0, a1, 230, -1, cv2.LINE_AA, shift)
    for cx, cy, r in circles.values():
        cv2.circle(canvas, P(cx, cy), R(r), 20, -1, cv2.LINE_AA, shift)
    return cv2.resize(canvas, (w, h), interpolation=cv2.INTER_AREA), lay


def test_printed_board_decodes_where_the_board_file_says(printed):
    d, board = printed
    img, lay = _raster(d, board)
    found = {m.code: m for m in detect_markers(img, bits=board.bits)}
    assert len(found) == board.rows * board.cols
    ox, oy = lay.origin_mm
    for r, row in enumerate(board.codes):
        for c, code in enumerate(row):
            x, y = board.mark_mm(r, c)
            m = found[code]
            assert m.x_px == pytest.approx((ox + x) * PX_PER_MM - 0.5, abs=0.05)
            assert m.y_px == pytest.approx((oy + y) * PX_PER_MM - 0.5, abs=0.05)


def test_pdf_is_true_scale_and_holds_the_same_marks(printed):
    d, board = printed
    data = (d / "b.pdf").read_bytes()
    lay = board_layout(board)
    k = 72 / 25.4
    box = [float(v) for v in re.search(rb"/MediaBox \[([^\]]+)\]", data).group(1).split()]
    assert box == pytest.approx([0, 0, lay.width_mm * k, lay.height_mm * k], abs=1e-3)
    assert f"{k:.4f} 0 0 {-k:.4f} 0 {lay.height_mm * k:.4f} cm".encode() in data
    starts = [tuple(map(float, m)) for m in re.findall(rb"([-\d.]+) ([-\d.]+) m\n?", data)]
    ox, oy = lay.origin_mm
    rc = board.center_d_mm / 2
    centre_starts = {(round(ox + x + rc, 3), round(oy + y, 3)) for x, y in
                     (board.mark_mm(r, c) for r in range(board.rows) for c in range(board.cols))}
    assert centre_starts <= {(round(x, 3), round(y, 3)) for x, y in starts}
    assert data.startswith(b"%PDF-1.4") and data.rstrip().endswith(b"%%EOF")


@pytest.mark.parametrize("code, bits, runs", [
    (0b101100000001, 12, [(2, 2), (11, 2)]),  # elements 11 and 0 are neighbours: one run
    (0b100000000001, 12, [(11, 2)]),
    (0b010000000010, 12, [(1, 1), (10, 1)]),
    (0b111111111111, 12, [(0, 12)]),
])
def test_ring_runs(code, bits, runs):
    assert sorted(ring_runs(code, bits)) == sorted(runs)


def test_board_refuses_overlapping_marks(tmp_path, capsys):
    assert main(["board", "--out", str(tmp_path / "b.json"), "--pitch-mm", "10"]) == 2
    assert "must be smaller than --pitch-mm" in capsys.readouterr().err


def test_a_standard_page_with_two_scale_bars_and_the_board_s_identifier(printed, tmp_path, capsys):
    """The 4 x 5 board goes on A4 (auto); bars across and down (a printer may scale the two directions differently);
    the identifier printed on the page is the one recomputed from the board file; a board too large for the paper
    asked for is one line, exit 2, nothing written."""
    from kinid.vision.board_print import PAGES, board_id

    d, board = printed
    lay = board_layout(board)
    assert lay.page == "a4" and (lay.width_mm, lay.height_mm) == PAGES["a4"]
    root, ns = _svg(d), "{http://www.w3.org/2000/svg}"
    vertical = next(g for g in root.iter(ns + "g") if g.get("id") == "scale-bar-vertical")
    assert float(vertical.find(ns + "rect").get("height")) == lay.vertical_bar_mm == 50.0
    text = (d / "b.svg").read_text()
    assert f"board {board_id(board)}" in text and board_id(board) == board_id(load_board(d / "b.json"))
    assert f"board {board_id(board)}".encode() in (d / "b.pdf").read_bytes()
    assert main(["board", "--out", str(tmp_path / "big.json"), "--pdf", str(tmp_path / "big.pdf"), "--page", "a4"]) == 2
    err = capsys.readouterr().err
    assert "does not fit a4" in err and err.count("\n") == 1
    assert not (tmp_path / "big.json").exists() and not (tmp_path / "big.pdf").exists()
    assert main(["board", "--out", str(tmp_path / "big.json"), "--page", "auto"]) == 0
    assert "a3 page" in capsys.readouterr().out


def test_the_board_file_and_its_drawings_are_written_as_one_unit(tmp_path, capsys, monkeypatch):
    """A drawing that cannot be written (its folder missing; a kill or a full disk mid-way) leaves no board file
    beside it: a board file without the drawing it describes — or beside an older one — is worse than none. The
    earlier files of the unit are not written, and an existing board file keeps its content."""
    old = tmp_path / "b.json"
    old.write_text("old\n")
    argv = ["board", "--out", str(old), "--svg", str(tmp_path / "b.svg"), "--pdf", str(tmp_path / "none" / "b.pdf")]
    assert main(argv) == 2
    assert "none" in capsys.readouterr().err
    assert old.read_text() == "old\n" and not (tmp_path / "b.svg").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.json"]  # no temporary file left either

    import kinid.vision.board_print as board_print

    def interrupted(*args, **kwargs):  # the SVG drawn, then the run stopped while the PDF was made
        raise KeyboardInterrupt

    monkeypatch.setattr(board_print, "board_pdf", interrupted)
    assert main(argv[:-1] + [str(tmp_path / "b.pdf")]) == 130  # the command line's status for an interrupt
    assert old.read_text() == "old\n" and sorted(p.name for p in tmp_path.iterdir()) == ["b.json"]
