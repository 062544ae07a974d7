"""kinid.vision.motion_scale: pixel equivalent, reversal gaps, 2 x 2 pixel-to-machine matrix."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError
from kinid.vision.motion_scale import backlash_from_reversals, pixel_equivalent, pixel_to_machine_matrix


def _matrix(scale_x, scale_y, rotation_deg, skew_deg, mirrored):
    """mm-per-pixel matrix with known columns: image x at rotation, image y at +/-(90 - skew) from it."""
    a = np.radians(rotation_deg)
    b = a + np.radians(90.0 - skew_deg) * (-1.0 if mirrored else 1.0)
    return np.column_stack([scale_x * np.array([np.cos(a), np.sin(a)]),
                            scale_y * np.array([np.cos(b), np.sin(b)])])


def test_pixel_equivalent_exact_on_rotated_camera():
    m = _matrix(0.005, 0.005, 7.0, 0.0, True)
    moves = np.array([[1.0, 0.0], [0.0, 1.0], [-0.4, 0.0], [0.0, -0.7], [0.3, 0.3]])
    shifts = np.linalg.solve(m, moves.T).T
    res = pixel_equivalent(moves, shifts)
    assert res.mm_per_px == pytest.approx(0.005, rel=1e-12)
    assert res.mm_per_px_x == pytest.approx(0.005, rel=1e-12)
    assert res.mm_per_px_y == pytest.approx(0.005, rel=1e-12)
    assert res.axes == ("x", "y", "x", "y", "xy")
    assert (res.n_x, res.n_y) == (2, 2)
    assert res.sigma == pytest.approx(0.0, abs=1e-15)


def test_pixel_equivalent_per_axis_with_rectangular_pixels():
    # Camera square to the axes, 5 um along image x, 6 um along image y.
    m = np.diag([0.005, -0.006])
    moves = np.array([[1.0, 0.0], [0.0, 1.2]])
    res = pixel_equivalent(moves, np.linalg.solve(m, moves.T).T)
    assert res.mm_per_px_x == pytest.approx(0.005)
    assert res.mm_per_px_y == pytest.approx(0.006)
    assert res.mm_per_px == pytest.approx(0.0055)
    assert res.per_move == pytest.approx([0.005, 0.006])


def test_pixel_equivalent_from_lengths_and_axes():
    res = pixel_equivalent([1.0, -0.5], [[200.0, 0.0], [0.0, 100.0]], axes=["x", "y"])
    assert res.mm_per_px_x == pytest.approx(0.005)
    assert res.mm_per_px_y == pytest.approx(0.005)
    res = pixel_equivalent([1.0], [[0.0, 250.0]])
    assert res.mm_per_px == pytest.approx(0.004)
    assert np.isnan(res.mm_per_px_x) and res.n_x == 0


@pytest.mark.parametrize("moves, shifts, match", [
    ([[1.0, 0.0]], [[0.0, 0.0]], "did not move in the image"),
    ([[0.0, 0.0]], [[10.0, 0.0]], "move 0 has length 0.0 mm"),
    ([[1.0, 0.0], [0.0, 1.0]], [[10.0, 0.0]], "must have 2 rows"),
    ([[1.0, 0.0, 0.0]], [[10.0, 0.0]], r"moves_mm must have shape \(N, 2\)"),
    ([[np.nan, 0.0]], [[10.0, 0.0]], "non-finite"),
])
def test_pixel_equivalent_bad_input(moves, shifts, match):
    with pytest.raises(DataError, match=match):
        pixel_equivalent(moves, shifts)


def test_pixel_equivalent_bad_axes():
    with pytest.raises(DataError, match="axes must give 'x', 'y' or 'xy' for each of the 2 moves"):
        pixel_equivalent([1.0, 1.0], [[1.0, 0.0], [0.0, 1.0]], axes=["x"])


def test_backlash_scalar_matches_patent_formula():
    p1 = np.array([[100.0, 100.0], [300.0, 120.0]])
    gap_px = np.array([[0.6, 0.8], [0.0, 1.0]])          # lengths 1.0 px and 1.0 px
    res = backlash_from_reversals(p1, p1 + gap_px, 0.005)
    assert res.per_reversal_mm == pytest.approx([0.005, 0.005])
    assert res.backlash_mm == pytest.approx(0.005)
    assert res.spread_mm == pytest.approx(0.0, abs=1e-15)
    assert res.n == 2


def test_backlash_signed_component_along_axis():
    m = _matrix(0.005, 0.005, -20.0, 0.0, True)
    gaps_mm = np.array([[0.004, 0.0], [0.003, 0.0], [-0.001, 0.0]])   # X gaps, one negative
    p1 = np.zeros((3, 2))
    p2 = np.linalg.solve(m, gaps_mm.T).T
    res = backlash_from_reversals(p1, p2, m, axis_mm=(1.0, 0.0))
    assert res.per_reversal_mm == pytest.approx([0.004, 0.003, -0.001])
    assert res.backlash_mm == pytest.approx(0.002)
    assert res.spread_mm == pytest.approx(np.std([0.004, 0.003, -0.001], ddof=1))
    assert res.sigma_mm == pytest.approx(res.spread_mm / np.sqrt(3))
    # Norm form (patent): always positive.
    assert backlash_from_reversals(p1, p2, m).per_reversal_mm == pytest.approx([0.004, 0.003, 0.001])


@pytest.mark.parametrize("scale, kwargs, match", [
    (-0.005, {}, "mm_per_px must be a positive number"),
    (0.005, {"axis_mm": (1, 0)}, "axis_mm needs mm_per_px as a 2 x 2"),
    (np.eye(3), {}, r"scalar or a 2 x 2 matrix, got shape \(3, 3\)"),
    (np.eye(2), {"axis_mm": (0, 0)}, "axis_mm must be a non-zero 2-vector"),
])
def test_backlash_bad_input(scale, kwargs, match):
    with pytest.raises(DataError, match=match):
        backlash_from_reversals([[0.0, 0.0]], [[1.0, 0.0]], scale, **kwargs)


def test_matrix_exact_rotated_skewed_mirrored():
    m = _matrix(0.005, 0.0052, 7.0, 1.5, True)
    rng = np.random.default_rng(3)
    shifts = rng.uniform(-300, 300, (6, 2))
    res = pixel_to_machine_matrix(shifts, shifts @ m.T)
    assert res.matrix == pytest.approx(m, abs=1e-15)
    assert res.scale_x == pytest.approx(0.005)
    assert res.scale_y == pytest.approx(0.0052)
    assert res.rotation_deg == pytest.approx(7.0)
    assert res.skew_deg == pytest.approx(1.5)
    assert res.mirrored
    assert res.residual_rms_mm == pytest.approx(0.0, abs=1e-12)
    assert res.to_machine(shifts[0]) == pytest.approx(m @ shifts[0])


@settings(max_examples=40, deadline=None)
@given(sx=st.floats(0.001, 0.02), sy=st.floats(0.001, 0.02), rot=st.floats(-179.0, 179.0),
       skew=st.floats(-10.0, 10.0), mirrored=st.booleans())
def test_matrix_property_recovers_any_camera(sx, sy, rot, skew, mirrored):
    m = _matrix(sx, sy, rot, skew, mirrored)
    shifts = np.array([[200.0, 0.0], [0.0, 150.0], [-120.0, 80.0]])
    res = pixel_to_machine_matrix(shifts, shifts @ m.T)
    assert res.matrix == pytest.approx(m, rel=1e-9, abs=1e-13)
    assert res.scale_x == pytest.approx(sx, rel=1e-9)
    assert res.scale_y == pytest.approx(sy, rel=1e-9)
    assert res.skew_deg == pytest.approx(skew, abs=1e-7)
    assert res.mirrored == mirrored
    assert np.exp(1j * np.radians(res.rotation_deg)) == pytest.approx(np.exp(1j * np.radians(rot)), abs=1e-9)


def test_matrix_least_squares_with_noise_reports_residual():
    m = _matrix(0.005, 0.005, 30.0, 0.0, False)
    rng = np.random.default_rng(0)
    shifts = rng.uniform(-300, 300, (40, 2))
    moves = shifts @ m.T + rng.normal(0, 1e-4, (40, 2))
    res = pixel_to_machine_matrix(shifts, moves)
    assert res.matrix == pytest.approx(m, abs=2e-6)
    assert 0.5e-4 < res.residual_rms_mm < 2e-4


def test_matrix_needs_two_independent_shifts():
    with pytest.raises(DataError, match="at least 2 linearly independent image shifts, got 2 spanning rank 1"):
        pixel_to_machine_matrix([[1.0, 2.0], [2.0, 4.0]], [[1.0, 0.0], [2.0, 0.0]])
    with pytest.raises(DataError, match="got 1 spanning"):
        pixel_to_machine_matrix([[1.0, 2.0]], [[1.0, 0.0]])
