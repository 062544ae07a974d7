"""``kinid backlash`` verb, run in-process."""
import json

import pytest

from kinid.cli import main


def test_json_output_matches_truth(capsys):
    status = main(["backlash", "--simulate", "--json", "--seed", "3", "--backlash-x-um", "6", "--backlash-y-um", "2",
                   "--backlash-theta-deg", "0.02", "--camera-angle-deg", "-11"])
    assert status == 0
    out = json.loads(capsys.readouterr().out)
    assert out["truth"]["backlash_x_um"] == 6.0
    assert out["measured"]["moves"] == 21
    assert abs(out["errors"]["backlash_x_um"]) < 0.3
    assert abs(out["errors"]["backlash_y_um"]) < 0.3
    assert abs(out["errors"]["backlash_theta_deg"]) < 0.002
    assert abs(out["errors"]["pixel_um_x"]) < 0.005          # 0.1 % of 5 um
    assert abs(out["errors"]["camera_rotation_deg"]) < 0.05


def test_readable_output_and_plot(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("MPLBACKEND", "Agg")
    png = tmp_path / "backlash.png"
    status = main(["backlash", "--simulate", "--plot", str(png), "--repeats", "2"])
    assert status == 0
    out = capsys.readouterr().out
    assert "33 moves (20 photos)" in out
    assert "backlash X (µm)" in out and "ISO 230-2 reversal value B" in out
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("argv, match", [
    (["--travel-mm", "0"], "--travel-mm must be a positive number, got 0.0"),
    (["--travel-deg", "-1"], "--travel-deg must be a positive number, got -1.0"),
    (["--repeats", "0"], "--repeats must be an integer >= 1, got 0"),
    (["--pixel-um", "0"], "--pixel-um must be > 0"),
    (["--backlash-x-um", "-2"], "--backlash-x-um must be >= 0, got -2.0"),
    (["--theta-centre-mm", "nan", "3"], "--theta-centre-mm must be finite, got nan 3.0"),
    (["--travel-mm", "3"], r"image after move 2 to \(x -1.5 mm, y -1.5 mm, theta 0 deg\): no fiducial found"),
])
def test_bad_input_one_line_exit_2(argv, match, capsys):
    import re

    assert main(["backlash", "--simulate", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kinid backlash: ")
    assert re.search(match, err)


def test_plot_into_missing_folder_is_an_error(tmp_path, capsys):
    assert main(["backlash", "--simulate", "--plot", str(tmp_path / "no" / "x.png")]) == 2
    err = capsys.readouterr().err
    assert "output folder" in err and "does not exist" in err
    assert err.count("\n") == 1
