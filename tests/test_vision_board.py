"""Tests of vision.board: codes, board file (docs/formats.md, "Board file"), matching with geometric checks."""
import json
from dataclasses import dataclass

import numpy as np
import pytest

from kinid.errors import DataError
from kinid.vision.board import Board, board_codes, load_board, make_board, match_to_board, save_board
from kinid.vision.ringcode import canonical_code


def test_patent_board_has_distinct_increasing_canonical_codes():
    b = make_board()
    flat = [c for row in b.codes for c in row]
    assert (b.rows, b.cols, b.pitch_mm, b.bits) == (14, 14, 16.0, 12)
    assert len(flat) == 196 and len(set(flat)) == 196
    assert flat == sorted(flat)
    assert all(canonical_code(c) == c for c in flat)
    assert all(c not in (0, 4095) for c in flat)
    # every decodable even-parity class (pairwise Hamming distance >= 2) is used, odd ones fill the rest
    even = {canonical_code(v) for v in range(1, 4095) if bin(v).count("1") % 2 == 0}
    assert len(even) == 178
    assert even <= set(flat)
    assert sum(bin(c).count("1") % 2 for c in flat) == 196 - 178


def test_mark_position_and_lookup():
    b = make_board(3, 5, pitch_mm=15.0)
    assert b.mark_mm(2, 4) == (60.0, 30.0)
    assert b.position_of(b.codes[1][3]) == (1, 3)
    assert b.position_of(4095) is None


def test_too_many_marks_for_the_code_space():
    with pytest.raises(DataError, match="distinct codes"):
        board_codes(400, bits=12)


def test_round_trip(tmp_path):
    b = make_board(4, 6, pitch_mm=12.5, center_d_mm=4.0, ring_inner_d_mm=7.0, ring_outer_d_mm=10.0)
    path = tmp_path / "board.json"
    save_board(b, path)
    data = json.loads(path.read_text())
    assert set(data) == {"pitch_mm", "rows", "cols", "center_d_mm", "ring_inner_d_mm", "ring_outer_d_mm", "bits",
                         "codes"}
    assert load_board(path) == b


def test_interfaces_example_loads(tmp_path):
    codes = make_board(2, 3).codes
    path = tmp_path / "b.json"
    path.write_text(json.dumps({"pitch_mm": 16, "rows": 2, "cols": 3, "center_d_mm": 5, "ring_inner_d_mm": 9,
                                "ring_outer_d_mm": 13, "bits": 12, "codes": [list(r) for r in codes]}))
    b = load_board(path)
    assert isinstance(b, Board) and b.pitch_mm == 16.0 and b.codes == codes


def _write(tmp_path, **changes):
    data = {"pitch_mm": 16, "rows": 2, "cols": 2, "center_d_mm": 5, "ring_inner_d_mm": 9, "ring_outer_d_mm": 13,
            "bits": 12, "codes": [[1, 3], [5, 7]]}
    for k, v in changes.items():
        if v is None:
            del data[k]
        else:
            data[k] = v
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("changes,match", [
    ({"pitch_mm": None}, r"bad\.json: pitch_mm: missing"),
    ({"rows": 2.5}, r"bad\.json: rows: must be an integer in \[1, 10000\], got 2\.5"),
    ({"pitch_mm": "16"}, r"bad\.json: pitch_mm: must be a number in \(0, 10000\], got '16'"),
    ({"codes": [[1, 3]]}, r"column 'codes': expected a list of 2 rows"),
    ({"codes": [[1, 3], [5]]}, r"row 1: expected a list of 2 codes"),
    ({"codes": [[1, 3], [5, "x"]]}, r"bad\.json: codes\[1\]\[1\]: must be an integer in \[0, .*\], got 'x'"),
    ({"codes": [[1, 3], [5, 3]]}, r"code 3 appears twice"),
    ({"codes": [[1, 3], [5, 6]]}, r"code 6 at row 1, column 1 is not canonical"),
    ({"codes": [[1, 3], [5, 4095]]}, r"not a decodable 12-bit code"),
    ({"ring_outer_d_mm": 17}, r"column 'ring_outer_d_mm': .*smaller than pitch_mm"),
    ({"ring_inner_d_mm": 4}, r"center_d_mm < ring_inner_d_mm"),
])
def test_malformed_board_files(tmp_path, changes, match):
    with pytest.raises(DataError, match=match):
        load_board(_write(tmp_path, **changes))


