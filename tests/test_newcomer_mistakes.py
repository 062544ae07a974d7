"""A newcomer's mistakes, each made on a simulated run of the README's five-axis flow: the command exits 2 with
one line naming the likely mistake and writes nothing; the same run without the mistake exits 0.

The mistakes are plain scalings of the CSV's columns (metres, inches, radians) and σ typed in mm; the truth
is the run simulated by kinid.identification.fitting.simulate with the README's error set.
"""
import json
import math
import warnings

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification.data import read_observations, unit_hints
from kinid.identification.data.observations import write_observations
from kinid.identification.fitting import errors_from_mapping, patent_plan, simulate
from kinid.identification.model import load_machine
from kinid.urdf import path

BC = str(path("five_axis_bc"))
#: The README's error set (examples/errors.json): the default model lacks the periodic error of X.
ERRORS = {"EX0C": 12.0, "EA0B": -25.0, "EC0Y": 8.0, "EX0W": 1.5, "EXX:periodic:10": [1.5, -0.8]}


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    d = tmp_path_factory.mktemp("newcomer")
    machine = load_machine(BC)
    effects, theta = errors_from_mapping(ERRORS, machine)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=1.0, rng=np.random.default_rng(5))
    write_observations(d / "obs.csv", obs, machine)
    return d


def _scaled(src, dst, columns, scale):
    """``src`` with each cell of ``columns`` replaced by ``scale(value)``: the unit a newcomer wrote."""
    rows = src.read_text().splitlines()
    header = rows[0].split(",")
    index = [header.index(c) for c in columns]
    out = [rows[0]]
    for line in rows[1:]:
        cells = line.split(",")
        for j in index:
            cells[j] = f"{scale(float(cells[j])):.9f}"
        out.append(",".join(cells))
    dst.write_text("\n".join(out) + "\n")
    return dst


def _one_line(capsys):
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    return lines[0]


MISTAKES = [  # (columns, scale, what the refusal must name)
    (("wx_mm", "wy_mm", "wz_mm"), lambda v: v / 1000, "wx_mm, wy_mm, wz_mm look like metres"),
    (("wx_mm", "wy_mm", "wz_mm"), lambda v: v / 25.4, "wx_mm, wy_mm, wz_mm look like inches"),
    (("x_mm",), lambda v: v / 25.4, "x_mm looks like inches"),
    (("x_mm", "y_mm", "z_mm"), lambda v: v / 25.4, "x_mm, y_mm, z_mm look like inches"),
    (("z_mm",), lambda v: v / 1000, "z_mm looks like metres"),
    (("b_deg", "c_deg"), math.radians, "b_deg, c_deg look like radians"),
    (("c_deg",), math.radians, "c_deg looks like radians"),
]


@pytest.mark.parametrize("columns, scale, named", MISTAKES, ids=[m[2] for m in MISTAKES])
@pytest.mark.parametrize("noise", [["--noise-um", "1"], []], ids=["sigma given", "sigma from residuals"])
def test_a_unit_mistake_is_refused_and_named(run, tmp_path, capsys, columns, scale, named, noise):
    data = _scaled(run / "obs.csv", tmp_path / "mistake.csv", columns, scale)
    before = data.read_bytes()
    out = tmp_path / "fit.json"
    assert main(["identify", "--machine", BC, "--data", str(data), *noise, "--out", str(out)]) == 2
    line = _one_line(capsys)
    assert "mistake.csv" in line and named in line and "no fit written" in line, line
    assert not out.exists()
    assert data.read_bytes() == before


def test_sigma_typed_in_mm_is_refused_and_named(run, tmp_path, capsys):
    """σ 0.001 (mm meant, µm read): the README's run leaves about 1.2 µm, over 1000× that σ."""
    out = tmp_path / "fit.json"
    assert main(["identify", "--machine", BC, "--data", str(run / "obs.csv"), "--noise-um", "0.001",
                 "--out", str(out)]) == 2
    line = _one_line(capsys)
    assert "× the σ given (0.001 µm" in line and "likely σ typed in mm" in line, line
    ratio = float(line.split(" µm is ")[1].split("×")[0])
    assert 800 < ratio < 1500, line
    assert not out.exists()


