"""``kinid model``: an existing URDF -> an identification machine with the source's kinematics.

Checked by an independent consumer: the source URDF's forward kinematics computed in plain numpy from its
XML (benchmarks/proving_truth.py, no kinid or Pinocchio code) against kinid's evaluation of the converted
machine with every error joint at zero.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification.model.machine import evaluate, load_machine, machine_from_urdf
from kinid.identification.model.urdf_import import identification_urdf
from kinid.urdf import path as urdf_path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import proving_truth as truth  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
ARM = ROOT / "examples" / "ur_like.urdf"


def _source_point_mm(text, q, tool, workpiece, offset_m, n):
    tm = truth.read_urdf(text)
    values = truth.joint_values(tm, q, {})
    R, p = truth._pose(tm, tool, values, n)
    Rw, pw = truth._pose(tm, workpiece, values, n)
    return np.einsum("nji,nj->ni", Rw, p + R @ np.asarray(offset_m) - pw) * 1e3


def _converted_point_mm(machine, q, n):
    axes = np.column_stack([q[a.joint] for a in machine.axes])
    return evaluate(machine, axes, np.zeros((n, len(machine.error_joints))), jacobian=False)


def test_a_ros_arm_keeps_its_kinematics_with_the_error_joints_at_zero():
    text = ARM.read_text()
    offset = (0.01, -0.02, 0.08)
    machine = machine_from_urdf(identification_urdf(text, base="world", tool="wrist_3_link", tool_offset_m=offset), "arm")
    assert [a.name for a in machine.axes] == ["J1", "J2", "J3", "J4", "J5", "J6"]
    assert machine.axes[0].joint == "shoulder_pan_joint"  # the source's names are kept
    assert {f"E{d}0J{k}" for d in "XYZABC" for k in range(1, 7)} <= {e.code for e in machine.error_joints}
    rng = np.random.default_rng(0)
    q = {a.joint: rng.uniform(-170, 170, 50) for a in machine.axes}
    diff = _converted_point_mm(machine, q, 50) - _source_point_mm(text, q, "wrist_3_link", "world", offset, 50)
    print(f"largest difference {np.abs(diff).max():.2e} mm over 50 random poses")
    assert np.abs(diff).max() < 1e-9


@pytest.mark.parametrize("layout", ["five_axis_bc", "five_axis_ac", "five_axis_bhead_c", "gantry_dual_y"])
def test_the_shipped_machines_keep_their_kinematics(layout):
    text = Path(urdf_path(layout)).read_text()
    machine = machine_from_urdf(identification_urdf(text, workpiece="workpiece", tool="tool"), layout)
    source = load_machine(urdf_path(layout))
    assert sorted(a.name for a in machine.axes) == sorted(a.name for a in source.axes)
    rng = np.random.default_rng(1)
    q = {a.name: rng.uniform(-60, 60, 40) for a in source.axes}
    diff = _converted_point_mm(machine, q, 40) - _source_point_mm(text, q, "tool", "workpiece", (0, 0, 0), 40)
    assert np.abs(diff).max() < 1e-9


def test_kinid_model_writes_a_machine_plain_pinocchio_loads(tmp_path, capsys):
    import pinocchio as pin

    out = tmp_path / "arm.urdf"
    assert main(["model", "--urdf", str(ARM), "--base", "world", "--tool", "wrist_3_link", "--tool-offset-mm", "10",
                 "-20", "80", "--out", str(out)]) == 0
    assert "J1 (shoulder_pan_joint)" in capsys.readouterr().out
    model = pin.buildModelFromXML(out.read_text())
    assert model.nq >= 6 + 48
    for argv, message in ((["--tool", "no_such_link"], "no link 'no_such_link'"),
                          (["--base", "wrist_3_link", "--tool", "world"], "is not below link"),
                          (["--tool", "wrist_3_link", "--tool-offset-mm", "1e300", "0", "0"], "--tool-offset-mm")):
        bad = tmp_path / "bad.urdf"
        assert main(["model", "--urdf", str(ARM), *argv, "--out", str(bad)]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1
        assert not bad.exists()


def test_position_dependent_joints_on_request_keep_the_kinematics():
    text = ARM.read_text()
    machine = machine_from_urdf(identification_urdf(text, base="world", tool="wrist_3_link", position_errors=True), "arm")
    codes = {e.code for e in machine.error_joints}
    assert {f"E{d}J3" for d in "XYZABC"} <= codes and {f"E{d}0J3" for d in "XYZABC"} <= codes
    rng = np.random.default_rng(2)
    q = {a.joint: rng.uniform(-170, 170, 20) for a in machine.axes}
    diff = _converted_point_mm(machine, q, 20) - _source_point_mm(text, q, "wrist_3_link", "world", (0, 0, 0), 20)
    assert np.abs(diff).max() < 1e-9
