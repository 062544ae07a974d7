"""Instrument exports read as they arrive (identification/data/exports.py, docs/formats.md "Instrument exports").

Truth in plain numpy: the ROS-style arm of examples/ur_like.urdf through ``kinid model``, its measured points by
benchmarks/proving_truth.py (no kinid code) as benchmarks/bench_arm_far_frame.py draws them — the frame 1-5 m
away and turned 10-60° — written the way a tracker or a motion-capture system exports them: semicolons and
decimal commas, metres and radians, the columns named as the URDF's joints.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_arm_far_frame as far  # noqa: E402
import proving_truth as truth  # noqa: E402

from kinid.cli import main  # noqa: E402
from kinid.errors import DataError  # noqa: E402
from kinid.identification.data import read_export, read_observations  # noqa: E402
from kinid.identification.fitting import design, load_fit, residuals  # noqa: E402

JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint")


@pytest.fixture(scope="module")
def arm(tmp_path_factory, ur_arm):
    """(folder, URDF path, machine, plain-numpy truth machine, names the fit identifies) of the arm."""
    d = tmp_path_factory.mktemp("export_arm")
    urdf, machine = ur_arm
    assert [a.joint for a in machine.axes] == list(JOINTS)  # the short names J1..J6 stand for these
    return d, urdf, machine, truth.read_urdf(urdf.read_text()), far.arm()[3]


def _decimal_comma(v):
    return f"{v:.12g}".replace(".", ",")


def _tracker_file(path, obs, *, extra=True):
    """``obs`` as a tracker exports it: ';', decimal commas, joints in rad under the URDF's names, the point in mm
    with its std, columns kinid does not read (a time stamp, the goal, the temperature)."""
    header = ["Timestamp", "Goal x", *JOINTS, "measurement_temperature", "measurement_x", "measurement_std_x",
              "measurement_y", "measurement_std_y", "measurement_z", "measurement_std_z"]
    lines = [";".join(header)]
    q_rad = np.radians(obs.axes)
    for i in range(len(obs)):
        cells = [2.02011e13, 0.4, *q_rad[i], 21.8675, obs.w_mm[i, 0], 0.03, obs.w_mm[i, 1], 0.01, obs.w_mm[i, 2], 0.004]
        lines.append(";".join(_decimal_comma(v) for v in cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_tracker_export_with_decimal_commas_is_read_as_the_observations_it_holds(arm):
    d, _, machine, tm, free = arm
    train, _, _, _ = far.draw(machine, tm, free, 2, n_train=12)
    export = read_export(_tracker_file(d / "small.csv", train), machine)
    obs = export.observations
    assert export.delimiter == ";" and export.decimal_comma
    assert np.allclose(obs.w_mm, train.w_mm, atol=1e-8) and np.allclose(obs.axes, train.axes, atol=1e-8)
    assert obs.lines == tuple(range(2, 14)) and set(obs.marks) == {"T1"}
    assert [(c, a, u) for c, a, u in export.axes] == [(j, f"J{k}", "rad") for k, j in enumerate(JOINTS, 1)]
    assert export.std_columns == ("measurement_std_x", "measurement_std_y", "measurement_std_z")
    assert export.ignored == ("Timestamp", "Goal x", "measurement_temperature")
    notes = "\n".join(export.notes())
    assert "shoulder_pan_joint [rad] -> J1" in notes and "not used as weights" in notes and "ignored: Timestamp" in notes


def test_identify_reads_a_tracker_export_as_it_is_and_recovers_the_truth(arm, capsys):
    d, urdf, machine, tm, free = arm
    train, test, errors, _ = far.draw(machine, tm, free, 5, n_train=60)
    data = _tracker_file(d / "tracker.csv", train)
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--out", str(d / "fit.json")]) == 0
    err = capsys.readouterr().err
    assert "';'-separated with decimal commas, 60 rows" in err and "elbow_joint [rad] -> J3" in err
    result = load_fit(d / "fit.json")
    assert result.success
    values = dict(zip(result.param_names, result.values))
    std = dict(zip(result.param_names, result.std))
    held = [n for n, ok in zip(result.param_names, result.identifiable) if ok]
    assert held and all(abs(values[n] - errors.get(n, 0.0)) <= far.WITHIN_STD * std[n] for n in held)
    r = residuals(machine, design(machine, result.effects, test), test, result.theta, jacobian=False)
    assert np.sqrt(np.mean(np.sum(r**2, axis=1))) / 1e3 < 1.0  # held-out 3-D RMS, mm (noise 0.05-0.3 mm)


def test_diagnose_reads_the_export_the_fit_was_made_from(arm, capsys):
    """diagnose takes the same export as identify (its mapping printed), and with the model right finds noise."""
    d, urdf, machine, tm, free = arm
    train, _, _, _ = far.draw(machine, tm, free, 5, n_train=60)
    data = _tracker_file(d / "tracker_d.csv", train)
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--out", str(d / "fit_d.json")]) == 0
    capsys.readouterr()
    assert main(["diagnose", "--fit", str(d / "fit_d.json"), "--data", str(data), "--json"]) == 0
    out, err = capsys.readouterr()
    assert "elbow_joint [rad] -> J3" in err
    import json

    assert json.loads(out)["verdict"] == "noise"


def test_several_targets_per_pose_in_metres_are_rows_of_their_own_and_verify_asks_for_one(arm, capsys):
    d, urdf, machine, tm, free = arm
    train, _, _, _ = far.draw(machine, tm, free, 3, n_train=8)
    second = train.w_mm + [10.0, -20.0, 5.0]
    header = ["frame", *JOINTS, "x1", "y1", "z1", "x2", "y2", "z2", "rx1"]
    rows = [",".join(header)]
    for i in range(len(train)):
        cells = [i, *np.radians(train.axes[i]), *(train.w_mm[i] / 1e3), *(second[i] / 1e3), 0.1]
        rows.append(",".join(f"{v:.12g}" for v in cells))
    path = d / "mocap.csv"
    path.write_text("\n".join(rows) + "\n")
    export = read_export(path, machine)
    obs = export.observations
    assert len(obs) == 16 and obs.marks[:4] == ("T1", "T2", "T1", "T2") and not export.decimal_comma
    assert np.allclose(obs.w_mm[1::2], second, atol=1e-8) and np.allclose(obs.axes[::2], train.axes, atol=1e-8)
    assert export.ignored == ("frame", "rx1")
    # identify fits several targets together (tests/test_several_targets.py); a verb that reads one asks for it
    from argparse import Namespace

    from kinid.identification.commands.data_input import read_data

    args = Namespace(allow_outside_limits=False, point=None, point_unit=None, joint_unit=None, target=None)
    with pytest.raises(DataError, match=r"2 targets per pose \(T1, T2\): choose one with --target T1"):
        read_data(path, machine, args)
    capsys.readouterr()


def test_a_point_named_by_option_in_its_unit_and_joints_in_degrees(arm):
    d, _, machine, tm, free = arm
    train, _, _, _ = far.draw(machine, tm, free, 4, n_train=6)
    rows = ["\t".join(["px", "py", "pz", *JOINTS])]
    rows += ["\t".join(_decimal_comma(v) for v in (*(train.w_mm[i] / 1e3), *train.axes[i])) for i in range(6)]
    path = d / "tabs.txt"
    path.write_text("\n".join(rows) + "\n")
    export = read_export(path, machine, point={"x": "px", "y": "py", "z": "pz"}, point_unit="m", joint_unit="deg")
    assert export.delimiter == "\t"
    assert np.allclose(export.observations.w_mm, train.w_mm, atol=1e-8)
    assert np.allclose(export.observations.axes, train.axes, atol=1e-8)
    with pytest.raises(DataError, match=r"the unit of px, py, pz is not in their names: add --point-unit"):
        read_export(path, machine, point={"x": "px", "y": "py", "z": "pz"})


def test_kinid_own_observation_csv_is_still_read_by_identify(arm, capsys):
    d, urdf, machine, tm, free = arm
    train, _, _, _ = far.draw(machine, tm, free, 6, n_train=40)
    from kinid.identification.data import write_observations

    write_observations(d / "own.csv", train, machine)
    assert read_observations(d / "own.csv", machine).w_mm.shape == (40, 3)
    assert main(["identify", "--machine", str(urdf), "--data", str(d / "own.csv"), "--point-unit", "mm",
                 "--out", str(d / "own.json")]) == 2
    assert "--point-unit is for an instrument export" in capsys.readouterr().err


BAD = [
    # (what is changed in the good file, the one line expected)
    (None, None),  # a cell that is not a number, written in the test
    (lambda lines: lines[:4] + [lines[4].rsplit(";", 1)[0]] + lines[5:], r":5: 14 cells, the header has 15"),
    (lambda lines: [lines[0].replace("elbow_joint", "elbow")] + lines[1:],
     r":1: no column for elbow_joint or J3"),
    (lambda lines: [lines[0].replace("measurement_x", "meas_x")] + lines[1:], r":1: no measured-point columns"),
    (lambda lines: [lines[0].replace("wrist_1_joint", "wrist_1_joint_mm")] + lines[1:],
     r":1, column 'wrist_1_joint_mm': axis J4 \(wrist_1_joint\) is revolute"),
    (lambda lines: lines[:1], r":1: no data rows after the header"),
]


@pytest.mark.parametrize("case", range(len(BAD)))
def test_bad_input_is_one_line_naming_file_line_and_column(arm, capsys, case):
    d, urdf, machine, tm, free = arm
    train, _, _, _ = far.draw(machine, tm, free, 2, n_train=6)
    good = _tracker_file(d / f"good{case}.csv", train).read_text().splitlines()
    change, expected = BAD[case]
    bad = d / f"bad{case}.csv"
    if expected is None:  # a cell that is not a number: line 4, the shoulder_lift_joint column
        cells = good[3].split(";")
        cells[JOINTS.index("shoulder_lift_joint") + 2] = "1,2,3"
        bad.write_text("\n".join(good[:3] + [";".join(cells)] + good[4:]) + "\n")
        expected = r":4, column 'shoulder_lift_joint': '1,2,3' is not a finite number"
    else:
        bad.write_text("\n".join(change(good)) + "\n")
    before = bad.read_bytes()
    assert main(["identify", "--machine", str(urdf), "--data", str(bad), "--out", str(d / "bad.json")]) == 2
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(lines) == 1 and str(bad) in lines[0], lines
    assert re.search(expected, lines[0]), lines[0]
    assert bad.read_bytes() == before and not (d / "bad.json").exists()


def test_kinid_own_csv_with_a_misspelt_column_is_named_by_its_own_reader(arm, capsys):
    d, urdf, *_ = arm
    path = d / "typo.csv"
    path.write_text("mark,wx_m,wy_mm,wz_mm,j1_deg,j2_deg,j3_deg,j4_deg,j5_deg,j6_deg\n"
                    "P1,1,2,3,0,0,0,0,0,0\nP2,1,2,3,1,0,0,0,0,0\n")
    assert main(["identify", "--machine", str(urdf), "--data", str(path), "--out", str(d / "typo.json")]) == 2
    assert "typo.csv:1: missing column 'wx_mm'" in capsys.readouterr().err


def test_plan_augment_reads_the_export_keeps_to_its_span_and_plans_for_the_fit_sigma(arm, capsys):
    """identify's next command carries the export's options; plan --augment reads the export as identify did,
    draws the candidates within the span the data read (not the URDF's travel) and plans for the fit's σ."""
    d, urdf, machine, tm, free = arm
    train, _, _, noise_mm = far.draw(machine, tm, free, 7, n_train=40, span_deg=60.0)
    data = _tracker_file(d / "tracker_a.csv", train)
    fit = d / "fit_a.json"
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--point-unit", "mm", "--target-um", "1",
                 "--out", str(fit)]) == 0
    out = capsys.readouterr().out
    said = [line for line in out.splitlines() if line.startswith("tool point: U")]
    assert len(said) == 1 and "above the target 1 µm" in said[0], out
    command = said[0].split("plan the alignments to add: ")[1].split()
    assert command[:6] == ["kinid", "plan", "--augment", str(fit), "--data", str(data)] and "--point-unit" in command
    u_um = float(said[0].split("U = ")[1].split()[0])
    command[command.index("--target-um") + 1] = f"{0.8 * u_um:.4g}"
    command[command.index("--out") + 1] = str(d / "more.csv")
    assert main(command[1:]) == 0
    out, err = capsys.readouterr()
    assert "elbow_joint [rad] -> J3" in err and "added alignments written to" in out, out + err
    sigma_um = load_fit(fit).noise_um
    assert abs(sigma_um / (noise_mm * 1e3) - 1.0) < 0.35  # the fit's σ is the data's noise …
    assert f"planned for the fit's σ = {sigma_um:.3g} µm" in out  # … and the plan is made for it, not for 1 µm
    added = read_observations(d / "more.csv", machine, optional_axes=())
    assert len(added) > 0
    lo, hi = np.nanmin(train.axes, axis=0), np.nanmax(train.axes, axis=0)
    assert np.all(added.axes >= lo - 1e-6) and np.all(added.axes <= hi + 1e-6)  # within the span the data read
    assert "within the span the measured data read on J1, J2, J3, J4, J5, J6" in out


@pytest.mark.parametrize("body, own", [
    (b"# a comment\n\nmark,wx_mm,wy_mm,wz_mm,x_mm\nM1,0,0,0,1\n", True),
    (b"\r\n# CR LF\r\nmark,wx_mm\r\n", True),
    (b"\xef\xbb\xbfmark,wx_mm\n", True),  # a byte-order mark: read as read_limited_text reads it
    ("x_m;y_m;z_m;note\n1;2;3;\u00b5m\n".encode(), False),  # UTF-8 past the header: an export
    (b"x_m,y_m,z_m\n1,2,3\n\xff\n", True),  # not UTF-8: kinid's reader names the byte
    (b"", True),
])
def test_is_observation_csv_judges_the_header_and_counts_an_unreadable_file_as_kinids(tmp_path, body, own):
    from kinid.identification.data import is_observation_csv

    path = tmp_path / "data.csv"
    path.write_bytes(body)
    assert is_observation_csv(path) is own
