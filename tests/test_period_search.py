"""Periods the candidate library does not list are found, named and refined; the error then falls.

The hidden periodic errors are put into the data by a plain formula on the
readings (not by kinid's effect code): for a positioning error e of X, the
reading x that puts the tool where the nominal reading x₀ would solves
x + e(x) = x₀; for an angular positioning error of the table C, the table
stands at c + e(c) when the reading says c. The kinematics of the machine
(location and set-up errors) come from kinid's simulator; the effect under
test does not.
"""
from dataclasses import replace

import re

import numpy as np
import pytest

from kinid.identification import load_machine
from kinid.identification.fitting.alignment import solve_axes
from kinid.identification import diagnose, forward_select
from kinid.identification.diagnosis.selection import what_is_left
from kinid.identification.model.effects import default_model, parse_effect
from kinid.identification.fitting.fit import fit
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.urdf import path

SIGMA = 1.0


@pytest.fixture(scope="module")
def bc():
    return load_machine(path("five_axis_bc"))


def _location_truth(machine, rng):
    truth = {e.code: float(rng.normal(0, 15.0)) for e in default_model(machine)}
    truth.update({"EX0W": 600.0, "EY0W": -400.0, "EC0W": 5000.0})
    return errors_from_mapping(truth, machine)


def _with_x_error(machine, obs, amp_um, period_mm, phase):
    """Readings of X when X has the positioning error amp·sin(2πx/P + phase): solve x + e(x) = x₀."""
    j = machine.axis_names.index("X")
    x0 = obs.axes[:, j].copy()
    x = x0.copy()
    for _ in range(20):
        x = x0 - amp_um * 1e-3 * np.sin(2 * np.pi * x / period_mm + phase)
    axes = obs.axes.copy()
    axes[:, j] = x
    return replace(obs, axes=axes)


def _held_out_rms(machine, result, truth_obs):
    poses = replace(truth_obs, axes=np.where(np.isin(np.arange(truth_obs.axes.shape[1]),
                                                      [machine.axis_names.index(a) for a in "XYZ"]),
                                             np.nan, truth_obs.axes))
    pred = solve_axes(machine, result.effects, result.theta, poses)
    cols = [machine.axis_names.index(a) for a in "XYZ"]
    return float(np.sqrt(np.mean(np.sum((pred.axes[:, cols] - truth_obs.axes[:, cols]) ** 2, axis=1)))) * 1e3


def test_off_list_lead_on_a_linear_axis(bc):
    P, amp = 13.3, 2.5  # a lead the library does not list
    rng = np.random.default_rng(101)
    effects, theta = _location_truth(bc, rng)
    obs = _with_x_error(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=rng), amp, P, 0.7)
    held = _with_x_error(bc, simulate(bc, patent_plan(bc, tilt_deg=(-50, -25, 5, 35, 55), turn_deg=tuple(range(15, 360, 40))),
                                      effects, theta, rng=rng), amp, P, 0.7)

    before = diagnose(bc, obs, default_model(bc), noise_um=SIGMA)
    assert before.verdict == "missing-effect"
    best = before.live[0]
    assert best.effect.startswith("EXX:periodic:"), [c.effect for c in before.live[:5]]
    found = float(best.effect.split(":")[2])
    assert "period found by search" in best.note
    std = float(best.note.split("±")[1].split()[0])
    assert abs(found - P) <= 3 * std and std < 0.2, (found, std)

    steps = forward_select(bc, obs, default_model(bc), noise_um=SIGMA)
    assert steps[-1].diagnosis.verdict == "noise"
    assert steps[1].added.startswith("EXX:periodic:")
    true_fit = fit(bc, obs, default_model(bc) + [parse_effect(f"EXX:periodic:{P}", bc)], noise_um=SIGMA)
    auto, truth, base = (_held_out_rms(bc, r, held) for r in (steps[-1].fit, true_fit, steps[0].fit))
    assert auto <= 1.5 * truth, (auto, truth)
    assert base > 2 * auto, (base, auto)


