"""`kinid compensate`: the controller's axis numbers said and recorded, and the set-up filtered by significance.

The URDF's chain order is read here with plain Pinocchio (the joints Pinocchio numbers, error joints left
out); the set-up's rotation is the plain formula of a rotation about y by the fitted angle.
"""
from __future__ import annotations

import json
import re

import numpy as np
import pinocchio as pin
import pytest

from kinid.cli import main
from kinid.identification.compensation.compensate import write_compensation
from kinid.identification.fitting.fit import FitResult
from kinid.identification.fitting.fit_file import save_fit
from kinid.identification.fitting.noise import Noise
from kinid.identification.model.effects import default_model
from kinid.identification.model.machine import load_machine
from kinid.urdf import path as urdf_path

BC = str(urdf_path("five_axis_bc"))
@pytest.fixture(scope="module")
def lead_fit(tmp_path_factory):
    d = tmp_path_factory.mktemp("numbers")
    assert main(["simulate", "--machine", BC, "--errors", "examples/errors.json", "--plan", "patent", "--noise-um", "1",
                 "--out", str(d / "obs.csv")]) == 0
    assert main(["identify", "--machine", BC, "--data", str(d / "obs.csv"), "--add", "EXX:periodic:10", "--noise-um", "1",
                 "--out", str(d / "fit.json")]) == 0
    return d / "fit.json"


def _numbers_in_files(folder):
    spf = (folder / "X_EEC_INI.spf").read_text()
    lis = (folder / "X_ssfk.lis").read_text()
    sinumerik = {int(n) for n in re.findall(r"\$AA_ENC_COMP\[0,\d+,AX(\d+)\]", spf)}
    twincat = int(re.search(r"^kopf\.achs_nr\s+(\d+)", lis, re.M).group(1))
    return sinumerik, twincat


def test_axis_numbers_from_the_urdf_are_said_and_recorded(lead_fit, tmp_path, capsys):
    machine = load_machine(BC)
    order = [a.name for a in machine.axes]
    joints = {a.joint: a.name for a in machine.axes}
    model = pin.buildModelFromUrdf(BC)
    truth = [joints[model.names[j]] for j in range(1, model.njoints) if model.names[j] in joints]
    assert order == truth
    place = {a: k for k, a in enumerate(truth, start=1)}
    assert place["X"] != 1  # the case the user met: X is not the chain's first joint
    out = tmp_path / "comp"
    assert main(["compensate", "--fit", str(lead_fit), "--out", str(out), "--format", "twincat", "sinumerik"]) == 0
    said = capsys.readouterr().out
    line = "axis numbers: " + " ".join(f"{a}={place[a]}" for a in truth) + \
           " (from the URDF's chain; --axis-number to set them)"
    assert line in said.splitlines()
    assert _numbers_in_files(out) == ({place["X"]}, place["X"])
    info = json.loads((out / "compensation.json").read_text())["axis_numbers"]
    assert info["source"] == "urdf" and info["numbers"] == place and info["given"] == []
    assert "depth first" in info["rule"]


def test_given_axis_numbers_are_said_and_recorded(lead_fit, tmp_path, capsys):
    out = tmp_path / "comp"
    assert main(["compensate", "--fit", str(lead_fit), "--out", str(out), "--format", "twincat", "sinumerik",
                 "--axis-number", "X=1", "Y=2", "Z=3", "B=4", "C=5"]) == 0
    said = capsys.readouterr().out
    order = [a.name for a in load_machine(BC).axes]
    given = {"X": 1, "Y": 2, "Z": 3, "B": 4, "C": 5}
    line = "axis numbers: " + " ".join(f"{a}={given[a]}" for a in order) + " (given with --axis-number)"
    assert line in said.splitlines()
    assert _numbers_in_files(out) == ({1}, 1)
    info = json.loads((out / "compensation.json").read_text())["axis_numbers"]
    assert info["source"] == "given" and info["numbers"] == {"X": 1, "Y": 2, "Z": 3, "B": 4, "C": 5}


