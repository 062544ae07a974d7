"""The image chain with the laser beside the camera: the CI-sized subset of benchmarks/proving_chain.py.

Truth: benchmarks/proving_truth.py (plain numpy on the URDF text) for the machine, benchmarks/camera_render.py (the
ray tracer tests/bc_camera_sim.py shares) for the images and the laser; no kinid kinematics. The full run
(``python benchmarks/proving_chain.py --scenarios 12``) is a benchmark; its table is in docs/observe.md.
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import camera_render as cam  # noqa: E402
import proving_chain as pc  # noqa: E402


def test_the_shared_laser_is_a_plain_ray_plane_intersection():
    """A beam along the camera's axis (−z of the tool) from (x, y) beside the tool point meets the plane of the board
    where the plane's equation says; the reading adds the stand-off."""
    rng = np.random.default_rng(4)
    for _ in range(20):
        a, b = rng.uniform(-0.05, 0.05, 2)
        Rw = np.array([[1, 0, b], [0, 1, -a], [-b, a, 1.0]])
        Rw, _ = np.linalg.qr(Rw)
        Rw = Rw * np.sign(np.diag(Rw))  # a small tilt, right-handed
        pw, pt = rng.uniform(-5, 5, 3), rng.uniform(-5, 5, 3) + [0, 0, 20]
        offset = rng.uniform(-30, 30, 2)
        start = pt + np.array([*offset, 0.0])  # the tool frame is the machine's
        n = Rw[:, 2]
        depth = (start - pw) @ n / n[2]  # along −z to the plane n·(p − pw) = 0
        assert abs(cam.laser_mm(pw, Rw, pt, np.eye(3), offset) - (cam.LASER_STANDOFF_MM + depth)) < 1e-9


def test_the_two_runs_share_their_images_and_differ_only_in_the_laser(tmp_path):
    sc = pc.draw(7, layouts=("five_axis_ac",), lenses=("telecentric",))
    tm = pc._machine(sc.layout)
    files = pc.write_run(tmp_path, sc, tm, np.random.default_rng(1))
    axis, offset = (list(csv.reader(open(files[case][0]))) for case in ("axis", "offset"))
    assert len(axis) == len(offset) == 1 + len(pc.TILTS_DEG) * pc.TURNS * len(pc.MARKS_MM)
    assert [r[:-1] for r in axis] == [r[:-1] for r in offset]  # the same images at the same readings
    lasers = np.array([[float(a[-1]), float(b[-1])] for a, b in zip(axis[1:], offset[1:])])
    assert np.abs(lasers[:, 0] - lasers[:, 1]).max() > 1e-3  # the board's tilt under a beam 0–30 mm aside
    assert len(list((tmp_path / "images").glob("*.png"))) == len(axis) - 1


@pytest.mark.slow
@pytest.mark.parametrize("seed", [pytest.param(SEED, id=name) for name, SEED in (("bc-telecentric", 0),)])
def test_the_laser_beside_the_camera_holds_the_on_axis_accuracy(seed):
    rec = pc.run(seed, layouts=("five_axis_bc",), lenses=("telecentric",))
    print(pc.line(rec))
    assert rec["offset"]["held_out_um"] <= 1.5 * rec["axis"]["held_out_um"]
    assert rec["offset"]["held_out_um"] < rec["uncompensated_um"] / 10  # the chain compensates at all
    assert not rec["offset"]["spurious"] and rec["pass"]
