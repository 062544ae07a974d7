"""The arm's gravity compliance (``EB0J2:gravity``): every joint whose axis stays horizontal turns by its own compliance
times the gravity torque it carries, one effect — against a plain-numpy arm.

The truth: a four-joint arm (J1 about the vertical, J2, J3 and J4 about horizontal axes, links of 0.6 m, 0.5 m and
0.2 m), no masses in its URDF, so a unit weight at the origin of every axis a joint carries and at the tool point:
J2 carries J3, J4 and T, J3 carries J4 and T, J4 carries T. Each turns by its compliance times that torque, written here
with numpy alone, sharing no code with kinid.
"""
from __future__ import annotations

import numpy as np
import pytest

from kinid.errors import DataError

ARM = """<robot name="gravity_arm">
  <link name="base"/><link name="l1"/><link name="l2"/><link name="l3"/><link name="l4"/><link name="tool"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><origin xyz="0 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="j3" type="revolute"><parent link="l2"/><child link="l3"/><origin xyz="0.6 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="j4" type="revolute"><parent link="l3"/><child link="l4"/><origin xyz="0.5 0 0"/>
    <axis xyz="0 1 0"/><limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="l4"/><child link="tool"/><origin xyz="0.2 0 0"/></joint>
</robot>
"""
#: Compliances of J2, J3, J4, µrad per unit weight × m (a UR10's upper arm shows about 1000, docs/identification.md).
COMPLIANCE_URAD_PER_M = (600.0, 900.0, 1500.0)
LINKS_M = (0.6, 0.5, 0.2)
NOISE_MM = 0.01


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0, s], [0, 1.0, 0], [-s, 0, c]])


def plain_torques_m(q_deg):
    """(N, 3) the torque about J2, J3, J4 of unit weights at the axes each carries and at the tool point, m."""
    q = np.radians(q_deg)
    a2, a3, a4 = q[:, 1], q[:, 1] + q[:, 2], q[:, 1] + q[:, 2] + q[:, 3]
    x3, x4, xt = LINKS_M[0] * np.cos(a2), LINKS_M[1] * np.cos(a3), LINKS_M[2] * np.cos(a4)  # links' horizontal reach
    return np.column_stack([x3 + (x3 + x4) + (x3 + x4 + xt), x4 + (x4 + xt), xt])


def plain_tool_mm(q_deg, gravity=True):
    """The tool point (mm), J2, J3 and J4 each turned by its compliance times the torque it carries (plain numpy)."""
    q = np.radians(np.asarray(q_deg, float)).copy()
    if gravity:
        q[:, 1:4] += plain_torques_m(q_deg) * np.array(COMPLIANCE_URAD_PER_M) * 1e-6
    out = []
    for a, b, c, d in q:
        p = np.array([0, 0, 0.4]) + _ry(b) @ [LINKS_M[0], 0, 0] + _ry(b + c) @ [LINKS_M[1], 0, 0] \
            + _ry(b + c + d) @ [LINKS_M[2], 0, 0]
        out.append(_rz(a) @ p)
    return np.array(out) * 1e3


@pytest.fixture(scope="module")
def arm(tmp_path_factory):
    from kinid.cli import main
    from kinid.identification.model import load_machine

    folder = tmp_path_factory.mktemp("gravity")
    (folder / "arm.urdf").write_text(ARM)
    assert main(["model", "--urdf", str(folder / "arm.urdf"), "--base", "base", "--tool", "tool",
                 "--out", str(folder / "machine.urdf")]) == 0
    return load_machine(folder / "machine.urdf")


def _observations(q_deg, rng):
    from kinid.identification.data import Observations

    w = plain_tool_mm(q_deg) + rng.normal(0.0, NOISE_MM, (len(q_deg), 3))
    return Observations(tuple(f"P{i}" for i in range(len(q_deg))), w, np.asarray(q_deg, float), None, {},
                        tuple(range(2, len(q_deg) + 2)), "simulated")


def _poses(rng, n):
    return np.column_stack([rng.uniform(-150, 150, n), rng.uniform(-170, 10, n), rng.uniform(-120, 120, n),
                            rng.uniform(-120, 120, n)])


def _held_out_um(machine, effects, theta, obs) -> float:
    from kinid.identification.fitting import design, residuals

    r = residuals(machine, design(machine, effects, obs), obs, theta, jacobian=False)
    return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))


def test_torques_are_the_chains_weight_about_each_horizontal_axis(arm):
    from kinid.identification.model import basis_values, parse_effect
    from kinid.identification.model.sag import loaded_axes

    assert loaded_axes(arm) == [("J2", "EB0J2"), ("J3", "EB0J3"), ("J4", "EB0J4")]  # J1 turns about the vertical
    q = _poses(np.random.default_rng(1), 20)
    effect = parse_effect("EB0J2:gravity", arm)
    assert effect.param_names() == ["EB0J2:gravity[J2]", "EB0J2:gravity[J3]", "EB0J2:gravity[J4]"]
    np.testing.assert_allclose(basis_values(effect, arm, q), plain_torques_m(q), atol=1e-12)
    # its size is judged at the largest torque: the arm stretched out level
    np.testing.assert_allclose(effect.args[2], plain_torques_m(np.zeros((1, 4)))[0], atol=1e-12)


def test_gravity_is_one_effect_on_the_first_loaded_joint(arm):
    from kinid.identification.model import candidate_library, parse_effect

    # added by name only: listed among --auto's candidates it changed nothing on the UR10 tracker series
    names = [e.name for e in candidate_library(arm, [], has_directions=False, has_time=False)]
    assert not [n for n in names if ":gravity" in n]
    with pytest.raises(DataError, match="write it on EB0J2, the rotation of J2, the first of them"):
        parse_effect("EB0J3:gravity", arm)


