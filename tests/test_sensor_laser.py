"""The laser beside the camera: ``kinid sensor`` measures its offset, ``kinid observe`` uses it.

Truth: tests/bc_camera_sim.py, the hand-written numpy B/C machine and its ray-traced camera, with the
laser mounted 18 mm beside the camera (parallel to its axis), as the five-axis method mounts it.
"""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest

import bc_camera_sim as sim
from kinid.cli import main
from kinid.urdf import path as urdf_path

MACHINE = str(urdf_path("five_axis_bc"))
LASER_MM = (18.0, -2.5)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("laser_run")
    poses = sim.plan(tilts=(-40.0, 0.0, 40.0), turns=(0.0, 120.0, 240.0))
    truth = sim.write_run(folder, poses, rng=np.random.default_rng(21), laser_offset_mm=LASER_MM)
    return folder, truth


def _observed_dz_error_um(folder, truth, sensor):
    (folder / "sensor_used.json").write_text(json.dumps(sensor))
    assert main(["observe", "--machine", MACHINE, "--board", str(folder / "board.json"), "--sensor",
                 str(folder / "sensor_used.json"), "--data", str(folder / "log.csv"), "--out",
                 str(folder / "obs.csv")]) == 0
    rows = list(csv.DictReader(open(folder / "obs.csv")))
    err = [float(r["mark_dz_mm"]) - sim.seen_offset(true, b, c, m)[2] for r, (true, b, c, m) in zip(rows, truth)]
    return np.abs(np.array(err)) * 1e3


def test_observe_places_the_laser_reading_at_its_spot(run, capsys):
    folder, truth = run
    sensor = json.loads((folder / "sensor.json").read_text())
    without = _observed_dz_error_um(folder, truth, sensor)
    with_offset = _observed_dz_error_um(folder, truth, {**sensor, "laser_offset_mm": list(LASER_MM)})
    print(f"mark_dz error: laser offset ignored {without.max():.0f} µm, used {with_offset.max():.2f} µm")
    assert without.max() > 1000.0  # tan 40° × 18 mm: the reason the offset matters
    assert with_offset.max() < 3.0  # 0.5 µm laser noise, as with the laser on the camera's axis


def _hole_rows(offset_mm, rng, repeats=5, noise_mm=0.002):
    """Readings of the hole measurement on the nominal machine (no errors): camera centred on the hole at
    workpiece (12, -7, 0), then the laser spot dropped in it; B = C = 0."""
    feature = np.array([12.0, -7.0, 0.0])
    rows = []
    for _ in range(repeats):
        cam = sim.align(feature, 0.0, 0.0, truth={}) + rng.normal(0.0, noise_mm, 3)
        las = sim.align(feature - np.array([*offset_mm, 0.0]), 0.0, 0.0, truth={}) + rng.normal(0.0, noise_mm, 3)
        rows += [("camera", *cam), ("laser", *las)]
    return rows


