"""``kinid verify``: the run measured after loading the compensation.

Truth: the hand-written numpy B/C machine of tests/bc_camera_sim.py (a 10 mm lead of X, C-axis offsets, a
tool length error). The second run is made on that machine through the compensation as a controller
applies it (tests/plain_machine.py: plain Pinocchio on calibrated.urdf with the axis tables and the
offsets of setup.json): the readings logged are the controller's, the nominal machine's with the work
and tool offsets; the axes physically go where the compensation sends them.
"""
from __future__ import annotations

import json
import re
import sys

import numpy as np
import pytest

import bc_camera_sim as sim
from kinid.cli import main
from kinid.urdf import path as urdf_path
from plain_machine import PlainMachine

MACHINE = str(urdf_path("five_axis_bc"))
SIGMA_UM = 0.4
HEADER = "mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg,mark_dx_mm,mark_dy_mm,mark_dz_mm\n"


def _row(k, mark, shown, b, c, seen, rng):
    seen = seen + rng.normal(0.0, SIGMA_UM * 1e-3, 3)
    return (f"M{k},{mark[0]:.6f},{mark[1]:.6f},{mark[2]:.6f},{shown[0]:.9f},{shown[1]:.9f},{shown[2]:.9f},"
            f"{b:.6f},{c:.6f},{seen[0]:.9f},{seen[1]:.9f},{seen[2]:.9f}\n")


def first_run(path, rng):
    """No compensation: the readings are the axes' own; the operator stops within ~30 µm of each mark."""
    lines = [HEADER]
    for k, (b, c, mark) in enumerate(sim.plan()):
        r = sim.align(mark, b, c) + rng.normal(0.0, 0.03, 3)
        lines.append(_row(k, mark, r, b, c, sim.seen_offset(r, b, c, mark), rng))
    path.write_text("".join(lines))


def second_run(path, comp, rng, *, compensated=True):
    """Other poses; the controller shows the nominal machine's readings (work and tool offsets applied) and,
    compensated, sends the axes where the calibrated machine reaches the same point."""
    shown_machine = PlainMachine(urdf=MACHINE, setup=comp / "setup.json")
    moved_machine = PlainMachine(comp)
    lines = [HEADER]
    poses = sim.plan(tilts=(-30.0, 10.0, 35.0), turns=(30.0, 90.0, 150.0, 210.0, 270.0, 330.0),
                     marks=((30.0, 25.0), (-35.0, 20.0), (-20.0, -40.0), (45.0, -30.0)))
    for k, (b, c, mark) in enumerate(poses):
        start = sim.align(mark, b, c)
        aligned = shown_machine.solve(np.array(mark), {"B": b, "C": c}, start=start)
        shown = np.array([aligned["X"], aligned["Y"], aligned["Z"]]) + rng.normal(0.0, 0.03, 3)
        if compensated:
            target = shown_machine.tool_in_workpiece_mm({"X": shown[0], "Y": shown[1], "Z": shown[2], "B": b, "C": c})
            moved = moved_machine.solve(target, {"B": b, "C": c}, start=shown)
            physical = np.array([moved["X"], moved["Y"], moved["Z"]])
        else:
            physical = shown
        lines.append(_row(k, mark, shown, b, c, sim.seen_offset(physical, b, c, mark), rng))
    path.write_text("".join(lines))


@pytest.fixture(scope="module")
def compensated(tmp_path_factory):
    folder = tmp_path_factory.mktemp("verify")
    rng = np.random.default_rng(11)
    first_run(folder / "run1.csv", rng)
    assert main(["identify", "--machine", MACHINE, "--data", str(folder / "run1.csv"), "--noise-um", str(SIGMA_UM),
                 "--add", "EXX:periodic:10", "--out", str(folder / "fit.json")]) == 0
    assert main(["compensate", "--fit", str(folder / "fit.json"), "--out", str(folder / "comp")]) == 0
    return folder


def test_verify_shows_the_error_falling_to_the_noise_level(compensated, capsys):
    folder = compensated
    second_run(folder / "run2.csv", folder / "comp", np.random.default_rng(12))
    capsys.readouterr()
    assert main(["verify", "--compensation", str(folder / "comp"), "--data", str(folder / "run2.csv"), "--json"]) == 0
    v = json.loads(capsys.readouterr().out)
    print(f"before {v['before_um']['3d']:.3f} µm, after {v['after_um']['3d']:.3f} µm, "
          f"noise level {v['noise_level_3d_um']:.3f} µm, p = {v['chi2_p']}")
    assert v["before_um"]["3d"] > 5 * v["after_um"]["3d"]
    assert v["after_um"]["3d"] <= 1.5 * v["noise_level_3d_um"]
    assert v["at_noise_level"] and v["noise_source"] == "fit"
    # the first run measured: a set-up-only fit of it leaves the machine's errors
    assert main(["verify", "--fit", str(folder / "fit.json"), "--data", str(folder / "run2.csv"), "--before",
                 str(folder / "run1.csv"), "--report", str(folder / "report")]) == 0
    out = capsys.readouterr().out
    assert "measured in the first run" in out and "the compensation worked" in out
    assert (folder / "report" / "index.html").exists() and (folder / "report" / "before_after.png").exists()


