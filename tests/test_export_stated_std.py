"""An instrument export on every verb that reads alignments (verify, predict), and its stated standard deviations
checked against the fit's residuals (identification/commands/data_input.py, identification/diagnosis/stated_std.py).

Truth in plain numpy: the arm of examples/ur_like.urdf and its measured points from benchmarks/proving_truth.py (no
kinid code) as benchmarks/bench_arm_far_frame.py draws them; the noise of each row is drawn here with a σ of its own,
and the export states that σ, a third of it, or σ of another row.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_arm_far_frame as far  # noqa: E402
import proving_truth as truth  # noqa: E402

from kinid.cli import main  # noqa: E402
from kinid.identification.data import read_export, write_observations  # noqa: E402
from kinid.identification.diagnosis import check_stated_std  # noqa: E402
from kinid.identification.fitting import load_fit  # noqa: E402

JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint",
          "wrist_3_joint")


@pytest.fixture(scope="module")
def arm(tmp_path_factory, ur_arm):
    """(folder, URDF path, machine, plain-numpy truth machine, names the fit identifies) of the arm."""
    d = tmp_path_factory.mktemp("stated_std_arm")
    urdf, machine = ur_arm
    return d, urdf, machine, truth.read_urdf(urdf.read_text()), far.arm()[3]


def _export(path, obs, std_mm):
    """``obs`` as a tracker exports it (';', decimal commas, joints in rad, the point in mm), each coordinate's
    stated std ``std_mm`` (N, 3) beside it."""
    header = ["Timestamp", *JOINTS, "measurement_x", "measurement_std_x", "measurement_y", "measurement_std_y",
              "measurement_z", "measurement_std_z"]
    lines = [";".join(header)]
    for i in range(len(obs)):
        w, s = obs.w_mm[i], std_mm[i]
        cells = [2.02011e13 + i, *np.radians(obs.axes[i]), w[0], s[0], w[1], s[1], w[2], s[2]]
        lines.append(";".join(f"{v:.12g}".replace(".", ",") for v in cells))
    path.write_text("\n".join(lines) + "\n")
    return path


def _noisy(machine, tm, free, seed, n):
    """(noise-free observations of ``n`` poses, the σ mm of each row and coordinate, the noisy observations)."""
    from dataclasses import replace

    _, clean, _, _ = far.draw(machine, tm, free, seed, n_train=2, n_test=n)
    rng = np.random.default_rng(seed + 100)
    sigma_mm = rng.uniform(0.02, 0.2, (n, 3))  # 10× from the quietest coordinate to the noisiest
    return clean, sigma_mm, replace(clean, w_mm=clean.w_mm + sigma_mm * rng.normal(size=(n, 3)))


# ---- the check on plain residuals ------------------------------------------------------------------------------

def _residuals(sigma_um, rng):
    return sigma_um * rng.normal(size=sigma_um.shape)


def test_stated_std_that_are_right_agree_and_track():
    rng = np.random.default_rng(1)
    sigma = rng.uniform(5.0, 50.0, (400, 3))
    check = check_stated_std(_residuals(sigma, rng), sigma, dof=1200)
    assert check.agree and check.tracks and abs(check.ratio - 1.0) < 0.1
    assert [b[1] for b in check.bins] == sorted(b[1] for b in check.bins)  # the thirds scatter more and more
    assert "agree with the residuals: RMS of residual/std 1." in check.line
    assert "rows with larger stated std scatter more" in check.line


def test_stated_std_three_times_too_small_are_named_so():
    rng = np.random.default_rng(2)
    sigma = rng.uniform(5.0, 50.0, (400, 3))
    check = check_stated_std(_residuals(sigma, rng), sigma / 3, dof=1200)
    assert not check.agree and check.tracks and 2.7 < check.ratio < 3.3
    assert "× smaller than the residuals show" in check.line and "not from them" in check.line
    assert check.line.split("are ")[1].startswith(("2.9×", "3×", "3.1×")), check.line


def test_stated_std_unrelated_to_the_residuals_are_uninformative():
    rng = np.random.default_rng(3)
    sigma = rng.uniform(5.0, 50.0, (400, 3))
    stated = rng.permutation(sigma.ravel()).reshape(sigma.shape)  # right sizes, wrong rows
    check = check_stated_std(_residuals(sigma, rng), stated, dof=1200)
    assert check.tracks is False
    assert "do not follow the residuals: rows with larger stated std scatter no more" in check.line


def test_the_dof_the_fit_took_are_given_back():
    """A fit's residuals are smaller than the noise by sqrt(dof / 3N): the check scales them back."""
    rng = np.random.default_rng(4)
    sigma = np.full((300, 3), 10.0)
    r = _residuals(sigma, rng) * np.sqrt(0.5)  # as if half the degrees of freedom were taken
    check = check_stated_std(r, sigma, dof=450)
    assert abs(check.ratio - 1.0) < 0.1 and check.tracks is None  # one std for all: nothing to track


