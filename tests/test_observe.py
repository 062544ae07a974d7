"""``kinid observe``: rendered camera views of a board at simulated machine poses -> observations -> fit.

The run is made by tests/bc_camera_sim.py, a hand-written numpy model of the B/C machine with a
known error set and a ray-traced telecentric camera (not kinid's kinematics).
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


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    folder = tmp_path_factory.mktemp("run")
    truth = sim.write_run(folder, sim.plan(), rng=np.random.default_rng(11))
    return folder, truth


def _observe(folder, *extra):
    return main(["observe", "--machine", MACHINE, "--board", str(folder / "board.json"), "--sensor",
                 str(folder / "sensor.json"), "--data", str(folder / "log.csv"), *extra])


def test_observe_recovers_the_seen_offsets(run, capsys):
    folder, truth = run
    assert _observe(folder, "--out", str(folder / "obs.csv")) == 0
    assert "72 observations from 72 of 72 images" in capsys.readouterr().out
    rows = list(csv.DictReader(open(folder / "obs.csv")))
    assert len(rows) == len(truth)
    err = []
    for r, (true, b, c, m) in zip(rows, truth):
        assert r["image"].startswith("images/")
        assert (float(r["wx_mm"]), float(r["wy_mm"])) == pytest.approx(m[:2])
        got = np.array([float(r[k]) for k in ("mark_dx_mm", "mark_dy_mm", "mark_dz_mm")])
        err.append(got - sim.seen_offset(true, b, c, m))
    err_um = np.abs(np.array(err)) * 1e3
    # 0.045 mm pixels, 2 grey levels of noise; 0.5 µm laser noise
    assert err_um[:, :2].max() < 1.5, err_um[:, :2].max()
    assert err_um[:, 2].max() < 3.0, err_um[:, 2].max()


def test_identify_on_observed_rows_recovers_the_errors(run, capsys):
    folder, _ = run
    if not (folder / "obs.csv").exists():
        assert _observe(folder, "--out", str(folder / "obs.csv")) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(folder / "obs.csv"), "--add", "EXX:periodic:10",
                 "--out", str(folder / "fit.json")]) == 0
    fit = json.loads((folder / "fit.json").read_text())
    params = {p["name"]: p for p in fit["parameters"]}
    # EZ0T is held (only EZ0B − EZ0T is identified: the tool length and the B axis height), so EZ0B carries −EZ0T
    expect = {"EX0C": 12.0, "EZ0B": -15.0, "EC0T": 800.0, "EXX:periodic:10[sin]": 1.5, "EXX:periodic:10[cos]": -0.8}
    for name, value in expect.items():
        p = params[name]
        assert p["identified"], name
        assert abs(p["value"] - value) < 4 * p["std"] + 0.05, (name, p["value"], p["std"])
    # the camera's rotation about the tool axis moves only what the camera sees: identifiable from offsets alone
    assert params["EC0T"]["std"] < 800.0 / 1.0


def test_observe_lists_images_it_cannot_read(run, tmp_path, capsys):
    import cv2

    folder, _ = run
    log = list(csv.reader(open(folder / "log.csv")))
    blank = np.full((sim.IMAGE_PX, sim.IMAGE_PX), 200, np.uint8)
    cv2.imwrite(str(tmp_path / "blank.png"), blank)
    for name in ("board.json", "sensor.json"):
        (tmp_path / name).write_text((folder / name).read_text())
    rows = [log[0]] + [[str(folder / r[0])] + r[1:] for r in log[1:6]] + [["blank.png"] + log[6][1:]]
    with open(tmp_path / "log.csv", "w", newline="") as f:
        csv.writer(f).writerows(rows)
    assert _observe(tmp_path, "--out", str(tmp_path / "obs.csv")) == 0
    out = capsys.readouterr().out
    assert "5 observations from 5 of 6 images" in out
    assert "log.csv line 7: blank.png: no ring-coded mark decoded" in out


@pytest.mark.parametrize("change, message", [
    (lambda log: log.replace("laser_mm", "laser"), None),  # an unknown column is ignored: laser optional
    (lambda log: log.replace("x_mm,", "xx_mm,"), "missing column 'x_mm'"),
    (lambda log: log.replace("images/001.png", "images/nope.png"), "image file does not exist"),
])
def test_observe_bad_log(run, tmp_path, capsys, change, message):
    folder, _ = run
    import shutil

    shutil.copytree(folder / "images", tmp_path / "images")
    for name in ("board.json", "sensor.json"):
        (tmp_path / name).write_text((folder / name).read_text())
    (tmp_path / "log.csv").write_text(change((folder / "log.csv").read_text()))
    status = _observe(tmp_path, "--out", str(tmp_path / "obs.csv"))
    err = capsys.readouterr().err
    if message is None:
        assert status == 0
    else:
        assert status == 2 and message in err and len(err.strip().splitlines()) == 1, err
        assert not (tmp_path / "obs.csv").exists()


def test_observe_refuses_to_write_over_an_image(run, capsys):
    folder, _ = run
    before = (folder / "images" / "000.png").read_bytes()
    assert _observe(folder, "--out", str(folder / "images" / "000.png")) == 2
    assert "never overwrites an input" in capsys.readouterr().err
    assert (folder / "images" / "000.png").read_bytes() == before


@pytest.mark.parametrize("sensor, message", [
    ({}, "give either pixel_mm"),
    ({"pixel_mm": -1}, "pixel_mm: must be a number in [1e-05, 10], got -1"),
    ({"pixel_mm": 0.01, "focal": 3}, "focal: unknown key; known keys: camera, "),
    ({"pixel_mm": 0.01, "optical_axis_px": [1]},
     "optical_axis_px: must be [a number in [-100000, 100000], a number in [-100000, 100000]], got [1]"),
])
def test_bad_sensor_file(run, tmp_path, capsys, sensor, message):
    folder, _ = run
    (tmp_path / "sensor.json").write_text(json.dumps(sensor))
    status = main(["observe", "--machine", MACHINE, "--board", str(folder / "board.json"), "--sensor",
                   str(tmp_path / "sensor.json"), "--data", str(folder / "log.csv"), "--out", str(tmp_path / "o.csv")])
    err = capsys.readouterr().err
    assert status == 2 and message in err and "sensor.json" in err, err


def test_calibrated_camera_offsets_match_projection():
    """A pinhole camera with distortion: points projected by OpenCV come back as their tool-frame offsets."""
    import cv2

    from kinid.identification.data.observe import Sensor, image_offsets_mm
    from kinid.vision import CameraModel

    K = np.array([[2400.0, 0, 1010.0], [0, 2400.0, 1030.0], [0, 0, 1]])
    dist = np.array([-0.08, 0.02, 0.0005, -0.0003, 0.0])
    cam = CameraModel(K, dist, (2048, 2048))
    wd, angle = 80.0, 7.0
    sensor = Sensor(camera=cam, working_distance_mm=wd, image_x_angle_deg=angle)
    rng = np.random.default_rng(0)
    d = np.column_stack([rng.uniform(-2, 2, (20, 2)), rng.uniform(-0.5, 0.5, 20)])  # tool frame, mm
    a = np.radians(angle)
    cam_axes = np.array([[np.cos(a), np.sin(a), 0.0], [np.sin(a), -np.cos(a), 0.0], [0.0, 0.0, -1.0]])
    # camera centre wd above the tool point on the tool z axis; points in the camera frame
    p_cam = (d - np.array([0.0, 0.0, wd])) @ cam_axes.T
    px, _ = cv2.projectPoints(p_cam, np.zeros(3), np.zeros(3), K, dist)
    got = image_offsets_mm(sensor, px.reshape(-1, 2), (2048, 2048), d[:, 2])
    np.testing.assert_allclose(got, d[:, :2], atol=1e-6)
