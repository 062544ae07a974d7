"""The held-out check of a searched candidate also chooses it again on the training blocks alone: a periodic
candidate's period, a local error's window, a warm-up's time constant.

The best period of a search over many is fitted to the noise of every alignment, the held-out blocks' too: on
pure noise it "predicts" them better than it would new alignments (the selection bias the check's docstring
measures). Chosen again on each turn's training blocks, the gain is what the period search brings to data it
did not see. Truth here: the patent plan on the B/C table, 1 µm noise, a lead of X written as a plain formula (for
the warm-ups, the proving ground's plain-numpy machine).
"""
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from kinid.identification import forward_select, load_machine
from kinid.identification.fitting.crossval import cross_validate
from kinid.identification.model.effects import default_model, parse_effect
from kinid.identification.fitting.fit import fit
from kinid.identification.fitting.leverage import model_pass
from kinid.identification.diagnosis.local_errors import local_windows, window_found_on
from kinid.identification.diagnosis.periods import search_periods
from kinid.identification.diagnosis.selection import _chosen_again
from kinid.identification.fitting.simulate import patent_plan, simulate
from kinid.urdf import path

sys.path.insert(0, str(Path(__file__).parent))
from test_period_search import _location_truth, _with_x_bump, _with_x_error  # noqa: E402
from test_proving_ground import _data, pg  # noqa: E402


@pytest.fixture(scope="module")
def bc():
    return load_machine(path("five_axis_bc"))


def _gains(machine, seed, lead_um):
    """Held-out gain (standard errors) of the best searched period: (chosen on all data, chosen per turn)."""
    rng = np.random.default_rng(seed)
    effects, theta = _location_truth(machine, rng)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=1.0, rng=rng)
    if lead_um:
        obs = _with_x_error(machine, obs, lead_um, 13.3, 0.7)
    model = default_model(machine)
    result = fit(machine, obs, model, noise_um=1.0)
    d_errors, _, q0 = model_pass(machine, obs, result)
    r = result.residuals_um.ravel()
    best = search_periods(machine, obs, r - q0 @ (q0.T @ r), d_errors, q0)[0].effect
    cv = cross_validate(machine, obs, model, parse_effect(best, machine), noise_um=1.0, theta0=result.theta,
                        choose=_chosen_again(machine, obs, best, result), always_choose=True)
    assert len(cv.chosen) == 4 and cv.improves == (cv.gain_se >= 2.0 and cv.chosen_gain_se >= 1.0)
    return cv.gain_se, cv.chosen_gain_se


def test_on_noise_the_period_chosen_per_turn_has_no_held_out_gain(bc):
    gains = np.array([_gains(bc, seed, 0.0) for seed in range(16)])
    fixed, again = gains.T
    # chosen on all data, the best period of noise gains about a standard error (13 of 16 seeds ≥ 1 when written)
    assert fixed.mean() > 1.0 and np.sum(fixed >= 1.0) >= 10
    # chosen per turn it gains nothing on average (−0.13 when written; 4 of 16 ≥ 1, 1 of 16 ≥ 2: a peak of the
    # noise that every turn finds again)
    assert again.mean() < 0.3 and np.sum(again >= 1.0) <= 5 and np.sum(again >= 2.0) <= 1


def test_a_real_lead_keeps_its_held_out_gain(bc):
    for seed in range(4):
        fixed, again = _gains(bc, seed, 1.0)  # a 1 µm lead under 1 µm noise: 4.7–6.0 standard errors when written
        assert again >= 2.0 and again > 0.9 * fixed


def _window_gains(machine, seed, bump_um):
    """Held-out gain (standard errors) of the likeliest local window of the linear axes' joints: (chosen on all
    data, chosen per turn among the same windows); the table every 20°, a bump of X at −15 mm if ``bump_um``."""
    rng = np.random.default_rng(seed)
    effects, theta = _location_truth(machine, rng)
    plan = patent_plan(machine, tilt_deg=(-60, -30, 0, 30, 60), turn_deg=tuple(range(0, 360, 20)))
    obs = simulate(machine, plan, effects, theta, noise_um=1.0, rng=rng)
    if bump_um:
        obs = _with_x_bump(machine, obs, bump_um, -15.0, 6.0)
    model = default_model(machine)
    result = fit(machine, obs, model, noise_um=1.0)
    windows = [w for code in ("EXX", "EYX", "EZX", "EXY", "EYY", "EZY") for w in local_windows(machine, obs, code)]
    best = window_found_on(machine, obs, result, windows)
    cv = cross_validate(machine, obs, model, best, noise_um=1.0, theta0=result.theta,
                        choose=_chosen_again(machine, obs, best.name, result), always_choose=True)
    # a window chosen per turn must bring the candidate's own 2 standard errors
    assert cv.improves == (cv.rms_with_um < cv.rms_without_um and cv.gain_se >= 2.0 and cv.chosen_gain_se >= 2.0)
    return best.name, cv.gain_se, cv.chosen_gain_se


