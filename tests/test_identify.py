"""Identification against synthetic truth: exact without noise, within σ with noise, held-out poses."""
from dataclasses import replace

import numpy as np
import pytest

from kinid.identification.fitting.alignment import solve_axes
from kinid.identification.model.effects import default_model, parse_effect
from kinid.errors import DataError
from kinid.identification.fitting.fit import fit
from kinid.identification.fitting.fit_file import load_fit, save_fit
from kinid.identification.model.machine import load_machine
from kinid.identification.fitting.residuals import design, residuals
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.urdf import path

MACHINES = ["five_axis_bc", "five_axis_ac", "five_axis_bhead_c"]


def random_truth(machine, rng, extra=None, setup_mm=1.0, setup_deg=0.5):
    """A random error set: every default-model error, mm / degree set-up of the board, plus ``extra``."""
    truth = {e.code: float(rng.normal(0, 20.0)) for e in default_model(machine)}
    truth["EX0W"] = setup_mm * 1000 * rng.uniform(0.5, 1.5)
    truth["EY0W"] = -setup_mm * 1000 * rng.uniform(0.5, 1.5)
    truth["EC0W"] = np.radians(setup_deg) * 1e6
    truth.update(extra or {})
    return truth


def expected_values(result, truth_by_name):
    """What the data determine: each identified parameter plus c × each parameter aliased onto it."""
    expected = {n: truth_by_name.get(n, 0.0) for n in result.param_names}
    for a in result.aliases:
        for partner, c in a.partners:
            expected[partner] += c * truth_by_name.get(a.name, 0.0)
    return np.array([expected[n] for n in result.param_names])


def param_truth(effects, theta):
    out, k = {}, 0
    for e in effects:
        for name in e.param_names():
            out[name] = theta[k]
            k += 1
    return out


def heldout(machine, rng, n=40):
    plan = patent_plan(machine)
    held = plan.subset(rng.choice(len(plan), n, replace=False))
    axes = held.axes.copy()
    rot = [j for j, a in enumerate(machine.axes) if a.kind == "revolute"]
    axes[:, rot] += rng.uniform(-8, 8, size=(n, len(rot)))
    return replace(held, axes=axes, w_mm=held.w_mm + np.c_[rng.uniform(-15, 15, (n, 2)), np.zeros(n)])


@pytest.fixture(scope="module", params=MACHINES)
def machine(request):
    return load_machine(path(request.param))


def test_exact_recovery_without_noise(machine):
    """The identifiable part of a random error set comes back to ~1e-9; held-out poses are exact."""
    rng = np.random.default_rng(11)
    pdge = next(e for e in machine.error_joints if not e.location and e.axis == "X")
    extra = {f"{pdge.code}:poly2": [0.02, -1e-4], f"{pdge.code}:periodic:10": [1.5, -0.7]}
    truth = random_truth(machine, rng, extra)
    effects, theta = errors_from_mapping(truth, machine)
    plan = patent_plan(machine)
    # which parameters these data cannot determine: keep the truth in the identifiable part
    probe = fit(machine, simulate(machine, plan, effects, theta, rng=rng), effects)
    for a in probe.aliases:
        truth[a.name] = 0.0
    effects, theta = errors_from_mapping(truth, machine)
    obs = simulate(machine, plan, effects, theta, noise_um=0.0, rng=rng)
    result = fit(machine, obs, effects)
    assert result.success, result.message
    assert result.rms_um < 1e-7
    ok = result.identifiable
    # to ~1e-9, or, for a parameter the plan hardly sees (EA0Z on the B-head machine), within the
    # uncertainty the fit states for it at the residual's own (rounding-level) σ
    tol = np.maximum(1e-8 + 2e-8 * np.abs(theta[ok]), 5 * result.std[ok])
    bad = np.abs(result.values[ok] - theta[ok]) > tol
    assert not bad.any(), [(n, v, t, s) for n, v, t, s, b in zip(np.array(result.param_names)[ok], result.values[ok],
                                                                  theta[ok], result.std[ok], bad) if b]
    assert np.count_nonzero(result.std[ok] * 5 > 1e-8 + 2e-8 * np.abs(theta[ok])) <= 1
    assert np.all(np.isnan(result.values[~ok])), "unidentifiable parameters must not be returned as numbers"
    held = heldout(machine, rng)
    true = solve_axes(machine, effects, theta, held)
    pred = solve_axes(machine, result.effects, result.theta, held)
    np.testing.assert_allclose(pred.axes, true.axes, atol=1e-10)


