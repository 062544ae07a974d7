"""A prior on the errors' sizes for small noisy data (``kinid identify --prior``).

Truth: the ROS-style arm of examples/ur_like.urdf with location errors drawn at random, its marker positions
computed in plain numpy from the URDF text (benchmarks/proving_truth.py), 20 poses measured with 0.5 mm noise:
few, noisy poses, where the plain fit of 48 effects follows the noise.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from kinid.cli import main
from kinid.identification import default_model, fit
from kinid.identification.model.machine import machine_from_urdf
from kinid.identification.data.observations import Observations
from kinid.identification.fitting.prior import choose_prior, held_out_check, prior_std
from kinid.identification.fitting.residuals import design, residuals
from kinid.identification.model.urdf_import import identification_urdf

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
import proving_truth as truth  # noqa: E402

NOISE_MM = 0.5


def _arm():
    text = identification_urdf((ROOT / "examples" / "ur_like.urdf").read_text(), base="world", tool="wrist_3_link",
                               tool_offset_m=(0.0, 0.0, 0.1))
    return text, machine_from_urdf(text, "arm.urdf")


def _poses(machine, tm, errors, n, rng, noise_mm):
    q = {a.name: rng.uniform(-120, 120, n) for a in machine.axes}
    values = {a.joint: q[a.name] for a in machine.axes}
    p = truth.tool_point_mm(tm, values, {k: np.full(n, v) for k, v in errors.items()}, n)
    axes = np.column_stack([q[a.name] for a in machine.axes])
    return Observations(tuple(f"P{i}" for i in range(n)), p + rng.normal(0, noise_mm, (n, 3)), axes, None, {},
                        tuple(range(2, n + 2)), "<arm>")


def _held_out_mm(machine, effects, result, test):
    r = residuals(machine, design(machine, effects, test), test, result.theta, jacobian=False)
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))) / 1e3


def _few_noisy(machine, tm, seed):
    """20 noisy training poses and 200 exact test poses of the arm with location errors of 0.3 mm / mrad and a
    measurement frame set up within millimetres, drawn from ``seed``."""
    rng = np.random.default_rng(seed)
    errors = {e.code: rng.normal(0, 300.0) for e in machine.error_joints if e.axis not in ("W", "T")}
    errors.update({f"E{d}0W": rng.normal(0, 2000.0) for d in "XYZABC"})
    return _poses(machine, tm, errors, 20, rng, NOISE_MM), _poses(machine, tm, errors, 200, rng, 0.0)


def _map_fit(machine, train, effects):
    """The prior's fit, its scale and σ chosen by the evidence of ``train``."""
    choice = choose_prior(machine, train, effects)
    return fit(machine, train, effects, noise_um=choice.noise_um, prior_std=prior_std(machine, effects, choice.scale))


def test_the_prior_predicts_unseen_poses_better_than_the_plain_fit_on_few_noisy_ones():
    text, machine = _arm()
    tm = truth.read_urdf(text)
    effects = list(default_model(machine))
    ratios = []
    for seed in range(5):
        train, test = _few_noisy(machine, tm, 40 + seed)
        plain = fit(machine, train, effects)
        mapped = _map_fit(machine, train, effects)
        ratios.append(_held_out_mm(machine, effects, mapped, test) / _held_out_mm(machine, effects, plain, test))
        assert not mapped.implausible(), mapped.implausible()
    print(f"held-out error, prior / plain: {np.round(ratios, 3)}")
    assert sum(r < 1.0 for r in ratios) >= 4 and np.median(ratios) < 0.9


def test_the_held_out_check_tells_what_fresh_poses_tell():
    """The nested check identify --prior prints (leave-one-out on the 20 poses, the scale chosen without the pose
    left out) against 200 fresh poses of the same arm: both say the prior predicts better, and the check's error,
    less the noise of the pose left out, is the fresh poses' error within the spread of 20 poses."""
    text, machine = _arm()
    tm = truth.read_urdf(text)
    effects = list(default_model(machine))
    train, test = _few_noisy(machine, tm, 41)
    check = held_out_check(machine, train, effects)
    mapped = _map_fit(machine, train, effects)
    fresh = [_held_out_mm(machine, effects, f, test) for f in (mapped, fit(machine, train, effects))]
    print(check.describe(), f"fresh poses: prior {fresh[0]:.3f} mm, plain {fresh[1]:.3f} mm")
    assert check.prior_um < check.plain_um and fresh[0] < fresh[1]
    without_noise = np.sqrt(max((check.prior_um / 1e3) ** 2 - 3 * NOISE_MM**2, 0.0))
    assert 0.5 * fresh[0] < without_noise < 2.0 * fresh[0]


