"""The rotary axes' geometry in the controllers' kinematics: each file, read and applied as its
controller applies it (tests/kinematics_consumers.py, plain numpy), puts the part's point under the tool where
the fitted machine does (plain Pinocchio on calibrated.urdf), on every shipped five-axis layout."""
from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification import fit, load_machine, save_fit
from kinid.identification.fitting.simulate import errors_from_mapping, load_plan, simulate
from kinid.identification.model.effects import model_effects
from kinid.kinematics_formats import KINEMATICS_FORMATS
from kinid.urdf import path as urdf_path
from kinematics_consumers import cycle800_points, read_carr, trt_points
from plain_machine import PlainMachine

#: The rotary axes' location errors of each layout (µm, µrad): pivot offsets of 25-40 µm, tilts of 40-60 µrad.
ROTARY_ERRORS = {
    "five_axis_bc": {"EX0B": 25, "EZ0B": -30, "EA0B": 60, "EC0B": -40, "EX0C": 40, "EY0C": -35, "EA0C": 50,
                     "EB0C": -45},
    "five_axis_ac": {"EY0A": 25, "EZ0A": -30, "EB0A": 60, "EC0A": -40, "EX0C": 40, "EY0C": -35, "EA0C": 50,
                     "EB0C": -45},
    "five_axis_bhead_c": {"EX0B": 25, "EZ0B": -30, "EA0B": 60, "EC0B": -40, "EX0C": 40, "EY0C": -35, "EA0C": 50,
                          "EB0C": -45},
}
#: The board's and the sensor's set-up (work and tool offsets, not kinematics).
SETUP = {"EX0W": 300, "EY0W": -200, "EC0W": 500, "EZ0T": 150}
#: The rotary axes in the controller's order (the head's first, then the table's, each from the machine out).
ORDER = {"five_axis_bc": ("B", "C"), "five_axis_ac": ("A", "C"), "five_axis_bhead_c": ("B", "C")}
NOISE_UM = 0.3


def _coordinates(readings: dict) -> np.ndarray:
    """The tool's coordinates relative to the part, mm: in the three URDFs X and Z carry the tool along +x and
    +z, Y carries the table along +y (so the tool moves along −y relative to it)."""
    return np.stack([readings["X"], -readings["Y"], readings["Z"]], axis=1)


def _carried_mm(urdf, names, rows, setup=None) -> np.ndarray:
    """Plain Pinocchio on ``urdf`` with the offsets of ``setup`` (setup.json): the tool point in the workpiece
    frame placed where the workpiece frame is at home, from the tool point at home (mm): the part's point under
    the tool in the machine frame at home (the board's offset cancels; the sensor's is where the tool point is)."""
    pm = PlainMachine(urdf=urdf, setup=setup)
    pm.tool_in_workpiece_mm(dict.fromkeys(names, 0.0))
    oMw0 = pm.data.oMf[pm.model.getFrameId("workpiece")] * pm.work_offset
    t0 = (pm.data.oMf[pm.model.getFrameId("tool")] * pm.tool_offset).translation.copy()
    return np.array([oMw0.act(pm.tool_in_workpiece_mm(dict(zip(names, r))) * 1e-3) - t0 for r in rows]) * 1e3


def _rms_um(a_mm) -> float:
    return 1e3 * float(np.sqrt(np.mean(np.sum(np.asarray(a_mm) ** 2, axis=1))))


def _compensated(tmp_path, name, errors, seed, *extra):
    m = load_machine(urdf_path(name))
    effects, theta = errors_from_mapping({**errors, **SETUP}, m)
    obs = simulate(m, load_plan("patent", m), effects, theta, noise_um=NOISE_UM, rng=np.random.default_rng(seed))
    result = fit(m, obs, model_effects(m), noise_um=NOISE_UM)
    save_fit(result, tmp_path / "fit.json")
    out = tmp_path / "comp"
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(out), *extra]) == 0
    return m, obs, out