def test_compliances_are_recovered_and_predict_poses_not_seen(arm):
    """Fitted with the gravity compliance (``--add``), the compliances are the truth within 4 standard deviations and
    300 poses not seen are predicted within the noise; the geometric model alone is many times worse."""
    from kinid.identification.fitting import design, fit, model_effects
    from kinid.identification.model import default_model

    rng = np.random.default_rng(7)
    train, test = _observations(_poses(rng, 200), rng), _observations(_poses(rng, 300), rng)
    effects = model_effects(arm, ["EB0J2:gravity"])
    res = fit(arm, train, effects)
    assert res.success
    names = design(arm, effects, train).param_names()
    for axis, truth in zip(("J2", "J3", "J4"), COMPLIANCE_URAD_PER_M):
        k = names.index(f"EB0J2:gravity[{axis}]")
        assert abs(res.theta[k] - truth) < 4 * res.std[k], (axis, res.theta[k], res.std[k])
    held_um = _held_out_um(arm, effects, res.theta, test)
    assert held_um < 2 * NOISE_MM * 1e3 * np.sqrt(3), held_um  # 3-D RMS within twice the noise's
    plain = fit(arm, train, default_model(arm))
    assert _held_out_um(arm, default_model(arm), plain.theta, test) > 10 * held_um


def test_a_compliance_below_zero_is_refused(arm):
    """An arm droops: a fitted compliance below zero beyond twice its standard deviation is a size no arm has."""
    from kinid.identification.fitting import fit, model_effects
    from kinid.identification.model import implausible_effects

    rng = np.random.default_rng(5)
    q = _poses(rng, 200)
    obs = _observations(q, rng)
    lifted = plain_tool_mm(q, gravity=False) * 2 - plain_tool_mm(q)  # the arm rising under its weight
    from dataclasses import replace
    res = fit(arm, replace(obs, w_mm=lifted + rng.normal(0.0, NOISE_MM, lifted.shape)), model_effects(arm, ["EB0J2:gravity"]))
    odd = implausible_effects(res)
    assert [a.effect for a in odd] == ["EB0J2:gravity"]
    assert "of the sign no machine has" in odd[0].describe()
    assert implausible_effects(fit(arm, obs, model_effects(arm, ["EB0J2:gravity"]))) == ()


def test_the_urdf_masses_are_carried_by_kinid_model_and_weigh_at_their_centres(tmp_path):
    """A URDF with ``<inertial>``: ``kinid model`` keeps each link's mass and centre (a fixed joint's link too), and
    the torques are Σ m · lever of the masses beyond each joint (kg·m), against plain numpy."""
    from kinid.cli import main
    from kinid.identification.model import basis_values, load_machine, parse_effect

    masses = {"l2": (10.0, 0.3), "l3": (4.0, 0.25), "tool": (0.5, 0.0)}  # kg, centre along the link (m)
    text = ARM
    for link, (kg, x) in masses.items():
        text = text.replace(f'<link name="{link}"/>', f'<link name="{link}"><inertial><mass value="{kg}"/><origin '
                            f'xyz="{x} 0 0"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
                            f'</inertial></link>')
    (tmp_path / "arm.urdf").write_text(text)
    assert main(["model", "--urdf", str(tmp_path / "arm.urdf"), "--base", "base", "--tool", "tool",
                 "--out", str(tmp_path / "machine.urdf")]) == 0
    machine = load_machine(tmp_path / "machine.urdf")
    effect = parse_effect("EB0J2:gravity", machine)
    assert effect.param_units(machine) == ["µrad/(kg·m)"] * 3
    q = _poses(np.random.default_rng(2), 20)
    r = np.radians(q)
    a2, a3, a4 = r[:, 1], r[:, 1] + r[:, 2], r[:, 1] + r[:, 2] + r[:, 3]
    (m2, c2), (m3, c3), (mt, _) = masses.values()
    x_l2, x_l3, x_t = c2 * np.cos(a2), LINKS_M[0] * np.cos(a2) + c3 * np.cos(a3), \
        LINKS_M[0] * np.cos(a2) + LINKS_M[1] * np.cos(a3) + LINKS_M[2] * np.cos(a4)  # centres' reach from J2
    j3, j4 = LINKS_M[0] * np.cos(a2), LINKS_M[0] * np.cos(a2) + LINKS_M[1] * np.cos(a3)  # J3, J4's reach from J2
    truth = np.column_stack([m2 * x_l2 + m3 * x_l3 + mt * x_t, m3 * (x_l3 - j3) + mt * (x_t - j3), mt * (x_t - j4)])
    np.testing.assert_allclose(basis_values(effect, machine, q), truth, atol=1e-12)


@pytest.mark.parametrize("inertial, message", [
    ('<mass value="heavy"/>', "link 'l2' <inertial> mass is not a number: 'heavy'"),
    ('<mass value="-1"/>', "link 'l2' <inertial> mass must be a finite number ≥ 0 kg, got '-1'"),
    ('<mass value="1"/><inertia ixx="nan"/>', "link 'l2' <inertial> inertia ixx must be a finite number, got 'nan'"),
])
def test_a_bad_mass_is_one_line_naming_the_link(tmp_path, capsys, inertial, message):
    from kinid.cli import main

    (tmp_path / "arm.urdf").write_text(ARM.replace('<link name="l2"/>',
                                                   f'<link name="l2"><inertial>{inertial}</inertial></link>'))
    assert main(["model", "--urdf", str(tmp_path / "arm.urdf"), "--base", "base", "--tool", "tool",
                 "--out", str(tmp_path / "machine.urdf")]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "machine.urdf").exists()