# ---- identify: the line printed and recorded in the fit --------------------------------------------------------

CASES = {"right": (1.0, "agree with the residuals"), "too small": (1 / 3, "× smaller than the residuals show"),
         "uninformative": (None, "do not follow the residuals")}


@pytest.mark.parametrize("case", sorted(CASES))
def test_identify_checks_the_exports_stated_std_against_its_residuals(arm, capsys, case):
    d, urdf, machine, tm, free = arm
    _, sigma_mm, noisy = _noisy(machine, tm, free, 7, 120)
    factor, said = CASES[case]
    stated = sigma_mm * factor if factor else np.random.default_rng(9).permutation(sigma_mm.ravel()).reshape(-1, 3)
    data = _export(d / f"std_{case.replace(' ', '_')}.csv", noisy, stated)
    out = d / f"std_{case.replace(' ', '_')}.json"
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--no-robust", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    recorded = load_fit(out).stated_std
    assert said in recorded["line"] and recorded["line"] in printed
    assert json.loads(out.read_text())["stated_std"]["line"] == recorded["line"]
    assert recorded["tracks"] is (case != "uninformative")
    if factor:
        assert abs(recorded["ratio"] * factor - 1.0) < 0.2  # the residuals say σ, whatever the file states


def test_a_fit_of_kinid_own_csv_records_no_stated_std(arm):
    d, urdf, machine, tm, free = arm
    _, _, noisy = _noisy(machine, tm, free, 7, 60)
    write_observations(d / "own_std.csv", noisy, machine)
    assert main(["identify", "--machine", str(urdf), "--data", str(d / "own_std.csv"), "--out",
                 str(d / "own_std.json")]) == 0
    assert load_fit(d / "own_std.json").stated_std == {}


def test_a_negative_stated_std_is_one_line_naming_line_and_column(arm):
    from kinid.errors import DataError

    d, _, machine, tm, free = arm
    _, sigma_mm, noisy = _noisy(machine, tm, free, 7, 6)
    sigma_mm[3, 1] = -0.01
    with pytest.raises(DataError, match=r":5, column 'measurement_std_y': a standard deviation cannot be negative"):
        read_export(_export(d / "negative.csv", noisy, sigma_mm), machine)


def test_the_std_of_several_targets_in_metres_are_read_in_mm_and_kept_with_their_target(arm):
    d, _, machine, tm, free = arm
    _, sigma_mm, noisy = _noisy(machine, tm, free, 8, 5)
    header = ["frame", *JOINTS, "x1", "y1", "z1", "x1_std", "y1_std", "z1_std", "x2", "y2", "z2", "x2_std",
              "y2_std", "z2_std"]
    rows = [",".join(header)]
    for i in range(5):
        cells = [i, *np.radians(noisy.axes[i]), *(noisy.w_mm[i] / 1e3), *(sigma_mm[i] / 1e3),
                 *((noisy.w_mm[i] + 10.0) / 1e3), *(2 * sigma_mm[i] / 1e3)]
        rows.append(",".join(f"{v:.12g}" for v in cells))
    path = d / "mocap_std.csv"
    path.write_text("\n".join(rows) + "\n")
    export = read_export(path, machine)
    assert export.observations.marks[:2] == ("T1", "T2")
    assert np.allclose(export.std_mm[0::2], sigma_mm, rtol=1e-9) and np.allclose(export.std_mm[1::2], 2 * sigma_mm)
    assert export.std_columns == ("x1_std", "y1_std", "z1_std", "x2_std", "y2_std", "z2_std")


