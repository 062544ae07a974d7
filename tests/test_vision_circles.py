"""Tests of vision.circles against an independent renderer (OpenCV drawing at 8x, INTER_AREA down)."""
import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import ImageError
from kinid.vision.circles import locate_disk, locate_hole, locate_sphere, offset_from_image_centre
from kinid.vision.render import render_disk

UP, SHIFT = 8, 4


def draw_disk(shape, centre_px, radius_px, *, low=30, high=220, blur_px=0.8, noise=2.0, rng=None):
    """Independent renderer: cv2.circle (anti-aliased, sub-pixel shift) at 8x, then INTER_AREA."""
    h, w = shape
    canvas = np.full((h * UP, w * UP), high, np.uint8)
    c = tuple(int(round(((v + 0.5) * UP - 0.5) * 2 ** SHIFT)) for v in centre_px)
    cv2.circle(canvas, c, int(round(radius_px * UP * 2 ** SHIFT)), int(low), -1, cv2.LINE_AA, SHIFT)
    img = cv2.resize(canvas.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    if noise > 0:
        img = img + rng.normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


@pytest.mark.parametrize("low,high", [(30, 220), (220, 30)])
@pytest.mark.parametrize("method,limit", [("fit", 0.01), ("centroid", 0.015)])
def test_centre_rms_independent_renderer(low, high, method, limit):
    rng = np.random.default_rng(11 if low < high else 12)
    err = []
    for _ in range(25):
        c = (60 + rng.uniform(-3, 3), 58 + rng.uniform(-3, 3))
        r = rng.uniform(6, 25)
        img = draw_disk((120, 120), c, r, low=low, high=high, blur_px=rng.uniform(0.5, 1.0), noise=2.0, rng=rng)
        res = locate_disk(img, method=method)
        assert res.found, res.reason
        err.append((res.x_px - c[0], res.y_px - c[1]))
        assert res.radius_px == pytest.approx(r, abs=0.1 if method == "fit" else 0.5)
    rms = float(np.sqrt(np.mean(np.square(err))))
    assert rms < limit


def test_sigma_estimate_is_realistic():
    rng = np.random.default_rng(3)
    err, sig = [], []
    for _ in range(25):
        c = (50 + rng.uniform(-1, 1), 50 + rng.uniform(-1, 1))
        img = draw_disk((100, 100), c, 15.0, blur_px=0.8, noise=4.0, rng=rng)
        res = locate_disk(img)
        err.append(res.x_px - c[0])
        sig.append(res.sigma_px)
    rms = float(np.sqrt(np.mean(np.square(err))))
    assert 0.3 < np.mean(sig) / rms < 3.0


@settings(max_examples=8, deadline=None, database=None, derandomize=True)
@given(dx=st.floats(-1.0, 1.0), dy=st.floats(-1.0, 1.0))
def test_subpixel_shift_moves_centre_by_same_amount(dx, dy):
    base = (40.3, 41.7)
    a = locate_disk(render_disk((84, 84), base, 12.0, blur_px=0.8, supersample=16))
    b = locate_disk(render_disk((84, 84), (base[0] + dx, base[1] + dy), 12.0, blur_px=0.8, supersample=16))
    # noise-free 8-bit images: grey-level rounding alone moves each centre by up to ~0.003 px
    assert b.x_px - a.x_px == pytest.approx(dx, abs=6e-3)
    assert b.y_px - a.y_px == pytest.approx(dy, abs=6e-3)


def test_no_fiducial_not_found_with_reason():
    rng = np.random.default_rng(0)
    flat = np.clip(rng.normal(128, 2, (80, 80)), 0, 255).astype(np.uint8)
    res = locate_disk(flat)
    assert not res.found and "contrast" in res.reason
    # a mark cut by the border is not a located disk
    cut = draw_disk((80, 80), (3.0, 40.0), 10.0, rng=rng)
    res = locate_disk(cut)
    assert not res.found and "inside" in res.reason
    with pytest.raises(ImageError, match="no feature located"):
        offset_from_image_centre(res, cut.shape)


def test_offset_from_image_centre_and_roi():
    rng = np.random.default_rng(5)
    img = draw_disk((101, 121), (70.25, 40.5), 8.0, noise=1.0, rng=rng)
    res = locate_disk(img)
    dx, dy = offset_from_image_centre(res, img.shape)
    assert dx == pytest.approx(70.25 - 60.0, abs=0.01) and dy == pytest.approx(40.5 - 50.0, abs=0.01)
    res_roi = locate_disk(img, roi=(50, 20, 45, 45))
    assert res_roi.x_px == pytest.approx(res.x_px, abs=0.01) and res_roi.y_px == pytest.approx(res.y_px, abs=0.01)


def test_hole_nearest_centre_back_lit():
    rng = np.random.default_rng(6)
    # two back-lit holes (light on dark); the one near the image centre is wanted even if smaller
    img = draw_disk((120, 160), (80.4, 60.2), 9.0, low=230, high=25, noise=0.0, rng=rng).astype(float)
    other = draw_disk((120, 160), (25.0, 25.0), 14.0, low=230, high=25, noise=0.0, rng=rng).astype(float)
    img = np.maximum(img, other) + rng.normal(0, 2.0, img.shape)
    res = locate_hole(np.clip(img, 0, 255).astype(np.uint8))
    assert res.found
    assert res.x_px == pytest.approx(80.4, abs=0.01) and res.y_px == pytest.approx(60.2, abs=0.01)
    big = locate_disk(np.clip(img, 0, 255).astype(np.uint8))
    assert big.x_px == pytest.approx(25.0, abs=0.02)


def render_sphere(shape, centre, radius, light=(0.5, -0.3), up=8, noise=2.0, rng=None):
    """Shaded (Lambertian + ambient) sphere with a specular spot on a dark background."""
    h, w = shape
    ys, xs = np.mgrid[0:h * up, 0:w * up]
    x = ((xs + 0.5) / up - 0.5 - centre[0]) / radius
    y = ((ys + 0.5) / up - 0.5 - centre[1]) / radius
    r2 = x * x + y * y
    inside = r2 <= 1
    z = np.sqrt(np.clip(1 - r2, 0, 1))
    lvec = np.array([light[0], light[1], 1.0])
    lvec /= np.linalg.norm(lvec)
    shade = np.clip(x * lvec[0] + y * lvec[1] + z * lvec[2], 0, 1)
    spec = np.exp(-((x - 0.3) ** 2 + (y + 0.2) ** 2) / 0.01)
    hi = np.where(inside, 90 + 120 * shade + 40 * spec, 20.0).astype(np.float32)
    img = cv2.resize(hi, (w, h), interpolation=cv2.INTER_AREA)
    img = cv2.GaussianBlur(img, (0, 0), 0.8) + rng.normal(0, noise, (h, w))
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_sphere_outline_centre():
    rng = np.random.default_rng(8)
    err = []
    for _ in range(5):
        c = (60 + rng.uniform(-5, 5), 55 + rng.uniform(-5, 5))
        r = rng.uniform(18, 35)
        res = locate_sphere(render_sphere((110, 120), c, r, rng=rng))
        assert res.found, res.reason
        assert res.radius_px == pytest.approx(r, abs=0.3)
        err.append((res.x_px - c[0], res.y_px - c[1]))
    assert float(np.sqrt(np.mean(np.square(err)))) < 0.05


def test_bad_image_raises_image_error():
    with pytest.raises(ImageError, match="2-D grey image"):
        locate_disk(np.zeros(10))
    with pytest.raises(ValueError, match="polarity"):
        locate_disk(np.zeros((10, 10), np.uint8) + np.eye(10, dtype=np.uint8) * 200, polarity="bright")


@pytest.mark.parametrize("radius", [4.0, 8.0, 20.0])
def test_small_disk_in_a_large_image(radius):
    # a fiducial covering well under 1 % of the frame sets the levels all the same
    rng = np.random.default_rng(int(radius))
    img = draw_disk((480, 640), (300.3, 200.6), radius, noise=2.0, rng=rng)
    res = locate_disk(img)
    assert res.found, res.reason
    assert res.x_px == pytest.approx(300.3, abs=0.03) and res.y_px == pytest.approx(200.6, abs=0.03)