def test_unreadable_board_files(tmp_path):
    with pytest.raises(DataError, match="board file not found"):
        load_board(tmp_path / "missing.json")
    p = tmp_path / "broken.json"
    p.write_text('{"pitch_mm": 16,\n "rows": }')
    with pytest.raises(DataError, match=r"broken\.json:2: not valid JSON"):
        load_board(p)
    p.write_text("[1, 2]")
    with pytest.raises(DataError, match="expected a JSON object"):
        load_board(p)


@dataclass(frozen=True)
class _M:
    code: int
    x_px: float
    y_px: float
    radius_px: float


def _markers(board, H, cells, radius_px):
    out = []
    for r, c in cells:
        p = H @ np.array([*board.mark_mm(r, c), 1.0])
        out.append(_M(board.codes[r][c], p[0] / p[2], p[1] / p[2], radius_px))
    return out


def test_match_rejects_valid_code_at_the_wrong_place():
    board = make_board()
    # 20 px/mm, rotated 30 deg, mild perspective
    a = np.deg2rad(30)
    H = np.array([[20 * np.cos(a), -20 * np.sin(a), 400], [20 * np.sin(a), 20 * np.cos(a), 100], [1e-4, 2e-4, 1]])
    cells = [(r, c) for r in range(3, 6) for c in range(4, 8)]
    marks = _markers(board, H, cells, radius_px=50.0)
    # a one-bit decoding error of the mark at (4, 5) that yields another code of the board
    true = board.codes[4][5]
    wrong = next(canonical_code(true ^ (1 << k)) for k in range(12)
                 if board.position_of(canonical_code(true ^ (1 << k))) not in (None, (4, 5)))
    marks[5] = _M(wrong, marks[5].x_px, marks[5].y_px, marks[5].radius_px)
    assert cells[5] == (4, 5)
    matches = match_to_board(board, marks)
    got = {(m.row, m.col) for m in matches}
    assert got == set(cells) - {(4, 5)}
    assert all(board.codes[m.row][m.col] == m.code for m in matches)
    # a code that is not on the board is ignored
    assert len(match_to_board(board, marks + [_M(4095, 0.0, 0.0, 50.0)])) == len(cells) - 1


def test_match_pair_checks_scale_and_single_is_kept():
    board = make_board()
    H = np.diag([20.0, 20.0, 1.0])
    two = _markers(board, H, [(0, 0), (0, 1)], radius_px=50.0)
    assert len(match_to_board(board, two)) == 2
    # same two codes but 3 pitches apart in the image: the scale contradicts the centre-circle size
    bad = [two[0], _M(two[1].code, two[0].x_px + 3 * 320.0, two[0].y_px, 50.0)]
    assert match_to_board(board, bad) == []
    (one,) = match_to_board(board, two[:1])
    assert (one.row, one.col) == (0, 0)


def test_match_single_row_of_marks():
    board = make_board()
    H = np.array([[15.0, 2.0, 100.0], [-2.0, 15.0, 300.0], [0.0, 0.0, 1.0]])
    cells = [(6, c) for c in range(2, 9)]
    marks = _markers(board, H, cells, radius_px=37.5)
    # swap in the code of a mark two rows below: a valid code at the wrong place
    marks[3] = _M(board.codes[8][5], marks[3].x_px, marks[3].y_px, 37.5)
    got = [(m.row, m.col) for m in match_to_board(board, marks)]
    assert got == [c for c in cells if c != (6, 5)]
