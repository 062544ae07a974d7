"""Tests of ``kinid markers`` (docs/hardware.md)."""
import json

import cv2
import numpy as np
import pytest

from kinid.cli import main
from kinid.vision.board import make_board
from kinid.vision.render import board_coverage, homography_image_to_plane, render_pattern, similarity_plane_to_image


@pytest.fixture(scope="module")
def board_image(tmp_path_factory):
    board = make_board()
    H = similarity_plane_to_image(0.1, -8.0, (90.0, 95.0))
    img = render_pattern(board_coverage(board), (400, 520), homography_image_to_plane(H), low=225, high=25,
                         blur_px=0.7, noise_sigma=2.0, rng=np.random.default_rng(3))
    path = tmp_path_factory.mktemp("img") / "board.png"
    cv2.imwrite(str(path), img)
    truth = {}
    for r in range(board.rows):
        for c in range(board.cols):
            p = H @ np.array([*board.mark_mm(r, c), 1.0])
            if 67 <= p[0] <= 519 - 67 and 67 <= p[1] <= 399 - 67:
                truth[board.codes[r][c]] = p[:2]
    return path, truth


def test_json_output(board_image, capsys):
    path, truth = board_image
    assert main(["markers", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert isinstance(out, list) and len(out) == len(truth) >= 4
    for item in out:
        assert list(item) == ["code", "x_px", "y_px"]
        assert isinstance(item["code"], int) and isinstance(item["x_px"], float)
        x, y = truth[item["code"]]
        assert np.hypot(item["x_px"] - x, item["y_px"] - y) < 0.03


def test_table_and_drawing(board_image, capsys, tmp_path):
    path, truth = board_image
    out_png = tmp_path / "drawn.png"
    assert main(["markers", str(path), "--bits", "12", "--draw", str(out_png)]) == 0
    text = capsys.readouterr().out
    assert f"{len(truth)} mark(s) decoded" in text
    for code in truth:
        assert f"{code:012b}" in text
    drawn = cv2.imread(str(out_png), cv2.IMREAD_UNCHANGED)
    assert drawn.shape == (400, 520, 3)
    # detections are drawn in colour on the grey image
    assert np.count_nonzero(drawn[..., 0].astype(int) != drawn[..., 2]) > 100


def test_unreadable_image_exits_2(tmp_path, capsys):
    bad = tmp_path / "not_an_image.png"
    bad.write_text("hello")
    assert main(["markers", str(bad), "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not_an_image.png" in err[0] and "cannot decode" in err[0]
    assert main(["markers", str(tmp_path / "missing.png")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "does not exist" in err[0]


def test_bad_bits_exits_2(board_image, capsys):
    path, _ = board_image
    assert main(["markers", str(path), "--bits", "2"]) == 2
    assert "--bits" in capsys.readouterr().err