def test_off_list_period_on_a_rotary_axis(bc):
    """A gear error of the table with 7 periods per turn (51.43°), on a plan with the table every 10°."""
    P, amp_urad = 360.0 / 7.0, 45.0
    rng = np.random.default_rng(202)
    effects, theta = _location_truth(bc, rng)
    c = bc.axis_names.index("C")

    def table_error(obs_plan, noise):
        actual = obs_plan.axes.copy()
        actual[:, c] += np.degrees(amp_urad * 1e-6 * np.sin(np.radians(obs_plan.axes[:, c]) * 7 + 0.4))
        sim = simulate(bc, replace(obs_plan, axes=actual), effects, theta, noise_um=noise, rng=rng)
        axes = sim.axes.copy()
        axes[:, c] = obs_plan.axes[:, c]  # the reading is the commanded angle
        return replace(sim, axes=axes)

    plan = patent_plan(bc, tilt_deg=(-60, -30, 0, 30, 60), turn_deg=tuple(range(0, 360, 10)))
    obs = table_error(plan, SIGMA)
    held = table_error(patent_plan(bc, tilt_deg=(-45, 15, 45), turn_deg=tuple(range(5, 360, 30))), 0.0)

    before = diagnose(bc, obs, default_model(bc), noise_um=SIGMA)
    assert before.verdict == "missing-effect"
    best = before.live[0]
    assert best.effect.startswith("ECC:periodic:"), [c.effect for c in before.live[:5]]
    found = float(best.effect.split(":")[2])
    std = float(best.note.split("±")[1].split()[0])
    assert abs(found - P) <= 3 * std and std < 0.5, (found, std)

    steps = forward_select(bc, obs, default_model(bc), noise_um=SIGMA)
    assert steps[-1].diagnosis.verdict == "noise"
    true_fit = fit(bc, obs, default_model(bc) + [parse_effect(f"ECC:periodic:{P}", bc)], noise_um=SIGMA)
    auto, truth = (_held_out_rms(bc, r, held) for r in (steps[-1].fit, true_fit))
    assert auto <= 1.5 * truth, (auto, truth)


def test_no_search_candidate_on_listed_periods(bc):
    """A listed period (10 mm) stays the listed name: a free period must earn its extra parameter."""
    rng = np.random.default_rng(303)
    effects, theta = _location_truth(bc, rng)
    obs = _with_x_error(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=rng), 2.5, 10.0, 1.1)
    dg = diagnose(bc, obs, default_model(bc), noise_um=SIGMA)
    assert dg.live[0].effect == "EXX:periodic:10", [c.effect for c in dg.live[:4]]


def test_gross_misread_on_top_of_a_real_effect(bc):
    """One alignment slipped by 25 µm in Y on data with an unlisted lead: set aside, named by its line; the
    lead is still found and nothing spurious is added."""
    P, amp = 7.3, 2.5
    rng = np.random.default_rng(404)
    effects, theta = _location_truth(bc, rng)
    obs = _with_x_error(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=rng), amp, P, 2.0)
    held = _with_x_error(bc, simulate(bc, patent_plan(bc, tilt_deg=(-50, -10, 25, 50), turn_deg=tuple(range(10, 360, 45))),
                                      effects, theta, rng=rng), amp, P, 2.0)
    bad_row, y = 141, bc.axis_names.index("Y")
    axes = obs.axes.copy()
    axes[bad_row, y] += 0.025
    dirty = replace(obs, axes=axes)

    steps = forward_select(bc, dirty, default_model(bc), noise_um=SIGMA)
    final = steps[-1]
    assert [a.line for a in final.fit.set_aside] == [obs.lines[bad_row]]
    assert final.diagnosis.verdict == "noise"
    added = [s.added for s in steps[1:]]
    assert len(added) == 1 and added[0].startswith("EXX:periodic:"), added
    clean = obs.subset(np.array([i for i in range(len(obs)) if i != bad_row]))
    true_fit = fit(bc, clean, default_model(bc) + [parse_effect(f"EXX:periodic:{P}", bc)], noise_um=SIGMA)
    auto, truth = (_held_out_rms(bc, r, held) for r in (final.fit, true_fit))
    assert auto <= 1.5 * truth, (auto, truth)
    # without setting it aside, the misread biases the fit
    plain = forward_select(bc, dirty, default_model(bc), noise_um=SIGMA, robust=False)
    assert _held_out_rms(bc, plain[-1].fit, held) > auto


