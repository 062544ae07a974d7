"""Compensation only where the data are, and never a file set that makes the machine worse.

The machine: the shipped B/C machine with B's travel widened to ±10 rad (as generated URDFs and many ROS files
give it); the patent plan measures B over −60 … 60° and C at 12 angles round the turn. The truth is the error
set given to the simulator, written here again as plain formulas (a polynomial in the reading, a sine and
cosine of a whole number of periods per turn); every controller file is read back by the independent
consumers of tests/controller_consumers.py (no kinid code), which apply it as its controller does.
"""
from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest

from kinid.axis_tables import CONTROLLER_FORMATS
from kinid.cli import main
from kinid.identification import fit, load_machine, save_fit
from kinid.identification.fitting.fit import model_effects
from kinid.identification.fitting.simulate import errors_from_mapping, load_plan, simulate
from kinid.urdf import path as urdf_path
from controller_consumers import READERS

FORMATS = ("linuxcnc", "sinumerik", "twincat")
SUFFIX = {"linuxcnc": ".comp", "twincat": "_ssfk.lis", "sinumerik": "_EEC_INI.spf"}
B_POLY = (2.0, 0.03, 0.0005)  # EBB:poly3, µrad/deg^k: 336 µrad at 60°
C_PERIODIC = (8.0, 4.0)  # ECC:periodic:90, µrad (sine, cosine)


def b_truth_urad(b_deg, coefficients=B_POLY):
    b = np.asarray(b_deg, float)
    return sum(c * b ** (k + 1) for k, c in enumerate(coefficients))


def c_truth_urad(c_deg, scale=0.0):
    phase = 2 * np.pi * np.asarray(c_deg, float) / 90.0
    return C_PERIODIC[0] * np.sin(phase) + C_PERIODIC[1] * np.cos(phase) + scale * np.asarray(c_deg, float)


def wide_machine(folder):
    text = urdf_path("five_axis_bc").read_text()
    limit = '<limit lower="-1.5708" upper="1.5708"'
    assert text.count(limit) == 1
    (folder / "bc_wide.urdf").write_text(text.replace(limit, '<limit lower="-10" upper="10"'))
    return load_machine(folder / "bc_wide.urdf")


def fitted(folder, truth: dict, name: str):
    """FIT.json of the wide machine with ``truth`` simulated on the patent plan (0.5 µm noise), fitted with it."""
    m = wide_machine(folder)
    effects, theta = errors_from_mapping(truth, m)
    obs = simulate(m, load_plan("patent", m), effects, theta, noise_um=0.5, rng=np.random.default_rng(7))
    result = fit(m, obs, model_effects(m, [n for n in truth if ":" in n]), noise_um=0.5)
    save_fit(result, folder / f"{name}.json")
    return folder / f"{name}.json", result


def applied_urad(folder, fmt, axis, x_deg, forward=True):
    reads = READERS[fmt]((folder / f"{axis}{SUFFIX[fmt]}").read_text(), True)
    return np.radians(reads(x_deg, forward)) * 1e6


@pytest.fixture(scope="module")
def poly_b(tmp_path_factory):
    folder = tmp_path_factory.mktemp("wide")
    fit_json, result = fitted(folder, {"EX0C": 12.0, "EBB:poly3": list(B_POLY), "ECC:periodic:90": list(C_PERIODIC)},
                              "fit")
    return folder, fit_json, result


