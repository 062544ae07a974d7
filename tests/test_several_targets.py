"""Several targets per pose fitted together: each its own point on the tool (``E?0T:target:<mark>``), the machine's
errors and the measurement frame shared (docs/formats.md, "Instrument exports").

Truth in plain numpy: the arm of examples/ur_like.urdf through ``kinid model``, its flange's pose from
benchmarks/proving_truth.py (no kinid code) with location errors of ~100 µm (those one target identifies, as
benchmarks/bench_arm_far_frame.py draws them), the tracker 3 m away and turned 35°,
three targets on the flange 100 mm apart (each the flange's origin plus its rotation times the target's offset),
30 poses, 20 µm of noise.
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
from kinid.errors import DataError  # noqa: E402
from kinid.identification.data.observations import Observations  # noqa: E402
from kinid.identification.fitting import design, fit, load_fit, model_effects, residuals  # noqa: E402

#: The targets' offsets on the flange (tool frame), mm: 100 mm apart, as a tracker's nest or a mocap cluster.
TARGETS = {"T1": (0.0, 0.0, 40.0), "T2": (100.0, 0.0, 40.0), "T3": (0.0, 100.0, 60.0)}
NOISE_MM = 0.020


@pytest.fixture(scope="module")
def arm(tmp_path_factory, ur_arm):
    """(folder, URDF path, machine, plain-numpy truth machine, errors {code: µm / µrad})."""
    d = tmp_path_factory.mktemp("targets_arm")
    urdf, machine = ur_arm
    # the default model's terms one target identifies (the others alias with them), the frame 3 m away turned 35°
    errors = far.far_errors(np.random.default_rng(7), far.arm()[3], distance_mm=3000.0, turn_deg=35.0)
    return d, urdf, machine, truth.read_urdf(urdf.read_text()), errors


def _draw(machine, tm, errors, n, noise_mm, rng, targets=TARGETS):
    """Observations of ``n`` poses × the targets (marks T1, T2 …, one row each, the pose's rows together)."""
    q = rng.uniform(-120, 120, (n, len(machine.axes)))
    R, p = truth.tool_pose_mm(tm, {a.joint: q[:, k] for k, a in enumerate(machine.axes)},
                              {c: np.full(n, v) for c, v in errors.items()}, n)
    w = np.stack([p + R @ np.array(t) for t in targets.values()], axis=1).reshape(-1, 3)
    w = w + rng.normal(0, noise_mm, w.shape)
    m = len(targets)
    return Observations(tuple(targets) * n, w, np.repeat(q, m, axis=0), None, {},
                        tuple(np.repeat(np.arange(2, n + 2), m).tolist()), "<plain numpy>")


def _one_target(obs, mark="T1"):
    return obs.subset(np.array([m == mark for m in obs.marks]))


def _held_out_rms_um(machine, effects, result, test):
    r = residuals(machine, design(machine, effects, test), test, result.theta, jacobian=False)
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1))))


def test_three_targets_fitted_together_recover_their_points_and_halve_the_machine_errors_sigma(arm):
    """From zero offsets: every target's x, y within 3σ of the truth; z along J6's axis is seen only with EZ0J6
    (one target's held, the others' differences and EZ0J6 + the held one's z within 3σ); the machine's errors within
    far.WITHIN_STD σ; their σ with three targets about half of one target's (0.53 measured by the median); the
    held-out 3-D error below the noise's."""
    _, _, machine, tm, errors = arm
    rng = np.random.default_rng(11)
    train, test = _draw(machine, tm, errors, 30, NOISE_MM, rng), _draw(machine, tm, errors, 200, 0.0, rng)
    effects = model_effects(machine, targets=tuple(TARGETS))
    result = fit(machine, train, effects)
    assert result.success
    got = {n: (v, s, ok) for n, v, s, ok in zip(result.param_names, result.values, result.std, result.identifiable)}
    truth_um = {f"E{c}0T:target:{m}": t[k] * 1e3 for m, t in TARGETS.items() for k, c in enumerate("XYZ")}
    held_z = [m for m in TARGETS if not got[f"EZ0T:target:{m}"][2]]
    assert len(held_z) == 1 and got["EZ0J6"][2]  # the flange's z and the targets' z: one sum held
    # EZ0J6 carries the held target's z (tens of mm): a set-up's size, not flagged as one no machine has
    assert abs(got["EZ0J6"][0]) > 1000.0 and not result.implausible()
    z0 = truth_um[f"EZ0T:target:{held_z[0]}"]
    truth_um = {n: v - z0 if n.startswith("EZ0T") else v for n, v in truth_um.items()}
    truth_um["EZ0J6"] = errors["EZ0J6"] + z0
    for name, v in truth_um.items():
        value, std, ok = got[name]
        assert not ok or abs(value - v) <= 3.0 * std, (name, value, v, std)
    assert sum(got[n][2] for n in truth_um if ":target:" in n) == 8
    one = fit(machine, _one_target(train), model_effects(machine))
    one_got = dict(zip(one.param_names, zip(one.std, one.identifiable)))
    shared = [n for n, (s, ok) in one_got.items() if ok and not n.endswith(("W", "T")) and n != "EZ0J6" and got[n][2]]
    assert len(shared) >= 10
    for n in shared:
        assert abs(got[n][0] - errors.get(n, 0.0)) <= far.WITHIN_STD * got[n][1], n
    ratio = np.array([got[n][1] / one_got[n][0] for n in shared])
    assert np.median(ratio) < 0.7 and ratio.max() < 0.8  # 0.53 (0.40-0.57) measured
    rms = _held_out_rms_um(machine, effects, result, test)
    assert rms < NOISE_MM * 1e3  # 13.2 µm measured (one target: 20.4 µm), 3-D, noise-free held-out poses
    assert _held_out_rms_um(machine, model_effects(machine), one, _one_target(test)) > rms