# ---- verify and predict on an export -----------------------------------------------------------------------------

def test_verify_on_an_export_gives_what_verify_on_the_same_rows_as_kinid_csv_gives(arm, capsys):
    d, urdf, machine, tm, free = arm
    _, sigma_mm, first = _noisy(machine, tm, free, 11, 80)
    _, _, second = _noisy(machine, tm, free, 12, 60)
    assert main(["identify", "--machine", str(urdf), "--data", str(_export(d / "first.csv", first, sigma_mm)),
                 "--out", str(d / "first.json")]) == 0
    export = _export(d / "second.csv", second, sigma_mm[:60])
    own = d / "second_own.csv"
    write_observations(own, read_export(export, machine).observations, machine)
    capsys.readouterr()
    assert main(["verify", "--fit", str(d / "first.json"), "--data", str(export), "--json"]) == 0
    from_export, err = capsys.readouterr()
    assert "shoulder_pan_joint [rad] -> J1" in err  # the mapping, as identify prints it
    assert main(["verify", "--fit", str(d / "first.json"), "--data", str(own), "--json"]) == 0
    from_own = capsys.readouterr().out
    a, b = json.loads(from_export), json.loads(from_own)
    assert a["n_observations"] == 60 and a["remaining_verdict"] == b["remaining_verdict"]
    assert a["at_noise_level"] == b["at_noise_level"]
    for key in ("before_um", "after_um"):
        assert all(abs(a[key][c] - b[key][c]) <= 1e-6 * max(1.0, abs(b[key][c])) for c in b[key]), (key, a, b)
    # --before an export too, the same options for both files
    assert main(["verify", "--fit", str(d / "first.json"), "--data", str(export), "--before",
                 str(d / "first.csv"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["before_source"] != a["before_source"]


def test_verify_refuses_an_export_option_for_kinid_csv_and_names_an_export_error_in_one_line(arm, capsys):
    d, urdf, machine, tm, free = arm
    _, sigma_mm, first = _noisy(machine, tm, free, 13, 40)
    assert main(["identify", "--machine", str(urdf), "--data", str(_export(d / "v.csv", first, sigma_mm)),
                 "--out", str(d / "v.json")]) == 0
    write_observations(d / "v_own.csv", first, machine)
    capsys.readouterr()
    assert main(["verify", "--fit", str(d / "v.json"), "--data", str(d / "v_own.csv"), "--point-unit", "m"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--point-unit is for an instrument export" in err[0]
    bad = d / "v_bad.csv"
    bad.write_text((d / "v.csv").read_text().replace("elbow_joint", "elbow"))
    assert main(["verify", "--fit", str(d / "v.json"), "--data", str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "v_bad.csv:1: no column for elbow_joint or J3" in err[0]


def test_predict_refuses_an_export_with_one_line_saying_why(arm, capsys):
    d, urdf, machine, tm, free = arm
    _, sigma_mm, first = _noisy(machine, tm, free, 13, 40)
    data = _export(d / "p.csv", first, sigma_mm)
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--out", str(d / "p.json")]) == 0
    capsys.readouterr()
    assert main(["predict", "--fit", str(d / "p.json"), "--poses", str(data), "--out", str(d / "pred.csv")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "is an instrument export" in err[0] and "nothing left to solve" in err[0]
    assert not (d / "pred.csv").exists()
