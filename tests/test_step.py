"""The step basis (``EZZ:step:Y:40``) and its searched position, against an XYZ stage in plain numpy.

The truth: a stage whose tool point is at (x, y, z − 100 mm) at readings x, y, z, and whose Z jumps by 6 µm where Y
passes 37.3 mm — ``z + 0.006 · (y > 37.3)``, written here with numpy alone, sharing no code with kinid. Y is read
every 30 mm, so the data place the step only between the readings 30 and 60 mm.
"""
from __future__ import annotations

import numpy as np
import pytest

from kinid.errors import DataError

STAGE = """<robot name="xyz">
  <link name="base"/><link name="lx"/><link name="ly"/><link name="lz"/><link name="tool"/>
  <joint name="x" type="prismatic"><parent link="base"/><child link="lx"/><axis xyz="1 0 0"/>
    <limit lower="-0.2" upper="0.2" effort="1" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="lx"/><child link="ly"/><axis xyz="0 1 0"/>
    <limit lower="-0.2" upper="0.2" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="ly"/><child link="lz"/><axis xyz="0 0 1"/>
    <limit lower="-0.1" upper="0.1" effort="1" velocity="1"/></joint>
  <joint name="flange" type="fixed"><parent link="lz"/><child link="tool"/><origin xyz="0 0 -0.1"/></joint>
</robot>
"""
STEP_AT_MM, STEP_UM = 37.3, 6.0
Y_READINGS_MM = np.linspace(-150, 150, 11)  # every 30 mm: the step lies between the readings 30 and 60


@pytest.fixture(scope="module")
def stage(tmp_path_factory):
    from kinid.cli import main
    from kinid.identification.model import load_machine

    folder = tmp_path_factory.mktemp("step")
    (folder / "xyz.urdf").write_text(STAGE)
    assert main(["model", "--urdf", str(folder / "xyz.urdf"), "--base", "base", "--tool", "tool",
                 "--out", str(folder / "machine.urdf")]) == 0
    return load_machine(folder / "machine.urdf")  # axes J1 (x), J2 (y), J3 (z)


def _observations(seed: int, step_um: float):
    """The plan's tool points (plain numpy truth) with 1 µm noise, as observations."""
    from kinid.identification.data import Observations

    rng = np.random.default_rng(seed)
    x, y, z = np.meshgrid(np.linspace(-120, 120, 5), Y_READINGS_MM, np.linspace(-50, 50, 3), indexing="ij")
    q = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    tool = np.column_stack([q[:, 0], q[:, 1], q[:, 2] - 100.0 + step_um * 1e-3 * (q[:, 1] > STEP_AT_MM)])
    w = tool + rng.normal(0.0, 1e-3, tool.shape)
    return Observations(tuple("P" for _ in q), w, q, None, {}, tuple(range(2, len(q) + 2)), "simulated")


def test_the_basis_jumps_at_its_position_and_is_zero_at_the_axis_zero(stage):
    from kinid.identification.model import basis_values, parse_effect

    q = np.array([-100.0, -10.0, 0.0, 45.0, 100.0])
    axes = np.zeros((q.size, 3))
    axes[:, 1] = q
    up, down = parse_effect("EZ0J3:step:J2:40", stage), parse_effect("EZ0J3:step:J2:-20", stage)
    assert up.axis == "J2" and up.n_params == 1
    np.testing.assert_array_equal(basis_values(up, stage, axes).ravel(), [0, 0, 0, 1, 1])
    np.testing.assert_array_equal(basis_values(down, stage, axes).ravel(), [-1, 0, 0, 0, 0])
    assert parse_effect("EZ0T:step:J2:40", stage).axis == "J2"  # a set-up joint may jump where an axis passes


@pytest.mark.parametrize("name, message", [
    ("EZ0J3:step:Q:40", "'Q' is not an axis of this machine"),
    ("EZ0J3:step:T:40", "'T' is not an axis of this machine"),
    ("EZ0J3:step:J2:1e999", "must be a finite number"),
    ("EZ0J3:step:40", "unknown basis"),
])
def test_a_bad_step_is_named(stage, name, message):
    from kinid.identification.model import parse_effect

    with pytest.raises(DataError, match=message):
        parse_effect(name, stage)