def test_aliased_truth_still_predicts_exactly(machine):
    """With every parameter true (aliased ones too) the fit still reproduces the data and new poses."""
    rng = np.random.default_rng(12)
    truth = random_truth(machine, rng)
    effects, theta = errors_from_mapping(truth, machine)
    obs = simulate(machine, patent_plan(machine), effects, theta, rng=rng)
    result = fit(machine, obs, effects)
    assert result.rms_um < 1e-6
    ok = result.identifiable
    # to first order the data see each identified parameter plus its aliased partners
    np.testing.assert_allclose(result.values[ok], expected_values(result, param_truth(effects, theta))[ok], atol=2e-3)
    held = heldout(machine, rng)
    pred = solve_axes(machine, result.effects, result.theta, held)
    true = solve_axes(machine, effects, theta, held)
    np.testing.assert_allclose(pred.axes, true.axes, atol=1e-8)


def test_bc_machine_names_the_aliases():
    m = load_machine(path("five_axis_bc"))
    obs = simulate(m, patent_plan(m), [], np.zeros(0), rng=np.random.default_rng(0))
    result = fit(m, obs)
    messages = {a.name: a for a in result.aliases}
    assert messages["EX0T"].kind == "aliased" and messages["EX0T"].partners[0][0] == "EX0B"
    assert "only their difference" in messages["EX0T"].message
    assert messages["EY0T"].partners[0][0] == "EY0C"
    for code in ("EA0T", "EB0T", "EC0T"):
        assert messages[code].kind == "invisible"
    assert result.rank == 17 and result.condition_number < 100
    assert 0 < result.o3 <= result.o1 * np.sqrt(3 * len(obs))


def test_recovery_with_noise_within_stated_uncertainty():
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(5)
    truth = random_truth(m, rng)
    effects, theta = errors_from_mapping(truth, m)
    z = []
    for seed in range(6):
        obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=np.random.default_rng(100 + seed))
        result = fit(m, obs, effects, noise_um=1.0)
        ok = result.identifiable
        z.append(((result.values - expected_values(result, param_truth(effects, theta))) / result.std)[ok])
    z = np.concatenate(z)
    assert np.all(np.abs(z) < 4.0), np.abs(z).max()
    # the stated σ is right: z-scores have unit variance (102 samples: ±30 % is > 3 standard errors)
    assert 0.7 < np.std(z) < 1.3


def test_heldout_prediction_with_noise_near_true_structure():
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(8)
    truth = random_truth(m, rng)
    effects, theta = errors_from_mapping(truth, m)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=rng)
    result = fit(m, obs, noise_um=1.0)
    held = heldout(m, rng)
    true = solve_axes(m, effects, theta, held)
    pred = solve_axes(m, result.effects, result.theta, held)
    rms3 = np.sqrt(np.mean(np.sum((pred.axes - true.axes) ** 2, axis=1))) * 1e3
    assert rms3 < 0.5, rms3


def test_large_setup_errors_converge():
    m = load_machine(path("five_axis_bc"))
    truth = {"EX0W": 4000.0, "EY0W": -3000.0, "EZ0W": 800.0, "EC0W": np.radians(5) * 1e6, "EA0W": np.radians(1) * 1e6, "EX0C": 30.0}
    effects, theta = errors_from_mapping(truth, m)
    obs = simulate(m, patent_plan(m), effects, theta, rng=np.random.default_rng(0))
    result = fit(m, obs)
    assert result.success and result.rms_um < 1e-7
    got = dict(zip(result.param_names, result.values))
    assert got["EC0W"] == pytest.approx(truth["EC0W"], abs=1e-6)
    assert got["EX0W"] == pytest.approx(4000.0, abs=1e-6)


def test_bounds_are_respected():
    m = load_machine(path("five_axis_bc"))
    effects, theta = errors_from_mapping({"EX0C": 25.0}, m)
    obs = simulate(m, patent_plan(m), effects, theta, rng=np.random.default_rng(0))
    result = fit(m, obs, bounds={"EX0C": (-10.0, 10.0)})
    assert result.values[result.param_names.index("EX0C")] == pytest.approx(10.0, abs=1e-6)
    free = fit(m, obs)
    assert free.values[free.param_names.index("EX0C")] == pytest.approx(25.0, abs=1e-6)


