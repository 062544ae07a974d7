"""A motion-capture file of an arm read as the capture system wrote it, and the held-out checks leaving a pose's rows
out together (docs/formats.md, "A motion-capture file as written").

The file has the shape of a real one (a Qualisys export of a robot arm's hand, FIGAROH's TIAGo example): the four
points of the hand's rigid body ``x1, y1, z1 … x4, y4, z4`` in metres first, then the joints' readings in radians
under the URDF's joint names; the fourth point a copy of the third on every row, as that export wrote it.

Truth in plain numpy: the arm of examples/ur_like.urdf through ``kinid model``, its flange's pose from
benchmarks/proving_truth.py (no kinid code) with location errors of ~100 µm (as benchmarks/bench_arm_far_frame.py
draws them), the capture frame 3 m away and turned 35°, 24 poses, 20 µm of noise.
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
from kinid.identification.data import read_export  # noqa: E402
from kinid.identification.data.observations import Observations  # noqa: E402
from kinid.identification.fitting import pose_folds  # noqa: E402

#: The hand's rigid-body points in the tool frame, mm (a cluster about 100 mm across; the fourth repeats the third).
POINTS_MM = ((0.0, 0.0, 40.0), (100.0, 0.0, 40.0), (0.0, 100.0, 60.0))
NOISE_MM = 0.020
POSES = 24


@pytest.fixture(scope="module")
def capture(tmp_path_factory, ur_arm):
    """(file, URDF path, machine, the true points (poses, 3, 3) in mm, the joints' readings in deg)."""
    urdf, machine = ur_arm
    tm = truth.read_urdf(urdf.read_text())
    rng = np.random.default_rng(5)
    errors = far.far_errors(rng, far.arm()[3], distance_mm=3000.0, turn_deg=35.0)
    q = rng.uniform(-120, 120, (POSES, len(machine.axes)))
    R, p = truth.tool_pose_mm(tm, {a.joint: q[:, k] for k, a in enumerate(machine.axes)},
                              {c: np.full(POSES, v) for c, v in errors.items()}, POSES)
    w = np.stack([p + R @ np.array(t) for t in POINTS_MM], axis=1) + rng.normal(0, NOISE_MM, (POSES, 3, 3))
    joints = [a.joint for a in machine.axes]
    header = [f"{c}{k}" for k in range(1, 5) for c in "xyz"] + joints
    rows = [",".join(header)]
    for i in range(POSES):
        points_m = np.concatenate([w[i].ravel(), w[i, 2]]) / 1e3  # the fourth point: the third's numbers again
        rows.append(",".join(repr(float(v)) for v in (*points_m, *np.radians(q[i]))))
    path = tmp_path_factory.mktemp("capture") / "qualisys_static_postures.csv"
    path.write_text("\n".join(rows) + "\n")
    return path, urdf, machine, w, q


def test_the_capture_file_is_read_as_written_and_a_copied_point_once(capture):
    path, _, machine, w, q = capture
    export = read_export(path, machine)
    obs = export.observations
    assert [label for label, *_ in export.targets] == ["T1", "T2", "T3"]
    assert export.copies == (("T4", ("x4", "y4", "z4"), "T3"),) and export.ignored == ()
    assert len(obs) == 3 * POSES and obs.marks[:4] == ("T1", "T2", "T3", "T1")
    assert np.allclose(obs.w_mm.reshape(POSES, 3, 3), w, atol=1e-9)  # metres -> mm
    assert np.allclose(obs.axes[::3], q, atol=1e-9)  # radians -> degrees, by the URDF's joint names
    notes = "\n".join(export.notes())
    assert f"{3 * POSES} rows ({POSES} poses × 3 target(s))" in notes
    assert "x4, y4, z4: the same numbers as T3's on every row, a copy, not another target (left out)" in notes


def test_identify_on_the_capture_file_as_written_finds_every_point_on_the_hand(capture, tmp_path, capsys):
    """``kinid identify`` on the file, no converter: the three points' x, y on the tool within 3σ of the truth (z
    along the last joint is one sum with EZ0J6: the differences of z within 3σ), the residual at the noise."""
    path, urdf, _, _, _ = capture
    out = tmp_path / "fit.json"
    assert main(["identify", "--machine", str(urdf), "--data", str(path), "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "a copy, not another target (left out)" in err and "targets T1, T2, T3 fitted together" in err
    saved = json.loads(out.read_text())
    got = {p["name"]: p for p in saved["parameters"]}
    for m, t in zip(("T1", "T2", "T3"), POINTS_MM):
        for k, c in enumerate("XY"):
            p = got[f"E{c}0T:target:{m}"]
            assert abs(p["value"] - t[k] * 1e3) < 3 * p["std"], (m, c, p)
    z = {m: got[f"EZ0T:target:{m}"] for m in ("T1", "T2", "T3")}
    held = [m for m, p in z.items() if not p["identified"]]
    assert len(held) == 1
    for m, t in zip(("T1", "T2", "T3"), POINTS_MM):
        if m != held[0]:
            diff_um = z[m]["value"]  # the held one's z stays at zero (no value written): the others' are from it
            true_um = (t[2] - POINTS_MM[("T1", "T2", "T3").index(held[0])][2]) * 1e3
            assert abs(diff_um - true_um) < 3 * np.hypot(z[m]["std"], 1.0), (m, diff_um, true_um)
    assert 0.7 * NOISE_MM * 1e3 < saved["rms_um"] < 1.3 * NOISE_MM * 1e3


def test_the_benchmark_leaves_each_pose_out_whole_and_predicts_it_at_the_noise(capture):
    """benchmarks/bench_capture_loo.py's leave-one-pose-out on the file (plain fit): every point's 3-D error above
    √3 σ (a new measurement's noise, plus the fit's share: 24 poses) and within 2× it (39.7 µm measured, √3 σ
    34.6 µm); its first target's figure, over the T1 rows alone, as well (40.9 µm)."""
    import bench_capture_loo as bench

    from kinid.identification.fitting import model_effects

    path, _, machine, _, _ = capture
    obs = read_export(path, machine).observations
    effects = model_effects(machine, targets=("T1", "T2", "T3"))
    every_um, first_um, scales = bench.leave_one_pose_out(machine, obs, effects, prior=False)
    noise_3d_um = np.sqrt(3) * NOISE_MM * 1e3
    assert noise_3d_um < every_um < 2.0 * noise_3d_um and noise_3d_um * 0.8 < first_um < 2.0 * noise_3d_um
    assert scales == []


def _poses(n_poses, n_targets, lines):
    """Observations of ``n_poses`` poses × ``n_targets`` rows each (readings distinct per pose), then one orientation-
    like row per pose appended after all the points (as an export's rotation rows are), its line the pose's."""
    q = np.arange(n_poses * 2, dtype=float).reshape(n_poses, 2)
    axes = np.vstack([np.repeat(q, n_targets, axis=0), q])
    line = np.concatenate([np.repeat(lines, n_targets), lines])
    marks = tuple(f"T{k + 1}" for k in range(n_targets)) * n_poses + ("R",) * n_poses
    return Observations(marks, np.zeros((len(marks), 3)), axes, None, {}, tuple(int(v) for v in line), "<poses>")


@pytest.mark.parametrize("n_poses, loo_max, folds", [(12, 30, 10), (34, 30, 10), (34, 60, 10)])
def test_the_held_out_folds_leave_every_row_of_a_pose_out_together(n_poses, loo_max, folds):
    obs = _poses(n_poses, 3, np.arange(2, n_poses + 2))
    tests, method = pose_folds(obs, loo_max, folds)
    assert np.array_equal(np.sort(np.concatenate(tests)), np.arange(len(obs)))  # every row left out once
    for test in tests:
        train = np.setdiff1d(np.arange(len(obs)), test)
        assert not set(np.asarray(obs.lines)[test]) & set(np.asarray(obs.lines)[train])
    k = n_poses if n_poses <= loo_max else folds
    assert len(tests) == k and all(len(t) == 4 * len(range(f, n_poses, k)) for f, t in enumerate(tests))
    expected = "leave-one-pose-out" if k == n_poses else f"{k}-fold, interleaved"
    assert method == f"{expected} over {n_poses} poses"


def test_rows_of_their_own_keep_the_folds_they_had_and_files_joined_keep_their_poses_apart():
    """One row per line (kinid's observation CSV): the interleaved row blocks as before. Two files joined (their
    line numbers alike, their readings not): a line number alone does not make two rows one pose."""
    single = _poses(23, 1, np.arange(2, 25))
    single = single.subset(np.arange(23))  # the points only
    tests, method = pose_folds(single, 30, 10)
    assert method == "leave-one-out" and [list(t) for t in tests] == [[i] for i in range(23)]
    tests, method = pose_folds(single, 10, 10)
    assert method == "10-fold, interleaved"
    assert all(np.array_equal(t, np.arange(f, 23, 10)) for f, t in enumerate(tests))
    a, b = _poses(5, 2, np.arange(2, 7)), _poses(5, 2, np.arange(2, 7))
    joined = Observations(a.marks + b.marks, np.vstack([a.w_mm, b.w_mm]), np.vstack([a.axes, b.axes + 100.0]), None,
                          {}, a.lines + b.lines, "<joined>")
    tests, method = pose_folds(joined, 30, 10)
    assert method == "leave-one-pose-out over 10 poses" and all(len(t) == 3 for t in tests)