def test_verify_says_what_is_left_when_the_compensation_was_not_loaded(compensated, capsys):
    folder = compensated
    second_run(folder / "run2_plain.csv", folder / "comp", np.random.default_rng(13), compensated=False)
    capsys.readouterr()
    assert main(["verify", "--fit", str(folder / "fit.json"), "--data", str(folder / "run2_plain.csv"), "--json"]) == 0
    v = json.loads(capsys.readouterr().out)
    assert not v["at_noise_level"]
    assert v["after_um"]["3d"] > 5 * v["noise_level_3d_um"]
    # without the compensation the second run measures the error the fit predicted for it
    assert v["after_um"]["3d"] == pytest.approx(v["before_um"]["3d"], rel=0.2)
    assert v["remaining_best_candidate"]["effect"].startswith(("EXX:periodic", "EX0C", "EY0C", "EZ0T"))


def test_verify_refuses_a_fit_that_is_not_the_compensations(compensated, tmp_path, capsys):
    folder = compensated
    (tmp_path / "comp").mkdir()
    info = json.loads((folder / "comp" / "compensation.json").read_text())
    info["fit"]["sha256"] = "0" * 64
    (tmp_path / "comp" / "compensation.json").write_text(json.dumps(info))
    assert main(["verify", "--compensation", str(tmp_path / "comp"), "--data", str(folder / "run1.csv")]) == 2
    assert "not the fit the compensation" in capsys.readouterr().err


def test_verify_tests_against_the_fits_own_sigma_when_it_was_estimated(compensated, capsys):
    """A fit made without --noise-um estimated σ from its residuals; verify carries that estimate (with the fit's
    degrees of freedom, an F test) instead of estimating σ from the run it judges, which can never fail."""
    folder = compensated
    assert main(["identify", "--machine", MACHINE, "--data", str(folder / "run1.csv"), "--add", "EXX:periodic:10",
                 "--out", str(folder / "fit_est.json")]) == 0
    fit = json.loads((folder / "fit_est.json").read_text())
    assert fit["noise_source"] == "residuals"
    assert main(["compensate", "--fit", str(folder / "fit_est.json"), "--out", str(folder / "comp_est")]) == 0
    second_run(folder / "run2_est.csv", folder / "comp_est", np.random.default_rng(21))
    second_run(folder / "run2_est_plain.csv", folder / "comp_est", np.random.default_rng(22), compensated=False)
    capsys.readouterr()
    verdicts = {}
    for name in ("run2_est", "run2_est_plain"):
        assert main(["verify", "--compensation", str(folder / "comp_est"), "--data", str(folder / f"{name}.csv"),
                     "--json"]) == 0
        verdicts[name] = json.loads(capsys.readouterr().out)
    done, not_loaded = verdicts["run2_est"], verdicts["run2_est_plain"]
    for v in verdicts.values():
        assert v["noise_source"] == "fit" and v["noise_dof"] == fit["dof"]
        assert v["noise_um"] == pytest.approx(fit["noise_um"])
        assert v["chi2_p"] is not None  # a test was made
    assert done["at_noise_level"] and done["chi2_p"] >= 0.01
    assert not not_loaded["at_noise_level"] and not_loaded["chi2_p"] < 1e-6
    assert main(["verify", "--compensation", str(folder / "comp_est"), "--data", str(folder / "run2_est_plain.csv")]) == 0
    out = capsys.readouterr().out
    assert "the fit's estimate from its own residuals" in out and "F test p = " in out