def test_auto_finds_the_step_and_places_it_between_the_readings(stage):
    """``--auto`` adds a step of Z's translation at J2 (y) named inside the interval (30, 60) the readings leave,
    sized to the truth, says that interval in its last words, and the model predicts poses it did not see."""
    from kinid.identification.fitting import design, residuals
    from kinid.identification.model import default_model, parse_effect
    from kinid.identification.diagnosis import forward_select, what_is_left

    steps = forward_select(stage, _observations(1, STEP_UM), default_model(stage), noise_um=1.0)
    added = [s.added for s in steps[1:]]
    assert len(added) == 1, added
    effect = parse_effect(added[0], stage)
    assert effect.basis == "step" and effect.code[:2] == "EZ" and effect.axis == "J2", added
    assert 30.0 < effect.args[0] < 60.0
    k = list(steps[-1].fit.param_names).index(added[0])
    value, std = steps[-1].fit.values[k], steps[-1].fit.std[k]
    assert abs(abs(value) - STEP_UM) < 4 * std, (value, std)
    assert "between the readings J2 = 30 and 60 mm" in what_is_left(steps)
    fresh = _observations(2, STEP_UM)  # new noise at the same poses
    r = residuals(stage, design(stage, steps[-1].fit.effects, fresh), fresh, steps[-1].fit.theta, jacobian=False)
    r0 = residuals(stage, design(stage, steps[0].fit.effects, fresh), fresh, steps[0].fit.theta, jacobian=False)
    assert np.sqrt(np.mean(r**2)) < 1.15 and np.sqrt(np.mean(r0**2)) > 1.2  # µm a coordinate; the noise is 1


@pytest.mark.parametrize("seed", [3, 4, 5])
def test_no_step_on_noise(stage, seed):
    from kinid.identification.model import default_model
    from kinid.identification.diagnosis import forward_select

    steps = forward_select(stage, _observations(seed, 0.0), default_model(stage), noise_um=1.0)
    assert not [s.added for s in steps[1:]]


def test_compensation_tables_a_step_of_its_own_axis_and_leaves_out_another(stage):
    from kinid.identification.compensation.compensate import axis_error_columns, compensation_model
    from kinid.identification.fitting import fit, model_effects

    obs = _observations(6, STEP_UM)
    own = fit(stage, obs, model_effects(stage, ["EZ0J2:step:J2:40"]), noise_um=1.0)
    columns = axis_error_columns(compensation_model(own).result, "J2", np.array([0.0, 30.0, 60.0]))
    np.testing.assert_allclose(np.diff(columns["EZ0J2_um"]), [0.0, own.values[own.param_names.index(
        "EZ0J2:step:J2:40")]])
    other = fit(stage, obs, model_effects(stage, ["EZ0J3:step:J2:40"]), noise_um=1.0)
    left = dict(compensation_model(other).left_out)
    assert "varies with J2: a cross compensation" in left["EZ0J3:step:J2:40"]
    assert "EZ0J3_um" not in axis_error_columns(compensation_model(other).result, "J2", np.array([0.0, 60.0]))


def test_the_figure_draws_a_step_at_another_axis_over_that_axis(stage, tmp_path):
    from kinid.identification.fitting import fit, model_effects
    from kinid.identification.reporting import figures

    result = fit(stage, _observations(7, STEP_UM), model_effects(stage, ["EZ0J3:poly2", "EZ0J3:step:J2:40"]),
                 noise_um=1.0)
    assert set(figures._varying_joints(result)) == {("EZ0J3", "J3"), ("EZ0J3", "J2")}
    assert figures.plot_identified_errors(result, _observations(7, STEP_UM), tmp_path / "errors.png")
    assert (tmp_path / "errors.png").stat().st_size > 0
