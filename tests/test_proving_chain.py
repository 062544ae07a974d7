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



def _case(held_out_um, spurious=(), refused=None):
    rec = {"held_out_um": held_out_um, "added": list(spurious), "spurious": list(spurious), "board_pose": None}
    return rec if refused is None else {**rec, "refused": refused}


def test_a_refused_on_axis_run_is_no_reference_neither_within_nor_beyond(capsys):
    """The on-axis run refused (held-out error inf, as run() records it): the offset run's 0.368 µm is judged neither
    within 1.5× nor beyond (the scenario 1000033 of docs/observe.md was counted within, 0.368 / inf = 0), does not
    pass, and the summary counts it apart and leaves it out of the rates; a refused offset run is beyond."""
    refused = _case(float("inf"), refused="compensate: the fit has EYZ:poly2 = 1940 µm")
    judged = pc.judge(refused, _case(0.368))
    assert judged["judged"] == pc.NO_REFERENCE and not judged["pass"] and not judged["pass_laser"]
    assert np.isnan(judged["ratio"])
    assert pc.judge(refused, refused)["judged"] == pc.NO_REFERENCE
    within = pc.judge(_case(0.5), _case(0.7))
    assert within["ratio"] == pytest.approx(1.4) and within["judged"] == "within" and within["pass"] and within["pass_laser"]
    assert pc.judge(_case(0.5), _case(0.8))["judged"] == "beyond"
    assert pc.judge(_case(0.5), _case(0.6, ["EZZ:poly1"]))["pass"] is False
    assert pc.judge(_case(0.5), refused)["judged"] == "beyond"
    common = {"layout": "five_axis_ac", "lens": "telecentric", "laser_offset_mm": [20.0, 20.0], "laser_mm": 28.3,
              "hidden": "sag EYZ", "ec0t_urad": 0.0, "board_tilt_urad": 0.0, "board_turn_urad": 0.0,
              "uncompensated_um": 50.0, "seconds": 1.0}
    records = [{**common, "seed": 1, "axis": refused, "offset": _case(0.368), **pc.judge(refused, _case(0.368))},
               {**common, "seed": 2, "axis": _case(0.5), "offset": _case(1.0), **pc.judge(_case(0.5), _case(1.0))}]
    pc.summarise(records)
    out = capsys.readouterr().out
    all_row = next(r.split() for r in out.splitlines() if r.startswith("all "))
    assert all_row[1:6] == ["2", "1", "0%", "0%", "0%"]  # n, no ref, within, pass, laser: over the one judged
    assert "failures: 1 of 1 judged" in out
    assert "no reference (the on-axis run refused; judged neither within nor beyond): 1" in out
    assert "NO REFERENCE" in out.split("no reference (")[1] and "NO REFERENCE" not in out.split("no reference (")[0]


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
@pytest.mark.parametrize("seed, layouts, lenses", [
    pytest.param(0, ("five_axis_bc",), ("telecentric",), id="bc-telecentric"),
    # a sag of X along Z, the laser 21 mm aside: its depths settled within the noise 1.4 µm but not within the
    # noise over √72 left the held-out error at 1.370 µm against 0.496 µm on the axis (the proving ground's seed 3)
    pytest.param(300009, pc.LAYOUTS, pc.LENSES, id="bc-telecentric-sag"),
])
def test_the_laser_beside_the_camera_holds_the_on_axis_accuracy(seed, layouts, lenses):
    rec = pc.run(seed, layouts=layouts, lenses=lenses)
    print(pc.line(rec))
    assert rec["offset"]["held_out_um"] <= 1.5 * rec["axis"]["held_out_um"]
    assert rec["offset"]["held_out_um"] < rec["uncompensated_um"] / 10  # the chain compensates at all
    assert not rec["offset"]["spurious"] and rec["pass"]


def test_the_board_slope_takes_the_turns_of_the_chain_that_carries_the_board():
    """The turns between the machine's base and the workpiece (the board's set-up, the table's axes) turn the board;
    the head's and the linear axes' (on this B head) and the camera's tilt on the tool do not enter its slope; the
    camera's turn EC0T does, as the frame of a drawing's offset."""
    from kinid.identification.commands.observe import _turns_the_board
    from kinid.identification.model import load_machine
    from kinid.urdf import path

    machine = load_machine(path("five_axis_bhead_c"))
    on = {code for code in machine.error_codes if _turns_the_board(machine, code)}
    assert {"EA0W", "EB0W", "EC0W", "EA0C", "EB0C", "EC0T"} <= on
    assert not on & {"EA0B", "EC0B", "EA0T", "EB0T", "EA0Z", "EB0Z"}
    assert _turns_the_board(machine, "EXC:poly1") and not _turns_the_board(machine, "EYB:poly1")


