"""The held-out check's blocks are whole machine poses dealt so that no block is one mark, one value of an axis or
one stretch of time; the final words say where the model is interpolation between an axis's few positions, rotary
axes included; a residual above the σ given with no structure says that σ looks too small.

Truth by plain formulas: the patent plan (every mark at every angle, marks innermost), a lead of X written as
x + e(x) = x₀ (tests/test_period_search.py), noise drawn here.
"""
import sys
from pathlib import Path

import numpy as np
import pytest

from kinid.identification import forward_select, load_machine
from kinid.identification.diagnosis.diagnose import diagnose
from kinid.identification.diagnosis.selection import what_is_left
from kinid.identification.fitting.crossval import DEALS, held_out_blocks, machine_poses
from kinid.identification.fitting.simulate import patent_plan, simulate
from kinid.identification.model.effects import default_model, parse_effect
from kinid.urdf import path

sys.path.insert(0, str(Path(__file__).parent))
from test_period_search import _location_truth, _with_x_error  # noqa: E402

LAYOUTS = ("five_axis_bc", "five_axis_ac", "five_axis_bhead_c")


@pytest.fixture(scope="module")
def machines():
    return {name: load_machine(path(name)) for name in LAYOUTS}


@pytest.mark.parametrize("name", LAYOUTS)
@pytest.mark.parametrize("deal", sorted(DEALS))
def test_no_block_is_one_mark_one_value_of_an_axis_or_one_stretch_of_time(machines, name, deal):
    machine = machines[name]
    obs = patent_plan(machine)
    marks = np.array(obs.marks)
    blocks = held_out_blocks(machine, obs, 4, deal=deal)
    assert len(blocks) == 4 and np.array_equal(np.sort(np.concatenate(blocks)), np.arange(len(obs)))
    in_time = np.argsort(np.argsort(obs.t_s, kind="stable"), kind="stable")  # each row's rank in time
    angles = [k for k, a in enumerate(machine.axes) if a.kind != "prismatic"]
    for rows in blocks:
        assert len(set(marks[rows])) > 1
        for k in angles:
            assert np.unique(obs.axes[rows, k]).size > 1, machine.axes[k].name
        ranks = np.sort(in_time[rows])
        assert ranks[-1] - ranks[0] + 1 > rows.size  # not one contiguous stretch of time
    # whole poses: the four marks read at one set of angles are in one block
    pose = machine_poses(machine, obs)
    block = np.empty(len(obs), int)
    for b, rows in enumerate(blocks):
        block[rows] = b
    assert pose.max() + 1 == 84
    assert all(np.unique(block[pose == p]).size == 1 for p in range(84))


def test_the_blocks_are_the_same_for_the_same_data(machines):
    machine = machines["five_axis_bhead_c"]
    obs = patent_plan(machine)
    first, again = (held_out_blocks(machine, obs, 4) for _ in range(2))
    assert all(np.array_equal(a, b) for a, b in zip(first, again))


def test_jittered_readings_of_one_pose_stay_one_pose(machines):
    """Linear axes read a few µm from where the plan sent them: the rows of one set of angles are still one pose."""
    machine = machines["five_axis_bc"]
    obs = patent_plan(machine)
    rng = np.random.default_rng(0)
    axes = obs.axes.copy()
    for k, a in enumerate(machine.axes):
        if a.kind == "prismatic":
            axes[:, k] = rng.uniform(-100, 100, len(obs))
        else:
            axes[:, k] += rng.uniform(-1e-4, 1e-4, len(obs))
    from dataclasses import replace

    assert machine_poses(machine, replace(obs, axes=axes)).max() + 1 == 84
    # the same angles visited again later are another visit
    twice = replace(obs, axes=np.r_[axes, axes], w_mm=np.r_[obs.w_mm, obs.w_mm], t_s=np.r_[obs.t_s, obs.t_s + 1e5],
                    marks=obs.marks * 2, lines=tuple(range(2 * len(obs))))
    assert machine_poses(machine, twice).max() + 1 == 168


def _bhead_lead(machine, seed, noise_um=1.0):
    """The B-head + C table, the patent plan, constant errors drawn, a 12.7 mm lead of X of 2.5 µm by formula."""
    rng = np.random.default_rng(seed)
    effects, theta = _location_truth(machine, rng)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=noise_um, rng=rng)
    return _with_x_error(machine, obs, 2.5, 12.7, 0.5)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_b_head_lead_is_added(machines, seed):
    """Each block one mark (every 4th alignment), one mark alone pinned EA0Z and that block refused the lead."""
    machine = machines["five_axis_bhead_c"]
    obs = _bhead_lead(machine, seed)
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    added = [s.added for s in steps[1:]]
    assert any(a.startswith("EXX:periodic:") and abs(float(a.split(":")[2]) - 12.7) <= 0.127 for a in added), added


def test_a_rotary_axis_read_at_few_angles_is_interpolation_between_them(machines):
    """An error of A in the final model, A read at the patent plan's 7 angles: the final words say that between
    them the model is interpolation; an error of C (12 angles) and the default model alone: no such words."""
    machine = machines["five_axis_ac"]
    rng = np.random.default_rng(3)
    effects, theta = _location_truth(machine, rng)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=1.0, rng=rng)
    model = default_model(machine) + [parse_effect("EBA:poly2", machine)]
    words = what_is_left(forward_select(machine, obs, model, noise_um=1.0, max_steps=0))
    assert "EBA:poly2 varies with A, read at 7 angles: between the 7 angles of A the model is interpolation" in words
    assert "measure A at more angles" in words
    model = default_model(machine) + [parse_effect("EBC:poly2", machine)]
    assert "interpolation" not in what_is_left(forward_select(machine, obs, model, noise_um=1.0, max_steps=0))
    assert "interpolation" not in what_is_left(forward_select(machine, obs, default_model(machine), noise_um=1.0,
                                                             max_steps=0))


@pytest.mark.parametrize("seed", range(5))
def test_noise_three_times_the_sigma_given_is_named_a_sigma_too_small(machines, seed):
    """Nothing hidden, noise 3 µm, σ given 1 µm: the residual is white; the verdict says the σ given looks too small,
    with the σ the residual shows, not a missing effect most structured along an axis."""
    machine = machines["five_axis_bhead_c"]
    rng = np.random.default_rng(seed)
    effects, theta = _location_truth(machine, rng)
    obs = simulate(machine, patent_plan(machine), effects, theta, noise_um=3.0, rng=rng)
    steps = forward_select(machine, obs, default_model(machine), noise_um=1.0)
    final = steps[-1].diagnosis
    assert len(steps) == 1 and final.verdict == "noise"
    words = what_is_left(steps)
    assert "the σ given looks too small" in words and "most structured along" not in words
    apparent = float(words.split("the noise is about ")[1].split(" µm")[0])
    assert 2.7 <= apparent <= 3.3  # the σ the residual shows (3 µm drawn)


@pytest.mark.parametrize("seed", range(2))
def test_a_missing_effect_with_the_sigma_given_right_is_still_a_missing_effect(machines, seed):
    machine = machines["five_axis_bhead_c"]
    obs = _bhead_lead(machine, seed)
    dg = diagnose(machine, obs, default_model(machine), noise_um=1.0)
    assert dg.verdict == "missing-effect" and "σ given looks too small" not in dg.note
