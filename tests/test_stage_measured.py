"""The stage commands on measured input: the files in examples/stages/, made by examples/stages/make_examples.py
from the simulators, whose truth is written beside them (``*truth.json``)."""
from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from kinid.cli import main

EX = Path(__file__).resolve().parent.parent / "examples" / "stages"


def _json_out(capsys):
    return json.loads(capsys.readouterr().out)


# --- backlash -------------------------------------------------------------------------------------

def test_backlash_from_a_recorded_run(tmp_path, capsys):
    truth = json.loads((EX / "backlash" / "truth.json").read_text())
    assert main(["backlash", "--data", str(EX / "backlash" / "log.csv"), "--travel-mm", "0.4", "--json",
                 "--out", str(tmp_path / "r.json"), "--tables", str(tmp_path / "t")]) == 0
    got = _json_out(capsys)["measured"]
    assert got["backlash_x_um"] == pytest.approx(truth["backlash_x_um"], abs=0.05)
    assert got["backlash_y_um"] == pytest.approx(truth["backlash_y_um"], abs=0.05)
    assert got["backlash_theta_deg"] == pytest.approx(truth["backlash_theta_deg"], abs=5e-4)
    assert got["pixel_um_x"] == pytest.approx(truth["pixel_um"], rel=2e-4)
    assert got["camera_rotation_deg"] == pytest.approx(truth["camera_rotation_deg"], abs=0.02)
    saved = json.loads((tmp_path / "r.json").read_text())
    assert saved["measured"]["backlash_x_um"] == got["backlash_x_um"] and "reversals" in saved
    # the controller table: reverse − forward actual position is the backlash (LinuxCNC type 0, mm)
    nominal, fwd, rev = np.loadtxt(tmp_path / "t" / "X.comp").T
    np.testing.assert_allclose((rev - fwd) * 1e3, got["backlash_x_um"], atol=2e-3)
    assert (tmp_path / "t" / "Y_ssfk.lis").exists() and (tmp_path / "t" / "X.csv").exists()


def test_backlash_plan_is_what_the_log_ran(tmp_path, capsys):
    assert main(["backlash", "--plan-out", str(tmp_path / "plan.csv"), "--travel-mm", "0.4"]) == 0
    assert "21 moves, 13 photos" in capsys.readouterr().out
    plan = list(csv.DictReader(open(tmp_path / "plan.csv")))
    log = list(csv.DictReader(open(EX / "backlash" / "log.csv")))
    assert [(p["x_mm"], p["y_mm"], p["theta_deg"], p["photo"]) for p in plan] == \
           [(r["x_mm"], r["y_mm"], r["theta_deg"], r["photo"]) for r in log]


def _copy_run(tmp_path):
    shutil.copytree(EX / "backlash", tmp_path / "run")
    return tmp_path / "run"