def test_on_noise_the_window_chosen_per_turn_has_no_held_out_gain(bc):
    """The same for a local error: the likeliest of ~1 700 windows, chosen again per turn among them."""
    gains = np.array([_window_gains(bc, seed, 0.0)[1:] for seed in range(12)])
    fixed, again = gains.T
    assert fixed.mean() > 0.3  # chosen on all data: +0.65 on average when written (5 of 12 ≥ 1)
    # per turn, among the windows its training rows hold up: −0.9 when written (1 of 12 ≥ 1, none ≥ 2)
    assert again.mean() < 0 and again.mean() < fixed.mean() - 1.0 and np.sum(again >= 2.0) == 0


def test_a_real_bump_keeps_its_window_held_out_gain(bc):
    for seed in range(3):
        name, fixed, again = _window_gains(bc, seed, 4.0)
        assert name.startswith("EXX:local:") and again >= 2.0, (name, fixed, again)


def test_every_kind_the_turns_choose_again_has_its_bar_and_name():
    from kinid.identification.fitting.crossval import CHOSEN_AGAIN
    from kinid.identification.diagnosis.selection import CHOOSERS

    assert set(CHOOSERS) == set(CHOSEN_AGAIN)


def test_the_selection_chooses_a_periodic_candidates_period_per_turn(bc, monkeypatch):
    import kinid.identification.fitting.crossval as crossval

    seen = []
    original = crossval.cross_validate

    def spy(machine, obs, effects, candidate, **kw):
        seen.append((candidate.name, kw.get("choose")))
        return original(machine, obs, effects, candidate, **kw)

    monkeypatch.setattr(crossval, "cross_validate", spy)
    rng = np.random.default_rng(3)
    effects, theta = _location_truth(bc, rng)
    obs = _with_x_error(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=1.0, rng=rng), 3.0, 13.3, 0.7)
    steps = forward_select(bc, obs, default_model(bc), noise_um=1.0)
    assert any(e.name.startswith("EXX:periodic:13.3") for e in steps[-1].fit.effects)
    periodic = [choose for name, choose in seen if ":periodic:" in name]
    assert periodic and all(choose is not None for choose in periodic)
    assert all(choose is None for name, choose in seen if ":periodic:" not in name)


def _warm_up_gains(seed, amp_um):
    """Held-out gain (standard errors) of the best warm-up candidate, its time constant refined as the selection
    refines it: (chosen on all data, chosen per turn). The truth: the proving ground's plain-numpy B/C machine, the
    patent plan in random order, 1 µm noise, a warm-up of the tool ``amp_um``·(1 − e^(−t/900 s))."""
    from kinid.identification import diagnose
    from kinid.identification.diagnosis.searched import refined_time_constant

    _, machine, obs = _data(seed, "five_axis_bc", [], {"EZ0T": lambda t: amp_um * (1.0 - np.exp(-t / 900.0))},
                            plan_kind="patent", order="random", misread_share=0.0)
    model = default_model(machine)
    result = fit(machine, obs, model, noise_um=1.0)
    dg = diagnose(machine, obs, model, noise_um=1.0, result=result)
    start = next(c.effect for c in dg.live if ":warmup:" in c.effect)
    name = refined_time_constant(machine, obs, result, start, 1.0)
    cv = cross_validate(machine, obs, model, parse_effect(name, machine), noise_um=1.0, theta0=result.theta,
                        choose=_chosen_again(machine, obs, name, result, start, 1.0), always_choose=True)
    # a time constant chosen per turn must bring the candidate's own 2 standard errors
    assert cv.improves == (cv.rms_with_um < cv.rms_without_um and cv.gain_se >= 2.0 and cv.chosen_gain_se >= 2.0)
    return name, cv.gain_se, cv.chosen_gain_se


def test_on_noise_the_warm_up_chosen_per_turn_does_not_pass():
    """The best of the library's warm-ups (3 time constants on each location joint), its τ refined over a continuum,
    gains about a standard error on noise whether τ is chosen on all data or per turn: the joint was chosen on all
    data. A bar of zero per turn let such a warm-up in at the edge of both tests (proving-ground seed 61 #408)."""
    gains = np.array([_warm_up_gains(seed, 0.0)[1:] for seed in range(12)])
    fixed, again = gains.T
    assert fixed.mean() > 0.5  # +1.0 on 16 seeds when written, per turn +0.8: never 2 on either
    assert np.all(again < 2.0) and again.mean() <= fixed.mean()
    # that warm-up passed at 2.4 on all data and 1.9 per turn: a turn's choice must now bring 2 as well
    from kinid.identification.fitting.crossval import CrossValidation

    edge = CrossValidation(4, 1.005, 1.000, 2.4, 1.9, tuple(f"EB0W:warmup:{t}" for t in (240.1, 501.1, 338.7, 455.2)))
    assert not edge.improves and "(2 needed) with the time constant chosen" in str(edge)
    assert replace(edge, chosen_gain_se=2.1).improves
    sc = pg.run(61 * 100003 + 408)  # the scenario itself: a dual-Y gantry, no effect hidden, σ not given
    assert not sc.hidden and sc.result["added"] == [], sc.result["added"]


def test_a_real_warm_up_keeps_its_held_out_gain_per_turn():
    for seed in range(3):  # 2 µm under 1 µm noise: 3.2–5.8 standard errors on all data when written
        name, fixed, again = _warm_up_gains(seed, 2.0)
        assert name.split(":")[0] in ("EZ0T", "EZ0B") and again >= 2.0 and again > 0.95 * fixed, (name, fixed, again)
