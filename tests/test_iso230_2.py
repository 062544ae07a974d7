"""ISO 230-2 evaluation against a worked example computed by hand from the standard's formulas."""
import json
import math

import numpy as np
import pytest

from kinid.cli import main
from kinid.errors import DataError
from kinid.stages.iso230_2 import _decimals, evaluate_runs

# targets 0, 10, 20 mm; two runs per direction; deviations µm
RUNS = [  # target, run, direction, deviation
    (0, 1, 1, 1.0), (0, 2, 1, 3.0), (0, 1, -1, -1.0), (0, 2, -1, 0.0),
    (10, 1, 1, 2.0), (10, 2, 1, 2.0), (10, 1, -1, 1.0), (10, 2, -1, 3.0),
    (20, 1, 1, -1.0), (20, 2, 1, -3.0), (20, 1, -1, -4.0), (20, 2, -1, -4.0),
]
R2 = math.sqrt(2.0)
# By hand (ISO 230-2 formulas, n = 2):
#   x̄↑ = (2, 2, -2), s↑ = (√2, 0, √2);  x̄↓ = (-0.5, 2, -4), s↓ = (√0.5, √2, 0)
#   x̄ = (0.75, 2, -3);  B_i = x̄↑ - x̄↓ = (2.5, 0, 2)  ->  B = 2.5, B̄ = 4.5 / 3 = 1.5
#   R↑ = 4 max s↑ = 4√2;  R↓ = 4√2
#   R_i = max(2s↑ + 2s↓ + |B_i|, 4s↑, 4s↓) = (2√2 + √2 + 2.5, 4√2, 4√2)  ->  R = 3√2 + 2.5
#   E↑ = 2 - (-2) = 4;  E↓ = 2 - (-4) = 6;  E = 2 - (-4) = 6;  M = 2 - (-3) = 5
#   A↑ = max(2 + 2√2, 2, -2 + 2√2) - min(2 - 2√2, 2, -2 - 2√2) = 4 + 4√2
#   A↓ = max(-0.5 + √2, 2 + 2√2, -4) - min(-0.5 - √2, 2 - 2√2, -4) = 6 + 2√2
#   A  = max(2 + 2√2, 2 + 2√2) - min(-2 - 2√2, -4) = 4 + 4√2
HAND = {"A_um": 4 + 4 * R2, "A_up_um": 4 + 4 * R2, "A_down_um": 6 + 2 * R2, "E_um": 6.0, "E_up_um": 4.0,
        "E_down_um": 6.0, "R_um": 3 * R2 + 2.5, "R_up_um": 4 * R2, "R_down_um": 4 * R2, "M_um": 5.0, "B_um": 2.5,
        "mean_reversal_um": 1.5}


def test_worked_example_by_hand():
    t, run, d, x = np.array(RUNS, float).T
    res = evaluate_runs(t, d, x).summary()
    for key, value in HAND.items():
        assert res[key] == pytest.approx(value, abs=1e-12), key
    assert [p["reversal_um"] for p in res["positions"]] == pytest.approx([2.5, 0.0, 2.0])


