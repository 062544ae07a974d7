"""The leverages and the pose advice from the fit's own R factor are those of a pass of their own.

``kinid identify`` on large files: the misread check's leverages and the pose advice took the R factor of the data's
Jacobian from the fit (``FitResult.jacobian_r`` at the fit, ``jacobian_r_zero`` at zero) instead of a pass more.
The old ways, kept here as plain numpy: the hat matrix's diagonal from the QR of the whole Jacobian held at once, and
the advice from a pass over every row (a fit without its R factors, as one loaded from its file, still does that).
On the README's example (the B/C machine, the patent's plan, examples/errors.json) and a small arm problem.
"""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from kinid.identification.data.observations import Observations
from kinid.identification.fitting import leverage
from kinid.identification.fitting.fit import fit
from kinid.identification.fitting.outliers import set_aside_with_fit
from kinid.identification.fitting.residuals import design, joint_values, residuals
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.identification.model import evaluate
from kinid.identification.model.effects import default_model
from kinid.identification.model.machine import load_machine, machine_from_urdf
from kinid.identification.model.urdf_import import identification_urdf
from kinid.identification.planning import data_advice
from kinid.urdf import path

ROOT = Path(__file__).resolve().parent.parent


def _readme():
    bc = load_machine(path("five_axis_bc"))
    effects, theta = errors_from_mapping(json.loads((ROOT / "examples" / "errors.json").read_text()), bc)
    return bc, simulate(bc, patent_plan(bc), effects, theta, noise_um=1.0, rng=np.random.default_rng(3))


def _arm():
    text = identification_urdf((ROOT / "examples" / "ur_like.urdf").read_text(), base="world", tool="wrist_3_link",
                               tool_offset_m=(0.0, 0.0, 0.1))
    arm = machine_from_urdf(text, "arm.urdf")
    rng = np.random.default_rng(5)
    effects = default_model(arm)
    theta = rng.normal(0.0, 20.0, sum(e.n_params for e in effects))
    n = 60  # joint readings at random, the marks where the arm with these errors puts the tool
    axes = rng.uniform(-120.0, 120.0, (n, len(arm.axes)))
    plain = Observations(tuple(f"P{i}" for i in range(n)), np.zeros((n, 3)), axes, None, {}, tuple(range(2, n + 2)),
                         "<arm>")
    p = evaluate(arm, axes, joint_values(arm, design(arm, effects, plain), theta), jacobian=False)
    return arm, replace(plain, w_mm=p + rng.normal(0.0, 0.01, (n, 3)))


@pytest.mark.parametrize("problem", [_readme, _arm], ids=["readme", "arm"])
def test_the_leverages_and_the_advice_from_the_fits_r_are_those_of_a_pass_of_their_own(problem):
    machine, obs = problem()
    result = fit(machine, obs, default_model(machine), noise_um=1.0)
    assert result.jacobian_r is not None and result.jacobian_r_zero is not None
    d = design(machine, result.effects, obs)
    J = residuals(machine, d, obs, result.theta)[1].reshape(-1, d.n_params)[:, result.identifiable]
    held = np.sum(np.linalg.qr(J, mode="reduced")[0] ** 2, axis=1).reshape(-1, 3)  # the old way: J held whole
    new = leverage.leverages(machine, obs, result)
    assert np.allclose(new, held, rtol=1e-9, atol=1e-12)
    assert abs(new.sum() - result.rank) < 1e-8
    own = replace(result, jacobian_r=None, jacobian_r_zero=None)  # a loaded fit's: passes of their own
    assert np.allclose(leverage.leverages(machine, obs, own), held, rtol=1e-9, atol=1e-12)
    assert result.aliases  # both problems hold parameters: the advice has something to say
    assert data_advice(machine, result, obs) == data_advice(machine, own, obs)


def test_the_set_aside_returns_the_fit_identify_would_make_again():
    """``kinid identify`` takes the set-aside's fit of the rows kept instead of fitting them again: the same fit."""
    bc, obs = _readme()
    obs = replace(obs, w_mm=obs.w_mm.copy())
    obs.w_mm[7] += 0.2  # a misread of 200 µm: set aside in the first round, the kept rows fitted in the second
    kept, aside, kept_fit = set_aside_with_fit(bc, obs, default_model(bc), noise_um=1.0)
    assert [a.row for a in aside] == [7] and kept_fit is not None
    again = fit(bc, kept, default_model(bc), noise_um=1.0)
    assert np.array_equal(kept_fit.values, again.values, equal_nan=True)
    assert np.array_equal(kept_fit.std, again.std, equal_nan=True)


def test_the_advice_takes_the_first_marks_np_unique_would():
    """The pool's marks: the first distinct rows in x, y, z order, as ``np.unique(axis=0)`` gives them, on marks
    all distinct, few or more than 50 marks repeated, ties in x, and none."""
    from kinid.identification.planning.advice import _first_marks

    rng = np.random.default_rng(1)
    cases = [rng.normal(0, 50, (20_000, 3)), np.round(rng.normal(0, 50, (20_000, 3))),
             np.repeat(rng.normal(0, 5, (7, 3)), 300, axis=0), np.repeat(rng.normal(0, 5, (80, 3)), 200, axis=0),
             np.column_stack([np.zeros(5000), rng.integers(0, 9, (5000, 2))]).astype(float), np.zeros((0, 3))]
    for w in cases:
        assert np.array_equal(_first_marks(w, 50), np.unique(np.round(w, 6), axis=0)[:50])
