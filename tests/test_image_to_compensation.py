"""The whole chain on rendered images: images + log -> observe -> identify -> diagnose -> compensate ->
commanded moves on the simulated machine.

Truth: tests/bc_camera_sim.py (a hand-written numpy B/C machine with a lead error, C-axis offsets, a tool
length error and a rotated camera; a ray-traced camera). The compensation is applied as a URDF consumer
would (tests/plain_machine.py: plain Pinocchio on calibrated.urdf with the axis tables), and the moves
are made on the hand-written machine.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

import bc_camera_sim as sim
from kinid.cli import main
from kinid.urdf import path as urdf_path
from plain_machine import PlainMachine

MACHINE = str(urdf_path("five_axis_bc"))
HELD_OUT = [(b, c, (mx, my, 0.0)) for b in (-25.0, 15.0, 35.0) for c in (20.0, 100.0, 200.0, 310.0)
            for mx, my in ((30.0, -20.0), (-35.0, 10.0), (5.0, 45.0))]


def _held_out_error_um(machine: PlainMachine) -> float:
    """RMS over the held-out poses of the 3-D distance between tool point and mark on the true machine,
    when the axes are commanded to where ``machine`` says the tool point meets the mark."""
    err = []
    for b, c, mark in HELD_OUT:
        start = sim.align(mark, b, c)  # a starting guess only
        r = machine.solve(np.array(mark), {"B": b, "C": c}, start=start)
        err.append(np.linalg.norm(sim.seen_offset(np.array([r["X"], r["Y"], r["Z"]]), b, c, mark)) * 1e3)
    return float(np.sqrt(np.mean(np.square(err))))


@pytest.mark.slow
def test_images_to_compensated_machine(tmp_path, capsys):
    sim.write_run(tmp_path, sim.plan(), rng=np.random.default_rng(21))
    run = lambda *argv: main([*argv])  # noqa: E731
    assert run("observe", "--machine", MACHINE, "--board", str(tmp_path / "board.json"), "--sensor",
               str(tmp_path / "sensor.json"), "--data", str(tmp_path / "log.csv"), "--out", str(tmp_path / "obs.csv")) == 0
    assert run("identify", "--machine", MACHINE, "--data", str(tmp_path / "obs.csv"), "--out", str(tmp_path / "fit0.json")) == 0
    capsys.readouterr()
    assert run("diagnose", "--fit", str(tmp_path / "fit0.json"), "--data", str(tmp_path / "obs.csv"), "--json") == 0
    diagnosis = json.loads(capsys.readouterr().out)
    assert diagnosis["verdict"] == "missing-effect"
    found = diagnosis["candidates"][0]["effect"]
    assert found.startswith("EXX:periodic:"), found  # the hidden 10 mm lead error
    assert run("identify", "--machine", MACHINE, "--data", str(tmp_path / "obs.csv"), "--add", found,
               "--out", str(tmp_path / "fit1.json")) == 0
    assert run("compensate", "--fit", str(tmp_path / "fit1.json"), "--out", str(tmp_path / "comp"),
               "--step-mm", "0.5") == 0
    # the noise-limited level: the model holding exactly the hidden effects, compensated the same way
    assert run("identify", "--machine", MACHINE, "--data", str(tmp_path / "obs.csv"), "--add", "EXX:periodic:10",
               "--out", str(tmp_path / "fit_true.json")) == 0
    assert run("compensate", "--fit", str(tmp_path / "fit_true.json"), "--out", str(tmp_path / "comp_true"),
               "--step-mm", "0.5") == 0

    before = _held_out_error_um(PlainMachine(urdf=MACHINE))
    after = _held_out_error_um(PlainMachine(tmp_path / "comp"))
    limit = _held_out_error_um(PlainMachine(tmp_path / "comp_true"))
    print(f"held-out 3-D error: uncompensated {before:.2f} µm, compensated {after:.3f} µm, "
          f"noise-limited {limit:.3f} µm")
    assert before > 15.0  # the hidden errors move the tool by tens of µm
    assert after <= 1.5 * limit
    assert after < before / 10