def test_sigma_given_too_small_adds_nothing_and_says_so(bc):
    """1.6 µm noise, σ given as 1 µm, no effect hidden: nothing is added, and the verdict gives no clean bill of
    health to a residual above the σ given — the residual is white, so it says the σ given looks too small, that the
    noise is about 1.6 µm, and how to say so."""
    added = 0
    for seed in range(6):
        rng = np.random.default_rng(500 + seed)
        effects, theta = _location_truth(bc, rng)
        obs = simulate(bc, patent_plan(bc), effects, theta, noise_um=1.6, rng=rng)
        steps = forward_select(bc, obs, default_model(bc), noise_um=1.0)
        added += len(steps) - 1
        dg = steps[0].diagnosis
        assert dg.verdict == "noise" and dg.note.startswith("the σ given looks too small")
        assert re.search(r"the noise is about 1\.[567] µm, not 1 µm as given \(give --noise-um 1\.[567]", dg.note), \
            dg.note
        words = what_is_left(steps)
        assert words.startswith("no effect was added") and "the σ given looks too small" in words
    assert added == 0


def test_two_simultaneous_effects(bc):
    """An unlisted lead of X and a reversal (backlash) of Y at once: both found, error at the true-structure level."""
    P, amp = 11.1, 2.0
    rng = np.random.default_rng(606)
    truth = {e.code: float(rng.normal(0, 15.0)) for e in default_model(bc)}
    truth["EYY:reversal"] = [5.0]
    effects, theta = errors_from_mapping(truth, bc)
    obs = _with_x_error(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=rng), amp, P, 0.3)
    held = _with_x_error(bc, simulate(bc, patent_plan(bc, tilt_deg=(-40, 20, 50), turn_deg=tuple(range(20, 360, 50))),
                                      effects, theta, rng=rng), amp, P, 0.3)
    steps = forward_select(bc, obs, default_model(bc), noise_um=SIGMA)
    added = [s.added for s in steps[1:]]
    assert any(a.startswith("EXX:periodic:") and abs(float(a.split(":")[2]) - P) < 0.2 for a in added), added
    assert "EYY:reversal" in added, added
    assert steps[-1].diagnosis.verdict == "noise"
    true_fit = fit(bc, obs, default_model(bc) + [parse_effect(f"EXX:periodic:{P}", bc), parse_effect("EYY:reversal", bc)],
                   noise_um=SIGMA)
    # held-out poses carry no approach directions: compare the constant and periodic part
    auto, truth_rms = (_held_out_rms(bc, r, held) for r in (steps[-1].fit, true_fit))
    assert auto <= 1.5 * truth_rms, (auto, truth_rms)


def _with_x_bump(machine, obs, amp_um, centre_mm, width_mm):
    """Readings of X when X has a local positioning error amp·exp(-((x-c)/w)²): solve x + e(x) = x₀."""
    j = machine.axis_names.index("X")
    x0 = obs.axes[:, j].copy()
    x = x0.copy()
    for _ in range(30):
        x = x0 - amp_um * 1e-3 * np.exp(-(((x - centre_mm) / width_mm) ** 2))
    axes = obs.axes.copy()
    axes[:, j] = x
    return replace(obs, axes=axes)


