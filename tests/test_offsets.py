"""Observations with measured offsets: the mark seen at an offset from the tool point, in the tool frame."""
from __future__ import annotations

import numpy as np
import pytest

from kinid.identification import default_model, fit, load_machine, parse_effect, read_observations
from kinid.identification.model.machine import evaluate
from kinid.identification.data.observations import write_observations
from kinid.identification.fitting.residuals import design, residuals
from kinid.identification.fitting.simulate import patent_plan, simulate
from kinid.urdf import path


def _rot(axis, rad):
    c, s = np.cos(rad), np.sin(rad)
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@pytest.mark.parametrize("ec0t_urad", [0.0, 2000.0])
def test_offset_point_matches_hand_formula(ec0t_urad):
    """Nominal B/C kinematics written by hand: the offset is carried by the tool frame (rotated by EC0T)."""
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(1)
    axes = {"X": 12.0, "Y": -30.0, "Z": 8.0, "B": 35.0, "C": 110.0}
    d = rng.normal(0, 2.0, size=3)
    tool_world = np.array([axes["X"], 0.0, axes["Z"] + 110.0]) + _rot("z", ec0t_urad * 1e-6) @ d
    R = _rot("y", np.radians(axes["B"])) @ _rot("z", np.radians(axes["C"]))
    p_w = np.array([0, axes["Y"], 150.0]) + _rot("y", np.radians(axes["B"])) @ [0, 0, -50.0] + R @ [0, 0, 10.0]
    expected = R.T @ (tool_world - p_w)
    a = np.array([[axes[n] for n in m.axis_names]])
    e = np.zeros(len(m.error_joints))
    e[m.error_codes.index("EC0T")] = ec0t_urad
    got = evaluate(m, a, e, jacobian=False, offsets_mm=d)[0]
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_offset_jacobians_match_finite_differences():
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(5)
    scale = np.array([100.0 if a.kind == "prismatic" else 40.0 for a in m.axes])
    axes = rng.uniform(-1, 1, size=(5, len(m.axes))) * scale
    errors = rng.normal(0, 300, size=len(m.error_joints))
    offsets = rng.normal(0, 3.0, size=(5, 3))
    p, d_err, d_ax = evaluate(m, axes, errors, offsets_mm=offsets)
    h = 1e-3
    for k in range(len(m.error_joints)):
        e1, e2 = errors.copy(), errors.copy()
        e1[k] += h
        e2[k] -= h
        fd = (evaluate(m, axes, e1, jacobian=False, offsets_mm=offsets)
              - evaluate(m, axes, e2, jacobian=False, offsets_mm=offsets)) / (2 * h) * 1e3
        np.testing.assert_allclose(d_err[:, :, k], fd, atol=1e-6, err_msg=m.error_codes[k])
    for k in range(len(m.axes)):
        a1, a2 = axes.copy(), axes.copy()
        a1[:, k] += h
        a2[:, k] -= h
        fd = (evaluate(m, a1, errors, jacobian=False, offsets_mm=offsets)
              - evaluate(m, a2, errors, jacobian=False, offsets_mm=offsets)) / (2 * h) * 1e3
        np.testing.assert_allclose(d_ax[:, :, k], fd, rtol=1e-6, atol=1e-4, err_msg=m.axis_names[k])
    # a rotation error of the tool set-up now moves the seen point (it does not move the tool point itself)
    k = m.error_codes.index("EC0T")
    assert np.abs(d_err[:, :2, k]).max() > 1e-4
    p0, d0, _ = evaluate(m, axes, errors)
    assert np.abs(d0[:, :, k]).max() < 1e-9


def test_effect_jacobian_with_offsets_matches_finite_differences():
    m = load_machine(path("five_axis_bc"))
    effects = [parse_effect(n, m) for n in ("EX0C", "EXX:periodic:10", "EC0T", "EB0C")]
    theta = np.array([5.0, 1.0, -0.5, 300.0, 40.0])
    obs = simulate(m, patent_plan(m).subset(slice(0, 40)), effects, theta, rng=np.random.default_rng(2), stop_scatter_um=200.0)
    d = design(m, effects, obs)
    r, J, _ = residuals(m, d, obs, theta)
    h = 1e-4
    for k in range(len(theta)):
        t1, t2 = theta.copy(), theta.copy()
        t1[k] += h
        t2[k] -= h
        fd = (residuals(m, d, obs, t1, jacobian=False) - residuals(m, d, obs, t2, jacobian=False)) / (2 * h)
        np.testing.assert_allclose(J[:, :, k], fd, atol=1e-6)