def test_the_auto_path_refuses_too_and_writes_no_report(run, tmp_path, capsys):
    data = _scaled(run / "obs.csv", tmp_path / "mistake.csv", ("wx_mm", "wy_mm", "wz_mm"), lambda v: v / 1000)
    out, report = tmp_path / "fit.json", tmp_path / "steps"
    assert main(["identify", "--machine", BC, "--data", str(data), "--noise-um", "1", "--auto",
                 "--report", str(report), "--out", str(out)]) == 2
    err = capsys.readouterr().err  # --auto reports its steps on stderr; the refusal is the last line
    assert "wx_mm, wy_mm, wz_mm look like metres" in err.strip().splitlines()[-1], err
    assert not out.exists() and not report.exists()


def test_the_prior_path_refuses_too(run, tmp_path, capsys):
    """--prior with σ typed in mm, on 48 alignments (the first four B tilts of the plan's 336 are 4 × 48 rows)."""
    rows = (run / "obs.csv").read_text().splitlines()
    (tmp_path / "few.csv").write_text("\n".join(rows[:49]) + "\n")
    out = tmp_path / "fit.json"
    assert main(["identify", "--machine", BC, "--data", str(tmp_path / "few.csv"), "--noise-um", "0.001",
                 "--prior", "--no-check", "--out", str(out)]) == 2
    line = _one_line(capsys)
    assert "likely σ typed in mm" in line, line
    assert not out.exists()


def test_the_right_run_and_a_missing_effect_are_written_without_a_warning(run, tmp_path, capsys):
    """The README's run in the right units: no unit warning; the default model misses the periodic error of X
    (a few σ at most: the diagnosis starts from this fit) and is written, exit 0."""
    out = tmp_path / "fit.json"
    assert main(["identify", "--machine", BC, "--data", str(run / "obs.csv"), "--noise-um", "1",
                 "--out", str(out)]) == 0
    assert capsys.readouterr().err == ""
    fit = json.loads(out.read_text())
    assert fit["success"] and 1.0 < fit["rms_um"] < 3.0
    machine = load_machine(BC)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert unit_hints(machine, read_observations(run / "obs.csv", machine)) == ()


@pytest.mark.parametrize("name", ["five_axis_bc", "five_axis_ac", "five_axis_bhead_c"])
def test_no_unit_hint_on_right_units_with_a_large_set_up(tmp_path, name):
    """Board set up 0.9 mm and 5 mrad off: the rigid placement takes it; no column looks wrong."""
    machine = load_machine(path(name))
    effects, theta = errors_from_mapping({"EX0W": 900.0, "EY0W": -800.0, "EC0W": 5000.0, "EX0C": 30.0}, machine)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=1.0, rng=np.random.default_rng(2))
    assert unit_hints(machine, obs) == ()
    radians = obs.axes.copy()
    rotary = [j for j, a in enumerate(machine.axes) if a.kind == "revolute"]
    radians[:, rotary] = np.radians(radians[:, rotary])
    from dataclasses import replace

    (hint,) = unit_hints(machine, replace(obs, axes=radians))
    assert hint.unit == "radians" and hint.undone_mm < 0.05 * hint.misfit_mm


def test_reading_a_file_in_radians_warns(run, tmp_path):
    """Readers other than identify (diagnose, verify) warn of the likely unit when the file is read."""
    data = _scaled(run / "obs.csv", tmp_path / "rad.csv", ("b_deg", "c_deg"), math.radians)
    with pytest.warns(UserWarning, match=r"rad.csv: b_deg, c_deg look like radians, not degrees: multiplied by 57.2958 "):
        read_observations(data, load_machine(BC))