def test_local_bump_is_described_by_a_map(bc, tmp_path):
    """A 4 µm bump of X over ~12 mm near x = −15 mm: no parametric effect describes it, a map does."""
    rng = np.random.default_rng(707)
    effects, theta = _location_truth(bc, rng)
    obs = _with_x_bump(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=rng), 4.0, -15.0, 6.0)
    held_plan = patent_plan(bc, tilt_deg=(-50, -20, 10, 40), turn_deg=tuple(range(5, 360, 40)))
    held = _with_x_bump(bc, simulate(bc, held_plan, effects, theta, rng=rng), 4.0, -15.0, 6.0)
    clean = simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=np.random.default_rng(708))
    held_clean = simulate(bc, held_plan, effects, theta, rng=rng)

    before = diagnose(bc, obs, default_model(bc), noise_um=SIGMA)
    assert before.verdict == "missing-effect"
    best = before.live[0]
    assert best.effect.startswith(("EXX:local:", "EXX:map:")), [c.effect for c in before.live[:4]]
    assert "a local error of X near x = -" in best.note and "not described by any parametric effect" in best.note
    near = float(best.note.split("x = ")[1].split()[0])
    assert abs(near - (-15.0)) <= 10.0, best.note

    steps = forward_select(bc, obs, default_model(bc), noise_um=SIGMA)
    assert steps[-1].diagnosis.verdict == "noise"
    assert any(s.added and s.added.startswith(("EXX:local:", "EXX:map:")) for s in steps)
    # the achievable level: the default model on the same machine without the bump
    noise_limited = _held_out_rms(bc, fit(bc, clean, default_model(bc), noise_um=SIGMA), held_clean)
    auto = _held_out_rms(bc, steps[-1].fit, held)
    base = _held_out_rms(bc, steps[0].fit, held)
    # a local error (zero outside its window, knots every 5 mm) describes the bump: within 1.5x the level
    # the same machine without the bump reaches
    assert auto <= 1.5 * noise_limited, (auto, noise_limited)
    assert base > auto, (base, auto)
    from kinid.identification.reporting.report import plot_identified_errors

    assert plot_identified_errors(steps[-1].fit, obs, tmp_path / "errors.png")
    assert (tmp_path / "errors.png").stat().st_size > 1000


@pytest.mark.slow
def test_local_bumps_of_several_sizes_and_places(bc):
    """Five bumps (2.5-5 µm, 4-8 mm wide, at x = -40 .. +35 mm), the same noise with and without the bump:
    each is described by a local error of an X joint near its place, and the held-out error stays near
    the level of the machine without the bump (measured ratios 1.07-1.87, median 1.38)."""
    from dataclasses import replace

    ratios = []
    for seed, (amp, centre, width) in [(707, (4.0, -15.0, 6.0)), (708, (4.0, -15.0, 6.0)), (709, (3.0, 20.0, 5.0)),
                                       (710, (5.0, 35.0, 8.0)), (711, (2.5, -40.0, 4.0))]:
        rng = np.random.default_rng(seed)
        effects, theta = _location_truth(bc, rng)
        base = simulate(bc, patent_plan(bc), effects, theta, rng=rng)
        cols = [bc.axis_names.index(a) for a in "XYZ"]
        noise = np.zeros_like(base.axes)
        noise[:, cols] = rng.normal(0, SIGMA * 1e-3, (len(base), 3))
        bumped = _with_x_bump(bc, base, amp, centre, width)
        obs, clean = replace(bumped, axes=bumped.axes + noise), replace(base, axes=base.axes + noise)
        held_plan = patent_plan(bc, tilt_deg=(-50, -20, 10, 40), turn_deg=tuple(range(5, 360, 40)))
        truth_held = simulate(bc, held_plan, effects, theta, rng=rng)
        held = _with_x_bump(bc, truth_held, amp, centre, width)
        steps = forward_select(bc, obs, default_model(bc), noise_um=SIGMA)
        added = [s.added for s in steps[1:]]
        assert added and added[0].split(":")[0] in ("EXX", "EBX", "ECX") and ":local:" in added[0], added
        lo, hi = (float(v) for v in added[0].split(":")[3:5])
        assert lo < centre < hi, (added, centre)
        limit = _held_out_rms(bc, fit(bc, clean, default_model(bc), noise_um=SIGMA), truth_held)
        ratios.append(_held_out_rms(bc, steps[-1].fit, held) / limit)
    assert np.median(ratios) <= 1.5 and max(ratios) <= 2.0, ratios


