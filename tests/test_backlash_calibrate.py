"""kinid.stages.backlash.calibrate: truth recovery on simulated stages ."""
import warnings

import numpy as np
import pytest

from kinid.errors import DataError, ImageError, StageError
from kinid.stages.backlash import SimulatedStage, calibrate

# Targets: pixel equivalent within 0.1 %, X/Y backlash within 0.3 um, θ within 0.002 deg,
# at a pixel near 5 um, camera not square to the axes, fiducial far (>= 10 mm) from the θ centre.
PIXEL_REL_TOL = 1e-3
XY_TOL_MM = 0.3e-3
THETA_TOL_DEG = 0.002


class RecordingStage:
    """Wraps a stage, records every command, hides ``position`` unless asked to expose it."""

    def __init__(self, stage, expose_position):
        self._stage = stage
        self.commands = []
        if expose_position:
            self.position = stage.position

    def move_to(self, x_mm, y_mm, theta_deg):
        self.commands.append((x_mm, y_mm, theta_deg))
        self._stage.move_to(x_mm, y_mm, theta_deg)
        if hasattr(self, "position"):
            self.position = self._stage.position

    def grab(self):
        return self._stage.grab()


def _check_truth(res, st):
    assert res.pixel_mm_x == pytest.approx(st.true_pixel_mm_along((1, 0)), rel=PIXEL_REL_TOL)
    assert res.pixel_mm_y == pytest.approx(st.true_pixel_mm_along((0, 1)), rel=PIXEL_REL_TOL)
    assert res.backlash_x_mm == pytest.approx(st.backlash_x_mm, abs=XY_TOL_MM)
    assert res.backlash_y_mm == pytest.approx(st.backlash_y_mm, abs=XY_TOL_MM)
    assert res.backlash_theta_deg == pytest.approx(st.backlash_theta_deg, abs=THETA_TOL_DEG)


@pytest.mark.parametrize("config", [
    # pixel 5 um, camera rotated 7 deg, fiducial 14.4 mm from the θ centre
    dict(pixel_mm=0.005, camera_angle_deg=7.0, theta_centre_mm=(-12.0, 8.0), backlash_x_mm=0.004,
         backlash_y_mm=0.003, backlash_theta_deg=0.01, seed=1),
    # unmirrored camera at -23 deg, rectangular pixels, larger backlash, centre 18 mm away
    dict(pixel_mm=(0.0048, 0.0051), camera_angle_deg=-23.0, mirror=False, theta_centre_mm=(10.0, -15.0),
         backlash_x_mm=0.012, backlash_y_mm=0.0005, backlash_theta_deg=0.03, seed=2),
])
def test_truth_recovery_on_rotated_camera(config):
    config = dict(config)
    seed = config.pop("seed")
    st = SimulatedStage(noise_sigma=2.0, rng=np.random.default_rng(seed), **config)
    res = calibrate(st, travel_mm=0.8, travel_deg=2.0)
    _check_truth(res, st)
    assert res.moves == 21 == len(st.history)
    assert res.matrix.rotation_deg == pytest.approx(st.camera_angle_deg, abs=0.05)
    assert res.matrix.mirrored == st.mirror
    assert res.theta_radius_mm == pytest.approx(np.hypot(*st.theta_centre_mm), rel=1e-3)
    assert res.theta_centre_mm == pytest.approx(st.theta_centre_mm, abs=0.05)
    # Patent's norm formula agrees for a clear backlash.
    assert res.backlash_x_patent_mm == pytest.approx(st.backlash_x_mm, abs=XY_TOL_MM)
    assert res.backlash_theta_patent_deg == pytest.approx(st.backlash_theta_deg, abs=THETA_TOL_DEG)


def test_noiseless_recovery_is_near_exact():
    st = SimulatedStage(noise_sigma=0.0, camera_angle_deg=7.0, rng=np.random.default_rng(0))
    res = calibrate(st)
    assert res.pixel_mm_x == pytest.approx(0.005, rel=1e-4)
    assert res.backlash_x_mm == pytest.approx(st.backlash_x_mm, abs=0.05e-3)
    assert res.backlash_y_mm == pytest.approx(st.backlash_y_mm, abs=0.05e-3)
    assert res.backlash_theta_deg == pytest.approx(st.backlash_theta_deg, abs=2e-4)