def _compare(m, obs, out, points_of):
    names = m.axis_names
    readings = dict(zip(names, obs.axes.T))
    fitted = _carried_mm(out / "calibrated.urdf", names, obs.axes, out / "setup.json")
    nominal = _carried_mm(urdf_path(m.path.rsplit("/", 1)[-1][:-5]), names, obs.axes, out / "setup.json")
    controller = points_of(_coordinates(readings), readings)
    return _rms_um(controller - fitted), _rms_um(fitted - nominal), 1e3 * float(np.abs(controller - fitted).max())


@pytest.mark.parametrize("name", sorted(ROTARY_ERRORS))
def test_cycle800_swivel_data_follow_the_fitted_machine(name, tmp_path, capsys):
    m, obs, out = _compensated(tmp_path, name, ROTARY_ERRORS[name], 3)
    said = capsys.readouterr().out
    text = (out / "KINID_CYCLE800.MPF").read_text()
    first, second = ORDER[name]
    left, effect, worst = _compare(m, obs, out, lambda J, r: cycle800_points(text, J, r[first], r[second]))
    print(f"{name}: CYCLE800 leaves {left:.3g} µm RMS ({worst:.3g} µm max) of the location errors' {effect:.3g} µm")
    assert effect > 20.0  # the location errors move the part's point by tens of µm
    assert left <= 0.10 * effect
    if name != "five_axis_bhead_c":  # against the true machine too (on the B head the patent plan leaves EY0C
        # undetermined, σ 64 µm with EA0Z, so it is left out: the fit's limit, not the file's)
        from test_compensation_files import _fit_of
        from kinid.identification.compensation.compensate import write_compensation

        write_compensation(_fit_of(m, {**ROTARY_ERRORS[name], **SETUP}), tmp_path / "truth")
        truth = _carried_mm(tmp_path / "truth" / "calibrated.urdf", m.axis_names, obs.axes,
                            tmp_path / "truth" / "setup.json")
        nominal = _carried_mm(urdf_path(name), m.axis_names, obs.axes, tmp_path / "truth" / "setup.json")
        readings = dict(zip(m.axis_names, obs.axes.T))
        controller = cycle800_points(text, _coordinates(readings), readings[first], readings[second])
        print(f"{name}: against the truth {_rms_um(controller - truth):.3g} µm of {_rms_um(truth - nominal):.3g} µm")
        assert _rms_um(controller - truth) <= 0.10 * _rms_um(truth - nominal)
    carr = read_carr(text)
    assert carr[23] == ("M" if name == "five_axis_bhead_c" else "P") and (carr[21], carr[22]) == ORDER[name]
    # compensation.json names the file with its sha256, and the command says where the axes turn
    info = json.loads((out / "compensation.json").read_text())
    entry = next(f for f in info["kinematics"]["files"] if f["format"] == "sinumerik")
    assert entry["sha256"] == hashlib.sha256(text.encode()).hexdigest()
    assert "pivot moved by" in said and "axis tilted by" in said and "Y -> -Y" in said


@pytest.mark.parametrize("name", ["five_axis_bc", "five_axis_ac"])
def test_trunnion_kinematics_follow_the_fitted_machine_without_tilts(name, tmp_path):
    pivots = {k: v for k, v in ROTARY_ERRORS[name].items() if k[1] in "XYZ"}  # pivot offsets only
    m, obs, out = _compensated(tmp_path, name, pivots, 4)
    text = (out / "trt-kins.hal").read_text()
    first, _ = ORDER[name]
    left, effect, worst = _compare(m, obs, out, lambda J, r: trt_points(text, J, r[first], r["C"]))
    print(f"{name}: trt-kins leaves {left:.3g} µm RMS ({worst:.3g} µm max) of the location errors' {effect:.3g} µm")
    assert effect > 20.0 and left <= 0.10 * effect


def test_trunnion_kinematics_name_the_tilts_they_cannot_hold(tmp_path, capsys):
    m, obs, out = _compensated(tmp_path, "five_axis_bc", ROTARY_ERRORS["five_axis_bc"], 5)
    said = capsys.readouterr().out
    text = (out / "trt-kins.hal").read_text()
    assert "# left out: C's direction departs from z" in text
    assert "note: trt-kins.hal: C's direction departs from z" in said
    info = json.loads((out / "compensation.json").read_text())
    entry = next(f for f in info["kinematics"]["files"] if f["format"] == "linuxcnc")
    assert any("B's direction" in line for line in entry["left_out"])