@pytest.mark.parametrize("name", ["EXX:poly3", "EXX:periodic:8", "EYY:reversal", "ECC:periodic:90", "EX0C:drift", "EB0C"])
def test_effect_jacobian_matches_finite_differences(name):
    m = load_machine(path("five_axis_bc"))
    effects = default_model(m)[:3] + [parse_effect(name, m)]
    obs = simulate(m, patent_plan(m), [], np.zeros(0), rng=np.random.default_rng(0)).subset(slice(0, 40))
    d = design(m, effects, obs)
    rng = np.random.default_rng(1)
    theta = rng.normal(0, 5, d.n_params) * np.r_[np.ones(3), 1e-3 ** np.arange(d.n_params - 3)]
    _, J, _ = residuals(m, d, obs, theta)
    for k in range(d.n_params):
        h = 1e-4 * max(1.0, abs(theta[k]))
        t1, t2 = theta.copy(), theta.copy()
        t1[k] += h
        t2[k] -= h
        fd = (residuals(m, d, obs, t1, jacobian=False) - residuals(m, d, obs, t2, jacobian=False)) / (2 * h)
        # central differences of µm-valued residuals carry ~1e-7 of rounding noise
        np.testing.assert_allclose(J[:, :, k], fd, rtol=1e-5, atol=1e-6 * (1 + np.abs(fd).max()))


def test_save_and_load_fit_round_trip(tmp_path):
    m = load_machine(path("five_axis_bc"))
    effects, theta = errors_from_mapping({"EX0C": 10.0, "EXX:periodic:10": [1.0, 0.5]}, m)
    obs = simulate(m, patent_plan(m), effects, theta, rng=np.random.default_rng(0))
    result = fit(m, obs, default_model(m) + [parse_effect("EXX:periodic:10", m)])
    save_fit(result, tmp_path / "fit.json")
    loaded = load_fit(tmp_path / "fit.json")
    np.testing.assert_array_equal(loaded.theta, result.theta)
    assert loaded.effects == result.effects
    assert loaded.machine.error_codes == m.error_codes


def test_fit_rejects_bad_noise():
    m = load_machine(path("five_axis_bc"))
    obs = simulate(m, patent_plan(m), [], np.zeros(0), rng=np.random.default_rng(0))
    with pytest.raises(DataError, match="noise_um must be a positive number"):
        fit(m, obs, noise_um=-1.0)


def test_loaded_fit_is_the_same_result_type_with_the_same_numbers(tmp_path):
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(11)
    effects, theta = errors_from_mapping({"EX0C": 15.0, "EA0B": -30.0}, m)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=0.5, rng=rng)
    result = fit(m, obs, noise_um=0.5)
    save_fit(result, tmp_path / "fit.json")
    loaded = load_fit(tmp_path / "fit.json")
    assert type(loaded) is type(result)
    assert loaded.residuals_um is None and loaded.n_observations == len(obs)
    for name in ("param_names", "units", "rank", "dof", "iterations", "success", "message", "noise"):
        assert getattr(loaded, name) == getattr(result, name), name
    for name in ("values", "std", "singular_values"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(result, name))
    assert loaded.aliases == result.aliases
    assert loaded.noise_um == 0.5 and loaded.noise_source == "given"


def test_sigma_keeps_its_source_through_selection_into_the_saved_fit(tmp_path):
    from kinid.identification import forward_select
    from kinid.identification.fitting.noise import Noise

    m = load_machine(path("five_axis_bc"))
    effects, theta = errors_from_mapping({"EX0C": 15.0, "EXX:periodic:10": [2.5, 0.0]}, m)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=np.random.default_rng(5))
    steps = forward_select(m, obs, default_model(m), noise_um=1.0, max_steps=2)
    assert len(steps) >= 2
    assert all(s.fit.noise == Noise(1.0, "given") and s.diagnosis.noise == Noise(1.0, "given") for s in steps)
    save_fit(steps[-1].fit, tmp_path / "fit.json")
    assert load_fit(tmp_path / "fit.json").noise == Noise(1.0, "given")
