"""A measured orientation read from an instrument export into rows of their own (docs/formats.md, "Measured
orientation"): three residuals per pose, the model's tool orientation against the measured one.

Truth in plain numpy: the arm of examples/ur_like.urdf through ``kinid model``, its tool's pose from
benchmarks/proving_truth.py (no kinid code) with location errors of ~100 µrad / µm and the tool tilted (EA0T, EB0T:
what one target on the tool cannot see: the tilt turns the tool about its own point), the tracker 3 m away and turned
35°, one target, 40 poses, 20 µm of noise on the point and 0.002° on each angle; the angles written as Rx, Ry, Rz of
R = Rx·Ry·Rz (Euler XYZ) in degrees, as a 6-DoF probe's export gives them.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_arm_far_frame as far  # noqa: E402
import proving_truth as truth  # noqa: E402

from kinid.cli import main  # noqa: E402
from kinid.identification.data import read_export  # noqa: E402
from kinid.identification.fitting import check_orientation, fit, orientation_residuals  # noqa: E402

NOISE_MM = 0.020
NOISE_DEG = 0.002
#: The tool's tilt, µrad: 2 mrad, a probe seated off its axis.
TILT_URAD = {"EA0T": 2000.0, "EB0T": -1500.0}


@pytest.fixture(scope="module")
def arm(ur_arm):
    """(URDF path, machine, plain-numpy truth machine, errors {code: µm / µrad})."""
    urdf, machine = ur_arm
    errors = far.far_errors(np.random.default_rng(5), far.arm()[3], distance_mm=3000.0, turn_deg=35.0)
    errors.update(TILT_URAD)
    return urdf, machine, truth.read_urdf(urdf.read_text()), errors


def _xyz_deg(R):
    """Angles (N, 3), deg, of R = Rx(a)·Ry(b)·Rz(c) (plain numpy)."""
    return np.degrees(np.column_stack([np.arctan2(-R[:, 1, 2], R[:, 2, 2]), np.arcsin(np.clip(R[:, 0, 2], -1, 1)),
                                       np.arctan2(-R[:, 0, 1], R[:, 0, 0])]))


def _export(path, machine, tm, errors, n, rng, *, angle_columns=("measurement_rx", "measurement_ry", "measurement_rz"),
            angles=_xyz_deg):
    """An export of ``n`` poses: ';'-separated, decimal commas, joints in rad, the point and its orientation with
    their std. The point is the tool's (its origin, no offset)."""
    q = rng.uniform(-120, 120, (n, len(machine.axes)))
    R, p = truth.tool_pose_mm(tm, {a.joint: q[:, k] for k, a in enumerate(machine.axes)},
                              {c: np.full(n, v) for c, v in errors.items()}, n)
    p = p + rng.normal(0, NOISE_MM, p.shape)
    a = angles(R) + rng.normal(0, NOISE_DEG, (n, 3))
    header = [m.joint for m in machine.axes] + ["measurement_x", "measurement_std_x", "measurement_y",
                                                 "measurement_std_y", "measurement_z", "measurement_std_z"]
    header += [c for col in angle_columns for c in (col, col.replace("measurement_", "measurement_std_"))]
    lines = [";".join(header)]
    for i in range(n):
        cells = list(np.radians(q[i])) + [v for c in range(3) for v in (p[i, c], NOISE_MM)]
        cells += [v for c in range(3) for v in (a[i, c], NOISE_DEG)]
        lines.append(";".join(f"{v:.9g}".replace(".", ",") for v in cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def test_orientation_rows_recover_the_tool_tilt_one_target_cannot_see(arm, tmp_path):
    """One target: the points alone hold EA0T and EB0T (the tilt turns the tool about its point); with the
    orientation rows both are identified, within 3σ of the truth, and their σ is well below the tilt; the
    orientation residuals' RMS is near the stated σ (0.002° per angle, 34.9 µrad), the points' near 20 µm, so the
    weighted ratio of the two is near 1."""
    urdf, machine, tm, errors = arm
    path = _export(tmp_path / "six_dof.csv", machine, tm, errors, 40, np.random.default_rng(3))
    points = read_export(path, machine, orientation="off")
    turned = read_export(path, machine)
    assert not points.observations.rotation_rows.any()
    assert turned.observations.rotation_rows.sum() == 40 and len(turned.observations) == 80
    assert check_orientation(machine, turned).ok
    plain = fit(machine, points.observations)
    both = fit(machine, turned.observations)
    for code, true in TILT_URAD.items():
        i = plain.param_names.index(code)
        assert not plain.identifiable[i], code
        assert both.identifiable[i], code
        assert abs(both.values[i] - true) < 3 * both.std[i], (code, both.values[i], both.std[i])
        assert both.std[i] < 0.1 * abs(true), (code, both.std[i])
    rows = turned.observations.rotation_rows
    weight = turned.observations.rotation_um_per_urad[rows][:, None]
    rot_rms_urad = float(np.sqrt(np.mean((both.residuals_um[rows] / weight) ** 2)))
    stated_urad = np.radians(NOISE_DEG) * 1e6
    assert 0.5 * stated_urad < rot_rms_urad < 1.5 * stated_urad, rot_rms_urad
    pos_rms_um = float(np.sqrt(np.mean(both.residuals_um[~rows] ** 2)))
    assert 0.5 * NOISE_MM * 1e3 < pos_rms_um < 1.5 * NOISE_MM * 1e3, pos_rms_um
    check = orientation_residuals(turned.observations, both.residuals_um)  # the weights hold: ratio near 1
    assert abs(check.rms_urad - rot_rms_urad) < 1e-9 and 1 / 1.5 < check.ratio < 1.5, check.line


def test_a_wrong_convention_or_unit_or_mount_is_named(arm, tmp_path):
    """The angles read as extrinsic xyz, or as radians, or the body turned 90° on the tool: the check refuses them
    (tens of degrees), names the reading that fits; ``kinid identify`` says it in one line, exit status 2."""
    urdf, machine, tm, errors = arm
    path = _export(tmp_path / "six_dof.csv", machine, tm, errors, 40, np.random.default_rng(4))
    wrong = check_orientation(machine, read_export(path, machine, orientation="xyz"))
    assert not wrong.ok and wrong.rms_deg > 5, wrong.line
    assert "read as Euler XYZ it is" in wrong.line, wrong.line
    mount = check_orientation(machine, read_export(path, machine, orientation_mount_deg=(0, 0, 90)))
    assert not mount.ok and mount.spread_deg < 0.1, mount.line
    assert abs(mount.mount_deg[2]) < 0.5 and "give that mount" in mount.line, mount.line
    rad = tmp_path / "six_dof_rad.csv"
    _export(rad, machine, tm, errors, 40, np.random.default_rng(4), angles=lambda R: np.radians(_xyz_deg(R)))
    as_rad = check_orientation(machine, read_export(rad, machine))
    assert not as_rad.ok and "(the angles in radians)" in as_rad.line, as_rad.line


def test_identify_refuses_a_wrong_convention_in_one_line(arm, tmp_path, capsys):
    urdf, machine, tm, errors = arm
    path = _export(tmp_path / "six_dof.csv", machine, tm, errors, 40, np.random.default_rng(6))
    code = main(["identify", "--machine", str(urdf), "--data", str(path), "--orientation", "zyx",
                 "--out", str(tmp_path / "fit.json")])
    err = capsys.readouterr().err
    assert code == 2
    assert "read as Euler XYZ it is" in err and "Traceback" not in err
    assert not (tmp_path / "fit.json").exists()


def test_orientation_without_std_is_left_out_with_a_note(arm, tmp_path):
    """Angle columns with no std and no σ given: the points only, the note says why."""
    urdf, machine, tm, errors = arm
    path = _export(tmp_path / "six_dof.csv", machine, tm, errors, 10, np.random.default_rng(8))
    text = path.read_text().splitlines()
    header = text[0].split(";")
    keep = [k for k, h in enumerate(header) if "std_r" not in h]
    path.write_text("\n".join(";".join(line.split(";")[k] for k in keep) for line in text) + "\n")
    export = read_export(path, machine)
    assert not export.observations.rotation_rows.any() and len(export.observations) == 10
    assert any("orientation not used" in line and "--orientation-std-urad" in line for line in export.notes())
    given = read_export(path, machine, orientation_std_urad=35.0)
    assert given.observations.rotation_rows.sum() == 10


def test_the_example_file_is_drawn_from_this_truth(arm, tmp_path):
    """examples/tracker_6dof.csv (docs/formats.md's example) is this module's export of 60 poses, seed 3."""
    urdf, machine, tm, errors = arm
    path = _export(tmp_path / "six_dof.csv", machine, tm, errors, 60, np.random.default_rng(3))
    drawn, shipped = (p.read_text().splitlines() for p in (path, ROOT / "examples" / "tracker_6dof.csv"))
    assert drawn[0] == shipped[0] and len(drawn) == len(shipped) == 61

    def numbers(lines):
        return np.array([[float(c.replace(",", ".")) for c in line.split(";")] for line in lines[1:]])

    np.testing.assert_allclose(numbers(drawn), numbers(shipped), rtol=1e-8, atol=1e-9)


def _turned_30(R):
    """The angles of a body mounted turned 30° about the tool's z (R_measured = R_tool · Rz(30°))."""
    c, s = np.cos(np.radians(30.0)), np.sin(np.radians(30.0))
    return _xyz_deg(R @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))


def test_a_mount_not_given_is_taken_from_the_data_and_said(arm, tmp_path, capsys):
    """The probe sits turned 30° on the tool and no mount is given: one turn on the tool explains the angles, so
    ``identify`` takes it from the data (it is set-up, as the measurement frame is), says so with the caveat that
    the tool's tilt is then carried by the mount, and fits; given explicitly wrong (0 0 0), it is refused in one line."""
    urdf, machine, tm, errors = arm
    path = _export(tmp_path / "six_dof.csv", machine, tm, errors, 40, np.random.default_rng(9), angles=_turned_30)
    code = main(["identify", "--machine", str(urdf), "--data", str(path), "--out", str(tmp_path / "fit.json")])
    err = capsys.readouterr().err
    assert code == 0, err
    line = next(s for s in err.splitlines() if "mount on the tool taken from the data" in s)
    mount = [float(v) for v in line.split("data: ")[1].split("°")[0].split()]
    assert abs(mount[2] - 30.0) < 0.5 and abs(mount[0]) < 0.5 and abs(mount[1]) < 0.5, line
    assert "carried by the mount" in line
    code = main(["identify", "--machine", str(urdf), "--data", str(path), "--orientation-mount-deg", "0", "0", "0",
                 "--out", str(tmp_path / "fit0.json")])
    err = capsys.readouterr().err
    assert code == 2 and "give that mount" in err and "Traceback" not in err, err
    assert not (tmp_path / "fit0.json").exists()