# --- no fit that cannot be trusted reaches a controller ------------------------------------------------------

@pytest.fixture(scope="module")
def good_fit(run):
    out = run / "fit2.json"
    assert main(["identify", "--machine", BC, "--data", str(run / "obs.csv"), "--add", "EXX:periodic:10",
                 "--noise-um", "1", "--out", str(out)]) == 0
    return out


EDITS = [  # (what an older or hand-edited file holds, what the refusal names)
    ({"success": False, "message": "did not converge in 100 iterations", "iterations": 100},
     "the fit did not converge in 100 iterations"),
    ({"noise_um": 0.001}, "× the σ given (0.001 µm"),
]


@pytest.mark.parametrize("edit, named", EDITS, ids=["not converged", "sigma in mm"])
def test_compensate_and_verify_refuse_a_fit_that_cannot_be_trusted(run, good_fit, tmp_path, capsys, edit, named):
    assert main(["compensate", "--fit", str(good_fit), "--out", str(tmp_path / "ok")]) == 0
    capsys.readouterr()
    data = json.loads(good_fit.read_text())
    data.update(edit)
    bad = tmp_path / "edited.json"
    bad.write_text(json.dumps(data))
    before = bad.read_bytes()
    comp = tmp_path / "comp"
    assert main(["compensate", "--fit", str(bad), "--out", str(comp)]) == 2
    line = _one_line(capsys)
    assert line.startswith(f"kinid compensate: {bad}: ") and named in line and "is not used" in line, line
    assert not comp.exists()
    report = tmp_path / "verify"
    assert main(["verify", "--fit", str(bad), "--data", str(run / "obs.csv"), "--report", str(report)]) == 2
    line = _one_line(capsys)
    assert f"{bad}: " in line and named in line, line
    assert not report.exists()
    assert bad.read_bytes() == before


def test_a_long_file_is_judged_on_a_spread_of_its_rows(run):
    """Past HINT_ROWS rows the clouds are compared on an even spread of them: the same mistake is named."""
    from dataclasses import replace

    from kinid.identification.data.units import HINT_ROWS

    machine = load_machine(BC)
    obs = read_observations(run / "obs.csv", machine)
    long = obs.subset(np.tile(np.arange(len(obs)), HINT_ROWS // len(obs) + 2))
    assert len(long) > HINT_ROWS and unit_hints(machine, long) == ()
    (hint,) = unit_hints(machine, replace(long, w_mm=long.w_mm / 1000))
    assert hint.columns == ("wx_mm", "wy_mm", "wz_mm") and hint.unit == "metres" and hint.factor == 1000


def test_the_documented_hole_measurement_is_not_taken_for_metres_and_one_in_metres_is(tmp_path, capsys):
    """`kinid sensor --hole examples/sensor_hole.csv` (docs/observe.md) warned "if they are metres" of its z column,
    which is near zero on every set-up measurement; the readings' reach tells metres instead."""
    from pathlib import Path

    hole = Path(__file__).resolve().parents[1] / "examples" / "sensor_hole.csv"
    assert main(["sensor", "--machine", str(path("five_axis_bc")), "--hole", str(hole),
                 "--out", str(tmp_path / "s.json")]) == 0
    assert "metres" not in capsys.readouterr().err
    rows = [line.split(",") for line in hole.read_text().splitlines()]
    in_metres = [rows[0]] + [[r[0]] + [f"{float(v) / 1000:.7f}" for v in r[1:4]] + r[4:] for r in rows[1:]]
    (tmp_path / "hole_m.csv").write_text("\n".join(",".join(r) for r in in_metres) + "\n")
    assert main(["sensor", "--machine", str(path("five_axis_bc")), "--hole", str(tmp_path / "hole_m.csv"),
                 "--out", str(tmp_path / "s2.json")]) == 0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "hole_m.csv" in err and "multiply by 1000" in err
