"""``kinid uvw``: runs on a simulated stage, prints the patent's and the model's numbers."""
import json

import pytest

from kinid.cli import main


def test_json_output(capsys):
    assert main(["uvw", "--simulate", "--json", "--validation-moves", "60", "--seed", "3"]) == 0
    out = json.loads(capsys.readouterr().out)
    w = out["worked_example"]
    assert (w["delta_xn_um"], w["delta_xm_um"], w["delta_x_um"]) == (2.02, 2.62, 2.29)
    assert w["forward_um"] == pytest.approx(0.96, abs=1e-9)
    assert w["reverse_um"] == pytest.approx(3.25, abs=1e-9)
    v = out["validation"]["all"]
    assert v["model"]["max_um"] < 0.6 < v["patent"]["max_um"] < v["uncompensated"]["max_um"]
    for name in ("X1", "X2", "Y"):
        p = out["model"][name]["parameters"]
        assert abs(p["backlash_um"]["value"] - p["backlash_um"]["truth"]) < 3 * p["backlash_um"]["std"] + 1e-3
        assert out["patent"][name]["repeats"] == 18
        assert out["model"][name]["linear_only_rms_um"] > 3 * out["model"][name]["rms_um"]
    assert out["stage"]["model"]["max_x_um"] < out["stage"]["patent"]["max_x_um"]


def test_text_report_and_plot(tmp_path, capsys):
    png = tmp_path / "uvw.png"
    assert main(["uvw", "--simulate", "--validation-moves", "30", "--plot", str(png)]) == 0
    text = capsys.readouterr().out
    assert "forward 0.96 µm, reverse 3.25 µm" in text
    assert "uncompensated" in text and "patent" in text and "model" in text
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.mark.parametrize("argv, message", [
    (["--lead-um", "0"], "lead-um must be a positive number"),
    (["--lead-um", "-5"], "lead-um must be a positive number"),
    (["--noise-um", "-1"], "noise-um must be >= 0"),
    (["--repeats", "0"], "repeats must be a positive integer"),
    (["--plot", "/nonexistent/dir/out.png", "--validation-moves", "5"], "output folder"),
    (["--report", "rep", "--tables", "tab"], "--tables is not written with --simulate"),
])
def test_bad_arguments_exit_2_with_one_line(argv, message, capsys):
    assert main(["uvw", "--simulate", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("kinid uvw: ")
    assert message in err


def test_a_folder_that_cannot_be_made_is_one_line(tmp_path, capsys):
    """The file system's refusal where kinid makes a folder (here: under a file) is one line naming it, exit 2."""
    from pathlib import Path

    moves = Path(__file__).resolve().parent.parent / "examples" / "stages" / "uvw_moves.csv"
    (tmp_path / "afile").write_text("")
    assert main(["uvw", "--data", str(moves), "--tables", str(tmp_path / "afile" / "tables")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "afile/tables: cannot use as output folder (Not a directory)" in err, err


def test_simulated_report_compares_the_methods_on_the_same_moves(tmp_path, capsys):
    """--simulate --report writes the simulated story's report: fitted against simulated values with k = 2
    uncertainties, and the patent's method and the model on the same validation moves."""
    import json

    args = ["uvw", "--simulate", "--seed", "4", "--validation-moves", "20", "--repeats", "1", "--patent-repeats", "5"]
    assert main([*args, "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert main([*args, "--report", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    backlash = r["model"]["X1"]["parameters"]["backlash_um"]
    assert f"{backlash['value']:.3f}" in page and f"{2 * backlash['std']:.3f}" in page and f"{backlash['truth']:.3f}" in page
    for method in ("uncompensated", "patent", "model"):
        assert f"{r['validation']['all'][method]['rms_um']:.3f}" in page
    assert "U (k = 2)" in page and "seed 4" in page
    for name in ("uvw_simulated.png", "report.html", "report.pdf"):
        assert (tmp_path / "rep" / name).stat().st_size > 1000