def test_a_head_layout_gets_no_trunnion_file_and_a_one_line_reason(tmp_path, capsys):
    m, obs, out = _compensated(tmp_path, "five_axis_bhead_c", ROTARY_ERRORS["five_axis_bhead_c"], 6,
                               "--kinematics-format", "linuxcnc", "sinumerik")
    said = capsys.readouterr().out
    assert not (out / "trt-kins.hal").exists() and (out / "KINID_CYCLE800.MPF").exists()
    assert "not written, trunnion kinematics hold two table axes" in said
    # the kinematics file is the folder's own: a second run replaces the folder (a foreign file would keep it)
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(out)]) == 0
    assert (out / "KINID_CYCLE800.MPF").exists()


def test_a_machine_without_rotary_axes_gets_no_kinematics_files(tmp_path):
    from test_compensation_files import _fit_of
    from kinid.identification.compensation.compensate import write_compensation

    m = load_machine(urdf_path("gantry_dual_y"))
    assert not any(a.kind == "revolute" for a in m.axes)
    assert {"sinumerik", "linuxcnc"} <= set(KINEMATICS_FORMATS)
    quiet = write_compensation(_fit_of(m, {}), tmp_path / "a")
    asked = write_compensation(_fit_of(m, {}), tmp_path / "b", kinematics_formats=["sinumerik"])
    assert quiet.geometry is None and not any("kinematics" in n for n in quiet.notes)
    assert "no kinematics files: the machine has no rotary axis" in asked.notes
    assert not list((tmp_path / "b").glob("*.MPF")) and not list((tmp_path / "b").glob("*.hal"))


def test_more_than_two_rotary_axes_get_a_note_not_a_file():
    from types import SimpleNamespace

    from kinid.identification.compensation.rotary_geometry import kinematics_note

    arm = SimpleNamespace(axes=[SimpleNamespace(name=n, kind="revolute") for n in ("J1", "J2", "J3")])
    assert kinematics_note(arm) == ("no kinematics files: 3 rotary axes (J1, J2, J3); a controller's five-axis "
                                    "kinematics holds one or two")
    five = SimpleNamespace(axes=[SimpleNamespace(name=n, kind="revolute") for n in ("B", "C")])
    assert kinematics_note(five) is None


@pytest.mark.parametrize("name", sorted(ROTARY_ERRORS))
def test_exact_location_errors_are_reproduced_by_the_swivel_data(name, tmp_path):
    """Exact recovery: a fit holding the location errors exactly (σ 0.1), no noise, poses over the whole travel."""
    from test_compensation_files import _fit_of
    from kinid.identification.compensation.compensate import write_compensation

    m = load_machine(urdf_path(name))
    values = {**ROTARY_ERRORS[name], **SETUP}
    out = write_compensation(_fit_of(m, values), tmp_path / "comp")
    assert "KINID_CYCLE800.MPF" in out.files and out.geometry.kind == ("head-table" if "bhead" in name else
                                                                       "table-table")
    rng = np.random.default_rng(11)
    names = m.axis_names
    rows = np.column_stack([rng.uniform(-100, 100, len(rng.random(200))) if m.axis(a).kind == "prismatic" else
                            rng.uniform(-90, 90, 200) for a in names])
    readings = dict(zip(names, rows.T))
    first, second = ORDER[name]
    text = (tmp_path / "comp" / "KINID_CYCLE800.MPF").read_text()
    fitted = _carried_mm(tmp_path / "comp" / "calibrated.urdf", names, rows, tmp_path / "comp" / "setup.json")
    nominal = _carried_mm(urdf_path(name), names, rows, tmp_path / "comp" / "setup.json")
    controller = cycle800_points(text, _coordinates(readings), readings[first], readings[second])
    assert _rms_um(fitted - nominal) > 20.0
    assert np.abs(controller - fitted).max() * 1e3 < 0.01  # µm: the file's 6 decimals of a mm, 9 of a unit vector
