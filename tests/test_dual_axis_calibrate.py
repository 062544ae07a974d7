"""the dual-axis method calibration of two parallel Y axes on the simulated gantry (urdf/gantry_dual_y.urdf)."""
import numpy as np
import pytest

from kinid.errors import DataError, ImageError, StageError
from kinid.stages.dual_axis import SimulatedGantry, calibrate, fit_smooth, verify
from kinid.stages.dual_axis.simulate import ErrorProfile, random_error_profiles
from kinid.stages.dual_axis.calibrate import measure_pixel_to_mm

HEAD0 = (0.0, 0.0)


def _truth_residual_um(g, comp, positions, y0=0.0, head0=HEAD0):
    out = []
    for p in positions:
        dx, dy = comp.head_move(y0, p)
        out.append(g.plate_offset_um(y0, head0, p, (head0[0] + dx, head0[1] + dy)))
    return np.array(out)


class _Nominal:
    """No compensation: the head follows the camera's Y move only."""

    def head_move(self, ps_mm, pe_mm):
        return 0.0, pe_mm - ps_mm


@pytest.fixture(scope="module")
def calibrated():
    g = SimulatedGantry(rng=np.random.default_rng(7))
    p2m = measure_pixel_to_mm(g, 0.0, HEAD0).matrix
    table = calibrate(g, 0.0, HEAD0, 10.0, 30, p2m, 1.0)
    return g, p2m, table


def test_pixel_to_mm_measured_by_head_moves(calibrated):
    g, p2m, _ = calibrated
    np.testing.assert_allclose(p2m, g.true_pixel_to_mm, atol=0.003 * g.pixel_mm)


def test_converges_within_three_rounds(calibrated):
    _, _, table = calibrated
    assert table.converged and table.rounds <= 3
    assert table.history[0].max_change_um > 10.0  # the first round sees the full drift (~16 µm)
    assert table.history[-1].max_change_um <= 1.0
    assert "converged in" in table.message


def test_table_vertices_match_the_true_correction(calibrated):
    g, _, table = calibrated
    true = np.array([g.true_correction_mm(0.0, HEAD0, y) for y in table.y_mm])
    np.testing.assert_allclose(table.offset_mm, true, atol=0.5e-3)  # 0.5 µm


def test_held_out_positions_within_2um_truth_and_camera(calibrated):
    g, p2m, table = calibrated
    held = table.y_mm[:-1] + 5.0
    before = _truth_residual_um(g, _Nominal(), held)
    assert np.abs(before).max() > 10.0  # without compensation the plate is far off
    # the camera measures the same displacement (sign and size) as the kinematic truth
    np.testing.assert_allclose(verify(g, _Nominal(), 0.0, HEAD0, held, p2m), before, atol=0.3)
    truth = _truth_residual_um(g, table, held)
    assert np.hypot(*truth.T).max() < 2.0
    measured = verify(g, table, 0.0, HEAD0, held, p2m)
    assert np.hypot(*measured.T).max() < 2.0
    np.testing.assert_allclose(measured, truth, atol=0.5)  # the camera sees what the truth says


def test_table_beats_smooth_model_on_wavy_axes(calibrated):
    g, _, table = calibrated
    held = table.y_mm[:-1] + 5.0
    smooth = fit_smooth(table, 3)
    t = np.hypot(*_truth_residual_um(g, table, held).T).max()
    s = np.hypot(*_truth_residual_um(g, smooth, held).T).max()
    assert t < s  # the default axes have a waviness that a cubic cannot follow


@pytest.mark.parametrize("seed", [3, 11])
def test_random_gantries_converge_and_hold_2um(seed):
    rng = np.random.default_rng(seed)
    g = SimulatedGantry(random_error_profiles(rng), repeat_um=0.1, rng=rng)
    y0, head0 = 20.0, (0.0, 20.0)
    p2m = measure_pixel_to_mm(g, y0, head0).matrix
    table = calibrate(g, y0, head0, 12.5, 24, p2m, 1.0)
    assert table.converged and table.rounds <= 3
    held = table.y_mm[:-1] + 6.25
    truth = _truth_residual_um(g, table, held, y0, head0)
    assert np.hypot(*truth.T).max() < 2.0


def test_perfect_axes_give_a_zero_table_in_one_round():
    g = SimulatedGantry((), noise_sigma=1.0, rng=np.random.default_rng(9))
    table = calibrate(g, 0.0, HEAD0, 25.0, 4, g.true_pixel_to_mm, 0.5)
    assert table.rounds == 1 and table.converged
    assert np.abs(table.offset_mm).max() < 0.05e-3  # 0.05 µm: image noise only
    np.testing.assert_allclose(table.head_move(0.0, 100.0), (0.0, 100.0), atol=0.05e-3)


def test_parallelism_only_gantry_gives_its_angle_and_a_straight_table():
    g = SimulatedGantry((ErrorProfile("EC0V", constant=40.0),), noise_sigma=0.5, rng=np.random.default_rng(1))
    table = calibrate(g, 0.0, HEAD0, 20.0, 10, g.true_pixel_to_mm, 0.5)
    s = fit_smooth(table, 1)
    assert s.parallelism_urad == pytest.approx(40.0, abs=0.5)
    # the V axis turned by 40 µrad about the V rail origin, the head 0.30 m from it: Y shortening is 2nd order
    assert abs(s.scale_um_per_m) < 1.0