def test_some_axis_numbers_given_the_rest_from_the_urdf(lead_fit, tmp_path, capsys):
    machine = load_machine(BC)
    place = {a.name: k for k, a in enumerate(machine.axes, start=1)}
    out = tmp_path / "comp"
    # X given the number the URDF would give it: no clash, the others from the URDF
    assert main(["compensate", "--fit", str(lead_fit), "--out", str(out), "--format", "twincat",
                 "--axis-number", f"X={place['X']}"]) == 0
    info = json.loads((out / "compensation.json").read_text())["axis_numbers"]
    assert info["source"] == "given+urdf" and info["given"] == ["X"] and info["numbers"] == place
    capsys.readouterr()
    # X given 1, the number the URDF's chain gives another axis: refused, nothing written
    first = next(a for a, n in place.items() if n == 1)
    assert main(["compensate", "--fit", str(lead_fit), "--out", str(tmp_path / "clash"), "--axis-number", "X=1"]) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "--axis-number" in err[0] and "gives axis X the number 1" in err[0] and first in err[0]
    assert not (tmp_path / "clash").exists()


# --- the set-up by significance -----------------------------------------------------------------

def _fit_of(machine, values: dict, std: dict) -> FitResult:
    """A fit of the default model holding ``values`` (µm / µrad) with ``std`` (default 0.1), all identified."""
    effects = tuple(default_model(machine))
    v = np.array([values.get(e.name, 0.0) for e in effects])
    s = np.array([std.get(e.name, 0.1) for e in effects])
    p = len(effects)
    return FitResult(machine=machine, effects=effects, param_names=tuple(e.name for e in effects),
                     units=tuple("µm" if e.unit == "um" else "µrad" for e in effects), values=v,
                     std=s, identifiable=np.ones(p, bool), aliases=(), rank=p, condition_number=1.0,
                     o1=1.0, o3=1.0, residuals_um=None, n_observations=100, rms_um=0.1, noise=Noise(0.1, "given"),
                     dof=300 - p, iterations=1, success=True, message="", axis_ranges={})


#: The user's case: EB0T = −903 ± 1143 µrad (k = 2, σ 571.5), and a significant EX0T and EX0W beside it.
SETUP = {"EB0T": -903.0, "EX0T": 40.0, "EX0W": 1200.0, "EX0C": 12.0}
SETUP_STD = {"EB0T": 571.5}


@pytest.mark.parametrize("all_terms", [False, True])
def test_a_set_up_term_within_its_uncertainty_is_written_as_zero(tmp_path, all_terms):
    m = load_machine(BC)
    result = _fit_of(m, SETUP, SETUP_STD)
    save_fit(result, tmp_path / "fit.json")
    out = tmp_path / "comp"
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(out)]
                + (["--all-terms"] if all_terms else [])) == 0
    setup = json.loads((out / "setup.json").read_text())
    tool = setup["tool"]
    pitch_deg = np.degrees(SETUP["EB0T"] * 1e-6)  # a rotation about y by the fitted angle
    assert pitch_deg == pytest.approx(-0.0517, abs=1e-4)  # the figure the user saw
    joint = tool["joints"]["EB0T"]
    info = json.loads((out / "compensation.json").read_text())
    zeroed = {d["effect"]: d["reason"] for d in info["setup_written_as_zero"]}
    if all_terms:
        assert tool["rotation_rpy_deg"][1] == pytest.approx(pitch_deg, rel=1e-9)
        assert joint["value"] == pytest.approx(SETUP["EB0T"]) and "written_as_zero" not in joint
        assert zeroed == {}
    else:
        assert tool["rotation_rpy_deg"] == pytest.approx([0.0, 0.0, 0.0], abs=1e-12)
        assert joint["value"] == 0.0 and joint["fitted_value"] == pytest.approx(SETUP["EB0T"])
        assert joint["written_as_zero"].startswith("not significant") and "|value|/σ 1.6" in joint["written_as_zero"]
        assert "EB0T" in zeroed
        # the set-up terms at zero (σ 0.1, value 0) are within their uncertainty too; EX0T and EX0W are not
        assert "EX0T" not in zeroed and "EX0W" not in zeroed
    # the significant ones are kept either way, as fitted (EX0T is a translation of the tool frame)
    assert tool["joints"]["EX0T"]["value"] == pytest.approx(40.0)
    assert tool["offset_mm"][0] == pytest.approx(0.040, rel=1e-9 if not all_terms else 1e-3)
    assert setup["workpiece"]["offset_mm"][0] == pytest.approx(1.2)
    # the machine's compensation is as before: the set-up never goes into calibrated.urdf
    assert "EB0T" not in (out / "calibrated.urdf").read_text().split("-->")[0]