def _mocap_file(path, obs, m=len(TARGETS)):
    """``obs`` (``m`` rows per pose) as a motion-capture export: one row per pose, x1/y1/z1 … in m, joints in rad."""
    header = ["frame", *(a for a in ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint",
                                     "wrist_2_joint", "wrist_3_joint")),
              *(f"{c}{k}" for k in range(1, m + 1) for c in "xyz")]
    rows = [",".join(header)]
    for i in range(len(obs) // m):
        cells = [i, *np.radians(obs.axes[i * m]), *(obs.w_mm[i * m:(i + 1) * m].ravel() / 1e3)]
        rows.append(",".join(f"{v:.12g}" for v in cells))
    path.write_text("\n".join(rows) + "\n")
    return path


def test_identify_without_target_fits_every_target_and_prints_each_point(arm, capsys):
    d, urdf, machine, tm, errors = arm
    obs = _draw(machine, tm, errors, 30, NOISE_MM, np.random.default_rng(5))
    data = _mocap_file(d / "mocap3.csv", obs)
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--out", str(d / "three.json")]) == 0
    out, err = capsys.readouterr()
    assert "90 rows (30 poses × 3 target(s))" in err and "targets T1, T2, T3 fitted together" in err
    lines = {ln.split(":")[0]: ln for ln in out.splitlines() if ln.startswith(("T1:", "T2:", "T3:"))}
    assert sorted(lines) == ["T1", "T2", "T3"] and "tool point x" in lines["T2"]
    result = load_fit(d / "three.json")
    values = dict(zip(result.param_names, zip(result.values, result.std)))
    x2, s2 = values["EX0T:target:T2"]
    shown = float(lines["T2"].split("x ")[1].split(" ±")[0])
    assert abs(shown - x2 / 1e3) < 1e-4 and abs(x2 - 100e3) <= 3 * s2
    assert main(["diagnose", "--fit", str(d / "three.json"), "--data", str(data), "--json"]) == 0
    capsys.readouterr()
    # compensate writes each target's point into setup.json (T2's 100 mm x was dropped without a word)
    assert main(["compensate", "--fit", str(d / "three.json"), "--out", str(d / "comp")]) == 0
    targets = json.loads((d / "comp" / "setup.json").read_text())["targets"]
    assert sorted(targets) == ["T1", "T2", "T3"]
    assert targets["T2"]["offset_mm"][0] == pytest.approx(x2 / 1e3, abs=1e-9)
    assert targets["T2"]["joints"]["EX0T"]["expanded_uncertainty_k2"] == pytest.approx(2 * s2)
    assert abs(targets["T3"]["offset_mm"][1] - TARGETS["T3"][1]) <= 3 * values["EY0T:target:T3"][1] / 1e3
    assert sum("held" in j for t in targets.values() for j in t["joints"].values()) == 1  # one z held


def test_a_target_chosen_fits_as_a_file_of_that_target_alone(arm, capsys):
    """--target T2 of a three-target file: the default model (one constant per set-up joint) and the very fit of
    the same rows as a one-target file: single targets fit as before."""
    d, urdf, machine, tm, errors = arm
    obs = _draw(machine, tm, errors, 20, NOISE_MM, np.random.default_rng(6))
    data = _mocap_file(d / "mocap_t2.csv", obs)
    assert main(["identify", "--machine", str(urdf), "--data", str(data), "--target", "T2", "--out",
                 str(d / "t2.json")]) == 0
    assert "target T2 fitted (--target), the others left out" in capsys.readouterr().err
    single = _one_target(obs, "T2")
    lone = _mocap_file(d / "mocap_lone.csv", single, m=1)
    assert main(["identify", "--machine", str(urdf), "--data", str(lone), "--out", str(d / "lone.json")]) == 0
    a, b = load_fit(d / "t2.json"), load_fit(d / "lone.json")
    assert list(a.param_names) == list(b.param_names) == [n for e in model_effects(machine) for n in e.param_names()]
    assert np.array_equal(a.values, b.values, equal_nan=True) and np.array_equal(a.std, b.std, equal_nan=True)


def test_a_target_basis_is_only_for_the_tool_point_and_needs_the_marks(arm):
    _, _, machine, _, _ = arm
    with pytest.raises(DataError, match="a target basis is a tool point's set-up .E.0T.; EX0J2 is not one"):
        model_effects(machine, ["EX0J2:target:T1"])
    effects = model_effects(machine, targets=("T1", "T2"))
    assert "EX0T:target:T2" in [e.name for e in effects] and "EX0T" not in [e.name for e in effects]
    from kinid.identification.model import basis_values

    e = next(e for e in effects if e.name == "EY0T:target:T2")
    assert basis_values(e, machine, np.zeros((3, 6)), marks=("T1", "T2", "T2")).ravel().tolist() == [0, 1, 1]
    with pytest.raises(DataError, match="needs the rows' marks"):
        basis_values(e, machine, np.zeros((3, 6)))