def test_map_effect_grammar_basis_and_round_trip(bc, tmp_path):
    from kinid.errors import DataError
    from kinid.identification.model.effects import basis_values
    from kinid.identification.fitting.fit_file import load_fit, save_fit

    e = parse_effect("EXX:map:5:-20:20", bc)
    assert e.knots == tuple(float(k) for k in range(-20, 21, 5)) and e.n_params == 9
    axes = np.zeros((4, len(bc.axes)))
    axes[:, bc.axis_names.index("X")] = [-30.0, -20.0, 2.5, 100.0]
    B = basis_values(e, bc, axes)
    np.testing.assert_allclose(B.sum(axis=1), 1.0)           # hat functions sum to one
    np.testing.assert_allclose(B[2, 4:6], [0.5, 0.5])        # halfway between the knots 0 and 5
    assert B[0, 0] == 1.0 and B[3, -1] == 1.0                # constant beyond the ends
    with pytest.raises(DataError, match="knots, more than"):
        parse_effect("EXX:map:0.5", bc)
    obs = simulate(bc, patent_plan(bc), [], np.zeros(0), noise_um=SIGMA, rng=np.random.default_rng(1))
    result = fit(bc, obs, default_model(bc) + [e], noise_um=SIGMA)
    save_fit(result, tmp_path / "fit.json")
    loaded = load_fit(tmp_path / "fit.json")
    assert loaded.effects == result.effects


def _ac_plan(machine, stagger_deg):
    """3 tilts × 6 table angles × 4 marks on the A/C table; the k-th tilt's table angles turned by k × stagger."""
    from kinid.identification.data.observations import Observations

    names, rows, w = machine.axis_names, [], []
    for k, a in enumerate((-40.0, 0.0, 40.0)):
        for c in np.arange(0.0, 360.0, 60.0) + k * stagger_deg:
            for mark in ((40.0, 40.0, 0.0), (-40.0, 40.0, 0.0), (-40.0, -40.0, 0.0), (40.0, -40.0, 0.0)):
                r = np.full(len(names), np.nan)
                r[names.index("A")], r[names.index("C")] = a, c
                rows.append(r)
                w.append(mark)
    n = len(rows)
    return Observations(tuple("M" for _ in range(n)), np.array(w), np.array(rows), np.arange(n) * 15.0, {},
                        tuple(range(2, n + 2)), "<A/C plan>")


def test_a_period_the_positions_cannot_determine_is_named():
    """On an A/C table a plan repeating the same six table angles at every tilt visits X at six positions: a 10 mm
    lead of X is significant, but 2, 5, 10 and 20 mm fit alike there and differ between them. The diagnosis says
    so; --auto adds the longest of them (the smoothest between the positions, as the period search's convention)
    and says so when it stops; with the table angles turned by 20° per tilt (18 positions of X) the lead is found
    within 1 % and nothing is said."""
    ac = load_machine(path("five_axis_ac"))
    effects, theta = errors_from_mapping({"EX0C": 12.0, "EY0C": -8.0, "EXX:periodic:10": [1.5, -0.8]}, ac)
    rng = np.random.default_rng(7)
    six = simulate(ac, _ac_plan(ac, 0.0), effects, theta, noise_um=0.5, rng=rng)
    dg = diagnose(ac, six, default_model(ac), noise_um=0.5)
    assert dg.verdict == "missing-effect" and "period is not determined" in dg.undetermined, dg.text()
    assert "6 positions of X" in dg.undetermined
    assert len(dg.twins) >= 3 and 20.0 in [round(p) for p in dg.twins], dg.twins
    steps = forward_select(ac, six, default_model(ac), noise_um=0.5)
    periods = [float(s.added.split(":")[2]) for s in steps[1:] if ":periodic:" in s.added]
    assert periods == [max(dg.twins + (float(dg.live[0].effect.split(":")[2]),))], [s.added for s in steps]
    assert "period is not determined" in steps[-1].stopped and "added, the longest of them" in steps[-1].stopped
    # the model is not determined between the positions: the final verdict says so and names the axis
    assert steps[-1].undetermined == ("EXX",)
    assert steps[-1].diagnosis.verdict == "missing-effect" and "measure X at more positions" in steps[-1].diagnosis.note
    assert "the period of the periodic error added for EXX is not determined" in what_is_left(steps)
    eighteen = simulate(ac, _ac_plan(ac, 20.0), effects, theta, noise_um=0.5, rng=rng)
    dg = diagnose(ac, eighteen, default_model(ac), noise_um=0.5)
    assert not dg.undetermined
    steps = forward_select(ac, eighteen, default_model(ac), noise_um=0.5)
    leads = [float(s.added.split(":")[2]) for s in steps[1:] if s.added.startswith("EXX:periodic:")]
    assert leads and abs(leads[0] - 10.0) <= 0.1, [s.added for s in steps]
    assert "not determined" not in steps[-1].stopped and steps[-1].undetermined == ()