def test_offset_rows_round_trip_and_fit(tmp_path):
    """Readings where the operator stopped 0.2 mm off the mark, offsets recorded: the fit recovers the truth;
    the same rows without their offsets do not."""
    m = load_machine(path("five_axis_bc"))
    truth = {"EX0C": 12.0, "EA0B": -25.0, "EC0T": 400.0, "EXX:periodic:10": [1.5, -0.8]}
    effects = [parse_effect(n, m) for n in truth]
    theta = np.concatenate([np.atleast_1d(v) for v in truth.values()]).astype(float)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=0.5, rng=np.random.default_rng(7), stop_scatter_um=200.0)
    assert obs.offsets_mm is not None and np.abs(obs.offsets_mm[:, :2]).max() > 0.2
    write_observations(tmp_path / "obs.csv", obs, m)
    header = (tmp_path / "obs.csv").read_text().splitlines()[0].split(",")
    assert header[-3:] == ["mark_dx_mm", "mark_dy_mm", "mark_dz_mm"]
    back = read_observations(tmp_path / "obs.csv", m)
    np.testing.assert_allclose(back.offsets_mm, obs.offsets_mm, atol=1e-6)
    model = list(default_model(m)) + [parse_effect("EXX:periodic:10", m)]
    result = fit(m, back, model, noise_um=0.5)
    names = result.param_names
    for name, value in (("EX0C", 12.0), ("EA0B", -25.0), ("EXX:periodic:10[sin]", 1.5), ("EXX:periodic:10[cos]", -0.8)):
        i = names.index(name)
        assert abs(result.theta[i] - value) < 4 * result.std[i] + 1e-9, (name, result.theta[i], result.std[i])
    assert result.rms_um < 0.6
    # the offsets thrown away: the 0.2 mm stops become residual
    from dataclasses import replace
    blind = fit(m, replace(back, offsets_mm=None), model, noise_um=0.5)
    assert blind.rms_um > 50 * result.rms_um


def test_partial_offset_columns_default_to_zero(tmp_path):
    m = load_machine(path("five_axis_bc"))
    text = ("mark,wx_mm,wy_mm,wz_mm,x_mm,y_mm,z_mm,b_deg,c_deg,mark_dz_mm\n"
            "M1,40,-40,-0.05,40,40,0,0,0,-0.05\n"
            "M2,40,-40,0,40,40,0,0,0,-0.05\n")
    (tmp_path / "o.csv").write_text(text)
    obs = read_observations(tmp_path / "o.csv", m)
    np.testing.assert_array_equal(obs.offsets_mm, [[0, 0, -0.05]] * 2)
    # M1 lies 0.05 mm below the tool point and was seen there: residual zero on the nominal machine;
    # M2 lies at the tool point but was seen 0.05 mm below it: residual -50 µm in z
    d = design(m, [], obs)
    np.testing.assert_allclose(residuals(m, d, obs, np.zeros(0), jacobian=False), [[0, 0, 0], [0, 0, -50.0]], atol=1e-6)


def test_solve_axes_with_offsets_puts_the_offset_point_on_the_mark():
    from dataclasses import replace

    from kinid.identification import solve_axes

    m = load_machine(path("five_axis_bc"))
    plan = patent_plan(m).subset(slice(0, 12))
    offsets = np.random.default_rng(4).normal(0, 0.3, (12, 3))
    solved = solve_axes(m, [], np.zeros(0), replace(plan, offsets_mm=offsets))
    d = design(m, [], solved)
    np.testing.assert_allclose(residuals(m, d, solved, np.zeros(0), jacobian=False), 0.0, atol=1e-6)
    plain = solve_axes(m, [], np.zeros(0), plan)
    assert np.abs(plain.axes - solved.axes).max() > 0.1  # the offsets moved the solution


def test_example_observation_files_read():
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent / "examples"
    m = load_machine(path("five_axis_bc"))
    plain = read_observations(root / "observations.csv", m)
    shifted = read_observations(root / "observations_offsets.csv", m)
    assert plain.offsets_mm is None and shifted.offsets_mm is not None
    assert plain.marks == shifted.marks and np.abs(shifted.offsets_mm).max() > 0.001
