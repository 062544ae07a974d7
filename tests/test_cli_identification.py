"""`kinid simulate / identify / predict / diagnose` as a user runs them, and bad input (exit 2, one line)."""
import json

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification.model.machine import load_machine
from kinid.identification.data.observations import read_observations
from kinid.urdf import path

BC = str(path("five_axis_bc"))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    (d / "errors.json").write_text(json.dumps({"EX0C": 12.0, "EA0B": -25.0, "EX0W": 900.0, "EC0W": 5000.0, "EXX:periodic:10": [2.0, 1.0]}))
    assert main(["simulate", "--machine", BC, "--errors", str(d / "errors.json"), "--noise-um", "1", "--seed", "3", "--out", str(d / "obs.csv")]) == 0
    return d


def _err_line(capsys):
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


def test_identify_predict_round_trip(workdir, capsys):
    d = workdir
    assert main(["identify", "--machine", BC, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10", "--noise-um", "1", "--out", str(d / "fit.json")]) == 0
    out = capsys.readouterr().out
    assert "EXX:periodic:10[sin]" in out and "µm" in out and "residual RMS" in out
    assert "EX0T" in out and "only their difference" in out
    fit = json.loads((d / "fit.json").read_text())
    sin = next(p for p in fit["parameters"] if p["name"] == "EXX:periodic:10[sin]")
    assert abs(sin["value"] - 2.0) < 4 * sin["std"]
    held = [p for p in fit["parameters"] if not p["identified"]]
    assert held and all(p["value"] is None for p in held)
    # predict the readings of the same poses from a file without the solved axes
    m = load_machine(BC)
    obs = read_observations(d / "obs.csv", m)
    lines = (d / "obs.csv").read_text().splitlines()
    header = lines[0].split(",")
    keep = [i for i, h in enumerate(header) if h not in ("x_mm", "y_mm", "z_mm")]
    (d / "poses.csv").write_text("\n".join(",".join(row.split(",")[i] for i in keep) for row in lines) + "\n")
    assert main(["predict", "--fit", str(d / "fit.json"), "--poses", str(d / "poses.csv"), "--out", str(d / "pred.csv")]) == 0
    pred = read_observations(d / "pred.csv", m)
    diff_um = (pred.axes - obs.axes) * 1e3
    # predictions differ from noisy readings by about the noise (1 µm per axis)
    assert 0.7 < np.sqrt(np.mean(diff_um[:, [3, 0, 4]] ** 2)) < 1.2
    np.testing.assert_array_equal(pred.axes[:, [1, 2]], obs.axes[:, [1, 2]])


def test_diagnose_json_names_the_hidden_effect(workdir, capsys):
    d = workdir
    assert main(["identify", "--machine", BC, "--data", str(d / "obs.csv"), "--noise-um", "1", "--out", str(d / "fit0.json")]) == 0
    capsys.readouterr()
    assert main(["diagnose", "--fit", str(d / "fit0.json"), "--data", str(d / "obs.csv"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert set(result) - {"time_follows", "structure"} == {"verdict", "rms_um", "noise_um", "candidates", "note", "set_aside"}
    assert [t["axis"] for t in result.get("time_follows", [])] == ["B"]  # the patent plan tilts B as its outer loop
    assert result["verdict"] == "missing-effect"
    assert result["noise_um"] == 1.0
    assert result["candidates"][0]["effect"] == "EXX:periodic:10"
    p = [c["p_value"] for c in result["candidates"]]
    assert all(a <= b * (1 + 1e-6) for a, b in zip(p, p[1:])), "best first"
    assert result["candidates"][0]["rms_after_um"] < result["rms_um"]


def test_diagnose_report_and_auto_identify(workdir, capsys, tmp_path):
    d = workdir
    assert main(["diagnose", "--fit", str(d / "fit0.json"), "--data", str(d / "obs.csv"), "--report", str(tmp_path / "rep")]) == 0
    out = capsys.readouterr().out
    assert "verdict: missing-effect" in out and "EXX:periodic:10" in out
    assert (tmp_path / "rep" / "index.html").is_file() and (tmp_path / "rep" / "periodogram.png").stat().st_size > 1000
    rows = (tmp_path / "rep" / "residuals.csv").read_text().splitlines()
    assert rows[0].startswith("row,mark,") and "dx_um" in rows[0] and len(rows) == 1 + 336
    assert "residuals by mark" in out
    assert main(["identify", "--machine", BC, "--data", str(d / "obs.csv"), "--noise-um", "1", "--auto", "--out", str(tmp_path / "auto.json")]) == 0
    fit = json.loads((tmp_path / "auto.json").read_text())
    assert "EXX:periodic:10" in fit["effects"]
    assert fit["rms_um"] < 1.05


def test_demo_runs_and_writes_report(tmp_path, capsys):
    assert main(["demo", "--out", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert "found and added" in out
    assert (tmp_path / "demo" / "index.html").is_file()
    assert (tmp_path / "demo" / "rms_steps.png").is_file()


# --- bad input: one line on stderr naming file/line/column, exit status 2, no output written ---------

BAD_CSV = [
    ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg\nM1,0,0,0,1,2,3,4\n", r"missing column 'c_deg'"),
    ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_mm,c_deg\nM1,0,0,0,1,2,3,4,5\n", r"column 'b_mm'.*expected column 'b_deg'"),
    ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg\nM1,0,0,0,1,2,3,4,5\nM2,0,0,abc,1,2,3,4,5\n", r"bad.csv:3, column 'wz_mm': 'abc' is not a number"),
    ("# comment\nmark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg,dir_x\nM1,0,0,0,1,2,3,4,5,0\n", r"bad.csv:3, column 'dir_x': approach direction must be \+1 or -1"),
    ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg\nM1,0,0,0,1,2,3,4\n", r"bad.csv:2: 8 cells but the header has 9 columns"),
    ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg\n", r"no data rows"),
    ("", r"no header row"),
    ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg\nM1,0,0,0,1,2,nan,4,5\n", r"column 'z_mm': 'nan' is not a finite number"),
]


@pytest.mark.parametrize("text, message", BAD_CSV)
def test_bad_csv_exits_2_with_one_line(tmp_path, capsys, text, message):
    bad = tmp_path / "bad.csv"
    bad.write_text(text)
    before = bad.read_bytes()
    status = main(["identify", "--machine", BC, "--data", str(bad), "--out", str(tmp_path / "fit.json")])
    assert status == 2
    import re

    assert re.search(message, _err_line(capsys))
    assert not (tmp_path / "fit.json").exists()
    assert bad.read_bytes() == before


def test_bad_machine_exits_2(tmp_path, capsys, workdir):
    bad = tmp_path / "m.urdf"
    bad.write_text("<robot name='x'>")
    assert main(["identify", "--machine", str(bad), "--data", str(workdir / "obs.csv"), "--out", str(tmp_path / "f.json")]) == 2
    assert "m.urdf" in _err_line(capsys)


def test_bad_effect_and_arguments_exit_2(tmp_path, capsys, workdir):
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--add", "EXX:wobble", "--out", str(tmp_path / "f.json")]) == 2
    assert "unknown basis 'wobble'" in _err_line(capsys)
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--add", "EQQ", "--out", str(tmp_path / "f.json")]) == 2
    assert "'EQQ' is not an error joint" in _err_line(capsys)
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--noise-um", "-1", "--out", str(tmp_path / "f.json")]) == 2
    assert "--noise-um must be a positive" in _err_line(capsys)
    with pytest.raises(SystemExit) as exc:
        main(["identify", "--machine", BC])
    assert exc.value.code == 2
    assert "required" in _err_line(capsys)


def test_bad_fit_file_and_errors_file(tmp_path, capsys, workdir):
    (tmp_path / "f.json").write_text("{not json")
    assert main(["predict", "--fit", str(tmp_path / "f.json"), "--poses", str(workdir / "obs.csv"), "--out", str(tmp_path / "p.csv")]) == 2
    assert "f.json:1: not valid JSON" in _err_line(capsys)
    (tmp_path / "e.json").write_text(json.dumps({"EXX:periodic:10": [1.0]}))
    assert main(["simulate", "--machine", BC, "--errors", str(tmp_path / "e.json"), "--out", str(tmp_path / "o.csv")]) == 2
    assert "needs 2 finite number(s)" in _err_line(capsys)
    assert main(["predict", "--fit", str(workdir / "fit.json"), "--poses", str(workdir / "obs.csv"), "--solve", "X,Q", "--out", str(tmp_path / "p.csv")]) == 2
    assert "unknown axes Q" in _err_line(capsys)
    assert not (tmp_path / "p.csv").exists()


def test_output_folder_missing(tmp_path, capsys, workdir):
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--out", str(tmp_path / "nope" / "f.json")]) == 2
    assert "output folder" in _err_line(capsys)


def test_identify_report_without_auto(workdir, tmp_path, capsys):
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--noise-um", "1",
                 "--report", str(tmp_path / "rep"), "--out", str(tmp_path / "f.json")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "verdict: missing-effect" in page and "EXX:periodic:10" in page


def test_demo_lead_case_finds_the_unlisted_period(tmp_path, capsys):
    from kinid.cli import main

    assert main(["demo", "--case", "lead", "--out", str(tmp_path / "demo")]) == 0
    out = capsys.readouterr().out
    assert "hidden effect: EXX:periodic:12.7" in out and "found and added as EXX:periodic:12.7" in out
    assert "period found by search" in out


def test_a_reading_just_past_the_travel_is_used_with_a_warning(workdir, tmp_path, capsys):
    """A reading 0.3° past B's ±90° is a stop past a soft limit (accepted, its line named); 5° past is a mistake."""
    rows = (workdir / "obs.csv").read_text().splitlines()
    header = rows[0].split(",")
    j = header.index("b_deg")

    def with_b(values):
        out = [rows[0]]
        for k, line in enumerate(rows[1:], start=2):
            cells = line.split(",")
            if k in values:
                cells[j] = values[k]
            out.append(",".join(cells))
        (tmp_path / "obs.csv").write_text("\n".join(out) + "\n")

    with_b({4: "90.3", 6: "-90.2"})
    assert main(["identify", "--machine", BC, "--data", str(tmp_path / "obs.csv"), "--out", str(tmp_path / "f.json")]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "2 reading(s) of b_deg beyond the URDF travel" in err and "(lines 4, 6)" in err
    with_b({4: "95"})
    assert main(["identify", "--machine", BC, "--data", str(tmp_path / "obs.csv"), "--out", str(tmp_path / "g.json")]) == 2
    assert "obs.csv:4, column 'b_deg': 95 deg is outside the travel of axis B" in capsys.readouterr().err
    assert not (tmp_path / "g.json").exists()


def test_predict_warns_for_poses_the_machine_cannot_reach(workdir, tmp_path, capsys):
    """A pose whose solved X lies past the URDF's ±600 mm travel is written, with one warning naming its line."""
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--noise-um", "1",
                 "--out", str(tmp_path / "fit.json")]) == 0
    (tmp_path / "poses.csv").write_text("mark,wx_mm,wy_mm,wz_mm,b_deg,c_deg\nM1,40,40,0,0,0\nM2,700,0,0,0,0\n")
    capsys.readouterr()
    assert main(["predict", "--fit", str(tmp_path / "fit.json"), "--poses", str(tmp_path / "poses.csv"),
                 "--out", str(tmp_path / "pred.csv")]) == 0
    err = capsys.readouterr().err
    assert "warning:" in err and "1 solved reading(s) of x_mm outside the URDF travel" in err and "(lines 3)" in err
    assert len((tmp_path / "pred.csv").read_text().splitlines()) == 3


def test_metres_in_millimetre_columns_are_warned_of(workdir, tmp_path, capsys):
    """Readings of X, Y, Z divided by 1000 (metres under x_mm): within the travel, so read, but every reading
    lies within 0.2 % of a ±600 mm travel: a warning per column says what looks wrong when the file is read; the
    readings in mm give none. ``identify`` fits them first: the fit does not converge, and its one line of refusal
    names the three columns as metres instead."""
    rows = (workdir / "obs.csv").read_text().splitlines()
    header = rows[0].split(",")
    cols = [header.index(c) for c in ("x_mm", "y_mm", "z_mm")]
    out = [rows[0]]
    for line in rows[1:]:
        cells = line.split(",")
        for j in cols:
            cells[j] = f"{float(cells[j]) / 1000:.9f}"
        out.append(",".join(cells))
    (tmp_path / "metres.csv").write_text("\n".join(out) + "\n")
    assert main(["identify", "--machine", BC, "--data", str(tmp_path / "metres.csv"), "--out",
                 str(tmp_path / "f.json")]) == 2
    line = _err_line(capsys)
    assert "x_mm, y_mm, z_mm look like metres" in line and "multiplied by 1000" in line, line
    assert not (tmp_path / "f.json").exists()
    with pytest.warns(UserWarning) as record:
        read_observations(tmp_path / "metres.csv", load_machine(BC))
    err = "\n".join(str(w.message) for w in record)
    for c in ("x_mm", "y_mm", "z_mm"):
        assert f"every reading of {c} is within" in err and "if they are metres, multiply by 1000" in err, err
    assert main(["identify", "--machine", BC, "--data", str(workdir / "obs.csv"), "--out", str(tmp_path / "g.json")]) == 0
    assert "metres" not in capsys.readouterr().err
