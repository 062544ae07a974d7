"""Sub-pixel template matching against rendered plates with known shifts."""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError, ImageError
from kinid.vision.calibration_targets import printed_features_coverage, smooth_texture_coverage
from kinid.vision.render import render_pattern
from kinid.vision.template import Template, locate_template, make_template

PIXEL_MM = 0.05
SHAPE = (112, 112)
ROI = (28, 28, 56, 56)


def _texture(seed):
    # shortest wavelength 6 px: band-limited, so point sampling is an exact shift
    return smooth_texture_coverage(np.random.default_rng(seed), wavelength_mm=6 * PIXEL_MM, n_waves=60)


def _render(coverage, shift_px, *, noise_sigma=0.0, blur_px=0.0, rng=None, supersample=1, low=30, high=220):
    shift = np.asarray(shift_px, dtype=float)

    def image_to_plane(pts_px):
        return (np.asarray(pts_px, dtype=float) - shift) * PIXEL_MM

    return render_pattern(coverage, SHAPE, image_to_plane, low=low, high=high, supersample=supersample,
                          blur_px=blur_px, noise_sigma=noise_sigma, rng=rng)


@pytest.fixture(scope="module")
def smooth():
    cov = _texture(7)
    return cov, make_template(_render(cov, (0, 0)), ROI)


def test_template_holds_region_and_origin(smooth):
    cov, tmpl = smooth
    ref = _render(cov, (0, 0))
    assert tmpl.origin_px == (28.0, 28.0)
    assert tmpl.image.shape == (56, 56)
    np.testing.assert_array_equal(tmpl.image, ref[28:84, 28:84])
    with pytest.raises(ValueError):
        tmpl.image[0, 0] = 1  # read-only copy


def test_zero_shift_is_exactly_zero(smooth):
    cov, tmpl = smooth
    m = locate_template(_render(cov, (0, 0)), tmpl)
    assert m.found and m.reason == ""
    assert abs(m.dx_px) < 1e-6 and abs(m.dy_px) < 1e-6
    assert m.score == pytest.approx(1.0, abs=1e-5)


@pytest.mark.parametrize("shift", [(0.37, -0.21), (2.5, 1.25), (-3.8, 4.6), (7.0, -5.0)])
def test_noise_free_shift_recovered(smooth, shift):
    cov, tmpl = smooth
    m = locate_template(_render(cov, shift), tmpl)
    assert m.found
    # left: 8-bit rounding and spline interpolation (0.0006 px RMS measured)
    assert m.dx_px == pytest.approx(shift[0], abs=0.002)
    assert m.dy_px == pytest.approx(shift[1], abs=0.002)


# noise-free RMS measured on this texture over 15 random shifts (lk 0.0006, ecc 0.010,
# upsampled 0.012, ncc 0.025, gauss 0.12, phase 0.21 px): bounds at about 3x the worst seen
@pytest.mark.parametrize("method, tol_px", [("lk", 0.003), ("ecc", 0.03), ("upsampled", 0.06), ("ncc", 0.09),
                                            ("gauss", 0.4), ("phase", 0.6)])
def test_every_refinement_is_subpixel_without_noise(smooth, method, tol_px):
    cov, tmpl = smooth
    shift = (1.3, -0.6)
    m = locate_template(_render(cov, shift), tmpl, search_px=4, method=method)
    assert m.found, m.reason
    assert np.hypot(m.dx_px - shift[0], m.dy_px - shift[1]) < tol_px


def test_rms_within_one_hundredth_pixel_with_noise_and_blur():
    rng = np.random.default_rng(42)
    cov = _texture(11)
    tmpl = make_template(_render(cov, (0, 0), noise_sigma=2.0, blur_px=0.8, rng=rng), ROI)
    shifts = rng.uniform(-3, 3, (10, 2))
    err = []
    for s in shifts:
        m = locate_template(_render(cov, s, noise_sigma=2.0, blur_px=0.8, rng=rng), tmpl, search_px=5)
        assert m.found
        err.append((m.dx_px - s[0], m.dy_px - s[1]))
    rms = np.sqrt((np.asarray(err) ** 2).sum(axis=1).mean())
    assert rms < 0.01  # the target; benchmark measures ~0.004 px


def test_printed_features_with_noise():
    rng = np.random.default_rng(5)
    cov = printed_features_coverage(rng, (0, 0, SHAPE[1] * PIXEL_MM, SHAPE[0] * PIXEL_MM), n_features=50,
                                    size_mm=(0.3, 1.2))
    ref = _render(cov, (0, 0), noise_sigma=2.0, blur_px=1.0, rng=rng, supersample=8)
    tmpl = make_template(ref, ROI)
    err = []
    for s in [(0.41, -1.73), (-2.26, 0.88), (1.5, 2.5)]:
        m = locate_template(_render(cov, s, noise_sigma=2.0, blur_px=1.0, rng=rng, supersample=8), tmpl)
        assert m.found
        err.append((m.dx_px - s[0], m.dy_px - s[1]))
    assert np.sqrt((np.asarray(err) ** 2).sum(axis=1).mean()) < 0.01


