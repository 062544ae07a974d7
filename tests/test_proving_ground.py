"""The diagnosis on machines nobody described: the CI-sized subset of benchmarks/proving_ground.py, and one test
per failure class it exposed, each with its effect injected by a plain formula (benchmarks/proving_truth.py:
plain numpy on the URDF text, no kinid code).

The full run (``python benchmarks/proving_ground.py --scenarios 500``) is a benchmark; its table is in
docs/identification.md.
"""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import proving_ground as pg  # noqa: E402
import proving_truth as truth  # noqa: E402


def test_the_truth_is_the_urdf_as_pinocchio_reads_it():
    """Two implementations that share nothing agree: the proving ground's numpy chain and kinid's Pinocchio pass."""
    from kinid.identification.model.machine import evaluate, machine_from_urdf

    rng = np.random.default_rng(0)
    for layout in pg.LAYOUTS:
        text = pg.urdf_text(layout)
        km, tm = machine_from_urdf(text, f"{layout}.urdf"), truth.read_urdf(text)
        readings = {a.name: rng.uniform(-50, 50, 40) for a in km.axes}
        errors = {e.code: rng.uniform(-50, 50, 40) for e in km.error_joints}
        ours = evaluate(km, np.column_stack([readings[a.name] for a in km.axes]),
                        np.column_stack([errors[e.code] for e in km.error_joints]), jacobian=False)
        assert np.abs(ours - truth.tool_point_mm(tm, readings, errors, 40)).max() < 1e-9, layout


def _line(sc):
    r = sc.result
    return (f"{sc.seed} {sc.layout} {sc.plan} {sc.order} {sc.kinds} σ {sc.sigma_declared} {r['verdict']} "
            f"held-out {r['held_out_um']:.3f} oracle {r['oracle_um']:.3f} default {r['default_um']:.3f} added {r['added']}")


@pytest.mark.slow
def test_rates_on_drawn_scenarios(capsys):
    """A fixed CI-sized draw of the proving ground: the rates the full run reports, on 40 scenarios."""
    scenarios = [pg.run(20261124 + k) for k in range(40)]
    summary = pg.summarise(scenarios)
    with capsys.disabled():
        print()
        for sc in scenarios:
            print(("PASS " if pg.verdict_of(sc)["pass"] else "FAIL ") + _line(sc))
        pg.print_table(summary)
    everything = summary["all"]
    hidden = [pg.verdict_of(sc)["pass"] for sc in scenarios if sc.hidden]
    assert everything["pass"] >= 0.85  # 90 % when written (36 of 40)
    assert np.mean(hidden) >= 0.80  # 84 % (21 of 25)
    assert everything["worse_than_default"] == 0.0
    assert everything["worse_on_plan"] == 0.0  # the same judged on every pose of the plan (noise-free truth)
    # the paired statistic is of the same poses and the same 5 %: above zero exactly when the ratio is above 1.05
    for sc in scenarios:
        r = sc.result
        assert (r["worse_z"] > 0) == (r["held_out_um"] > 1.05 * r["default_um"]), _line(sc)
    none = [sc for sc in scenarios if not sc.hidden and sc.sigma_declared == pg.NOISE_UM]
    assert none and all(not sc.result["added"] for sc in none)


def test_the_held_out_check_refits_with_the_candidate():
    """Class 1: a six-joint arm, location errors only, a gear error of J6 (a 30° period on EA0J6). The diagnosis
    ranks it first; the held-out check warm-started from the full data's fit must refit it (it gave the same
    figure to the last digit before and after when a warm start held other aliased parameters)."""
    from kinid.identification import default_model, diagnose, parse_effect
    from kinid.identification.fitting.crossval import cross_validate

    sc, machine, obs = _data(3, "arm6", ["gear"])
    effects = list(default_model(machine))
    dg = diagnose(machine, obs, effects, noise_um=1.0)
    best = parse_effect(dg.live[0].effect, machine)
    assert best.code == sc.hidden[0].joint
    cold = cross_validate(machine, obs, effects, best, noise_um=1.0)
    warm = cross_validate(machine, obs, effects, best, noise_um=1.0, theta0=dg.fit.theta)
    print(f"cold {cold}; warm {warm}")
    assert warm.rms_with_um < 0.8 * warm.rms_without_um
    assert warm.rms_without_um == pytest.approx(cold.rms_without_um, rel=1e-6)
    # every live candidate with a column that is not zero moves the held-out figure
    for c in dg.live[:6]:
        cv = cross_validate(machine, obs, effects, parse_effect(c.effect, machine), noise_um=1.0, theta0=dg.fit.theta)
        assert cv.rms_with_um != cv.rms_without_um, c.effect