def test_tables_of_a_wide_travel_cover_the_readings_and_are_never_worse(poly_b, capsys):
    """(a) B's travel ±573°, readings −60 … 60°: not modulo, over the readings; applied by each controller,
    never worse than none anywhere in the measured range; beyond, the end values held."""
    folder, fit_json, result = poly_b
    assert result.axis_ranges["B"] == pytest.approx((-60.0, 60.0))
    out = folder / "comp"
    assert main(["compensate", "--fit", str(fit_json), "--out", str(out), "--format", *FORMATS]) == 0
    said = capsys.readouterr().out
    info = json.loads((out / "compensation.json").read_text())
    b = info["tables"]["B"]
    assert (b["from"], b["to"], b["modulo"]) == (pytest.approx(-60.0), pytest.approx(60.0), False)
    assert info["tables"]["C"]["modulo"] and "checked: each of the" in said
    x = np.linspace(-60.0, 60.0, 2401)
    truth = b_truth_urad(x)
    tol = 0.1 * np.sqrt(np.mean(truth ** 2))
    for fmt in FORMATS:
        for forward in (True, False):
            left = truth - applied_urad(out, fmt, "B", x, forward)
            worst = np.max(np.abs(left) - np.abs(truth))
            print(f"{fmt}: left {np.sqrt(np.mean(left ** 2)):.3g} of {np.sqrt(np.mean(truth ** 2)):.3g} µrad RMS; "
                  f"worst excess over none {worst:.3g} µrad")
            assert worst <= tol
            assert np.sqrt(np.mean(left ** 2)) <= 0.1 * np.sqrt(np.mean(truth ** 2))
        # beyond the readings (the old modulo table gave 0.34° here): the end values, held
        ends = applied_urad(out, fmt, "B", np.array([-573.0, -200.0, 200.0, 573.0]))
        np.testing.assert_allclose(ends, b_truth_urad([-60.0, -60.0, 60.0, 60.0]), atol=0.05 * np.abs(truth).max())


