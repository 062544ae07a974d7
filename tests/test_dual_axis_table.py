"""Offset table and smooth model of two parallel Y axes: head_move definition, composition, update rule."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError, StageError
from kinid.stages.dual_axis.smooth import fit_smooth
from kinid.stages.dual_axis.table import OffsetTable


def _table(seed=0, n=12, step=10.0, y0=-20.0):
    rng = np.random.default_rng(seed)
    y = y0 + step * np.arange(n + 1)
    off = rng.normal(0.0, 0.01, (n + 1, 2))
    off[0] = 0.0
    return OffsetTable(y, off)


def test_head_move_definition():
    """dx = cx(Pe) - cx(Ps); dy = (Pe - Ps) + cy(Pe) - cy(Ps), with linear interpolation between vertices."""
    t = OffsetTable(np.array([0.0, 10.0, 20.0]), np.array([[0.0, 0.0], [0.004, -0.002], [0.010, 0.001]]))
    dx, dy = t.head_move(5.0, 20.0)
    assert dx == pytest.approx(0.010 - 0.002, abs=1e-12)
    assert dy == pytest.approx(15.0 + 0.001 - (-0.001), abs=1e-12)
    assert t.head_move(7.0, 7.0) == (0.0, 0.0)
    np.testing.assert_allclose(t.correction_mm(15.0), [0.007, -0.0005], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(st.floats(-20, 100), st.floats(-20, 100), st.floats(-20, 100), st.integers(0, 5))
def test_head_move_composes(a, b, c, seed):
    t = _table(seed)
    ab, bc, ac = np.array(t.head_move(a, b)), np.array(t.head_move(b, c)), np.array(t.head_move(a, c))
    np.testing.assert_allclose(ab + bc, ac, atol=1e-12)
    np.testing.assert_allclose(np.array(t.head_move(b, a)), -ab, atol=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.floats(-20, 100), st.floats(-20, 100), st.integers(0, 5))
def test_smooth_model_head_move_composes(a, b, seed):
    s = fit_smooth(_table(seed), 3)
    ab, ba = np.array(s.head_move(a, b)), np.array(s.head_move(b, a))
    np.testing.assert_allclose(ab + ba, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.array(s.head_move(a, 40.0)) + s.head_move(40.0, b), ab, atol=1e-12)


def test_with_offsets_adds_to_existing_entries():
    t = _table(1)
    add = np.random.default_rng(2).normal(0.0, 0.001, t.offset_mm.shape)
    t2 = t.with_offsets(add, rounds=2)
    np.testing.assert_array_equal(t2.offset_mm, t.offset_mm + add)
    assert t2.rounds == 2 and t.rounds == 0  # the original is unchanged (frozen)


def test_outside_calibrated_range_is_an_error():
    t = _table()
    with pytest.raises(StageError, match=r"camera Y 101.* outside the calibrated range \[-20, 100\] mm"):
        t.head_move(0.0, 101.0)
    with pytest.raises(StageError, match="outside the calibrated range"):
        t.correction_mm(np.nan)


def test_smooth_model_recovers_polynomial_exactly():
    y = np.linspace(0.0, 300.0, 31)
    u = y / 300.0
    cx = 0.012 * u - 0.004 * u ** 2 + 0.002 * u ** 3
    cy = -0.006 * u + 0.003 * u ** 3
    s = fit_smooth(OffsetTable(y, np.column_stack([cx, cy])), 3)
    np.testing.assert_allclose(s.coef_x_mm, [0.012, -0.004, 0.002], atol=1e-12)
    np.testing.assert_allclose(s.coef_y_mm, [-0.006, 0.0, 0.003], atol=1e-12)
    assert s.rms_um.max() < 1e-9
    # a pure straight line: the parallelism angle and scale are its slopes
    line = fit_smooth(OffsetTable(y, np.column_stack([40e-6 * y, -15e-6 * y])), 2)
    assert line.parallelism_urad == pytest.approx(40.0, abs=1e-9)
    assert line.scale_um_per_m == pytest.approx(-15.0, abs=1e-9)


def test_smooth_model_bad_degree():
    with pytest.raises(DataError, match="degree must be an integer >= 1, got 0"):
        fit_smooth(_table(), 0)
    with pytest.raises(DataError, match="needs at least 5 steps in the table, it has 2"):
        fit_smooth(_table(n=2), 5)


def test_to_dict_in_micrometres():
    t = OffsetTable(np.array([0.0, 10.0]), np.array([[0.0, 0.0], [0.004, -0.002]]), rounds=2, converged=True)
    d = t.to_dict()
    assert d["offset_x_um"] == pytest.approx([0.0, 4.0]) and d["offset_y_um"] == pytest.approx([0.0, -2.0])
    assert d["rounds"] == 2 and d["converged"] is True
