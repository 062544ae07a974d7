"""The image chain with the sensor as the five-axis method mounts it: the laser 18 mm beside the camera, and a
calibrated pinhole camera 120 mm above the tool point (with lens distortion), against the laser on the axis of
a telecentric camera.

Truth: tests/bc_camera_sim.py (the hand-written numpy B/C machine, its ray tracer for both lenses, and the
laser beam traced to the board). Each run is observed, fitted with ``--auto`` and compensated as a user would;
the compensation is applied by plain Pinocchio (tests/plain_machine.py) and the held-out moves made on the
hand-written machine.
"""
from __future__ import annotations

import csv
import importlib
import json

import numpy as np
import pytest

import bc_camera_sim as sim
from kinid.cli import main
from kinid.urdf import path as urdf_path
from plain_machine import PlainMachine
from test_image_to_compensation import _held_out_error_um

observe_module = importlib.import_module("kinid.identification.data.observe")  # the data door's `observe` is the function

MACHINE = str(urdf_path("five_axis_bc"))
LASER_MM = (18.0, -2.5)
MEASURED = list(sim.laser_offset_as_measured(LASER_MM))  # what kinid sensor reports (tests/test_sensor_laser.py)


def _observe(folder, sensor_extra=None, out="obs.csv"):
    sensor = {**json.loads((folder / "sensor.json").read_text()), **(sensor_extra or {})}
    (folder / "sensor_used.json").write_text(json.dumps(sensor))
    assert main(["observe", "--machine", MACHINE, "--board", str(folder / "board.json"), "--sensor",
                 str(folder / "sensor_used.json"), "--data", str(folder / "log.csv"), "--out", str(folder / out)]) == 0
    return folder / out


def _offset_errors_um(csv_path, truth):
    rows = list(csv.DictReader(open(csv_path)))
    assert len(rows) == len(truth)
    got = np.array([[float(r[k]) for k in ("mark_dx_mm", "mark_dy_mm", "mark_dz_mm")] for r in rows])
    return (got - np.array([sim.seen_offset(true, b, c, m) for true, b, c, m in truth])) * 1e3


def test_a_tilted_mark_seen_through_a_pinhole_is_put_at_its_centre(tmp_path, monkeypatch, capsys):
    """The located ellipse centre of a mark tilted 40° is ~26 µm from the image of its centre (r² sinB cosB / D);
    observe takes that bias off."""
    truth = sim.write_run(tmp_path, sim.plan(tilts=(-40.0, 0.0, 40.0), turns=(0.0, 180.0), marks=((40.0, 40.0),)),
                          rng=np.random.default_rng(5), camera=sim.PINHOLE)
    corrected = np.abs(_offset_errors_um(_observe(tmp_path), truth)).max(axis=0)
    monkeypatch.setattr(observe_module, "perspective_bias_n", lambda sensor, off, normal, r: np.zeros((len(off), 2)))
    plain = np.abs(_offset_errors_um(_observe(tmp_path, out="obs_plain.csv"), truth)).max(axis=0)
    print(f"largest offset error (x, y, z): ellipse centres taken as mark centres {plain.round(2)} µm, "
          f"corrected {corrected.round(2)} µm")
    assert plain[0] > 15.0  # the bias the correction removes is real and large
    assert np.all(corrected < [1.0, 1.0, 2.5])  # image noise and the laser's 0.5 µm


@pytest.mark.slow
def test_sensor_as_mounted_holds_the_coaxial_telecentric_accuracy(tmp_path_factory):
    cases = {"laser on the axis of a telecentric camera": ({}, {}),
             "laser 18 mm beside a telecentric camera": ({"laser_offset_mm": LASER_MM}, {"laser_offset_mm": MEASURED}),
             "laser 18 mm beside a pinhole camera at 120 mm": ({"laser_offset_mm": LASER_MM, "camera": sim.PINHOLE},
                                                               {"laser_offset_mm": MEASURED})}
    held_out = {}
    for name, (render, sensor) in cases.items():
        folder = tmp_path_factory.mktemp("run")
        sim.write_run(folder, sim.plan(), rng=np.random.default_rng(21), **render)
        obs = _observe(folder, sensor)
        assert main(["identify", "--machine", MACHINE, "--data", str(obs), "--auto", "--out", str(folder / "fit.json")]) == 0
        fit = json.loads((folder / "fit.json").read_text())
        assert not fit["implausible"]
        assert main(["compensate", "--fit", str(folder / "fit.json"), "--out", str(folder / "comp"), "--step-mm", "0.5"]) == 0
        held_out[name] = (_held_out_error_um(PlainMachine(folder / "comp")), fit["effects"])
        print(f"{name}: held-out 3-D error {held_out[name][0]:.3f} µm; added {[e for e in fit['effects'] if ':' in e]}")
    reference = held_out["laser on the axis of a telecentric camera"][0]
    before = _held_out_error_um(PlainMachine(urdf=MACHINE))
    print(f"uncompensated: held-out {before:.2f} µm")
    for name, (err, _) in held_out.items():
        assert err <= 1.5 * reference, name
        assert err < before / 10, name