@pytest.mark.parametrize("change, argv, message", [
    (None, ["--travel-mm", "0.8"], "log.csv:2: move 1 went to (-0.4, -0.4, 0) but the plan's move 1 is (-0.8, -0.8, 0)"),
    (lambda t: t.replace("move_002.png", "gone.png"), ["--travel-mm", "0.4"], "gone.png: image file does not exist"),
    (lambda t: t.replace(",1,move_002.png", ",1,"), ["--travel-mm", "0.4"], "log.csv:3, column 'image': the plan takes a photo"),
    (lambda t: t.replace("-0.200000,-0.200000", "-0.200000,abc", 1), ["--travel-mm", "0.4"], "column 'y_mm': 'abc' is not a number"),
    (lambda t: "\n".join(t.splitlines()[:15]) + "\n", ["--travel-mm", "0.4"], "the log ends after 14 moves"),
])
def test_backlash_bad_logs(tmp_path, capsys, change, argv, message):
    run = _copy_run(tmp_path)
    if change is not None:
        (run / "log.csv").write_text(change((run / "log.csv").read_text()))
    assert main(["backlash", "--data", str(run / "log.csv"), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err


def test_backlash_needs_a_mode(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["backlash"])
    assert exit_.value.code == 2
    assert "one of the arguments --data --plan-out --simulate is required" in capsys.readouterr().err


# --- UVW ------------------------------------------------------------------------------------------

def test_uvw_from_measured_moves(tmp_path, capsys):
    truth = json.loads((EX / "uvw_moves_truth.json").read_text())
    assert main(["uvw", "--data", str(EX / "uvw_moves.csv"), "--json", "--out", str(tmp_path / "m.json"),
                 "--tables", str(tmp_path / "t")]) == 0
    got = _json_out(capsys)["actuators"]
    for a in ("X1", "X2", "Y"):
        p, t = got[a]["parameters"], truth[a]
        for name, value in (("scale_ppm", t["scale_ppm"]), ("backlash_um", t["backlash_um"]),
                            ("s1_um", t["periodic_um"][0][0]), ("k1_um", t["periodic_um"][0][1])):
            assert abs(p[name]["value"] - value) < 4 * p[name]["std"] + 1e-9, (a, name, p[name], value)
    assert json.loads((tmp_path / "m.json").read_text())["actuators"].keys() == got.keys()
    nominal, fwd, rev = np.loadtxt(tmp_path / "t" / "X1.comp").T
    assert nominal.size <= 256 and np.mean(rev - fwd) * 1e3 == pytest.approx(got["X1"]["parameters"]["backlash_um"]["value"], abs=1e-3)


@pytest.mark.parametrize("change, message", [
    (lambda t: t.replace("X1,", "X9,", 1), "column 'actuator': unknown actuator 'X9'"),
    (lambda t: t.replace(",1,", ",0,", 1), "column 'direction': direction must be +1 or -1"),
    (lambda t: t.replace("measured_um", "measured"), "missing column 'measured_um'"),
])
def test_uvw_bad_moves(tmp_path, capsys, change, message):
    (tmp_path / "m.csv").write_text(change((EX / "uvw_moves.csv").read_text()))
    assert main(["uvw", "--data", str(tmp_path / "m.csv")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err


# --- dual axis ------------------------------------------------------------------------------------

def test_dual_axis_from_one_measured_round(tmp_path, capsys):
    truth = json.loads((EX / "dual_axis_truth.json").read_text())
    m = np.array(truth["pixel_to_mm"]).round(7).ravel()
    assert main(["dual-axis", "--data", str(EX / "dual_axis.csv"), "--pixel-to-mm", *map(str, m),
                 "--out", str(tmp_path / "table.csv"), "--json"]) == 0
    rep = _json_out(capsys)
    got = np.column_stack([rep["table"]["offset_x_um"], rep["table"]["offset_y_um"]])
    np.testing.assert_allclose(got, truth["true_correction_um"], atol=0.1)
    rows = [r for r in csv.reader(open(tmp_path / "table.csv")) if not r[0].startswith("#")]
    assert rows[0] == ["camera_y_mm", "head_dx_mm", "head_dy_mm"] and len(rows) == 22


@pytest.mark.parametrize("argv, message", [
    ([], "--data needs --pixel-to-mm"),
    (["--pixel-to-mm", "0", "0", "0", "0"], "pixel_to_mm is not invertible"),
])
def test_dual_axis_bad_input(capsys, argv, message):
    assert main(["dual-axis", "--data", str(EX / "dual_axis.csv"), *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1, err


def test_backlash_report(tmp_path, capsys):
    import hashlib

    assert main(["backlash", "--data", str(EX / "backlash" / "log.csv"), "--travel-mm", "0.4", "--report",
                 str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert hashlib.sha256((EX / "backlash" / "log.csv").read_bytes()).hexdigest() in page
    assert "backlash of X</td><td class=\"num\">4.003" in page and "The stage loses" in page
    assert (tmp_path / "rep" / "backlash.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("argv, title, figure", [
    (["uvw", "--data", str(EX / "uvw_moves.csv")], "UVW stage: actuator error models", "actuators.png"),
    (["dual-axis", "--data", str(EX / "dual_axis.csv"), "--pixel-to-mm", "0.0049931", "0.0002617", "0.0002617",
      "-0.0049931"], "Dual-axis offset table", "offset_table.png"),
])
def test_stage_reports(tmp_path, capsys, argv, title, figure):
    import hashlib

    assert main([*argv, "--report", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    data = Path(argv[2])
    assert f"<h1>{title}</h1>" in page and hashlib.sha256(data.read_bytes()).hexdigest() in page
    assert f'src="{figure}"' in page and (tmp_path / "rep" / figure).read_bytes()[:4] == b"\x89PNG"
    assert "U (k = 2)" in page or "head dx (µm)" in page