def test_sensor_recovers_the_offset_from_the_hole_within_its_uncertainty(tmp_path, capsys):
    rng = np.random.default_rng(3)
    inside = 0
    for k in range(40):
        folder = tmp_path / f"h{k}"
        folder.mkdir()
        with open(folder / "hole.csv", "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["role", "x_mm", "y_mm", "z_mm", "b_deg", "c_deg"])
            w.writerows([(r, f"{x:.6f}", f"{y:.6f}", f"{z:.6f}", "0", "0") for r, x, y, z in _hole_rows(LASER_MM, rng)])
        (folder / "base.json").write_text(json.dumps({"pixel_mm": 0.045, "laser_standoff_mm": 30.0}))
        # the alignment's repeatability is known (2 µm per reading): the offset's σ is then exact
        assert main(["sensor", "--machine", MACHINE, "--hole", str(folder / "hole.csv"), "--base",
                     str(folder / "base.json"), "--noise-mm", "0.002", "--out", str(folder / "sensor.json")]) == 0
        s = json.loads((folder / "sensor.json").read_text())
        assert s["pixel_mm"] == 0.045 and s["laser_standoff_mm"] == 30.0  # the base file's keys are kept
        got, std = np.array(s["laser_offset_mm"]), np.array(s["laser_offset_std_mm"])
        assert np.all(np.abs(got - LASER_MM) < 0.01)
        inside += bool(np.all(np.abs(got - LASER_MM) <= 2 * std))
    print(f"within the expanded uncertainty (k = 2) in both coordinates: {inside}/40")
    assert inside >= 32  # 0.954² ≈ 0.91 of the time for two independent coordinates


def test_sensor_refuses_a_tilted_tool_and_unknown_roles(tmp_path, capsys):
    (tmp_path / "hole.csv").write_text("role,x_mm,y_mm,z_mm,b_deg,c_deg\ncamera,0,0,0,30,0\nlaser,18,0,0,30,0\n")
    assert main(["sensor", "--machine", MACHINE, "--hole", str(tmp_path / "hole.csv"), "--out",
                 str(tmp_path / "s.json")]) == 2
    assert "rotary axes at zero" in capsys.readouterr().err
    (tmp_path / "hole.csv").write_text("role,x_mm,y_mm,z_mm,b_deg,c_deg\ncam,0,0,0,0,0\nlaser,18,0,0,0,0\n")
    assert main(["sensor", "--machine", MACHINE, "--hole", str(tmp_path / "hole.csv"), "--out",
                 str(tmp_path / "s.json")]) == 2
    assert "role must be camera or laser" in capsys.readouterr().err
    assert not (tmp_path / "s.json").exists()


def test_a_wrong_sensor_offset_is_called_inconsistent_and_nothing_implausible_is_added(run, tmp_path, capsys):
    """The same run observed as if the laser were on the camera's axis: the fit needs centimetres and does not
    converge; identify refuses it in one line that says the observations look inconsistent and names the sizes
    (it wrote such a fit, flagged, before a fit that did not converge was refused), so nothing implausible is
    added and nothing reaches a controller; with the offset measured the fit is written and nothing is flagged."""
    folder, truth = run
    sensor = json.loads((folder / "sensor.json").read_text())
    for name, s in (("wrong", sensor), ("right", {**sensor, "laser_offset_mm": list(LASER_MM)})):
        (tmp_path / f"{name}.json").write_text(json.dumps(s))
        assert main(["observe", "--machine", MACHINE, "--board", str(folder / "board.json"), "--sensor",
                     str(tmp_path / f"{name}.json"), "--data", str(folder / "log.csv"), "--out",
                     str(tmp_path / f"{name}.csv")]) == 0
    capsys.readouterr()
    assert main(["identify", "--machine", MACHINE, "--data", str(tmp_path / "wrong.csv"), "--auto",
                 "--out", str(tmp_path / "wrong_fit.json")]) == 2
    last = capsys.readouterr().err.strip().splitlines()[-1]  # --auto's step lines come before it
    assert last.startswith("kinid identify: ") and "the observations look inconsistent" in last
    assert "no machine has" in last and last.endswith("no fit written")
    assert not (tmp_path / "wrong_fit.json").exists()
    assert main(["identify", "--machine", MACHINE, "--data", str(tmp_path / "right.csv"), "--auto",
                 "--out", str(tmp_path / "right_fit.json")]) == 0
    right = json.loads((tmp_path / "right_fit.json").read_text())
    assert not right["implausible"]


def _without_lever_columns(path):
    """The observation CSV without observe's lever and slope columns: identify fits the depths as observed (with
    them it judges them again with its fitted board pose, which takes up part of a moved offset through the board's
    tilt; tests/test_laser_board_pose.py tests that)."""
    rows = list(csv.DictReader(open(path)))
    names = [c for c in rows[0] if c not in ("laser_lever_x_mm", "laser_lever_y_mm", "board_slope_x", "board_slope_y")]
    with open(path, "w", newline="") as f:
        out = csv.DictWriter(f, names, extrasaction="ignore")
        out.writeheader()
        out.writerows(rows)


def test_the_laser_offsets_uncertainty_is_carried_into_the_fit(run, tmp_path, capsys):
    """observe writes how mark_dz moves per σ of the laser offset (the board's slope); the fit's std includes it,
    and the parameter changes it states are those of refitting with the offset moved by one σ."""
    folder, _ = run
    sensor = json.loads((folder / "sensor.json").read_text())
    offset = list(sim.laser_offset_as_measured(LASER_MM))
    std_mm = [0.01, 0.01]

    def fitted(name, laser, std):
        (tmp_path / f"{name}.json").write_text(json.dumps({**sensor, "laser_offset_mm": laser,
                                                           **({"laser_offset_std_mm": std} if std else {})}))
        assert main(["observe", "--machine", MACHINE, "--board", str(folder / "board.json"), "--sensor",
                     str(tmp_path / f"{name}.json"), "--data", str(folder / "log.csv"), "--out",
                     str(tmp_path / f"{name}.csv")]) == 0
        _without_lever_columns(tmp_path / f"{name}.csv")
        assert main(["identify", "--machine", MACHINE, "--data", str(tmp_path / f"{name}.csv"), "--noise-um", "0.5",
                     "--out", str(tmp_path / f"{name}_fit.json")]) == 0
        fit = json.loads((tmp_path / f"{name}_fit.json").read_text())
        return fit, {p["name"]: p for p in fit["parameters"] if p["identified"]}

    plain, p0 = fitted("plain", offset, None)
    carried, p1 = fitted("carried", offset, std_mm)
    header = open(tmp_path / "carried.csv").readline()
    # B tilts the board about the tool's y axis: the slope, and so the laser's y offset, moves nothing
    assert "shift_laser_offset_x_dz_mm" in header and "shift_laser_offset_y" not in header
    assert "shared uncertainty of laser_offset_x (type B)" in capsys.readouterr().out
    assert not plain["shared_std"] and set(carried["shared_std"]) == {"laser_offset_x"}
    names = [p["name"] for p in carried["parameters"]]
    worst = 0.0
    for j, axis in enumerate("x"):
        moved = list(offset)
        moved[j] += std_mm[j]
        _, p2 = fitted(f"moved_{axis}", moved, None)
        stated = dict(zip(names, carried["shared_std"][f"laser_offset_{axis}"]))
        for n in p0:
            refit = p2[n]["value"] - p0[n]["value"]
            # linear propagation against the refit: within 2 % of the change, or a third of the noise's σ where a
            # 7 mrad camera rotation (EC0T absorbs the laser's x offset) bends the model
            worst = max(worst, abs(refit - stated[n]) / (0.02 * abs(stated[n]) + p0[n]["std"] / 3))
    grown = max(p1[n]["std"] / p0[n]["std"] for n in p0)
    print(f"the std grows up to {grown:.1f}×; stated vs refitted change: {worst:.2f} of the tolerance")
    assert grown > 1.5  # a 10 µm offset uncertainty matters on a board tilted 40°
    assert worst <= 1.0
    assert all(p1[n]["std"] >= p0[n]["std"] for n in p0)