def test_verify_says_made_worse_and_where(tmp_path, capsys):
    """A compensation loaded with the wrong sign doubles the machine's errors: the second run is simulated with
    twice the errors of examples/errors.json (the set-up as it was). Verify says "made worse", not "check that the
    compensation is loaded", and names the pose where the error grew most."""
    errors = json.loads(open("examples/errors.json").read())
    doubled = {k: v if k.endswith("W") else (2 * v if not isinstance(v, list) else [2 * x for x in v])
               for k, v in errors.items()}
    (tmp_path / "doubled.json").write_text(json.dumps(doubled))
    run = ["simulate", "--machine", MACHINE, "--plan", "patent", "--noise-um", "0.5"]
    assert main(run + ["--errors", "examples/errors.json", "--seed", "1", "--out", str(tmp_path / "run1.csv")]) == 0
    assert main(["identify", "--machine", MACHINE, "--data", str(tmp_path / "run1.csv"), "--add", "EXX:periodic:10",
                 "--noise-um", "0.5", "--out", str(tmp_path / "fit.json")]) == 0
    assert main(run + ["--errors", str(tmp_path / "doubled.json"), "--seed", "2",
                       "--out", str(tmp_path / "run2.csv")]) == 0
    capsys.readouterr()
    assert main(["verify", "--fit", str(tmp_path / "fit.json"), "--data", str(tmp_path / "run2.csv"), "--json"]) == 0
    v = json.loads(capsys.readouterr().out)
    print(f"before {v['before_um']['3d']:.3f} µm, after {v['after_um']['3d']:.3f} µm; grew most {v['grew_most']}")
    assert v["after_um"]["3d"] == pytest.approx(2 * v["before_um"]["3d"], rel=0.2)  # twice the error
    assert v["made_worse"] and not v["at_noise_level"]
    g = v["grew_most"]
    assert {"B", "C"} <= set(g["readings"]) and g["after_um"] - g["before_um"] >= \
        v["after_um"]["3d"] - v["before_um"]["3d"]
    assert main(["verify", "--fit", str(tmp_path / "fit.json"), "--data", str(tmp_path / "run2.csv"),
                 "--report", str(tmp_path / "report")]) == 0
    out = capsys.readouterr().out
    assert "verdict: made worse" in out and "the error grew most at " in out and f"(mark {g['mark']}" in out
    assert f"B = {g['readings']['B']:.4g}" in out
    assert "check that the compensation is loaded" not in out
    assert "Made worse" in (tmp_path / "report" / "index.html").read_text()


def test_the_loop_works_on_a_urdf_whose_rotary_travels_are_wider_than_the_data(tmp_path, capsys):
    """The same loop on the machine's URDF with B's travel ±10 rad (as generated URDFs and many ROS files give it;
    C's is two turns), B measured over −40…40°: the tables cover the readings, and the second run, made through
    the compensation as a controller applies it, is at the noise level ("worked")."""
    text = (urdf_path("five_axis_bc")).read_text()
    text = text.replace('<limit lower="-1.5708" upper="1.5708"', '<limit lower="-10" upper="10"')
    wide = tmp_path / "bc_wide.urdf"
    wide.write_text(text)
    rng = np.random.default_rng(21)
    first_run(tmp_path / "run1.csv", rng)
    assert main(["identify", "--machine", str(wide), "--data", str(tmp_path / "run1.csv"), "--noise-um",
                 str(SIGMA_UM), "--add", "EXX:periodic:10", "--out", str(tmp_path / "fit.json")]) == 0
    assert main(["compensate", "--fit", str(tmp_path / "fit.json"), "--out", str(tmp_path / "comp")]) == 0
    second_run(tmp_path / "run2.csv", tmp_path / "comp", np.random.default_rng(22))
    capsys.readouterr()
    assert main(["verify", "--compensation", str(tmp_path / "comp"), "--data", str(tmp_path / "run2.csv"),
                 "--json"]) == 0
    v = json.loads(capsys.readouterr().out)
    print(f"wide travels: before {v['before_um']['3d']:.3f} µm, after {v['after_um']['3d']:.3f} µm, "
          f"noise level {v['noise_level_3d_um']:.3f} µm")
    assert v["after_um"]["3d"] <= 1.5 * v["noise_level_3d_um"] and v["before_um"]["3d"] > 5 * v["after_um"]["3d"]


def test_verify_says_its_long_steps_on_a_terminal_and_only_there(compensated, monkeypatch, capsys):
    """On a terminal each step says what it does (here every step, STEP_SHOWN_S set to 0); the JSON on stdout is
    untouched, and with stderr not a terminal nothing is said."""
    import io

    import kinid.progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    folder = compensated
    second_run(folder / "run_steps.csv", folder / "comp", np.random.default_rng(13))
    monkeypatch.setattr(kinid.progress, "STEP_SHOWN_S", 0.0)
    args = ["verify", "--compensation", str(folder / "comp"), "--data", str(folder / "run_steps.csv"), "--json",
            "--report", str(folder / "steps_report")]
    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(args) == 0
    lines = terminal.getvalue().splitlines()
    assert re.fullmatch(r"fitting the set-up to the \d+ alignments of the run and judging what is left …", lines[0])
    assert lines[1].startswith("fitting the set-up to the") and ": done in " in lines[1]
    assert lines[2] == f"writing the report to {folder / 'steps_report'} …" and ": done in " in lines[3]
    assert "after_um" in json.loads(capsys.readouterr().out)
    monkeypatch.undo()
    monkeypatch.setattr(kinid.progress, "STEP_SHOWN_S", 0.0)
    assert main(args) == 0
    assert "…" not in capsys.readouterr().err