@settings(max_examples=12, deadline=None)
@given(dx=st.floats(-2.0, 2.0), dy=st.floats(-2.0, 2.0))
def test_property_shift_moves_match_by_same_amount(dx, dy):
    cov = _texture(3)
    tmpl = make_template(_render(cov, (0.0, 0.0)), ROI)
    a = locate_template(_render(cov, (0.25, -0.5)), tmpl, search_px=4)
    b = locate_template(_render(cov, (0.25 + dx, -0.5 + dy)), tmpl, search_px=4)
    assert a.found and b.found
    assert b.dx_px - a.dx_px == pytest.approx(dx, abs=0.003)
    assert b.dy_px - a.dy_px == pytest.approx(dy, abs=0.003)


def test_gain_and_offset_change_do_not_move_the_match(smooth):
    cov, tmpl = smooth
    m = locate_template(_render(cov, (0.6, 0.3), low=60, high=180), tmpl)
    assert m.found
    assert m.dx_px == pytest.approx(0.6, abs=0.003) and m.dy_px == pytest.approx(0.3, abs=0.003)


def test_inverted_contrast_is_not_a_match(smooth):
    cov, tmpl = smooth
    m = locate_template(_render(cov, (0.0, 0.0), low=220, high=30), tmpl)
    assert not m.found
    assert "below min_score" in m.reason
    assert np.isnan(m.dx_px) and np.isnan(m.dy_px)


def test_shift_beyond_search_window_reports_edge(smooth):
    cov, tmpl = smooth
    m = locate_template(_render(cov, (9.0, 0.0)), tmpl, search_px=3)
    assert not m.found
    assert "search window" in m.reason or "below min_score" in m.reason
    whole = locate_template(_render(cov, (9.0, 0.0)), tmpl)
    assert whole.found and whole.dx_px == pytest.approx(9.0, abs=0.003)


def test_noise_image_not_found(smooth):
    _, tmpl = smooth
    noise = np.random.default_rng(0).integers(0, 256, SHAPE).astype(np.uint8)
    m = locate_template(noise, tmpl)
    assert not m.found and "min_score" in m.reason


def test_bgr_image_accepted(smooth):
    cov, tmpl = smooth
    img = _render(cov, (1.2, -0.4))
    m = locate_template(np.dstack([img, img, img]), tmpl)
    assert m.found and m.dx_px == pytest.approx(1.2, abs=0.01)


@pytest.mark.parametrize(
    "roi, match",
    [((100, 0, 20, 20), "not inside the 112x112 px image"), ((-1, 0, 20, 20), "not inside"),
     ((0, 0, 4, 20), "smaller than 8x8"), ((0, 0, 20), "four integers"), ((0.5, 0, 20, 20), "four integers")],
)
def test_make_template_rejects_bad_roi(smooth, roi, match):
    cov, _ = smooth
    with pytest.raises(DataError, match=match):
        make_template(_render(cov, (0, 0)), roi)


def test_make_template_rejects_flat_region_and_bad_image():
    with pytest.raises(ImageError, match="uniform"):
        make_template(np.full((40, 40), 128, np.uint8), (0, 0, 16, 16))
    with pytest.raises(ImageError, match="2-D grey image"):
        make_template(np.zeros((4, 4, 4, 4)), (0, 0, 2, 2))


def test_locate_rejects_bad_arguments(smooth):
    cov, tmpl = smooth
    img = _render(cov, (0, 0))
    with pytest.raises(DataError, match="method must be one of"):
        locate_template(img, tmpl, method="sift")
    with pytest.raises(DataError, match="search_px must be a positive integer"):
        locate_template(img, tmpl, search_px=-2)
    with pytest.raises(DataError, match="template must be a Template"):
        locate_template(img, np.zeros((8, 8)))
    with pytest.raises(ImageError, match="smaller than the template"):
        locate_template(img[:20, :20], tmpl)
    assert isinstance(tmpl, Template)


def test_lk_sigma_covers_the_error():
    # fresh noisy reference per trial, so the template's own noise is part of the error
    rng = np.random.default_rng(8)
    cov = _texture(11)
    err, sig = [], []
    for _ in range(30):
        tmpl = make_template(_render(cov, (0, 0), noise_sigma=2.0, blur_px=0.8, rng=rng), ROI)
        s = rng.uniform(-3, 3, 2)
        m = locate_template(_render(cov, s, noise_sigma=2.0, blur_px=0.8, rng=rng), tmpl, search_px=5)
        err.append((m.dx_px - s[0], m.dy_px - s[1]))
        sig.append((m.sigma_dx_px, m.sigma_dy_px))
    err, sig = np.abs(np.asarray(err)), np.asarray(sig)
    assert np.all(sig > 0) and np.all(sig < 0.01)
    assert np.mean(err <= 3 * sig) > 0.95
    other = locate_template(_render(cov, (0.5, 0.5)), tmpl, method="ncc")
    assert np.isnan(other.sigma_dx_px) and np.isnan(other.sigma_dy_px)