def test_command_line_json_text_and_plot(tmp_path, capsys):
    f = tmp_path / "runs.csv"
    f.write_text("target_mm,run,direction,deviation_um\n" + "\n".join(",".join(map(str, r)) for r in RUNS) + "\n")
    assert main(["iso230-2", "--data", str(f), "--json", "--plot", str(tmp_path / "iso.png")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["standard"] == "ISO 230-2:2014" and out["source"] == str(f)
    for key, value in HAND.items():
        assert out[key] == pytest.approx(value, abs=1e-9), key
    assert (tmp_path / "iso.png").stat().st_size > 5000
    assert main(["iso230-2", "--data", str(f), "--axis", "X"]) == 0
    text = capsys.readouterr().out
    k = _decimals([HAND["A_um"], HAND["R_um"], HAND["E_um"]])  # four significant digits of A
    assert text.startswith("ISO 230-2:2014 positioning of axis X from runs.csv")
    assert "accuracy A (µm)" in text and f"{HAND['A_um']:14.{k}f}" in text and f"{HAND['R_um']:14.{k}f}" in text


def test_decimals_follow_the_size_of_the_axis():
    """An axis of 22 µm shows 22.04; one of 0.09 µm shows 0.08941, not 0.089."""
    assert _decimals([22.04]) == 2 and f"{22.0412:.{_decimals([22.0412])}f}" == "22.04"
    assert f"{0.089412:.{_decimals([0.089412])}f}" == "0.08941"
    assert _decimals([1234.5]) == 1 and _decimals([0.0]) == 3


@pytest.mark.parametrize("rows, message", [
    ("target_mm,run,direction,deviation_um\n0,1,1,1\n0,2,1,2\n0,1,-1,1\n", "run(s) in direction -"),
    ("target_mm,run,direction,deviation_um\n0,1,2,1\n", "bad.csv:2, column 'direction': direction must be"),
    ("target_mm,run,deviation_um\n0,1,1\n", "missing column 'direction'"),
    ("target_mm,run,direction,deviation_um\n0,1,1,abc\n", "'abc' is not a number"),
    ("target_mm,run,direction,deviation_um\n0,1,1,1\n0,2,1,2\n0,1,1,1.5\n", "measured twice, on lines 2 and 4"),
])
def test_bad_runs_files(tmp_path, capsys, rows, message):
    f = tmp_path / "bad.csv"
    f.write_text(rows)
    assert main(["iso230-2", "--data", str(f)]) == 2
    err = capsys.readouterr().err
    assert message in err, err
    assert err.count("\n") == 1


def test_api_names_the_problem():
    with pytest.raises(DataError, match="direction must be"):
        evaluate_runs([0, 0], [1, 0], [1, 2])


def test_millimetres_in_the_micrometre_column_are_warned_of(tmp_path, capsys):
    f = tmp_path / "mm.csv"
    rows = [(t, r, d, (0.001 * r + 0.002 * t / 100) * (1 if d > 0 else 1.5)) for t in (0, 100, 200)
            for r in (1, 2, 3) for d in (1, -1)]
    f.write_text("target_mm,run,direction,deviation_um\n" + "\n".join(",".join(map(str, r)) for r in rows) + "\n")
    assert main(["iso230-2", "--data", str(f)]) == 0
    err = capsys.readouterr().err
    assert "if they are millimetres, multiply by 1000" in err and err.count("\n") == 1
    f.write_text("target_mm,run,direction,deviation_um\n" + "\n".join(",".join(map(str, (t, r, d, v * 1000)))
                                                                       for t, r, d, v in rows) + "\n")
    assert main(["iso230-2", "--data", str(f)]) == 0
    assert "millimetres" not in capsys.readouterr().err


def test_report_states_the_standard_axis_file_and_values(tmp_path, capsys):
    """--report: the test report to hand over names the edition, the axis and the runs file, and holds the axis values
    and the per-target table the text prints (the same decimals), the plot, one-file HTML and PDF."""
    import pathlib

    runs = pathlib.Path(__file__).resolve().parent.parent / "examples" / "x_runs.csv"
    assert main(["iso230-2", "--data", str(runs), "--axis", "X", "--json"]) == 0
    values = json.loads(capsys.readouterr().out)
    assert main(["iso230-2", "--data", str(runs), "--axis", "X", "--report", str(tmp_path / "rep")]) == 0
    assert f"report written to {tmp_path / 'rep'}" in capsys.readouterr().out
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "ISO 230-2:2014" in page and "x_runs.csv" in page and "SHA-256" in page and "of axis X" in page
    for key in ("A_um", "E_um", "R_um", "M_um", "B_um", "mean_reversal_um", "A_up_um", "R_down_um"):
        assert f"{values[key]:.3f}" in page, key
    for row in values["positions"]:
        assert f"{row['target_mm']:.3f}" in page and f"{row['repeatability_um']:.3f}" in page
    for name in ("positioning.png", "report.html", "report.pdf"):
        assert (tmp_path / "rep" / name).stat().st_size > 1000