def test_zero_backlash_gives_about_zero():
    st = SimulatedStage(backlash_x_mm=0.0, backlash_y_mm=0.0, backlash_theta_deg=0.0, noise_sigma=2.0,
                        camera_angle_deg=7.0, rng=np.random.default_rng(4))
    res = calibrate(st)
    assert abs(res.backlash_x_mm) < 0.1e-3
    assert abs(res.backlash_y_mm) < 0.1e-3
    assert abs(res.backlash_theta_deg) < 5e-4


@pytest.mark.parametrize("expose_position", [True, False])
def test_every_command_within_travel_of_start(expose_position):
    start = (5.0, -3.0, 10.0) if expose_position else (0.0, 0.0, 0.0)
    at = SimulatedStage(initial_command=start, backlash_x_mm=0.0, backlash_y_mm=0.0,
                        backlash_theta_deg=0.0).fiducial_mm()        # keep the fiducial in view at the start
    st = SimulatedStage(initial_command=start, camera_at_mm=at, rng=np.random.default_rng(7))
    rec = RecordingStage(st, expose_position)
    res = calibrate(rec, travel_mm=0.6, travel_deg=1.5, n_targets=2)
    cmds = np.array(rec.commands)
    assert len(cmds) == res.moves == 9 + 4 * (2 * 2 + 1)
    assert np.all(np.abs(cmds[:, :2] - start[:2]) <= 0.6 + 1e-12)
    assert np.all(np.abs(cmds[:, 2] - start[2]) <= 1.5 + 1e-12)
    assert res.start == start
    _check_truth(res, st)


def test_iso_reversal_values_over_targets():
    st = SimulatedStage(backlash_x_mm=0.006, backlash_y_mm=0.002, rng=np.random.default_rng(11))
    res = calibrate(st, n_targets=3)
    assert res.reversals_x_mm.size == 3
    assert res.iso_reversal_x_mm == pytest.approx(0.006, abs=XY_TOL_MM)
    assert res.iso_mean_reversal_x_mm == pytest.approx(-0.006, abs=XY_TOL_MM)
    assert res.iso_reversal_y_mm == pytest.approx(0.002, abs=XY_TOL_MM)
    assert res.spread_x_mm < 0.1e-3


def test_positioning_scatter_shows_in_spread():
    st = SimulatedStage(repeatability_mm=0.0002, rng=np.random.default_rng(12))
    res = calibrate(st, repeats=3)
    assert res.spread_x_mm > 0.05e-3
    assert res.backlash_x_mm == pytest.approx(st.backlash_x_mm, abs=XY_TOL_MM)


def test_move_outside_stage_travel_raises_stage_error():
    st = SimulatedStage(limits_mm=((-0.5, 0.5), (-0.5, 0.5)), rng=np.random.default_rng(0))
    with pytest.raises(StageError, match=r"x = -0.8 mm is outside the stage travel \[-0.5, 0.5\] mm"):
        calibrate(st, travel_mm=0.8)


def test_fiducial_out_of_view_raises_image_error():
    st = SimulatedStage(rng=np.random.default_rng(0))
    with pytest.raises(ImageError, match=r"image after move 2 to \(x -1.5 mm, y -1.5 mm, theta 0 deg\): no fiducial"):
        calibrate(st, travel_mm=3.0)


def test_blank_camera_raises_image_error():
    class Blank(RecordingStage):
        def grab(self):
            return np.full((100, 120), 128, np.uint8)

    with pytest.raises(ImageError, match="image after move 2 .*no fiducial"):
        calibrate(Blank(SimulatedStage(rng=np.random.default_rng(0)), False))


@pytest.mark.parametrize("kwargs, match", [
    ({"travel_mm": 0.0}, "travel_mm must be a positive number, got 0.0"),
    ({"travel_mm": -0.5}, "travel_mm must be a positive number, got -0.5"),
    ({"travel_deg": 0}, "travel_deg must be a positive number, got 0"),
])
def test_non_positive_travel_raises_data_error(kwargs, match):
    st = SimulatedStage(rng=np.random.default_rng(0))
    with pytest.raises(DataError, match=match):
        calibrate(st, **kwargs)
    assert st.history == []   # validated before any move