def test_the_bounded_search_is_scipys_step_for_step():
    """kinid's bounded Brent search (used so that --auto does not import scipy.optimize) gives scipy's abscissa
    and value exactly, with the selection's settings (xatol 0.01, 20 steps) and with scipy's default steps."""
    from scipy.optimize import minimize_scalar

    from kinid.identification.diagnosis.periods import bounded_minimum

    rng = np.random.default_rng(0)
    for _ in range(200):
        a, b, c = rng.normal(size=3)
        lo, hi = sorted(rng.uniform(-3, 3, 2))

        def f(u):
            return np.sin(3 * a * u) + b * u**2 + c * np.cos(7 * u)

        for xatol, steps in ((0.01, 20), (1e-6, 500)):
            theirs = minimize_scalar(f, bounds=(lo, hi), method="bounded", options={"xatol": xatol, "maxiter": steps})
            assert bounded_minimum(f, lo, hi, xatol=xatol, maxiter=steps) == (theirs.x, theirs.fun)


@pytest.mark.parametrize("teeth", [2, 3])
def test_an_undetermined_period_of_the_table_is_named_by_whole_cycles_per_turn(bc, teeth):
    """The table read at six angles 60° apart, a gear error of 2 or 3 cycles per turn: the period is not determined
    (many fit the six angles alike), and the one added makes a whole number of cycles per turn (a model that does
    not jump where the readings come round), not the longest of all (1.947 cycles before)."""
    rng = np.random.default_rng(40 + teeth)
    effects, theta = _location_truth(bc, rng)
    c = bc.axis_names.index("C")
    plan = patent_plan(bc, tilt_deg=(-60, -30, 0, 30, 60), turn_deg=tuple(range(0, 360, 60)))
    actual = plan.axes.copy()
    actual[:, c] += np.degrees(60e-6 * np.sin(np.radians(plan.axes[:, c]) * teeth + 0.9))
    sim = simulate(bc, replace(plan, axes=actual), effects, theta, noise_um=SIGMA, rng=rng)
    axes = sim.axes.copy()
    axes[:, c] = plan.axes[:, c]
    obs = replace(sim, axes=axes)
    steps = forward_select(bc, obs, default_model(bc), noise_um=SIGMA)
    added = [e.name for e in steps[-1].fit.effects if e.basis == "periodic"]
    assert added and all(e.startswith("ECC:") for e in added), added
    for name in added:
        cycles = 360.0 / float(name.split(":")[2])
        assert cycles == pytest.approx(round(cycles), abs=1e-4), name
    if teeth == 2:  # not determined on six angles (3 cycles, 120°, is: the shortest period they resolve)
        assert "not determined" in steps[-1].stopped and "whole cycles per turn" in steps[-1].stopped