def test_measured_offsets_add_to_existing_entries():
    """With pixel_to_mm at half its true value each round measures half of what is left: the table after
    round r is (1 - 0.5**r) x the true correction, which only holds if every round ADDS its offsets."""
    g = SimulatedGantry((ErrorProfile("EC0V", constant=40.0), ErrorProfile("EYV", "V", poly=(8.0,))),
                        noise_sigma=0.5, rng=np.random.default_rng(2))
    with pytest.warns(UserWarning, match="not converged after 3 rounds"):
        table = calibrate(g, 0.0, HEAD0, 20.0, 10, 0.5 * g.true_pixel_to_mm, 0.01, max_rounds=3)
    assert table.rounds == 3 and not table.converged
    true_um = np.array([g.true_correction_mm(0.0, HEAD0, y) for y in table.y_mm]) * 1e3
    assert np.abs(true_um).max() > 7.0
    for rec in table.history:
        np.testing.assert_allclose(rec.offsets_um, 0.5 ** rec.round * true_um, atol=0.15)
    np.testing.assert_allclose(table.offset_mm * 1e3, 0.875 * true_um, atol=0.2)
    np.testing.assert_allclose(table.offset_mm * 1e3, sum(r.offsets_um for r in table.history), atol=1e-9)


# ----------------------------------------------------------------- bad input
@pytest.fixture(scope="module")
def gantry():
    return SimulatedGantry(rng=np.random.default_rng(5))


@pytest.mark.parametrize("n_steps", [0, -3, 2.5, True])
def test_bad_n_steps(gantry, n_steps):
    with pytest.raises(DataError, match=r"n_steps must be an integer >= 1, got"):
        calibrate(gantry, 0.0, HEAD0, 10.0, n_steps, gantry.true_pixel_to_mm, 1.0)


@pytest.mark.parametrize("step", [0.0, -5.0])
def test_bad_step(gantry, step):
    with pytest.raises(DataError, match=r"step_mm must be positive"):
        calibrate(gantry, 0.0, HEAD0, step, 5, gantry.true_pixel_to_mm, 1.0)


@pytest.mark.parametrize("matrix,match", [
    ([[0.005, 0.01], [0.0025, 0.005]], "pixel_to_mm is not invertible"),
    (np.zeros((2, 2)), "pixel_to_mm is not invertible"),
    ([[0.005, 0.0, 0.0], [0.0, 0.005, 0.0]], r"finite 2 x 2 matrix .* got shape \(2, 3\)"),
    ([[0.005, np.nan], [0.0, 0.005]], "finite 2 x 2 matrix"),
])
def test_bad_pixel_to_mm(gantry, matrix, match):
    with pytest.raises(DataError, match=match):
        calibrate(gantry, 0.0, HEAD0, 10.0, 5, matrix, 1.0)


def test_bad_spec_and_head(gantry):
    with pytest.raises(DataError, match="spec_um must be a positive number"):
        calibrate(gantry, 0.0, HEAD0, 10.0, 5, gantry.true_pixel_to_mm, 0.0)
    with pytest.raises(DataError, match=r"head_start_mm must be two finite numbers"):
        calibrate(gantry, 0.0, (0.0,), 10.0, 5, gantry.true_pixel_to_mm, 1.0)


class _LosesPlate:
    """The simulated gantry, but the plate falls off the head after ``keep`` images."""

    def __init__(self, gantry, keep):
        self.g, self.keep, self.n = gantry, keep, 0

    def move(self, *a):
        self.g.move(*a)

    def grab(self):
        self.n += 1
        img = self.g.grab()
        return img if self.n <= self.keep else np.full_like(img, 200)


def test_plate_not_found_is_an_image_error(gantry):
    with pytest.raises(ImageError, match=r"round 1, step 2 \(camera Y 20 mm\): plate not found"):
        calibrate(_LosesPlate(gantry, 2), 0.0, HEAD0, 10.0, 5, gantry.true_pixel_to_mm, 1.0)


def test_blank_start_image_is_an_image_error(gantry):
    with pytest.raises(ImageError, match=r"start image: plate not found"):
        calibrate(_LosesPlate(gantry, 0), 0.0, HEAD0, 10.0, 5, gantry.true_pixel_to_mm, 1.0)


def test_bad_roi_is_a_data_error(gantry):
    with pytest.raises(DataError, match=r"roi \(150, 100, 100, 100\) is not inside"):
        calibrate(gantry, 0.0, HEAD0, 10.0, 2, gantry.true_pixel_to_mm, 1.0, roi=(150, 100, 100, 100))


def test_move_outside_travel_is_a_stage_error(gantry):
    with pytest.raises(StageError, match=r"axis Y target 510.* outside its travel \[-50, 500\] mm"):
        calibrate(gantry, 460.0, (0.0, 460.0), 10.0, 5, gantry.true_pixel_to_mm, 1.0)


def test_simulator_rejects_bad_moves_and_unknown_error_joints(gantry):
    with pytest.raises(StageError, match=r"axis X target nan mm is outside its travel"):
        gantry.move(0.0, float("nan"), 0.0)
    with pytest.raises(StageError, match=r"axis V target must be a number, got 'a'"):
        gantry.move(0.0, 0.0, "a")
    with pytest.raises(DataError, match=r"error profile 'EXZ' is not an error joint of the machine"):
        SimulatedGantry((ErrorProfile("EXZ", "Z", poly=(1.0,)),))