def test_the_held_out_check_gives_the_refits_figures(monkeypatch):
    """The check's turns are Gauss–Newton steps from the fit on all the data, not refits: on an arm (aliased pairs
    that differ between blocks), the A/C table and the gantry, with the best candidate and a poor one, the held-out
    figures and the gain are those of refitting each turn to convergence, written here without the check — and
    those of the check on data too large to hold their Jacobian, which refits every turn."""
    import kinid.identification.fitting.crossval as crossval
    from kinid.identification import default_model, diagnose, fit, parse_effect
    from kinid.identification.fitting.crossval import _gain_se, cross_validate, held_out_blocks
    from kinid.identification.fitting.residuals import design, residuals

    for seed, layout, kinds in ((3, "arm6", ["gear"]), (5, "five_axis_ac", ["lead"]), (8, "gantry_dual_y", ["sag"])):
        _, machine, obs = _data(seed, layout, kinds, misread_share=0.0)
        effects = list(default_model(machine))
        dg = diagnose(machine, obs, effects, noise_um=1.0)
        for c in (dg.live[0], dg.live[len(dg.live) // 2]):
            candidate = parse_effect(c.effect, machine)
            cv = cross_validate(machine, obs, effects, candidate, noise_um=1.0, theta0=dg.fit.theta)
            squares = np.zeros((2, len(obs)))
            for test in held_out_blocks(machine, obs, 4):  # the check's blocks: whole poses
                train, te = obs.subset(np.setdiff1d(np.arange(len(obs)), test)), obs.subset(test)
                for m, model in enumerate((effects, effects + [candidate])):
                    refit = fit(machine, train, model, noise_um=1.0)
                    r = residuals(machine, design(machine, model, te), te, refit.theta, jacobian=False)
                    squares[m, test] = np.sum(r**2, axis=1)
            rms = np.sqrt(squares.sum(axis=1) / (3 * len(obs)))
            assert cv.rms_without_um == pytest.approx(rms[0], rel=1e-6), (layout, c.effect)
            assert cv.rms_with_um == pytest.approx(rms[1], rel=1e-6), (layout, c.effect)
            assert cv.gain_se == pytest.approx(_gain_se(squares[0] - squares[1]), rel=1e-4, abs=1e-4), (layout, c.effect)
            with monkeypatch.context() as m:
                m.setattr(crossval, "LINEAR_MAX_VALUES", 0)
                refitted = cross_validate(machine, obs, effects, candidate, noise_um=1.0, theta0=dg.fit.theta)
            assert (refitted.rms_without_um, refitted.rms_with_um) == pytest.approx(tuple(rms), rel=1e-6)


def _data(seed, layout, kinds, extra=None, **fixed):
    """The proving ground's rows for one scenario, as kinid Observations (fit rows only); ``extra``: {error joint:
    a plain formula of the time, s} added to what the scenario hides."""
    from kinid.identification.model.machine import machine_from_urdf
    from kinid.identification.data.observations import Observations

    sc, text, tm, readings, labels, t_s, errors, rng = pg.draw(seed, layout, kinds, **fixed)
    n = len(t_s)
    values = dict(errors)
    for h in sc.hidden:
        values[h.joint] = values.get(h.joint, 0.0) + h(readings, t_s)
    for code, formula in (extra or {}).items():
        values[code] = values.get(code, 0.0) + formula(t_s)
    p = truth.tool_point_mm(tm, readings, values, n) + rng.normal(0.0, 1e-3, (n, 3))
    machine = machine_from_urdf(text, f"{layout}.urdf")
    axes = np.column_stack([readings[a.name] for a in machine.axes])
    return sc, machine, Observations(tuple(f"M{k}" for k in labels), p, axes, t_s, {}, tuple(range(2, n + 2)), "<drawn>")


def test_time_that_follows_an_axis_is_named_and_a_warm_up_is_found_in_random_order():
    """Class 2 and 3: a spindle warm-up A·(1 − e^(−t/τ)) on the tool. Visited tilt-major, time follows the tilt
    axis: the diagnosis says so. Visited in random order, --auto finds the warm-up at the oracle's error."""
    from kinid.identification import default_model, diagnose

    _, machine, obs = _data(11, "five_axis_bc", ["warm-up"], plan_kind="patent", order="axis-major")
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    assert [a for a, _ in dg.time_follows] == ["B"]
    assert "time follows B" in dg.text()
    sc = pg.run(11, "five_axis_bc", ["warm-up"], plan_kind="patent", order="random", misread_share=0.0, sigma=1.0)
    print(_line(sc))
    assert any(":warmup:" in a for a in sc.result["added"])
    assert sc.result["held_out_um"] <= 1.5 * sc.result["oracle_um"]


def test_an_error_of_one_axis_that_varies_with_another_is_found():
    """Class 3: X's positioning error growing along X at a rate set by Y (a thermal gradient): EXX:with:Y."""
    sc = pg.run(10, "five_axis_ac", ["cross-axis"], misread_share=0.0, sigma=1.0)
    print(_line(sc))
    assert any(":with:" in a for a in sc.result["added"])
    assert sc.result["held_out_um"] <= 1.5 * sc.result["oracle_um"]


def test_misreads_above_two_percent_are_set_aside_when_they_stand_apart():
    """Class 4: 5 % of the rows misread by 10–40 µm, no effect hidden: every misread is set aside (the fixed 2 %
    cap set none aside) and the held-out error is the oracle's."""
    sc = pg.run(6, "gantry_dual_y", [], misread_share=0.05, sigma=1.0, plan_kind="large")
    print(_line(sc), sc.result["misreads"], sc.result["set_aside"])
    assert sc.result["misreads"] >= 20
    assert sc.result["set_aside"] >= sc.result["misreads"] - 1  # a misread of 10 µm along the noise may hide
    assert sc.result["held_out_um"] <= 1.2 * sc.result["oracle_um"]


def test_structure_left_with_sigma_given_is_a_missing_effect_not_noise(monkeypatch):
    """Class 5: an effect no candidate describes (here: no candidate at all, the library's nor a map or local error
    proposed), σ given correctly. The residual exceeds σ and neighbouring alignments agree: the verdict is
    missing-effect, naming where — never the note that blames σ. With no effect hidden, the same path says noise."""
    import importlib

    from kinid.identification import default_model, diagnose

    diagnose_module = importlib.import_module("kinid.identification.diagnosis.diagnose")
    monkeypatch.setattr(diagnose_module, "score_all", lambda *args, **kwargs: [])
    monkeypatch.setattr(diagnose_module, "proposed_maps", lambda *args, **kwargs: [])  # a local window fits a sag
    _, machine, obs = _data(4, "five_axis_ac", ["sag"], plan_kind="patent", misread_share=0.0)
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    print(dg.note)
    assert dg.chi2_p < 1e-3
    assert dg.verdict == "missing-effect" and "looks like noise" not in dg.note
    assert dg.structure.p_value < 0.01 and dg.structure.axis == "Y"  # the sag is of Y
    _, machine, obs = _data(4, "five_axis_ac", [], plan_kind="patent", misread_share=0.0)
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    assert dg.verdict == "noise" and dg.structure.p_value > 0.01


def test_an_effect_of_two_axes_nobody_listed_is_structure_along_that_pair():
    """An error of an arm's base as a product of functions of two wrist joints, 3 µm·sin J4·cos J6 on EY0J1 (a plain
    formula, 150 poses in random order): no candidate is significant, and in the readings of all six joints at once
    the nearest neighbours differ in the four joints the error does not depend on — it was called noise
    (p = 0.064 in the readings, the σ estimated from the residual). In the plane of J4 and J6 neighbouring poses
    agree: missing-effect, named on that pair. Without the formula the same rows are noise."""
    from kinid.identification import default_model, diagnose
    from kinid.identification.model.machine import machine_from_urdf
    from kinid.identification.data.observations import Observations

    sc, text, tm, readings, labels, t_s, errors, rng = pg.draw(1, "arm6", [], order="random", misread_share=0.0)
    n = len(t_s)
    noise = rng.normal(0.0, 1e-3, (n, 3))
    machine = machine_from_urdf(text, "arm6.urdf")
    axes = np.column_stack([readings[a.name] for a in machine.axes])
    for size_um, verdict in ((3.0, "missing-effect"), (0.0, "noise")):
        values = dict(errors)
        values["EY0J1"] = values["EY0J1"] + size_um * np.sin(np.radians(readings["J4"])) * np.cos(
            np.radians(readings["J6"]))
        p = truth.tool_point_mm(tm, readings, values, n) + noise
        obs = Observations(tuple(f"M{k}" for k in labels), p, axes, t_s, {}, tuple(range(2, n + 2)), "<drawn>")
        dg = diagnose(machine, obs, default_model(machine))
        print(size_um, dg.verdict, dg.structure, dg.note)
        assert n == 150 and dg.verdict == verdict, dg.text()
        if size_um:
            assert dg.structure.p_value < 0.01 and set(dg.structure.axes) == {"J4", "J6"}, dg.structure
            assert dg.structure.axis in ("J4", "J6") and "the readings of J6 and J4 together" in dg.note, dg.note
        else:
            assert dg.structure.p_value > 0.05, dg.structure


def test_the_structure_tests_looks_together_keep_its_level_on_noise():
    """Noise in 100 draws (a grid of two rotary axes, four marks with linear axes aligned to them, time in random
    order): the smallest p-value over twenty looks, judged against the smallest of each permutation, stays at its
    level — about 1 % below 0.01, about 5 % below 0.05."""
    from kinid.identification.diagnosis.structure import structure_left

    rng = np.random.default_rng(5)
    p = []
    for _ in range(100):
        b, c, mark = np.meshgrid(np.linspace(-40, 40, 5), np.arange(8) * 45.0, np.arange(4), indexing="ij")
        b, c, mark = b.ravel(), c.ravel(), mark.ravel()
        linear = np.column_stack([np.cos(np.radians(c + 90 * mark)), np.sin(np.radians(c + 90 * mark)),
                                  np.sin(np.radians(b))]) * 56.6
        order = rng.permutation(len(b))
        axes = np.column_stack([linear, b, c])[order]
        p.append(structure_left(rng.normal(size=(len(b), 3)), axes, np.arange(len(b)) * 12.0,
                                names=("X", "Y", "Z", "B", "C"), rng=rng).p_value)
    p = np.asarray(p)
    print(np.mean(p < 0.01), np.mean(p < 0.05))
    assert np.mean(p < 0.01) <= 0.04 and np.mean(p < 0.05) <= 0.1


def test_the_oracle_is_the_true_structure():
    """The oracle floor fits the default model and each hidden effect's exact shape (its size free): on rows
    without noise it reproduces the truth, whatever the effects' forms, to within 0.01 µm (set-up errors of
    millimetres held at zero where the data cannot tell them apart leave a few nm of second-order residual)."""
    from kinid.identification import default_model, fit

    for seed, layout, kinds in ((3, "five_axis_bhead_c", ["bump", "warm-up"]), (4, "gantry_dual_y", ["sag", "drift"]),
                                (5, "arm6", ["gear"])):
        sc, machine, obs = _data(seed, layout, kinds, misread_share=0.0)
        assert len(sc.hidden) == len(kinds), (layout, kinds)
        sc, text, tm, readings, labels, t_s, errors, rng = pg.draw(seed, layout, kinds, misread_share=0.0)
        values = dict(errors)
        for h in sc.hidden:
            values[h.joint] = values.get(h.joint, 0.0) + h(readings, t_s)
        exact = replace(obs, w_mm=truth.tool_point_mm(tm, readings, values, len(t_s)))
        effects = list(default_model(machine)) + pg._truth_effects(machine, sc.hidden, readings, t_s)
        result = fit(machine, exact, effects)
        assert np.sqrt(np.mean(result.residuals_um**2)) < 0.01, (layout, kinds)
        without = fit(machine, exact, default_model(machine))
        assert np.sqrt(np.mean(without.residuals_um**2)) > 0.1, (layout, kinds)


def test_a_local_error_is_proposed_where_no_whole_map_fits():
    """Class 6: a bump of Z (3–6 µm, FWHM 8–20 mm) on the B/C machine, where Z is read at positions too few for a
    whole map and spaced wider than the map's knots. It was described by a stack of periods (held-out 1.8× the
    oracle's); it is now proposed as a local error on the joint of the best candidates, with knots no closer than
    the readings resolve."""
    sc = pg.run(5, "five_axis_bc", ["bump"], plan_kind="patent", misread_share=0.0, sigma=1.0)
    print(_line(sc))
    assert sc.hidden[0].joint == "EZZ"
    assert [a.split(":")[:2] for a in sc.result["added"]] == [["EZZ", "local"]]
    assert sc.result["held_out_um"] <= 1.5 * sc.result["oracle_um"]


def test_a_bump_on_an_axis_read_at_few_positions_is_its_error_at_each_of_them():
    """Class 6 where the plan is small: a bump (3–6 µm, FWHM 8–20 mm) of X, Y or Z on each five-axis layout in the
    small plan, where the linear axes are read at 6 or 7 positions — too few for a map or a local window. A bump at
    one position is no period and no low polynomial: it was taken for a period the positions do not determine, or
    left in the residual (held-out error on these 12: median 1.34× the oracle's, 7 within 1.5×). The error at each
    position measured (the polynomial through them) is now a candidate: median 1.19×, 10 within 1.5×."""
    ratios, worse, tables = [], 0, 0
    for seed in range(12):
        layout = ("five_axis_bc", "five_axis_ac", "five_axis_bhead_c")[seed % 3]
        sc = pg.run(seed, layout, ["bump"], plan_kind="small", misread_share=0.0, sigma=1.0)
        print(_line(sc))
        r = sc.result
        ratios.append(r["held_out_um"] / r["oracle_um"])
        worse += r["held_out_um"] > 1.05 * r["default_um"]
        tables += any(":poly" in a and int(a.split(":poly")[1]) > 3 for a in r["added"])
    assert np.median(ratios) <= 1.25 and sum(x <= 1.5 for x in ratios) >= 9 and worse == 0
    assert tables >= 4


def test_the_final_words_say_a_table_is_not_measured_between_its_positions(monkeypatch, tmp_path):
    """The error at each of Y's 6 positions (a bump of Y, the B/C table's small plan) is known there only: the final
    words say so and name the axis to measure at more positions, and its figure marks the positions measured."""
    from kinid.identification import default_model, forward_select
    from kinid.identification.reporting import figures as report_figures
    from kinid.identification.data.positions import distinct_positions
    from kinid.identification.diagnosis.selection import what_is_left

    _, machine, obs = _data(0, "five_axis_bc", ["bump"], plan_kind="small", misread_share=0.0)
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    assert [s.added for s in steps[1:]] == ["EYY:poly5"]
    words = what_is_left(steps)
    assert "EYY:poly5 is the error at each of the 6 positions of Y measured" in words
    assert "measure Y at more positions" in words
    default_only = forward_select(machine, obs, default_model(machine), noise_um=1.0, max_steps=0)
    assert "positions of" not in what_is_left(default_only)
    drawn = []
    monkeypatch.setattr(report_figures, "save_figure", lambda fig, path, **kw: drawn.append(fig))
    assert report_figures.plot_identified_errors(steps[-1].fit, steps[-1].data, tmp_path / "errors.png")
    marked = [line for ax in drawn[0].axes for line in ax.get_lines() if line.get_marker() == "o"]
    y = obs.axes[:, machine.axis_names.index("Y")]
    assert len(marked) == 1 and np.allclose(marked[0].get_xdata(), distinct_positions(y))


def test_a_local_error_rests_on_readings_per_coefficient_not_per_knot():
    """Class 6 on the gantry: a bump of Y (FWHM 8–20 mm) in the random-half plan, Y read about every 10 mm. Asking
    every knot of a window for readings (its end knots too, where the error is held at zero) refused every window
    with knots every 10 mm; the 20 mm window left rang between the positions, and the final model predicted held-out
    alignments 1.7× worse than the default model. Each coefficient's B-spline resting on readings admits them."""
    from kinid.identification.model.bsplines import _bsplines
    from kinid.identification.diagnosis.local_errors import _bspline_support

    q = np.random.default_rng(3).uniform(-60.0, 60.0, 300)
    assert np.allclose(_bspline_support(q, -80.0, 10.0, 17), _bsplines(q, -80.0 + 10.0 * np.arange(17), 10.0).sum(0))
    sc = pg.run(13 * 100003 + 7)  # proving ground seed 13, scenario 7
    print(_line(sc))
    assert sc.layout == "gantry_dual_y" and sc.kinds == "bump"
    local = [a.split(":") for a in sc.result["added"] if ":local:" in a]
    assert local and float(local[0][2]) == 10.0  # knots every half map step (the map's step is 20 mm)
    assert sc.result["held_out_um"] <= 1.05 * sc.result["default_um"]
    assert sc.result["held_out_um"] <= 1.5 * sc.result["oracle_um"]


def test_a_bump_narrower_than_the_windows_knots_is_found_with_knots_twice_as_close():
    """Class 6 on a long axis: a 5.9 µm bump of the gantry's Y (FWHM 8–20 mm) in its large plan, Y read every 0.7 mm
    over 440 mm (proving ground seed 31 #53). The map's step is 20 mm and the finest windows tried had knots every
    10 mm: the best of them took 2.1× the oracle's held-out error and left a residual the tests call noise. Around
    the likeliest window the diagnosis now tries knots twice as close."""
    from kinid.identification import diagnose, default_model
    from kinid.identification.diagnosis.local_errors import local_windows

    sc = pg.run(31 * 100003 + 53)
    print(_line(sc))
    assert sc.layout == "gantry_dual_y" and sc.kinds == "bump"
    assert [a.split(":")[:3] for a in sc.result["added"]] == [["EYY", "local", "5"]]
    assert sc.result["held_out_um"] <= 1.2 * sc.result["oracle_um"]  # 1.10 when written (2.08 with 10 mm knots)
    # the windows tried everywhere have knots every 10, 20 and 40 mm; the diagnosis's own proposal has 5 mm ones
    _, machine, obs = _data(31 * 100003 + 53, None, None)
    steps = {float(w.name.split(":")[2]) for w in local_windows(machine, obs, "EYY")}
    assert steps == {10.0, 20.0, 40.0}
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    best = [c for c in dg.live if ":local:" in c.effect]
    assert best and best[0].effect.startswith("EYY:local:5:")


def test_a_local_error_is_tried_on_joints_no_parametric_candidate_points_to():
    """Class 6 where the readings are sparse: a 5.6 µm bump of the B-head's X (FWHM 8–20 mm) where X is read at 42
    positions about 7 mm apart (proving ground seed 23 #317). The bump stands out on a few rows; with one of them set
    aside as a misread, no candidate of EXX was among the best three, whose joints were the only ones local windows
    were tried on, and the run ended "noise" at 8.4× the oracle's held-out error. Windows are now tried on every
    joint, at a tenth of the test's level: the likeliest is the bump's, far beyond chance. It was then named and not
    added (its window, chosen per turn on blocks of every 4th row, gained 1.9 standard errors); with the held-out
    blocks made of whole visits it is added, and the held-out error is within 1.5x the oracle's."""
    sc = pg.run(23 * 100003 + 317)
    print(_line(sc))
    assert sc.layout == "five_axis_bhead_c" and sc.kinds == "bump" and sc.hidden[0].joint == "EXX"
    r = sc.result
    assert any(a.startswith("EXX:local:") for a in r["added"]), r["stopped"]  # it ended "noise", naming nothing
    assert r["held_out_um"] <= 1.5 * r["oracle_um"]


def test_misreads_are_judged_against_the_residuals_scale_not_a_sigma_given_too_large():
    """Class 4: 5 % misreads of 10–40 µm with σ given as 2.7 µm where the noise is 1 µm. Judged against the given σ,
    a misread of 10 µm is 3.6 σ and stayed in (9 of 13 set aside); against the residuals' robust scale all go."""
    sc = pg.run(1, "gantry_dual_y", [], plan_kind="patent", misread_share=0.05, sigma=2.7)
    print(_line(sc), sc.result["misreads"], sc.result["set_aside"])
    assert sc.result["misreads"] >= 10
    assert sc.result["set_aside"] == sc.result["misreads"]


def test_the_held_out_check_asks_for_a_gain_beyond_its_scatter():
    """The best candidate on pure noise, chosen on all the data, lowers the held-out sum of squares of the blocks
    left out almost always (11 of 12 seeds here): a bare fall is no evidence. It must fall by two standard errors."""
    from kinid.identification import default_model, diagnose, parse_effect
    from kinid.identification.fitting.crossval import cross_validate

    falls = improves = 0
    for seed in range(12):
        _, machine, obs = _data(300 + seed, "five_axis_ac", [], plan_kind="patent", misread_share=0.0)
        effects = list(default_model(machine))
        dg = diagnose(machine, obs, effects, noise_um=1.0)
        cv = cross_validate(machine, obs, effects, parse_effect(dg.live[0].effect, machine), noise_um=1.0,
                            theta0=dg.fit.theta)
        falls += cv.rms_with_um < cv.rms_without_um
        improves += cv.improves
    print(f"falls {falls}, improves {improves} of 12")
    assert falls >= 9 and improves <= 1
    # a real effect passes by far: the gear error of the arm (class 1)
    sc, machine, obs = _data(3, "arm6", ["gear"])
    effects = list(default_model(machine))
    dg = diagnose(machine, obs, effects, noise_um=1.0)
    cv = cross_validate(machine, obs, effects, parse_effect(dg.live[0].effect, machine), noise_um=1.0,
                        theta0=dg.fit.theta)
    assert cv.improves and cv.gain_se > 5, cv


def test_a_period_that_only_the_held_out_blocks_noise_chose_is_not_added(monkeypatch):
    """No hidden effect, σ not given, the B-head's random-half plan (proving ground seed 23 #428): the best searched
    period, 5 mm of the Z straightness along X, gains 2.1 standard errors on the held-out blocks chosen on all the
    data and 0.1 chosen again on each turn's training blocks. Added, it predicted held-out poses 2.3× worse than
    the default model; the turns' own choices must bring one standard error."""
    from kinid.identification.fitting import crossval

    sc = pg.run(23 * 100003 + 428)
    print(_line(sc))
    assert not sc.hidden and sc.sigma_declared is None
    assert sc.result["added"] == [] and sc.result["held_out_um"] == sc.result["default_um"]
    # the same scenario with a gain above zero asked of the period chosen per turn, as before, and the blocks dealt
    # as they were then (every 4th alignment in measurement order): the period goes in
    monkeypatch.setitem(crossval.CHOSEN_AGAIN, "period", 0.0)
    assert pg.run(23 * 100003 + 428).result["added"] == []  # with blocks of whole poses, not even then
    monkeypatch.setattr(crossval, "held_out_blocks", lambda machine, obs, folds, **kw: [
        np.sort(np.argsort(obs.t_s, kind="stable")[k::folds]) for k in range(folds)])
    before = pg.run(23 * 100003 + 428)
    assert [a.split(":")[:2] for a in before.result["added"]] == [["EZX", "periodic"]]
    assert before.result["held_out_um"] > 2.0 * before.result["default_um"]


def test_misreads_that_stand_out_only_at_the_end_do_not_steer_the_selection():
    """Class 4: a sag and a straightness error of the gantry with 5 % misreads. The two effects' residual hides
    the misreads at the start, they steered the selection to a cross-axis term and a yaw (held-out 3.5× the
    oracle's), and were set aside only at the end. The selection now runs again without them and finds both."""
    sc = pg.run(11 * 100003 + 184)  # a scenario of the full run (seed 11), drawn whole
    print(_line(sc))
    assert (sc.layout, sc.kinds, sc.misread_share) == ("gantry_dual_y", "sag+straightness", 0.05)
    assert sc.result["set_aside"] == sc.result["misreads"]
    assert sorted(sc.result["added"]) == sorted(f"{h.joint}:poly{3 if h.kind == 'straightness' else 2}"
                                                 for h in sc.hidden)
    assert sc.result["held_out_um"] <= 1.2 * sc.result["oracle_um"]


def test_the_final_model_says_what_it_explains_and_whether_structure_remains():
    """The selection's last word: the share of the starting model's residual sum of squares the final model
    explains, computed from the two fits, and whether anything structured remains."""
    from kinid.identification import default_model, forward_select
    from kinid.identification.diagnosis.selection import what_is_left

    _, machine, obs = _data(3, "arm6", ["gear"])
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    text = what_is_left(steps)
    print(text)
    share = 1.0 - (steps[-1].diagnosis.rms_um / steps[0].diagnosis.rms_um) ** 2
    assert len(steps) > 1 and f"explains {share:.0%} of the starting model's residual" in text and share > 0.3
    assert steps[-1].diagnosis.verdict == "noise" and "nothing structured remains" in text


def test_the_last_word_says_why_a_significant_candidate_stayed_out_in_whole_words():
    """The reason was the stop message cut at its first colon: "(the best candidate, EAY)" for EAY:poly3."""
    from types import SimpleNamespace

    from kinid.identification.fitting.crossval import CrossValidation
    from kinid.identification.diagnosis.selection import _why_not_added

    stopped = ("the best candidate, EAY:poly3 (p = 3.3e-06), does not predict held-out data better: held-out "
               "blocks -4% (1.332 → 1.275 µm, 4-fold, gain 1.6 standard errors)")
    why = _why_not_added(SimpleNamespace(held_out=CrossValidation(4, 1.332, 1.275, 1.6), stopped=stopped))
    assert why == "it does not predict held-out alignments better: a gain of 1.6 standard errors, 2 needed"
    other = "adding EXX:map:10 needs EXX:map:10 = 7235 µm, beyond 1000 µm: the observations look inconsistent; not added"
    assert _why_not_added(SimpleNamespace(held_out=None, stopped=other + "; also: x",
                                          diagnosis=SimpleNamespace(inseparable=""))) == other.split("; ")[0]


def test_a_drift_and_an_error_of_the_axis_time_follows_are_named_inseparable():
    """Class 2: a drift of the tool, the plan visited tilt-major (time follows B). An error of B's position explains
    the data as well as the drift: the diagnosis names both and the plan's order as the cause, in the text, the
    JSON and the selection's last word; the selection adds neither (a model of either would compensate what may
    be the other), and its verdict is that an effect remains. Visited at random, the same drift is found without
    that note, and added."""
    from kinid.identification import default_model, diagnose, forward_select
    from kinid.identification.diagnosis.selection import what_is_left

    _, machine, obs = _data(12, "five_axis_bc", ["drift"], plan_kind="patent", order="axis-major", misread_share=0.0)
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    print(dg.inseparable)
    kinds = {":drift" in dg.live[0].effect or ":warmup:" in dg.live[0].effect}
    assert dg.inseparable.startswith(dg.live[0].effect + " and ") and "time follows B" in dg.inseparable
    other = dg.inseparable.split(" and ")[1].split(" ")[0]
    kinds.add(":drift" in other or ":warmup:" in other)
    assert kinds == {True, False}  # one driven by time, the other by B's position
    assert "inseparable: " in dg.text() and dg.summary()["inseparable"] == dg.inseparable
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    assert "time follows B" in steps[-1].stopped and f"{dg.live[0].effect} (p = " in steps[-1].stopped
    assert len(steps) == 1 and steps[-1].diagnosis.verdict == "missing-effect"
    last = what_is_left(steps)
    print(last)
    assert "structure remains" in last and "cannot be told apart" in last and "(--auto adds neither)" not in last
    _, machine, obs = _data(12, "five_axis_bc", ["drift"], plan_kind="patent", order="random", misread_share=0.0)
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    assert ":drift" in dg.live[0].effect and not dg.inseparable
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    assert any(":drift" in (s.added or "") for s in steps)


def test_a_warm_up_is_added_at_its_own_time_constant():
    """Class 3: a spindle warm-up of 6 µm with τ = 1 300 s, between the library's 600 s and 1 800 s and where the
    τ search's trials penalty keeps its own proposal behind the library's: added at 1 800 s, its amplitude missed
    the growth between (on three plans' draws the previous version added τ = 1 800 s each time). The selection now
    refines the τ of the warm-up it adds. EZ0B and EZ0T differ only in sign on this machine."""
    from kinid.identification import default_model, forward_select

    for seed in (21, 22, 23):
        _, machine, obs = _data(seed, "five_axis_bc", [], {"EZ0T": lambda t: 6.0 * (1.0 - np.exp(-t / 1300.0))},
                                plan_kind="patent", order="random", misread_share=0.0)  # the truth, a plain formula
        steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
        warm = [s.added for s in steps[1:] if s.added and ":warmup:" in s.added]
        print(seed, [s.added for s in steps[1:]])
        assert len(warm) == 1 and warm[0].split(":")[0] in ("EZ0T", "EZ0B")
        assert 1000.0 <= float(warm[0].rpartition(":")[2]) <= 1700.0
        final = steps[-1].fit
        assert abs(final.values[final.param_names.index(warm[0])]) == pytest.approx(6.0, abs=0.5)


def test_of_candidates_the_data_cannot_tell_apart_the_one_a_machine_could_have_comes_first():
    """A period of the B-head's turn is read as well by a roll, a pitch or a straightness of B (identical columns,
    the same statistic to 9 digits). The tie went to whichever rounding put first: on proving-ground seed 19 #168
    the roll, at 2.4·10⁴ µrad, which --auto then refused as a size no machine has, and stopped with the default
    model (held-out 20× the oracle's). Of tied candidates the one whose estimated size is the smallest share of
    what a machine has comes first."""
    from kinid.identification import default_model, diagnose
    from kinid.identification.model.plausibility import share_of_limit

    tied_seen = 0
    for seed in (19 * 100003 + 168, 5, 6, 7):
        drawn = dict(layout=None, kinds=None) if seed > 100 else dict(layout="five_axis_bhead_c", kinds=["rotary-period"],
                                                                     plan_kind="patent")
        _, machine, obs = _data(seed, **drawn)
        dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
        tied = [c for c in dg.live if round(c.log10_p, 6) == round(dg.live[0].log10_p, 6)]
        shares = [share_of_limit(machine, c.effect.split(":")[0], c.size, c.size_unit) for c in tied]
        print(seed, [(c.effect, f"{c.size:.3g} {c.size_unit}") for c in tied])
        assert shares[0] == min(shares)
        tied_seen += len(tied) > 1
    assert tied_seen >= 1


def test_a_candidate_only_a_size_no_machine_has_explains_is_passed_over():
    """A bump of Z's position on the B-head's fine plan (proving-ground seed 47 #129, drawn whole): the score test
    ranks first a pitch of Z (EAZ:poly1) that explains a little more than a scale error of Z (EZZ:poly1), but only
    at 44 mrad over Z's range — nearly aliased with the model, it needs a size no machine has. --auto added it
    (the fitted size it then reached passed, the model's EA0Z went to 47 mrad) and ended at 2.6× the oracle's
    held-out error. The selection now passes it over, says so, and adds the scale error that a machine could have;
    when only such sizes explain the structure, it stops and says why (the rule a fitted addition meets)."""
    import io

    from kinid.identification import default_model, diagnose, forward_select
    from kinid.identification.model.plausibility import implausible_candidate, implausible_effects

    passed_over = sys.modules["kinid.identification.diagnosis.diagnose"].passed_over
    from kinid.identification.diagnosis.selection import _first_determined

    _, machine, obs = _data(47 * 100003 + 129, layout=None, kinds=None)
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    odd = implausible_candidate(machine, dg.live[0], dg.fit.axis_ranges)
    assert odd is not None and odd.size > odd.limit and dg.live[0].p_value < dg.threshold
    assert dg.summary()["passed_over"][0]["effect"] == dg.live[0].effect and "not advised" in dg.text()
    best, passed, _ = _first_determined(dg)
    assert passed[0][0] is dg.live[0] and best is dg.live[len(passed)] and best.p_value < dg.threshold
    assert implausible_candidate(machine, best, dg.fit.axis_ranges) is None
    said = io.StringIO()
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0, progress=said)
    added = [s.added for s in steps[1:]]
    assert added and added[0] == best.effect and dg.live[0].effect not in added
    assert f"passed over: {passed_over(*passed[0])}" in said.getvalue()
    assert not implausible_effects(steps[-1].fit, names=tuple(added))


def test_a_selection_only_sizes_no_machine_has_would_explain_stops_and_says_so(monkeypatch):
    """Every candidate sized beyond what a machine has (the check made to say so): nothing is added, the last word
    names the best candidate and the size it would need, and the final text says structure remains."""
    from kinid.identification import default_model, forward_select
    from kinid.identification.model.plausibility import Implausible

    monkeypatch.setattr(sys.modules["kinid.identification.diagnosis.diagnose"], "implausible_candidate",
                        lambda machine, c, ranges: Implausible(c.effect, 2e4, 1e4, "µrad"))
    _, machine, obs = _data(47 * 100003 + 129, layout=None, kinds=None)
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    best = steps[0].diagnosis.live[0]
    assert len(steps) == 1 and steps[-1].stopped.startswith(f"the best candidate, {best.effect} (p = ")
    assert "would need " in steps[-1].stopped and steps[-1].stopped.endswith("; not added")
    left = sys.modules["kinid.identification.diagnosis.selection"].what_is_left(steps)
    text = steps[0].diagnosis.text()  # the diagnosis advises no addition, and says why
    assert "--add" not in text and f"the best candidate, {best.effect} (p = " in text and "would need" in text
    assert f"structure remains: {best.effect} is significant" in left and "would need" in left


def test_runs_recorded_apart_give_the_table_of_the_runs_together(tmp_path, capsys):
    """``--merge``: the docs' table over several seeds is the benchmark's, from the JSONs its runs wrote — the same
    rates as summarising the scenarios themselves."""
    import json

    for seed in (5, 6):
        pg.main(["--scenarios", "2", "--seed", str(seed), "--json", str(tmp_path / f"{seed}.json")])
    capsys.readouterr()
    pg.main(["--merge", str(tmp_path / "5.json"), str(tmp_path / "6.json"), "--json", str(tmp_path / "all.json"),
             "--figure", str(tmp_path / "all.png")])
    out = capsys.readouterr().out
    merged = json.loads((tmp_path / "all.json").read_text())
    direct = pg.summarise([pg.run(seed * 100003 + k) for seed in (5, 6) for k in range(2)])
    assert merged["summary"] == json.loads(json.dumps(direct))
    hidden = [r for r in merged["scenarios"] if r["hidden"]]
    assert f"with a hidden effect: {sum(r['pass'] for r in hidden)} of {len(hidden)} pass" in out
    assert "more than 5 % worse than the default model, held-out: " in out and (tmp_path / "all.png").stat().st_size


def test_a_crash_is_a_failed_scenario_in_the_table(monkeypatch):
    """A scenario whose selection raises is recorded as failed and worse than the default model, and the table and
    its figures count it (it raised a KeyError in the table)."""
    import kinid.identification as ident

    def crash(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(ident, "forward_select", crash)
    sc = pg.run(5 * 100003)
    assert sc.result["verdict"] == "crash: RuntimeError: boom"
    summary = pg.summarise([sc])["all"]
    assert summary["n"] == 1 and summary["pass"] == 0.0 and summary["worse_than_default"] == 1.0
    assert summary["pass_floor"] == 0.0


# -- the families of hidden effects nobody named (benchmarks/proving_families.py) ---------------------------
import proving_families as families  # noqa: E402


def test_the_instrument_reads_offsets_in_the_tool_frame_as_kinid_places_them():
    """The families' truth of an offset (numpy: the tool frame's rotation on the URDF text) and kinid's model of
    the offset columns (the mark at the tool point plus the offset in the tool frame) agree to 1e-9 mm."""
    from kinid.identification.model.machine import evaluate, machine_from_urdf

    rng = np.random.default_rng(1)
    for layout in pg.LAYOUTS:
        text = pg.urdf_text(layout)
        km, tm = machine_from_urdf(text, f"{layout}.urdf"), truth.read_urdf(text)
        readings = {a.name: rng.uniform(-50, 50, 30) for a in km.axes}
        errors = {e.code: rng.uniform(-50, 50, 30) for e in km.error_joints}
        offsets = rng.uniform(-5, 5, (30, 3))
        ours = evaluate(km, np.column_stack([readings[a.name] for a in km.axes]),
                        np.column_stack([errors[e.code] for e in km.error_joints]), jacobian=False, offsets_mm=offsets)
        R, p = truth.tool_pose_mm(tm, readings, errors, 30)
        assert np.abs(ours - (p + np.einsum("nij,nj->ni", R, offsets))).max() < 1e-9, layout
        marks = p + np.einsum("nij,nj->ni", R, offsets)
        assert np.abs(families.offsets_true_mm(tm, readings, errors, marks) - offsets).max() < 1e-9, layout


@pytest.mark.parametrize("family", ["smooth-1", "smooth-2", "step"])
def test_each_family_moves_the_tool_point_5_to_40_um_on_every_layout(family):
    """Every layout has a place for each family; the effect drawn moves the tool point 5–40 µm RMS about its mean
    over the plan (measured here by the truth's chain, with and without it), and what a right verdict may name is
    the machine's axes or time."""
    for k, layout in enumerate(pg.LAYOUTS):
        sc, text, tm, readings, labels, t_s, errors, rng = pg.draw(900 + k, layout, [family], misread_share=0.0)
        assert len(sc.hidden) == 1 and sc.kinds == family, layout
        h = sc.hidden[0]
        n = len(t_s)
        moved = (truth.tool_point_mm(tm, readings, {**errors, h.joint: errors.get(h.joint, 0.0) + h(readings, t_s)}, n)
                 - truth.tool_point_mm(tm, readings, errors, n)) * 1e3
        rms = np.sqrt(np.mean(np.sum((moved - moved.mean(axis=0)) ** 2, axis=1)))
        assert 4.9 < rms < 40.5, (layout, h.joint, h.how, rms)  # (second order of the set-up errors: < 1 %)
        assert h.axes and set(h.axes) <= set(tm.motion) | {"time"}, (layout, h.axes)


def test_a_drawn_step_lies_between_two_positions_the_plan_visits_not_on_one():
    """The step family's step lies between positions: every position of its axis (readings within 0.01 mm or
    0.01°) holds the step's one value at all its rows. Drawn at a percentile, it lay on a position visited many
    times (the five-axis plans' Y at -46.292 mm, 36 rows): the truth's ``q > p`` put 8 of those rows beyond by
    rounding 1e-12 mm of the solved readings, which no model of the readings can place and the oracle could."""
    for k in range(40):
        layout = pg.LAYOUTS[k % len(pg.LAYOUTS)]
        sc, text, tm, readings, labels, t_s, errors, rng = pg.draw(1900 + k, layout, ["step"], misread_share=0.0)
        h = sc.hidden[0]
        axis = h.how.split()[2]
        q, v = np.asarray(readings[axis], float), np.asarray(h(readings, t_s), float)
        beyond = v > 0.5 * (v.min() + v.max())
        assert beyond.any() and not beyond.all(), (layout, h.how)
        position = np.round(q, 2)
        mixed = [p for p in np.unique(position) if 0 < beyond[position == p].mean() < 1]
        assert not mixed, (layout, h.how, mixed)


def test_an_instruments_scale_acts_on_the_offsets_not_on_the_machine():
    """The camera's scale changes only the offsets read: the oracle, which reads them true, fits to the noise,
    while the default model fitted on the offsets read keeps the scale's share (the 'tool-offset' error of the
    instrument is the tool point a user knows, so the held-out truth is where the instrument reads 0)."""
    sc = pg.run(7 * 100003 + 3, kinds=["instrument"])
    assert sc.hidden[0].joint == "camera-scale" and sc.layout == "five_axis_ac"
    r = sc.result
    assert r["oracle_um"] < 1.5 * r["floor_um"] and r["default_um"] > 5 * r["oracle_um"], _line(sc)
    sc = pg.run(7 * 100003 + 7, kinds=["instrument"])
    assert sc.hidden[0].joint == "tool-offset" and pg.verdict_of(sc)["pass"], _line(sc)
    assert sc.result["default_um"] < 1.5 * sc.result["oracle_um"], _line(sc)


def test_an_arms_tilt_with_the_carrying_joints_angle_is_modelled():
    """An arm's J2 tilt, a smooth function of J1's angle (seed 700021 of smooth-1): once only named on J1
    (``missing-effect``, not modelled); the on:<axis> candidate of J2's location joints on J1, the joint that carries
    J2, now models it — the held-out error at the oracle's and nothing left."""
    sc = pg.run(7 * 100003 + 0, kinds=["smooth-1"])
    r, v = sc.result, pg.verdict_of(sc)
    assert "J1" in sc.hidden[0].axes and any(n.startswith("EB0J2:on:J1") for n in r["added"]), _line(sc)
    assert r["held_out_um"] <= 1.5 * r["oracle_um"] and r["verdict"] == "noise" and v["pass"], _line(sc)


@pytest.mark.parametrize("seed, family, named", [
    (7 * 100003 + 5, "smooth-2", "C"),  # a B-head's workpiece tilt with Z × C: named on C
])
def test_a_shape_nobody_named_is_named_on_its_axis(seed, family, named):
    """Seeded scenarios of the families that pass by the verdict: whatever the model it ends with, its
    missing-effect verdict names an axis the shape is a function of."""
    sc = pg.run(seed, kinds=[family])
    v = pg.verdict_of(sc)
    assert sc.result["verdict"] == "missing-effect" and named in sc.result["named"], _line(sc)
    assert named in sc.hidden[0].axes and v["pass"], _line(sc)


def test_a_gantrys_yaw_stepping_along_v_is_modelled_as_a_step():
    """A gantry's yaw stepping along V passed by its verdict (a local error of V added, V named); the step at a searched
    position now models it: a step of V added, the held-out error within 1.5× the oracle's."""
    sc = pg.run(7 * 100003 + 6, kinds=["step"])
    r, v = sc.result, pg.verdict_of(sc)
    assert "V" in sc.hidden[0].axes and any(":step:V:" in n for n in r["added"]), _line(sc)
    assert r["held_out_um"] <= 1.5 * r["oracle_um"] and v["pass"] and not v["worse_than_default"], _line(sc)


def test_the_cameras_scale_is_named_not_replaced_by_a_machine_error():
    """A camera whose scale is off made the selection add a lead of X in its place (held-out 9.66 µm
    against the default model's 5.96). The instrument's errors are now scored against the residual: they explain
    it more than the lead does, so nothing is added and the verdict names the camera's scale."""
    sc = pg.run(7 * 100003 + 3, kinds=["instrument"])
    r, v = sc.result, pg.verdict_of(sc)
    assert sc.hidden[0].joint == "camera-scale", _line(sc)
    assert r["added"] == [] and r["verdict"] == "missing-effect" and "camera" in r["named"], _line(sc)
    assert "the camera's scale" in r["stopped"] and v["pass"] and not v["worse_than_default"], r["stopped"]


def test_a_lasers_scale_on_an_arm_is_named_though_no_machine_error_stands_out():
    """A laser whose scale is 1.8 % off on an arm (seed 15 of the families' run 2311): the fit took part of it into
    the joints' errors, no machine candidate was significant and the verdict said noise (held-out 7.1 µm against
    the oracle's 0.50). The instrument is now scored at every stop: its χ² drop (thousands) names the laser."""
    sc = pg.run(2311 * 100003 + 15, kinds=["instrument"])
    r, v = sc.result, pg.verdict_of(sc)
    assert sc.hidden[0].joint == "laser-scale" and sc.layout == "arm6", _line(sc)
    assert r["added"] == [] and r["verdict"] == "missing-effect" and "laser" in r["named"], _line(sc)
    assert "the laser's scale" in r["stopped"] and v["pass"], r["stopped"]


def test_the_instruments_errors_are_estimated_from_offsets_alone():
    """Rows made by the truth's chain with the camera's scale 1.2 % long and turned 3 mrad, and the laser's scale
    0.8 % short, no noise: at the default model's fit, the score test estimates both scales within 2 % of their
    size; the turn is the tool set-up's own rotation, which the default model holds (EC0T: not scored); on
    alignments (no offsets) there is nothing to score."""
    from kinid.identification import default_model, fit
    from kinid.identification.data.observations import Observations
    from kinid.identification.diagnosis.instrument import instrument_errors
    from kinid.identification.model.machine import machine_from_urdf

    sc, text, tm, readings, labels, t_s, errors, rng = pg.draw(3, "five_axis_bc", [], misread_share=0.0)
    n = len(t_s)
    marks = truth.tool_point_mm(tm, readings, {}, n)
    near = families.stop_near(tm, readings, 3.0, np.random.default_rng(4))
    true = families.offsets_true_mm(tm, near, errors, marks)
    c, s = np.cos(3e-3), np.sin(3e-3)
    read = np.column_stack([1.012 * (c * true[:, 0] - s * true[:, 1]), 1.012 * (s * true[:, 0] + c * true[:, 1]),
                            0.992 * true[:, 2]])
    machine = machine_from_urdf(text, "five_axis_bc.urdf")
    axes = np.column_stack([near[a.name] for a in machine.axes])
    obs = Observations(tuple(f"M{k}" for k in labels), marks, axes, t_s, {}, (), "<truth>", read)
    result = fit(machine, obs, default_model(machine), noise_um=1.0)
    found = instrument_errors(machine, obs, result, 1.0)
    scale, laser = (found.sizes[k][0] for k in ("camera-scale", "laser-scale"))
    assert abs(scale - (1.012 * c - 1)) < 0.02 * 0.012 and abs(laser + 0.008) < 0.02 * 0.008, found.sizes
    assert set(found.named) == {"camera-scale", "laser-scale"} and found.k == 2, found.sizes
    assert "EC0T" in result.param_names and result.rms_um > 1.0  # the scales, not the turn, are left
    assert instrument_errors(machine, replace(obs, offsets_mm=None), result, 1.0) is None