def test_the_jitter_of_solved_readings_is_no_finer_sampling():
    """The A/C plan that visits X at six positions, measured three times, X read each time as an alignment solves it
    (a few µm apart): the search covers the periods the six positions resolve — the same shortest period and
    number of trials as on readings repeated exactly — not the millimetre periods thousands of distinct readings
    would seem to resolve (on a grid of six positions those alias onto longer ones: noise picks among them)."""
    from kinid.identification.data.positions import distinct_positions
    from kinid.identification.fitting.leverage import model_pass
    from kinid.identification.data.observations import Observations
    from kinid.identification.diagnosis.periods import search_periods

    ac = load_machine(path("five_axis_ac"))
    effects, theta = errors_from_mapping({"EX0C": 12.0, "EY0C": -8.0}, ac)
    base = _ac_plan(ac, 0.0)
    plan = Observations(base.marks * 3, np.tile(base.w_mm, (3, 1)), np.tile(base.axes, (3, 1)),
                        np.arange(3 * len(base)) * 15.0, {}, tuple(range(2, 3 * len(base) + 2)), "<A/C plan x 3>")
    rng = np.random.default_rng(11)
    exact = simulate(ac, plan, effects, theta, noise_um=1.0, rng=rng)
    x = ac.axis_names.index("X")
    assert distinct_positions(exact.axes[:, x]).size == 6
    axes = exact.axes.copy()
    axes[:, x] += rng.normal(0.0, 2e-3, len(axes))  # 2 µm: what the alignment solved, not where the plan sent X
    jittered = replace(exact, axes=axes)
    assert np.unique(np.round(axes[:, x], 3)).size > 30 and distinct_positions(axes[:, x]).size == 6
    found = {}
    for name, obs in (("exact", exact), ("jittered", jittered)):
        model = default_model(ac)
        result = fit(ac, obs, model, noise_um=1.0)
        d_errors, _, q0 = model_pass(ac, obs, result)
        r = result.residuals_um.ravel()
        found[name] = {e.code: e for e in search_periods(ac, obs, r - q0 @ (q0.T @ r), d_errors, q0) if e.axis == "X"}
    assert found["exact"] and found["jittered"].keys() == found["exact"].keys()
    spacing = np.min(np.diff(distinct_positions(exact.axes[:, x])))
    for code, e in found["jittered"].items():
        assert e.trials == pytest.approx(found["exact"][code].trials, rel=1e-3), code
        assert e.period >= 2.0 * spacing * (1 - 1e-9), (code, e.period, spacing)


def test_readings_a_few_micrometres_apart_are_one_position_wherever_they_fall():
    """Three positions read 50 times each, 2 µm apart at most, one of them on the boundary of a grid of 0.1 % of the
    span (where rounding to a grid would split it in two); a position read exactly keeps its value to the last
    digit."""
    from kinid.identification.data.positions import distinct_positions

    rng = np.random.default_rng(3)
    q = np.repeat([10.01, 20.0, 30.0], 50) + np.r_[rng.uniform(-2e-3, 2e-3, 50), np.zeros(50), rng.normal(0, 1e-3, 50)]
    found = distinct_positions(rng.permutation(q))
    assert found.size == 3 and found[1] == 20.0 and np.allclose(found, [10.01, 20.0, 30.0], atol=3e-3), found
    assert distinct_positions([]).size == 0 and distinct_positions([7.5]).tolist() == [7.5]


def test_refining_the_best_few_gives_them_as_refining_all_does(bc):
    """The diagnosis refines only the joints that can be among its four best periods: those come out as refining
    every joint gives them (period, its std, Δ), in the same order; the others keep their grid peak (std NaN) and
    are still counted (the trials multiply by the joints searched)."""
    from kinid.identification.fitting.leverage import model_pass
    from kinid.identification.diagnosis.periods import search_periods

    rng = np.random.default_rng(21)
    effects, theta = _location_truth(bc, rng)
    obs = _with_x_error(bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=SIGMA, rng=rng), 3.0, 13.3, 0.4)
    result = fit(bc, obs, default_model(bc), noise_um=SIGMA)
    d_errors, _, q0 = model_pass(bc, obs, result)
    r = result.residuals_um.ravel() / SIGMA
    r = r - q0 @ (q0.T @ r)
    every = search_periods(bc, obs, r, d_errors, q0, SIGMA)
    few = search_periods(bc, obs, r, d_errors, q0, SIGMA, refine=4)
    assert len(few) == len(every) > 8
    for a, b in zip(every[:4], few[:4]):
        assert (a.code, a.period, a.period_std, a.statistic) == (b.code, b.period, b.period_std, b.statistic)
    assert every[0].code == "EXX" and abs(every[0].period - 13.3) < 0.1
    rest = [e for e in few if np.isnan(e.period_std)]
    assert rest and all(e.statistic <= 0.5 * few[3].statistic for e in rest)
    assert {e.code for e in rest} | {e.code for e in few[:4]} <= {e.code for e in every}
