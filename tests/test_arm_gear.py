"""An arm-like chain whose URDF has location errors only (no position-dependent joints), with a gear error of J2.

The gear error (a period of 40° in J2, not in the library) is put into the
readings by a plain formula: the joint stands at r + e(r) when its reading is
r. The location joint EB0J2 turns about the same line as J2, so its value
varying with J2 is that gear error, and the diagnosis must find it there.
"""
from dataclasses import replace

import numpy as np
import pytest

from kinid.errors import DataError
from kinid.identification import default_model, diagnose, fit, forward_select, parse_effect, solve_axes
from kinid.identification.model.effects import axis_dependent_joints
from kinid.identification.model.machine import machine_from_urdf
from kinid.identification.data.observations import Observations
from kinid.identification.fitting.simulate import errors_from_mapping
from kinid.identification.model.urdf_builder import Axis, Fixed, machine_urdf, setup

PI = np.pi
L1, L2, H, X0 = 350.0, 300.0, 300.0, 450.0  # mm: upper arm, forearm, shoulder height, board distance
P_DEG, A_URAD, NOISE_UM = 40.0, 80.0, 5.0


@pytest.fixture(scope="module")
def arm():
    work = [Fixed("table", (X0 / 1e3, 0.0, 0.0)), setup("W")]
    tool = [Axis("J1", "revolute", (0, 0, 1), location_errors=("X", "Y", "A", "B"), pdge=False, limit=(-PI, PI)),
            Fixed("shoulder", (0, 0, H / 1e3)),
            Axis("J2", "revolute", (0, 1, 0), location_errors=("X", "Z", "A", "B", "C"), pdge=False, limit=(-PI, PI)),
            Fixed("upper_arm", (L1 / 1e3, 0, 0)),
            Axis("J3", "revolute", (0, 1, 0), location_errors=("X", "Z", "A", "B", "C"), pdge=False, limit=(-PI, PI)),
            Fixed("forearm", (L2 / 1e3, 0, 0)), setup("T")]
    return machine_from_urdf(machine_urdf("arm3", work, tool, "three-joint arm for tests"), "arm3.urdf")


def _ik_deg(w):
    """Elbow-up inverse kinematics of the nominal arm (hand-derived), degrees: the starting guesses."""
    x, y, z = w[:, 0] + X0, w[:, 1], w[:, 2]
    j1 = np.arctan2(y, x)
    r, h = np.hypot(x, y), -(z - H)
    b = -np.arccos(np.clip((r**2 + h**2 - L1**2 - L2**2) / (2 * L1 * L2), -1, 1))
    a = np.arctan2(h, r) - np.arctan2(L2 * np.sin(b), L1 + L2 * np.cos(b))
    return np.degrees(np.c_[j1, a, b])


def _plan(n, rng):
    w = np.c_[rng.uniform(-250, 150, 4 * n), rng.uniform(-250, 250, 4 * n), rng.uniform(-300, 150, 4 * n)]
    reach = np.sqrt((w[:, 0] + X0) ** 2 + w[:, 1] ** 2 + (w[:, 2] - H) ** 2)
    w = w[(reach > 250) & (reach < 600)][:n]
    return Observations(tuple(f"P{i}" for i in range(len(w))), w, _ik_deg(w), None, {}, tuple(range(2, len(w) + 2)),
                        "<arm plan>")


def _data(arm, plan, effects, theta, noise_um, rng):
    nominal = solve_axes(arm, effects, theta, plan, ("J1", "J2", "J3"))
    actual = nominal.axes[:, 1]
    reading = actual.copy()
    for _ in range(30):  # reading r with r + e(r) = actual
        reading = actual - np.degrees(A_URAD * 1e-6 * np.sin(2 * np.pi * reading / P_DEG + 0.5))
    axes = nominal.axes.copy()
    axes[:, 1] = reading
    axes += np.degrees(rng.normal(0, noise_um * 1e-3 / (L1 + L2), axes.shape))
    return replace(nominal, axes=axes)


def _held_out_um(arm, result, truth):
    poses = replace(truth, axes=_ik_deg(truth.w_mm))
    pred = solve_axes(arm, result.effects, result.theta, poses, ("J1", "J2", "J3"))
    d = np.radians(pred.axes - truth.axes) * (L1 + L2) * 1e3  # joint-angle error as µm at the tool
    return float(np.sqrt(np.mean(np.sum(d**2, axis=1))))


def test_location_joints_on_the_axis_line_can_vary_with_it(arm):
    assert sorted(c for c, _ in axis_dependent_joints(arm)) == ["EB0J2", "EB0J3"]


def test_gear_error_of_an_arm_joint_is_found_on_its_location_joint(arm):
    rng = np.random.default_rng(71)
    truth = {e.code: float(rng.normal(0, 20.0)) for e in default_model(arm)}
    effects, theta = errors_from_mapping(truth, arm)
    obs = _data(arm, _plan(300, rng), effects, theta, NOISE_UM, rng)
    held = _data(arm, _plan(80, rng), effects, theta, 0.0, rng)

    before = diagnose(arm, obs, default_model(arm))
    assert before.verdict == "missing-effect"
    best = before.live[0]
    assert best.effect.startswith("EB0J2:periodic:"), [c.effect for c in before.live[:4]]
    std = float(best.note.split("±")[1].split()[0])
    assert abs(float(best.effect.split(":")[2]) - P_DEG) <= 3 * std

    steps = forward_select(arm, obs, default_model(arm))
    assert steps[-1].diagnosis.verdict == "noise", steps[-1].stopped
    true_fit = fit(arm, obs, default_model(arm) + [parse_effect(f"EB0J2:periodic:{P_DEG}", arm)])
    auto, truth_um, base = (_held_out_um(arm, r, held) for r in (steps[-1].fit, true_fit, steps[0].fit))
    assert auto <= 1.5 * truth_um, (auto, truth_um)
    assert base > 3 * auto, (base, auto)


def test_an_axis_without_varying_joints_is_named_with_the_joints_to_add(arm):
    from kinid.identification.diagnosis.diagnose import joints_the_urdf_lacks

    assert joints_the_urdf_lacks(arm) == [("J1", ["EXJ1", "EYJ1", "EZJ1", "EAJ1", "EBJ1", "ECJ1"])]


def test_alignment_that_does_not_converge_names_the_row_and_the_remedy(arm):
    rng = np.random.default_rng(5)
    plan = _plan(5, rng)
    far = replace(plan, axes=np.where(np.arange(5)[:, None] == 3, np.nan, plan.axes))  # row 4: no starting guess
    far = replace(far, axes=np.nan_to_num(far.axes, nan=170.0))
    with pytest.raises(DataError, match=r"<arm plan>:5: no readings of J1, J2, J3 align the tool point with mark "
                                        r"'P3'.*starting guess"):
        solve_axes(arm, [], np.zeros(0), far, ("J1", "J2", "J3"), max_iter=8)