def test_a_prior_as_wide_as_nothing_is_the_plain_fit():
    text, machine = _arm()
    tm = truth.read_urdf(text)
    rng = np.random.default_rng(7)
    obs = _poses(machine, tm, {"EX0J2": 200.0, "EC0J3": -300.0}, 60, rng, 0.05)
    effects = list(default_model(machine))
    plain = fit(machine, obs, effects, noise_um=50.0)
    wide = fit(machine, obs, effects, noise_um=50.0, prior_std=prior_std(machine, effects, 1e9))
    # the same fit: aliased parameters the plain fit holds are split by the (faint) prior instead, so values
    # differ where the data cannot tell them apart; the residual and the prediction of unseen poses do not
    test = _poses(machine, tm, {"EX0J2": 200.0, "EC0J3": -300.0}, 100, rng, 0.0)
    assert wide.rms_um == pytest.approx(plain.rms_um, rel=5e-3)
    held = [_held_out_mm(machine, effects, f, test) for f in (plain, wide)]
    print(f"held-out: plain {held[0] * 1e3:.2f} µm, prior ×1e9 {held[1] * 1e3:.2f} µm")
    assert held[1] == pytest.approx(held[0], rel=0.1)


def test_identify_prior_on_the_command_line(tmp_path, capsys):
    text, machine = _arm()
    tm = truth.read_urdf(text)
    (tmp_path / "arm.urdf").write_text(text)
    obs = _poses(machine, tm, {"EX0J2": 200.0}, 20, np.random.default_rng(3), NOISE_MM)
    from kinid.identification.data.observations import write_observations

    write_observations(tmp_path / "obs.csv", obs, machine)
    run = ["identify", "--machine", str(tmp_path / "arm.urdf"), "--data", str(tmp_path / "obs.csv")]
    assert main([*run, "--prior", "--out", str(tmp_path / "fit.json")]) == 0
    out = capsys.readouterr().out
    assert "maximum a posteriori estimate" in out and "chosen by the marginal likelihood" in out
    assert "held-out check (leave-one-out" in out and "plain least squares" in out
    assert "held-out check" in json.loads((tmp_path / "fit.json").read_text())["prior"]
    assert "chosen by the marginal likelihood" in json.loads((tmp_path / "fit.json").read_text())["prior"]
    assert main([*run, "--prior-um", "200", "--out", str(tmp_path / "g.json")]) == 2
    assert "add --prior" in capsys.readouterr().err
    assert main([*run, "--prior", "--auto", "--out", str(tmp_path / "g.json")]) == 2
    assert not (tmp_path / "g.json").exists()


def test_a_value_far_beyond_its_prior_is_flagged_and_the_prior_is_saved(tmp_path):
    """A location error of 0.8 mm under a prior of 0.1 mm: inside the 1 mm a machine may have, but beyond
    PRIOR_MULTIPLE (5) prior standard deviations — flagged; FIT.json keeps the prior and the flag."""
    from kinid.identification.fitting.fit_file import load_fit, save_fit

    text, machine = _arm()
    tm = truth.read_urdf(text)
    obs = _poses(machine, tm, {"EX0J2": 800.0}, 60, np.random.default_rng(9), 0.05)
    effects = list(default_model(machine))
    result = fit(machine, obs, effects, noise_um=50.0, prior_std=prior_std(machine, effects, 0.1))
    flagged = {a.effect: a for a in result.implausible()}
    assert "EX0J2" in flagged and flagged["EX0J2"].limit == pytest.approx(500.0), flagged
    assert 500.0 < flagged["EX0J2"].size < 1000.0
    assert not fit(machine, obs, effects, noise_um=50.0).implausible()  # least squares: within a machine's 1 mm
    save_fit(result, tmp_path / "fit.json")
    again = load_fit(tmp_path / "fit.json")
    assert np.array_equal(np.isfinite(again.prior_std), np.isfinite(result.prior_std))
    assert {a.effect for a in again.implausible()} == set(flagged)