@pytest.mark.slow
def test_settled_depths_beside_a_b_head_are_not_turned_by_a_head_tilt_the_fit_misattributes(tmp_path, monkeypatch):
    """A B head with a hidden straightness of Y along Z, the laser 27 mm beside the camera: the default model explains
    the straightness with the head's tilt EA0B (257 µrad where it is 37), whose turn of the tool, taken into the
    board's slope, put every settled mark_dz_mm 4.0 µm (mean) off the renderer's truth and the tool's length with it.
    Taken from the turns of the workpiece's chain alone, the settled depths are 0.9 µm off (the head's true 10–40
    µrad turns times the lever)."""
    sc = pc.draw(67, ("five_axis_bhead_c",), ("telecentric",))
    settled, _, frames = _settled_run(tmp_path, monkeypatch, sc, 67, ())
    images = [row["image"] for row in csv.DictReader(open(tmp_path / "obs.csv"))]
    err_um = []
    for i, image in enumerate(images):
        pw, Rw, pt, Rt = frames[int(Path(image).stem)]
        err_um.append((settled.offsets_mm[i, 2] - (Rt.T @ (pw + Rw @ settled.w_mm[i] - pt))[2]) * 1e3)
    assert abs(np.mean(err_um)) < 1.5, np.mean(err_um)  # 4.0 µm with the head's fitted tilt


@pytest.mark.slow
def test_settled_depths_take_the_marks_own_lever_in_the_machines_axes(tmp_path, monkeypatch):
    """A B/C table turned to ±40° (the board's slope 0.84 in the tool frame), the camera turned 2.25 mrad on the tool
    (EC0T), the laser 15.6 mm aside (its offset in the machine's axes, as kinid sensor measures it) and the marks up
    to 0.5 mm from the tool point: the slope settled in the machine's axes times the marks' own part of the lever,
    seen in the camera's axes, left the depths 0.45 µm RMS off the truth (less the laser's noise), following the pose,
    which --auto took for a cubic EZZ the truth lacks (the chain's proving ground, scenario 300010). Turned into the
    machine's axes by the fitted EC0T, the depths are the truth's within 0.2 µm RMS."""
    sc = pc.draw(300010, pc.LAYOUTS, ("telecentric",))
    assert sc.layout == "five_axis_bc" and abs(sc.constants["EC0T"] - 2251) < 1 and sc.hidden.joint == "EZY"
    # the truth's structure: the hidden straightness is a cubic
    settled, log, frames = _settled_run(tmp_path, monkeypatch, sc, 300010, ("EZY:poly3",))
    laser = {row["image"]: float(row["laser_mm"]) for row in csv.DictReader(open(log))}
    images = [row["image"] for row in csv.DictReader(open(tmp_path / "obs.csv"))]
    err_um = []
    for i, image in enumerate(images):
        pw, Rw, pt, Rt = frames[int(Path(image).stem)]
        noise_mm = laser[image] - cam.laser_mm(pw, Rw, pt, Rt, sc.laser_offset_mm)  # the reading's drawn noise
        true_mm = (Rt.T @ (pw + Rw @ settled.w_mm[i] - pt))[2]
        err_um.append((settled.offsets_mm[i, 2] + noise_mm - true_mm) * 1e3)
    print(f"settled depths less the laser noise, RMS off the truth: {np.sqrt(np.mean(np.square(err_um))):.3f} µm")
    assert np.sqrt(np.mean(np.square(err_um))) < 0.2, np.sqrt(np.mean(np.square(err_um)))


def _settled_run(tmp_path, monkeypatch, sc, seed: int, named: tuple):
    """Scenario ``sc``'s offset run observed and its depths settled with the default model plus ``named``: the
    settled observations, the run's log and the frames (board pose, tool pose) each image was rendered at."""
    from kinid.identification.commands.board_settle import read_levers, settle
    from kinid.identification.data import read_observations
    from kinid.identification.fitting import fit, model_effects
    from kinid.identification.model import load_machine
    from kinid.urdf import path

    tm = pc._machine(sc.layout)
    frames = []
    render = cam.render_at

    def spy(pw, Rw, pt, Rt, rng, **kw):
        frames.append((pw, Rw, pt, Rt))
        return render(pw, Rw, pt, Rt, rng, **kw)

    monkeypatch.setattr(cam, "render_at", spy)
    log, sensor = pc.write_run(tmp_path, sc, tm, np.random.default_rng([seed, 1]))["offset"]
    machine_path = str(path(sc.layout))
    pc._kinid("observe", "--machine", machine_path, "--board", tmp_path / "board.json", "--sensor", sensor,
              "--data", log, "--out", tmp_path / "obs.csv")
    machine = load_machine(machine_path)
    obs = read_observations(tmp_path / "obs.csv", machine)
    effects = model_effects(machine, named)
    settled = settle(machine, obs, read_levers(tmp_path / "obs.csv", obs),
                     lambda o: fit(machine, o, effects, noise_um=None), say=lambda line: None).obs
    return settled, log, frames