def test_range_travel_is_refused_where_the_travel_is_more_than_the_data(poly_b, capsys):
    folder, fit_json, _ = poly_b
    capsys.readouterr()
    assert main(["compensate", "--fit", str(fit_json), "--out", str(folder / "travel"), "--table-range", "travel"]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "--table-range travel: axis B's travel" in err and "--table-range data" in err
    assert not (folder / "travel").exists()


@pytest.fixture(scope="module")
def scale_errors(tmp_path_factory):
    """Scale errors of both rotary axes: B (−60 … 60°) and C (the readings go all the way round)."""
    folder = tmp_path_factory.mktemp("scale")
    fit_json, result = fitted(folder, {"EX0C": 12.0, "EBB:poly1": [0.5], "ECC:poly1": [0.2],
                                       "ECC:periodic:90": list(C_PERIODIC)}, "fit")
    out = folder / "comp"
    assert main(["compensate", "--fit", str(fit_json), "--out", str(out), "--format", *FORMATS]) == 0
    return out


def test_a_rotary_scale_error_is_compensated_not_dropped(scale_errors, capsys):
    """(b) EBB:poly1 and ECC:poly1: a table that is not modulo over the readings, which removes ≥ 90 % of the
    error; for C, whose readings go round, the scale is stated (ppm) and why the table is not modulo."""
    out = scale_errors
    info = json.loads((out / "compensation.json").read_text())
    for axis, truth_at, (lo, hi) in (("B", lambda q: b_truth_urad(q, (0.5,)), (-60.0, 60.0)),
                                     ("C", lambda q: c_truth_urad(q, 0.2), (0.0, 330.0))):
        table = info["tables"][axis]
        assert not table["modulo"] and (table["from"], table["to"]) == (pytest.approx(lo), pytest.approx(hi))
        x = np.linspace(lo, hi, 2001)
        truth = truth_at(x)
        for fmt in FORMATS:
            left = truth - applied_urad(out, fmt, axis, x)
            removed = 1 - np.sqrt(np.mean(left ** 2)) / np.sqrt(np.mean(truth ** 2))
            print(f"{axis} {fmt}: {removed:.1%} of the error removed")
            assert removed >= 0.90
    why = info["tables"]["C"]["not_modulo"]
    # 0.2 µrad/deg = 0.2 · 180/π µrad/rad
    assert why["scale_ppm"] == pytest.approx(0.2 * 180 / np.pi, rel=0.05)
    assert "scale error" in why["reason"] and info["tables"]["B"]["not_modulo"] is None


@pytest.fixture(scope="module")
def full_turn(tmp_path_factory):
    folder = tmp_path_factory.mktemp("turn")
    fit_json, _ = fitted(folder, {"EX0C": 12.0, "ECC:periodic:90": list(C_PERIODIC)}, "fit")
    out = folder / "comp"
    assert main(["compensate", "--fit", str(fit_json), "--out", str(out), "--format", *FORMATS]) == 0
    return out


def test_readings_all_the_way_round_still_give_a_modulo_table(full_turn):
    """(c) C read at 12 angles round the turn, a periodic error: one turn, modulo, applied anywhere on the turn."""
    out = full_turn
    assert json.loads((out / "compensation.json").read_text())["tables"]["C"]["modulo"]
    assert "kw.ssfk.modulo                      1" in (out / "C_ssfk.lis").read_text()
    assert re.search(r"\$AA_ENC_COMP_IS_MODULO\[0,AX\d+\]=1", (out / "C_EEC_INI.spf").read_text())
    x = np.linspace(-360.0, 720.0, 2161)  # the controllers that wrap: every turn alike
    truth = c_truth_urad(x)
    for fmt in ("sinumerik", "twincat"):
        left = truth - applied_urad(out, fmt, "C", x)
        assert np.sqrt(np.mean(left ** 2)) <= 0.2 * np.sqrt(np.mean(truth ** 2))


def test_a_file_that_would_make_the_machine_worse_is_refused(full_turn, monkeypatch, capsys):
    """(d) A TwinCAT writer that flips the sign: the check reads the file back, finds more error than none,
    and nothing is written."""
    fit_json = full_turn.parent / "fit.json"
    good = CONTROLLER_FORMATS["twincat"]

    def flipped(table, options):
        return good.write(dataclasses.replace(table, forward=-table.forward,
                                              reverse=None if table.reverse is None else -table.reverse), options)

    monkeypatch.setitem(CONTROLLER_FORMATS, "twincat", dataclasses.replace(good, write=flipped))
    capsys.readouterr()
    out = full_turn.parent / "flipped"
    assert main(["compensate", "--fit", str(fit_json), "--out", str(out), "--format", "twincat"]) == 2
    err = capsys.readouterr().err
    print(err)
    assert len(err.strip().splitlines()) == 1
    assert "C_ssfk.lis: applied as the controller applies it, it would leave" in err and " at C = " in err
    assert "nothing written" in err and not out.exists()
    # the same in an earlier folder: it stays as it was
    assert main(["compensate", "--fit", str(fit_json), "--out", str(full_turn), "--format", "twincat"]) == 2
    assert (full_turn / "C.comp").exists()


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("rotary", [False, True])
def test_kinids_readers_agree_with_the_independent_consumers(fmt, rotary):
    """The readers compensate checks its files with (kinid.axis_tables.readers) apply a file as the independent consumers
    of tests/controller_consumers.py do, in both directions, inside, between and beyond the points."""
    from kinid.axis_tables import applied
    from kinid.axis_tables import AxisErrorTable, TableOptions

    rng = np.random.default_rng(3)
    q = np.linspace(0.0, 360.0, 25) if rotary else np.linspace(-80.0, 120.0, 41)
    forward = rng.uniform(-30.0, 30.0, q.size)
    reverse = forward + rng.uniform(-5.0, 5.0, q.size)
    if rotary:
        forward[-1], reverse[-1] = forward[0], reverse[0]
    f = CONTROLLER_FORMATS[fmt]
    text = f.write(AxisErrorTable("C" if rotary else "X", rotary, q, forward, reverse), TableOptions(modulo=rotary))
    mine = f.read(text, rotary)
    theirs = READERS[fmt](text, rotary)
    x = np.linspace(q[0] - 100.0, q[-1] + 100.0, 3001)
    to_unit = (lambda v: np.radians(v) * 1e6) if rotary else (lambda v: v * 1e3)
    for direction in (True, False):
        got = applied(mine, x, direction) if f.bidirectional else applied(mine, x)
        want = to_unit(theirs(x, direction)) if f.bidirectional else to_unit(theirs(x))
        np.testing.assert_allclose(got, want, atol=1e-6)
    assert abs(np.max(np.abs(applied(mine, q))) - np.max(np.abs(forward if f.bidirectional else
                                                              0.5 * (forward + reverse)))) <= f.resolution(rotary)
