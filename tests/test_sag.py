"""The sag basis (``EB0J2:sag:J3``): a joint that gives under the weight it carries, against a plain-numpy arm.

The truth: a three-joint arm (J1 about the vertical, J2 and J3 about horizontal axes, links of 0.6 m and 0.5 m) whose
J2 turns by c2 × (0.6 m · cos q2) and J3 by c3 × (0.5 m · cos(q2 + q3)) — the torque of a weight at J3 about J2 and
of a weight at the tool point about J3 — written here with numpy alone, sharing no code with kinid.
"""
from __future__ import annotations

import numpy as np
import pytest

from kinid.errors import DataError

ARM = """<robot name="sag_arm">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.6 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="l3"/><child link="tool"/><origin xyz="0.5 0 0"/></joint>
</robot>
"""
C2_URAD_PER_M, C3_URAD_PER_M = 900.0, 1500.0  # a UR10's upper arm shows about 1000 µrad per m of a unit weight's lever


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def plain_tool_mm(q_deg, sag=True):
    """The tool point (mm) of the arm, its J2 and J3 turned by the weights' torques (plain numpy)."""
    q1, q2, q3 = np.radians(q_deg).T
    if sag:
        q2, q3 = (q2 + C2_URAD_PER_M * 1e-6 * 0.6 * np.cos(q2),
                  q3 + C3_URAD_PER_M * 1e-6 * 0.5 * np.cos(q2 + q3))
    return np.array([_rz(a) @ (np.array([0, 0, 0.4]) + _ry(b) @ np.array([0.6, 0, 0]) + _ry(b + c) @ [0.5, 0, 0])
                     for a, b, c in zip(q1, q2, q3)]) * 1e3


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    from kinid.cli import main
    from kinid.identification.model import load_machine

    folder = tmp_path_factory.mktemp("sag")
    (folder / "arm.urdf").write_text(ARM)
    assert main(["model", "--urdf", str(folder / "arm.urdf"), "--base", "base", "--tool", "tool",
                 "--out", str(folder / "machine.urdf")]) == 0
    return load_machine(folder / "machine.urdf")


def _observations(machine, q_deg, rng, noise_mm=0.01):
    from kinid.identification.data import Observations

    w = plain_tool_mm(q_deg) + rng.normal(0.0, noise_mm, (len(q_deg), 3))
    return Observations(tuple(f"P{i}" for i in range(len(q_deg))), w, np.asarray(q_deg, float), None, {},
                        tuple(range(2, len(q_deg) + 2)), "simulated")


def _poses(rng, n, q2_deg):
    return np.column_stack([rng.uniform(-150, 150, n), rng.uniform(*q2_deg, n), rng.uniform(-120, 120, n)])


def test_lever_is_the_weights_torque_about_the_axis(arm):
    from kinid.identification.model.sag import levers_m

    q = _poses(np.random.default_rng(1), 20, (-170, 10))
    q2, q3 = np.radians(q[:, 1]), np.radians(q[:, 2])
    np.testing.assert_allclose(levers_m(arm, q, "J2", "J3"), 0.6 * np.cos(q2), atol=1e-12)
    np.testing.assert_allclose(levers_m(arm, q, "J3", "T"), 0.5 * np.cos(q2 + q3), atol=1e-12)
    np.testing.assert_allclose(levers_m(arm, q, "J2", "T"), 0.6 * np.cos(q2) + 0.5 * np.cos(q2 + q3), atol=1e-12)


def test_sag_is_recovered_and_predicts_poses_of_another_range(arm):
    """Trained on the upper arm below the horizontal, held out above it: the geometric model alone cannot carry
    the sag there, the sag basis can."""
    from kinid.identification.fitting import fit, model_effects, residuals, design

    rng = np.random.default_rng(7)
    train = _observations(arm, _poses(rng, 150, (-60, 20)), rng)
    test = _observations(arm, _poses(rng, 150, (-170, -100)), rng)
    held = {}
    for add in ((), ("EB0J2:sag:J3", "EB0J3:sag:T")):
        effects = model_effects(arm, add)
        res = fit(arm, train, effects)
        assert res.success
        r = residuals(arm, design(arm, effects, test), test, res.theta, jacobian=False)
        held[add] = float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))
        if add:
            names = design(arm, effects, train).param_names()
            for name, truth in zip(add, (C2_URAD_PER_M, C3_URAD_PER_M)):
                k = names.index(name)
                assert abs(res.theta[k] - truth) < max(5 * res.std[k], 0.02 * truth), (name, res.theta[k], res.std[k])
    assert held[("EB0J2:sag:J3", "EB0J3:sag:T")] < 2 * 10.0 * np.sqrt(3)  # µm: within the noise (10 µm a coordinate)
    assert held[()] > 5 * held[("EB0J2:sag:J3", "EB0J3:sag:T")], held


def test_sag_names_what_the_axis_carries(arm):
    from kinid.identification.model import parse_effect

    with pytest.raises(DataError, match="'J2' is not carried by J3; the weight may hang at T"):
        parse_effect("EB0J3:sag:J2", arm)
    with pytest.raises(DataError, match="not a rotation of a rotary axis"):
        parse_effect("EX0J2:sag:T", arm)


def test_sag_candidates_for_the_carried_rotary_axes(arm):
    from kinid.identification.model import candidate_library

    names = {e.name for e in candidate_library(arm, [], has_directions=False, has_time=False)}
    assert {"EB0J2:sag:J3", "EB0J2:sag:T", "EB0J3:sag:T", "EA0J3:sag:T"} <= names
    assert not any(n.startswith(("EX0J2:sag", "EC0J1:sag")) for n in names)


def test_compensation_leaves_the_sag_out_saying_why(arm):
    from kinid.identification.compensation.compensate import compensation_model
    from kinid.identification.fitting import fit, model_effects

    rng = np.random.default_rng(3)
    result = fit(arm, _observations(arm, _poses(rng, 100, (-170, 10)), rng), model_effects(arm, ["EB0J2:sag:J3"]))
    left = dict(compensation_model(result).left_out)
    assert "no axis table holds it" in left["EB0J2:sag:J3"]


def test_a_table_axis_carries_no_tool_point():
    """On an A/C table the C axis carries the workpiece: no weight at the tool point (T) for its sag."""
    from pathlib import Path

    from kinid.identification.model import candidate_library, load_machine, parse_effect

    machine = load_machine(Path(__file__).resolve().parents[1] / "urdf" / "five_axis_ac.urdf")
    names = [e.name for e in candidate_library(machine, [], has_directions=False, has_time=False)]
    assert not any(":sag:T" in n for n in names)
    with pytest.raises(DataError, match="'T' is not carried by C; it carries no axis nor the tool point"):
        parse_effect("EA0C:sag:T", machine)
