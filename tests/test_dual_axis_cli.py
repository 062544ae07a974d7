"""``kinid dual-axis`` in-process: report, JSON, plot, bad input."""
import json

import numpy as np

import pytest

from kinid.cli import main


def test_json_report(capsys):
    assert main(["dual-axis", "--simulate", "--steps", "12", "--step-mm", "20", "--seed", "4", "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["converged"] and rep["rounds"] <= 3 and len(rep["max_change_um"]) == rep["rounds"]
    assert rep["max_change_um"][0] > 5.0 and rep["max_change_um"][-1] <= 1.0
    held = rep["held_out"]
    assert held["positions"] == 12
    assert held["uncompensated_truth"]["max_um"] > 5.0
    assert held["table_truth"]["max_um"] < 2.0 and held["table_measured"]["max_um"] < 2.0
    assert rep["better"] in ("table", "smooth")
    assert len(rep["table"]["offset_x_um"]) == 13 and rep["table"]["offset_x_um"][0] == 0.0


def test_readable_report_and_plot(tmp_path, capsys):
    out = tmp_path / "offsets.png"
    assert main(["dual-axis", "--simulate", "--steps", "6", "--step-mm", "25", "--plot", str(out)]) == 0
    text = capsys.readouterr().out
    assert "round  max entry change" in text and "converged after" in text
    assert "table (truth)" in text and "smooth (truth)" in text and "better on held-out positions" in text
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("argv,match", [
    (["--steps", "0"], "--steps must be an integer >= 1, got 0"),
    (["--step-mm", "-2"], "--step-mm must be positive"),
    (["--spec-um", "0"], "--spec-um must be a positive number"),
    (["--noise-grey", "-1"], "--noise-grey must be a non-negative number"),
    (["--steps", "60", "--step-mm", "10"], "outside its travel"),
])
def test_bad_input_one_line_exit_2(argv, match, capsys):
    assert main(["dual-axis", "--simulate", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("kinid dual-axis: ") and match in err and err.count("\n") == 1


def test_plot_into_missing_folder_is_an_error(tmp_path, capsys):
    assert main(["dual-axis", "--simulate", "--steps", "3", "--step-mm", "20", "--plot", str(tmp_path / "no" / "x.png")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_bad_degree(capsys):
    assert main(["dual-axis", "--simulate", "--degree", "0"]) == 2
    assert "degree must be an integer >= 1, got 0" in capsys.readouterr().err


def test_offset_table_is_written_to_a_file(tmp_path, capsys):
    out = tmp_path / "table.csv"
    assert main(["dual-axis", "--simulate", "--steps", "4", "--step-mm", "20", "--out", str(out), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    assert lines[0] == "camera_y_mm,head_dx_mm,head_dy_mm"
    rows = np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]])
    assert rows.shape == (5, 3)
    np.testing.assert_allclose(rows[:, 0], [0, 20, 40, 60, 80])
    assert np.all(rows[0, 1:] == 0.0)
    assert rep["rounds"] >= 1


def test_simulated_report_states_the_held_out_check(tmp_path, capsys):
    """--simulate --report writes the simulated method's report: the table, the held-out check against the
    simulated truth (the figures the text output prints), the figure, the single-file HTML and PDF."""
    import json

    args = ["dual-axis", "--simulate", "--steps", "8", "--step-mm", "20", "--seed", "3", "--random-errors"]
    assert main([*args, "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert main([*args, "--report", str(tmp_path / "rep")]) == 0
    assert f"report written to {tmp_path / 'rep'}" in capsys.readouterr().out
    page = (tmp_path / "rep" / "index.html").read_text()
    h = rep["held_out"]
    for key in ("uncompensated_truth", "table_truth", "table_measured", "smooth_truth"):
        assert f"{h[key]['max_um']:.3f}" in page
    assert "seed 3, random errors" in page and f"{len(rep['table']['y_mm'])}" in page
    for name in ("dual_axis_simulated.png", "report.html", "report.pdf"):
        assert (tmp_path / "rep" / name).stat().st_size > 1000
