"""evaluate_blocks: the tool point and its derivatives of rows that share the turning joints' values, from one
evaluation per group and its slopes along the sliding joints, against evaluate pose by pose."""
import importlib

import numpy as np
import pytest

from kinid.identification.model.machine import evaluate, evaluate_blocks, load_machine
from kinid.urdf import path

placements = importlib.import_module("kinid.identification.model.placements")


def _rows(m, n, rng, *, turning_values=4):
    """Axis readings (n, n_axes): the turning axes at a few values each, the sliding ones anywhere in ±300 mm; error
    values (n, n_errors): constant, but for three sliding ones different in every row (a positioning error)."""
    axes = np.empty((n, len(m.axes)))
    for j, a in enumerate(m.axes):
        axes[:, j] = (rng.uniform(-300, 300, n) if a.kind == "prismatic"
                      else rng.choice(np.linspace(-90, 90, turning_values), n))
    errors = np.tile(rng.normal(0, 30, len(m.error_joints)), (n, 1))
    sliding = [k for k, e in enumerate(m.error_joints) if e.kind == "prismatic"][:3]
    errors[:, sliding] += rng.normal(0, 5, (n, len(sliding)))
    return axes, errors


def _joined(blocks, n):
    got = list(blocks)
    assert [(lo, hi) for lo, hi, _ in got] == [(lo, min(lo + 64, n)) for lo in range(0, n, 64)]
    outs = [out if isinstance(out, tuple) else (out,) for _, _, out in got]
    return [None if outs[0][k] is None else np.concatenate([o[k] for o in outs]) for k in range(len(outs[0]))]


@pytest.mark.parametrize("name", ["five_axis_bc", "five_axis_bhead_c"])
@pytest.mark.parametrize("kw", [dict(jacobian=False), dict(), dict(error_columns=[0, 4, 7], axes_jacobian=False)])
def test_grouped_rows_give_evaluate_to_rounding(name, kw):
    m, rng = load_machine(path(name)), np.random.default_rng(3)
    axes, errors = _rows(m, 1000, rng)
    plan = placements._affine_plan(m, axes, errors, None)
    assert plan is not None and len(np.unique(plan["group"])) <= 16  # the affine route was taken
    ref = evaluate(m, axes, errors, **kw)
    ref = ref if isinstance(ref, tuple) else (ref,)
    for r, g in zip(ref, _joined(evaluate_blocks(m, axes, errors, block=64, **kw), len(axes))):
        assert (r is None) == (g is None)
        if r is not None:  # mm, or µm per unit: rounding of numbers of a metre's size
            np.testing.assert_allclose(g, r, rtol=0, atol=1e-9 * max(1.0, np.abs(r).max()))


def test_a_constant_offset_is_grouped_and_offsets_of_their_own_go_pose_by_pose():
    m, rng = load_machine(path("five_axis_bc")), np.random.default_rng(4)
    axes, errors = _rows(m, 600, rng)
    assert placements._affine_plan(m, axes, errors, np.array([1.0, -2.0, 30.0])) is not None
    own = rng.normal(0, 10, (len(axes), 3))
    assert placements._affine_plan(m, axes, errors, own) is None
    for off in (np.array([1.0, -2.0, 30.0]), own):
        p, d_err, d_ax = evaluate(m, axes, errors, offsets_mm=off)
        got = _joined(evaluate_blocks(m, axes, errors, block=64, offsets_mm=off), len(axes))
        for r, g in zip((p, d_err, d_ax), got):
            np.testing.assert_allclose(g, r, rtol=0, atol=1e-9 * np.abs(r).max())


def test_rows_that_share_no_turning_value_go_pose_by_pose_unchanged():
    m, rng = load_machine(path("five_axis_bc")), np.random.default_rng(5)
    axes, errors = _rows(m, 300, rng)
    turning = [j for j, a in enumerate(m.axes) if a.kind != "prismatic"]
    axes[:, turning] = rng.uniform(-90, 90, (len(axes), len(turning)))  # every row its own group
    assert placements._affine_plan(m, axes, errors, None) is None
    for lo, hi, out in evaluate_blocks(m, axes, errors, block=64):  # each block through evaluate, as before
        for r, g in zip(evaluate(m, axes[lo:hi], errors[lo:hi]), out):
            assert np.array_equal(g, r)


def test_the_grouping_kept_for_the_same_rows_gives_what_a_fresh_one_gives():
    """The passes of a fit keep the rows' grouping (``groups``) and ask again at other error values: each call the
    same numbers as without the store; error values that vary by row are grouped afresh, never kept."""
    m, rng = load_machine(path("five_axis_bc")), np.random.default_rng(6)
    axes, varying = _rows(m, 700, rng)
    store = {}
    for _ in range(2):  # a second parameter vector: other error values, the grouping taken from the store
        errors = np.broadcast_to(rng.normal(0, 30, len(m.error_joints)), varying.shape)
        fresh = _joined(evaluate_blocks(m, axes, errors, block=64), len(axes))
        kept = _joined(evaluate_blocks(m, axes, errors, block=64, groups=store), len(axes))
        assert len(store) == 1
        for a, b in zip(fresh, kept):
            assert np.array_equal(a, b)
    own = {}
    fresh = _joined(evaluate_blocks(m, axes, varying, block=64), len(axes))
    for a, b in zip(fresh, _joined(evaluate_blocks(m, axes, varying, block=64, groups=own), len(axes))):
        assert np.array_equal(a, b)
    assert own == {}
