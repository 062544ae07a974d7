"""``kinid compensate`` and the controller files (kinid.axis_tables).

The written tables and calibrated.urdf are applied here by an independent implementation: plain
Pinocchio on the calibrated URDF, error joints set from the CSV tables by linear interpolation —
none of kinid's kinematics or effect code.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from kinid.axis_tables import AxisErrorTable, linuxcnc_text, twincat_text
from kinid.cli import main
from kinid.errors import DataError
from kinid.identification import default_model, fit, load_machine, parse_effect, save_fit
from kinid.identification.model.machine import evaluate
from kinid.identification.fitting.residuals import design, joint_values
from kinid.identification.fitting.simulate import patent_plan, simulate
from kinid.urdf import path as urdf_path
from plain_machine import PlainMachine

# --- controller formats against the examples of their documentation ------------------------------


def test_linuxcnc_type0_matches_the_documented_example():
    """LinuxCNC "INI Configuration", [JOINT_<num>] COMP_FILE, "Type 0 Example": nominal, then the actual
    positions reached travelling in the positive and the negative direction."""
    table = AxisErrorTable("X", False, [-1.0, 0.0, 1.0], forward=[-5.0, 2.0, 3.0], reverse=[5.0, -3.0, -2.0])
    assert linuxcnc_text(table) == ("-1.000000 -1.005000 -0.995000\n"
                                    "0.000000 0.002000 -0.003000\n"
                                    "1.000000 1.003000 0.998000\n")


def test_linuxcnc_refuses_more_points_than_it_reads():
    table = AxisErrorTable("X", False, np.arange(300.0), np.zeros(300))
    with pytest.raises(DataError, match="at most 256"):
        linuxcnc_text(table)


def _pairs(text):
    return dict(line.split(None, 1) for line in text.strip().splitlines())


def test_twincat_matches_the_documented_example():
    """Beckhoff TF5200 axis compensation, "Example - Non-equidistant bilateral SSFK": setpoints and values in
    0.1 µm; the value is actual − setpoint (programmed 19866.7 µm, measured 19856.5 µm in + and 19874.7 µm in
    − direction give -102 and 80)."""
    setpoints = np.array([-200000, -199306, -198667, -198001])  # 0.1 µm, from the example
    pos = np.array([0, 24, -102, 7])  # the example's first three, one of ours
    neg = np.array([0, 67, 80, -3])
    table = AxisErrorTable("Y", False, setpoints * 1e-4, forward=pos / 10.0, reverse=neg / 10.0)
    got = _pairs(twincat_text(table, axis_number=2, axis_name="Y AXIS"))
    assert got["kopf.achs_nr"] == "2" and got["kopf.log_achs_name"] == "Y AXIS"
    assert got["kw.ssfk.interval"] == "0" and got["kw.ssfk.unit"] == "1" and got["kw.ssfk.bilateral"] == "1"
    assert got["kw.ssfk.kw_startpos"] == "-200000" and got["kw.ssfk.kw_nr_max"] == "4"
    for i, (s, p, n) in enumerate(zip(setpoints, pos, neg)):
        assert got[f"kw.ssfk.table[{i}].setpoint"] == str(s)
        assert got[f"kw.ssfk.table[{i}].pos"] == str(p)
        assert got[f"kw.ssfk.table[{i}].neg"] == str(n)
    # the documented measurement: actual − programmed, in 0.1 µm
    measured = AxisErrorTable("Y", False, [19.8667, 19.9], forward=[19856.5 - 19866.7, 0.0],
                              reverse=[19874.7 - 19866.7, 0.0])
    got = _pairs(twincat_text(measured))
    assert got["kw.ssfk.table[0].pos"] == "-102" and got["kw.ssfk.table[0].neg"] == "80"


def test_twincat_rotary_axis_in_ten_thousandths_of_a_degree():
    table = AxisErrorTable("C", True, [0.0, 90.0], forward=[np.radians(0.0012) * 1e6, 0.0])  # 0.0012° in µrad
    got = _pairs(twincat_text(table))
    assert got["kw.ssfk.table[1].setpoint"] == "900000" and got["kw.ssfk.table[0].pos"] == "12"


def test_axis_table_checks_its_input():
    with pytest.raises(DataError, match="ascending"):
        AxisErrorTable("X", False, [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(DataError, match="finite"):
        AxisErrorTable("X", False, [0.0, 1.0], [0.0, np.nan])


# --- the compensation of a fit, applied independently ---------------------------------------------

TRUTH = {"EX0C": 12.0, "EA0B": -25.0, "EB0C": 30.0, "EZ0B": 8.0, "EY0C": -6.0,
         "EXX:periodic:10": [1.5, -0.8], "EXX:reversal": 3.0, "EYY:poly2": [0.004, -2e-5],
         "ECC:periodic:90": [4.0, 2.0], "EZX:poly1": [0.003]}


@pytest.fixture(scope="module")
def compensated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("comp")
    m = load_machine(urdf_path("five_axis_bc"))
    effects = [parse_effect(n, m) for n in TRUTH]
    theta = np.concatenate([np.atleast_1d(v) for v in TRUTH.values()]).astype(float)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=0.5, rng=np.random.default_rng(3))
    model = list(default_model(m)) + [e for e in effects if e.basis != "constant"]
    result = fit(m, obs, model, noise_um=0.5)
    save_fit(result, folder / "fit.json")
    # LinuxCNC's 256 points cannot follow the 10 mm lead over the 1200 mm travel: refused (below)
    assert main(["compensate", "--fit", str(folder / "fit.json"), "--out", str(folder / "out"), "--all-terms",
                 "--table-range", "travel", "--step-mm", "0.5", "--step-deg", "0.5", "--format", "twincat", "sinumerik"]) == 0
    return folder / "out", result


def axes_nominal(result, axes):
    return evaluate(result.machine, axes, np.zeros(len(result.machine.error_joints)), jacobian=False)


def _model_mm(result, axes, directions):
    from kinid.identification.data.observations import Observations

    m = result.machine
    n = axes.shape[0]
    obs = Observations(tuple("P" * n), np.zeros((n, 3)), axes, None, {k: np.asarray(v, float) for k, v in directions.items()})
    d = design(m, result.effects, obs)
    return evaluate(m, axes, joint_values(m, d, result.theta), jacobian=False)


@pytest.mark.parametrize("on_grid", [True, False])
def test_tables_and_calibrated_urdf_reproduce_the_fit(compensated, on_grid):
    folder, result = compensated
    plain = PlainMachine(folder)
    m = result.machine
    rng = np.random.default_rng(1 if on_grid else 2)
    rows, dirs = [], {"X": []}
    for _ in range(40):
        r = {}
        for a in m.axes:
            if a.name not in plain.tables:  # an axis without compensated errors has no table
                r[a.name] = rng.uniform(-30.0, 30.0)
                continue
            grid = plain.tables[a.name][0]
            k = rng.integers(1, grid.size - 2)
            r[a.name] = grid[k] if on_grid else grid[k] + rng.uniform(0.05, 0.95) * (grid[k + 1] - grid[k])
        rows.append(r)
        dirs["X"].append(rng.choice([-1.0, 1.0]))
    axes = np.array([[r[n] for n in m.axis_names] for r in rows])
    expected = _model_mm(result, axes, dirs)
    got = np.array([plain.tool_in_workpiece_mm(r, {"X": d}) for r, d in zip(rows, dirs["X"])])
    err_um = np.abs(got - expected).max() * 1e3
    print(f"largest difference {err_um:.2e} µm; the errors move the tool by {np.abs(got - axes_nominal(result, axes)).max() * 1e3:.1f} µm")
    assert np.abs(got - axes_nominal(result, axes)).max() * 1e3 > 10  # the test sees the errors at all
    assert err_um <= (0.01 if on_grid else 0.1), err_um


def test_constants_json_and_calibrated_urdf_hold_the_identified_constants(compensated):
    folder, result = compensated
    consts = {c["name"]: c for c in json.loads((folder / "constants.json").read_text())["errors"]}
    i = result.param_names.index("EX0C")
    assert consts["EX0C"]["value"] == pytest.approx(result.values[i]) and consts["EX0C"]["unit"] == "µm"
    assert consts["EX0C"]["std"] == pytest.approx(result.std[i])
    held = [c for c in consts.values() if not c["identified"]]
    assert held and all(c["value"] is None for c in held)
    # kinid's own loader accepts the calibrated machine: error joints kept with zero origins
    cal = load_machine(folder / "calibrated.urdf")
    assert cal.error_codes == result.machine.error_codes


def test_compensation_json_and_controller_files(compensated):
    folder, result = compensated
    info = json.loads((folder / "compensation.json").read_text())
    assert info["tables"]["X"]["range"] == "URDF travel"
    assert info["tables"]["X"]["columns"][:1] == ["EXX_um"] and "EXX_rev_um" in info["tables"]["X"]["columns"]
    assert len(info["fit"]["sha256"]) == 64
    files = {c["file"]: c for c in info["controller_files"]}
    assert files["X_ssfk.lis"]["points"] <= 1500 and files["X_EEC_INI.spf"]["points"] <= 5000


def test_linuxcnc_over_the_travel_is_refused_and_over_the_data_holds_the_reversal(compensated, capsys):
    """LinuxCNC: the 256 points over 1200 mm cannot follow a 10 mm lead — between its points the file would leave
    more error than none inside the measured range, so nothing is written; over the measured readings it follows."""
    folder, result = compensated
    fit_json = folder.parent / "fit.json"
    capsys.readouterr()
    assert main(["compensate", "--fit", str(fit_json), "--out", str(folder.parent / "lcnc_travel"), "--all-terms",
                 "--table-range", "travel", "--step-mm", "0.5", "--format", "linuxcnc"]) == 2
    err = capsys.readouterr().err
    assert "X.comp: applied as the controller applies it, it would leave" in err and " at X = " in err
    assert len(err.strip().splitlines()) == 1 and not (folder.parent / "lcnc_travel").exists()
    folder = folder.parent / "lcnc_data"
    assert main(["compensate", "--fit", str(fit_json), "--out", str(folder), "--all-terms", "--step-mm", "0.5",
                 "--format", "linuxcnc"]) == 0
    files = {c["file"]: c for c in json.loads((folder / "compensation.json").read_text())["controller_files"]}
    assert files["X.comp"]["points"] <= 256
    lines = (folder / "X.comp").read_text().splitlines()
    assert len(lines) == files["X.comp"]["points"]
    nominal, fwd, rev = np.array([l.split() for l in lines], float).T
    # direction − minus direction + is the fitted reversal (3 µm) everywhere
    i = result.param_names.index("EXX:reversal")
    np.testing.assert_allclose((fwd - rev) * 1e3, result.values[i], atol=2e-3)


def test_a_default_format_that_cannot_follow_is_left_out_and_the_others_written(compensated, capsys):
    """Without --format, the format that would leave more error than none (LinuxCNC's 256 points over the travel)
    is left out with a note naming it and why, and the formats that follow are written (it once wrote nothing);
    asked for by name, the same format is refused (the test above)."""
    folder, _ = compensated
    out = folder.parent / "default_travel"
    capsys.readouterr()
    assert main(["compensate", "--fit", str(folder.parent / "fit.json"), "--out", str(out), "--all-terms",
                 "--table-range", "travel", "--step-mm", "0.5"]) == 0
    printed = capsys.readouterr().out
    assert "X.comp: left out — applied as the controller applies it, it would leave" in printed
    assert "more error than none" in printed and "X.comp: the controller's interpolation" not in printed
    assert not (out / "X.comp").exists() and (out / "X_ssfk.lis").exists() and (out / "X_EEC_INI.spf").exists()
    info = json.loads((out / "compensation.json").read_text())
    names = {c["file"] for c in info["controller_files"]}
    assert "X.comp" not in names and {"Y.comp", "X_ssfk.lis", "X_EEC_INI.spf"} <= names
    assert all(c["never_worse"]["left_max"] >= 0 for c in info["controller_files"])


def test_compensate_refuses_bad_input(tmp_path, capsys):
    (tmp_path / "fit.json").write_text("{}")
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(tmp_path / "c")]) == 2
    assert "not a kinid fit" in capsys.readouterr().err
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(tmp_path / "c"), "--step-mm", "0"]) == 2
    assert "--step-mm must be a positive number" in capsys.readouterr().err