def test_backlash_near_excursion_warns():
    st = SimulatedStage(backlash_x_mm=0.12, rng=np.random.default_rng(0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        calibrate(st, travel_mm=0.4)
    assert any("X backlash" in str(w.message) and "increase travel_mm" in str(w.message) for w in caught)


class PerfectCameraStage(SimulatedStage):
    """Simulated stage whose 'image' is the exact fiducial position (no rendering, no locator error)."""

    def grab(self):
        return self.fiducial_px()


class ClockwiseThetaStage(PerfectCameraStage):
    """θ turns clockwise seen from above (the other sense than the calibration's centre fit assumes)."""

    def fiducial_mm(self):
        x, y, th = self.actual
        c = np.array(self.theta_centre_mm)
        t = np.radians(-th)
        rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
        return np.array([x, y]) + c + rot @ (-c)


def _exact(image, what=""):
    return float(image[0]), float(image[1])


@pytest.mark.parametrize("kwargs", [
    dict(pixel_mm=0.005, camera_angle_deg=7.0, theta_centre_mm=(-12.0, 8.0)),
    dict(pixel_mm=(0.0047, 0.0053), camera_angle_deg=-31.0, mirror=False, theta_centre_mm=(20.0, 3.0),
         backlash_x_mm=0.0, backlash_y_mm=0.02, backlash_theta_deg=0.05),
])
def test_exact_on_noiseless_positions(kwargs):
    st = PerfectCameraStage(rng=np.random.default_rng(0), **kwargs)
    res = calibrate(st, repeats=2, n_targets=2, locate=_exact)
    assert res.pixel_mm_x == pytest.approx(st.true_pixel_mm_along((1, 0)), rel=1e-12)
    assert res.pixel_mm_y == pytest.approx(st.true_pixel_mm_along((0, 1)), rel=1e-12)
    assert res.backlash_x_mm == pytest.approx(st.backlash_x_mm, abs=1e-12)
    assert res.backlash_y_mm == pytest.approx(st.backlash_y_mm, abs=1e-12)
    assert res.backlash_theta_deg == pytest.approx(st.backlash_theta_deg, abs=1e-10)
    # The centre is reported relative to the fiducial in the first "up" photo, taken at θ = -B/2.
    t = np.radians(-st.backlash_theta_deg / 2)
    expected = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]]) @ np.array(st.theta_centre_mm)
    assert res.theta_centre_mm == pytest.approx(expected, abs=1e-9)
    assert res.matrix.matrix == pytest.approx(np.linalg.inv(st.machine_to_pixel_matrix()), rel=1e-10)
    assert res.spread_x_mm == pytest.approx(0.0, abs=1e-12)


def test_clockwise_theta_gives_same_backlash():
    st = ClockwiseThetaStage(rng=np.random.default_rng(0), backlash_theta_deg=0.02, theta_centre_mm=(3.0, -14.0))
    res = calibrate(st, locate=_exact)
    # The centre is fitted in the wrong (mirrored) place; the gap angle is still right to first order.
    assert res.backlash_theta_deg == pytest.approx(0.02, rel=1e-3)
    assert res.theta_radius_mm == pytest.approx(np.hypot(3.0, -14.0), rel=1e-3)


def test_fiducial_on_theta_centre_warns_and_gives_nan():
    st = PerfectCameraStage(rng=np.random.default_rng(0), theta_centre_mm=(0.001, 0.0))
    with pytest.warns(UserWarning, match="too close to the θ rotation centre"):
        res = calibrate(st, locate=_exact)
    assert np.isnan(res.backlash_theta_deg)
    assert res.backlash_x_mm == pytest.approx(st.backlash_x_mm, abs=1e-12)


def test_iso_reversal_from_the_standards_evaluation_matches_the_gaps():
    """With two runs per target, B and the mean reversal come from kinid.stages.iso230_2; they equal the
    per-target means of the reversal gaps (B_i = mean up − mean down = −mean gap)."""
    import numpy as np

    from kinid.stages.backlash import SimulatedStage, calibrate

    stage = SimulatedStage(backlash_x_mm=0.004, backlash_y_mm=0.003, rng=np.random.default_rng(4))
    res = calibrate(stage, travel_mm=0.8, travel_deg=2.0, repeats=2, n_targets=3)
    ups = [r for r in res.log if r.axis == "x" and r.role == "up"]
    targets = np.array([r.target for r in ups])
    b_i = [-np.mean(res.reversals_x_mm[targets == t]) for t in np.unique(targets)]
    assert res.iso_reversal_x_mm == pytest.approx(np.max(np.abs(b_i)), abs=1e-9)
    assert res.iso_mean_reversal_x_mm == pytest.approx(np.mean(b_i), abs=1e-9)
