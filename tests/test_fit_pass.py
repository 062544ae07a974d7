"""The fit's passes on the machine reduced to the error joints in use, and its stop by the predicted step."""
import importlib
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.optimize

from kinid.identification.fitting.fit import fit
from kinid.identification.fitting.fit_pass import model_pass_qr, reduced
from kinid.identification.fitting.lm_step import STOP_STEP_STD, below_noise
from kinid.identification.fitting.residuals import design, residuals
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.identification.model.effects import default_model
from kinid.identification.model.machine import load_machine
from kinid.urdf import path

ROOT = Path(__file__).resolve().parent.parent


def _readme_example(name="five_axis_bc"):
    m = load_machine(path(name))
    effects, theta = errors_from_mapping(json.loads((ROOT / "examples" / "errors.json").read_text()), m)
    return m, simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=np.random.default_rng(0))


@pytest.mark.parametrize("name", ["five_axis_bc", "five_axis_bhead_c"])
def test_the_reduced_machine_gives_the_full_machines_points_and_columns(name):
    m, obs = _readme_example(name)
    obs = obs.subset(np.arange(0, len(obs), 7))
    rng = np.random.default_rng(3)
    offsets = rng.normal(0, 20, (len(obs), 3))  # a point off the tool, mm: the tool frame's turn counts too
    obs = replace(obs, offsets_mm=offsets)
    d = design(m, default_model(m), obs)
    mr, dr = reduced(m, d)
    assert mr.model.nq < m.model.nq and len(mr.error_joints) == len(np.unique(d.joint_index))
    assert [mr.error_joints[j].code for j in dr.joint_index] == [m.error_joints[j].code for j in d.joint_index]
    theta = rng.normal(0, 30, d.n_params)  # µm / µrad, as errors are
    r_full, J_full, _ = residuals(m, d, obs, theta)
    r_red, J_red, _ = residuals(mr, dr, obs, theta)
    np.testing.assert_allclose(r_red, r_full, atol=1e-9)  # µm
    np.testing.assert_allclose(J_red, J_full, atol=1e-9)
    assert reduced(mr, dr)[0] is mr  # a reduced machine is reduced no further


def test_below_noise_is_a_step_shorter_than_its_share_of_a_standard_deviation():
    sigma = 2.0
    at = 0.5 * (STOP_STEP_STD * sigma) ** 2  # ½‖Jδ‖² of a step STOP_STEP_STD σ long in the covariance's metric
    assert below_noise(0.99 * at, 1e3, sigma, 100)
    assert not below_noise(1.01 * at, 1e3, sigma, 100)
    # σ from the residuals: 2·cost/dof = σ²
    assert below_noise(0.99 * at, 0.5 * 100 * sigma**2, None, 100)
    assert not below_noise(1.01 * at, 0.5 * 100 * sigma**2, None, 100)
    assert not below_noise(0.0, 1.0, None, 0)  # no degrees of freedom: no σ to judge by


def test_the_fit_stops_after_one_residual_check_at_the_optimum(monkeypatch):
    m, obs = _readme_example()
    fit(m, obs, noise_um=1.0)  # the first pass on a machine checks its view of Pinocchio's placements once
    calls = []
    original = pin.forwardKinematics
    monkeypatch.setattr(pin, "forwardKinematics", lambda model, data, q: (calls.append(model.nq), original(model, data, q))[1])
    fit_module = importlib.import_module("kinid.identification.fitting.fit")
    passes = []
    for name in ("model_pass_qr", "residuals_chunked"):
        f = getattr(fit_module, name)
        monkeypatch.setattr(fit_module, name, lambda *a, f=f, name=name, **k: (passes.append(name), f(*a, **k))[1])
    res = fit(m, obs, noise_um=1.0)
    monkeypatch.undo()
    assert passes == ["model_pass_qr", "model_pass_qr", "residuals_chunked"]
    assert res.success and res.message == f"converged in {res.iterations} iterations"
    # passes: the Jacobian at zero, at the first step, and the residuals of the last step (no third Jacobian)
    assert len(calls) == 3 * len(obs)
    d = design(m, res.effects, obs)
    mr, dr = reduced(m, d)
    assert set(calls) == {mr.model.nq}  # on the reduced machine only
    # the optimum from scipy with tight tolerances, on the full machine
    free = res.identifiable

    def point(x):
        t = np.zeros(d.n_params)
        t[free] = x
        return t

    sol = scipy.optimize.least_squares(
        lambda x: residuals(m, d, obs, point(x), jacobian=False).ravel(), np.zeros(free.sum()),
        jac=lambda x: residuals(m, d, obs, point(x))[1].reshape(-1, d.n_params)[:, free],
        method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    # the step left after the last one taken is second order: far below the STOP_STEP_STD σ it was judged by
    assert np.max(np.abs(res.values[free] - sol.x) / res.std[free]) < 1e-3
    # the covariance is the last Jacobian pass's, a step of < 1 % σ from the optimum: the same std to 1e-6
    R_opt = model_pass_qr(m, d, obs, point(sol.x)).R[:, free]
    std_opt = np.sqrt(np.diag(np.linalg.inv(R_opt.T @ R_opt)))
    np.testing.assert_allclose(res.std[free], std_opt, rtol=1e-6)


def test_the_placements_copied_a_pose_at_a_time_are_pinocchios_one_by_one():
    m, obs = _readme_example()
    placements = importlib.import_module("kinid.identification.model.placements")
    machine_module = importlib.import_module("kinid.identification.model.machine")
    obs = obs.subset(np.arange(0, len(obs), 5))
    errors = np.random.default_rng(4).normal(0, 30, (len(obs), len(m.error_joints)))  # µm / µrad
    qs = machine_module._configurations(m, machine_module.axes_to_si(m, obs.axes), errors * 1e-6)
    data = m.model.createData()
    first, last = 2, m.model.njoints - 1
    copied = placements._read_placements(m, data, qs, first, last)
    m.__dict__["_placements_view_cache"][id(data)] = (data, None)  # as where the view's layout is not Pinocchio's
    one_by_one = placements._read_placements(m, data, qs, first, last)
    assert copied.shape == (len(obs), last - first + 1, 12)
    assert np.array_equal(copied, one_by_one)
    expected = []
    for q in qs:
        pin.forwardKinematics(m.model, data, q)
        expected.append([np.r_[data.oMi[j].rotation.ravel(order="F"), data.oMi[j].translation] for j in (first, last)])
    assert np.array_equal(copied[:, [0, -1]], expected)
