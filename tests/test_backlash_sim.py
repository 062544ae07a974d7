"""kinid.stages.backlash: play operator, simulated stage, fiducial locator, move plan."""
import numpy as np
import pytest

from kinid.errors import DataError, ImageError, StageError
from kinid.stages.backlash import SimulatedStage, locate_fiducial, plan_moves
from kinid.stages.backlash.simulate import play
from kinid.stages.backlash.locate import centroid_locate
from kinid.vision.render import render_disk


def test_play_operator_loses_backlash_on_reversal():
    b = 0.004
    a = play(0.0, 1.0, b)                  # positive move: lags by b/2
    assert a == pytest.approx(1.0 - b / 2)
    assert play(a, 1.0 - b / 2, b) == a     # reversal inside the dead band: no motion
    a2 = play(a, 0.5, b)                   # reversal: leads by b/2
    assert a2 == pytest.approx(0.5 + b / 2)
    assert a - a2 == pytest.approx(0.5 - b)   # a 0.5 mm reversal loses the backlash b
    assert play(a2, 0.2, 0.0) == 0.2


def test_stage_moves_fiducial_through_camera_model():
    st = SimulatedStage(backlash_x_mm=0.0, backlash_y_mm=0.0, backlash_theta_deg=0.0, camera_angle_deg=0.0,
                        noise_sigma=0.0, rng=np.random.default_rng(0))
    p0 = st.fiducial_px()
    st.move_to(0.5, 0.0, 0.0)
    assert st.fiducial_px() - p0 == pytest.approx([100.0, 0.0])
    st.move_to(0.5, 0.5, 0.0)                 # machine +Y is image -y (mirror)
    assert st.fiducial_px() - p0 == pytest.approx([100.0, -100.0])
    assert st.history == [(0.5, 0.0, 0.0), (0.5, 0.5, 0.0)]
    assert st.position == (0.5, 0.5, 0.0)


def test_stage_theta_rotates_fiducial_about_centre():
    st = SimulatedStage(backlash_x_mm=0.0, backlash_y_mm=0.0, backlash_theta_deg=0.0,
                        theta_centre_mm=(-12.0, 8.0), noise_sigma=0.0,
                        rng=np.random.default_rng(0))
    st.move_to(0.0, 0.0, 1.0)
    f = st.fiducial_mm()
    c = np.array([-12.0, 8.0])
    assert np.hypot(*(f - c)) == pytest.approx(np.hypot(*c))
    ang = np.degrees(np.arctan2(*(f - c)[::-1]) - np.arctan2(*(-c)[::-1]))
    assert ang == pytest.approx(1.0)


def test_stage_rejects_move_outside_limits():
    st = SimulatedStage(limits_mm=((-1.0, 1.0), (-1.0, 1.0)), limits_deg=(-5.0, 5.0), rng=np.random.default_rng(0))
    with pytest.raises(StageError, match=r"x = 1.5 mm is outside the stage travel \[-1, 1\] mm"):
        st.move_to(1.5, 0.0, 0.0)
    with pytest.raises(StageError, match=r"theta = -6 deg is outside the stage travel \[-5, 5\] deg"):
        st.move_to(0.0, 0.0, -6.0)
    assert st.history == []


def test_stage_rejects_bad_parameters():
    with pytest.raises(DataError, match="backlash_x_mm must be a number >= 0, got -0.001"):
        SimulatedStage(backlash_x_mm=-0.001)
    with pytest.raises(DataError, match="pixel_mm must be a positive number"):
        SimulatedStage(pixel_mm=0.0)


@pytest.mark.parametrize("locator", [locate_fiducial, lambda im: centroid_locate(im)[:2]])
def test_locator_accuracy_on_rendered_disk(locator):
    rng = np.random.default_rng(5)
    errs = []
    for _ in range(6):
        c = rng.uniform(250, 350, 2)
        im = render_disk((480, 640), tuple(c), 40.0, noise_sigma=2.0, rng=rng)
        errs.append(np.subtract(locator(im), c))
    rms = np.sqrt(np.mean(np.square(errs)))
    assert rms < 0.02


def test_locator_small_fiducial_in_large_image():
    # A 20 px disk covers 0.4 % of the image; locate_fiducial falls back to the centroid if needed.
    rng = np.random.default_rng(8)
    im = render_disk((480, 640), (205.62, 239.48), 20.0, noise_sigma=2.0, rng=rng)
    assert locate_fiducial(im) == pytest.approx((205.62, 239.48), abs=0.03)


def test_locator_finds_light_disk_on_dark():
    im = render_disk((200, 200), (90.3, 110.7), 30.0, low=230, high=20, noise_sigma=1.0,
                     rng=np.random.default_rng(1))
    x, y, r = centroid_locate(im)
    assert (x, y) == pytest.approx((90.3, 110.7), abs=0.03)
    assert r == pytest.approx(30.0, abs=1.0)


@pytest.mark.parametrize("locator", [locate_fiducial, centroid_locate])
def test_locator_blank_image_raises(locator):
    im = np.clip(np.random.default_rng(0).normal(128, 2, (120, 160)), 0, 255).astype(np.uint8)
    with pytest.raises(ImageError, match="no fiducial found"):
        locator(im, what="image after move 3")


def test_centroid_locator_border_and_shape():
    im = render_disk((200, 200), (10.0, 100.0), 30.0)
    with pytest.raises(ImageError, match="touches the image border"):
        centroid_locate(im)
    with pytest.raises(ImageError, match="expected a 2-D grey image"):
        locate_fiducial(np.zeros((4, 4, 3), np.uint8))


def test_plan_stays_within_travel_and_counts():
    for repeats, n_targets in ((1, 1), (2, 3)):
        plan = plan_moves(0.8, 2.0, repeats=repeats, n_targets=n_targets)
        assert len(plan) == 9 + 4 * repeats * (2 * n_targets + 1)
        off = np.array([m.offset for m in plan])
        assert np.all(np.abs(off[:, :2]) <= 0.8 + 1e-12)
        assert np.all(np.abs(off[:, 2]) <= 2.0 + 1e-12)
    # Every X/Y photo of the scale path is approached from the negative side on both axes.
    plan = plan_moves(0.8, 2.0)
    last = np.array([np.nan, np.nan])
    for m in plan[:9]:
        xy = np.array(m.offset[:2])
        if m.photo:
            assert np.all((xy > last) | (xy == last))
        last = xy


@pytest.mark.parametrize("kwargs, match", [
    ({"travel_mm": 0.0}, "travel_mm must be a positive number, got 0.0"),
    ({"travel_mm": -1}, "travel_mm must be a positive number, got -1"),
    ({"travel_deg": float("nan")}, "travel_deg must be a positive number"),
    ({"repeats": 0}, "repeats must be an integer >= 1, got 0"),
    ({"n_targets": 1.5}, "n_targets must be an integer >= 1, got 1.5"),
])
def test_plan_bad_input(kwargs, match):
    args = {"travel_mm": 0.8, "travel_deg": 2.0, **kwargs}
    with pytest.raises(DataError, match=match):
        plan_moves(args.pop("travel_mm"), args.pop("travel_deg"), **args)
