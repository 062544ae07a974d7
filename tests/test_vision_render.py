"""Tests of vision.render: geometry, bit order, anti-aliasing, noise."""
import numpy as np
import pytest

from kinid.vision.board import make_board
from kinid.vision.render import (board_coverage, disk_coverage, homography_image_to_plane, render_disk, render_pattern,
                           ring_mark_coverage, similarity_plane_to_image)


def _ink(img, low=30, high=220):
    return (high - img.astype(float)) / (high - low)


def test_render_disk_area_and_centroid_match_truth():
    c, r = (40.37, 33.81), 11.3
    img = render_disk((80, 90), c, r, blur_px=0.0, supersample=8)
    w = _ink(img)
    # area of the disk (anti-aliased coverage sums to pi r^2; grey rounding costs < 0.3 %)
    assert w.sum() == pytest.approx(np.pi * r * r, rel=3e-3)
    ys, xs = np.mgrid[0:80, 0:90]
    assert (w * xs).sum() / w.sum() == pytest.approx(c[0], abs=3e-3)
    assert (w * ys).sum() / w.sum() == pytest.approx(c[1], abs=3e-3)


def test_blur_keeps_centroid_and_ink():
    c, r = (30.25, 29.6), 8.0
    sharp = _ink(render_disk((60, 60), c, r, blur_px=0.0))
    blurred = _ink(render_disk((60, 60), c, r, blur_px=1.5))
    assert blurred.sum() == pytest.approx(sharp.sum(), rel=3e-3)
    ys, xs = np.mgrid[0:60, 0:60]
    assert (blurred * xs).sum() / blurred.sum() == pytest.approx(c[0], abs=5e-3)
    def edge(w):
        return np.count_nonzero((w > 0.02) & (w < 0.98))

    assert edge(blurred) > 2 * edge(sharp)  # the blur widened the edge


def test_light_on_dark_polarity():
    img = render_disk((40, 40), (20, 20), 6, low=220, high=30, blur_px=0.0)
    assert img[20, 20] == 220 and img[0, 0] == 30


def test_noise_is_reproducible_and_has_requested_sigma():
    a = render_disk((200, 200), (100, 100), 5, noise_sigma=3.0, rng=np.random.default_rng(4))
    b = render_disk((200, 200), (100, 100), 5, noise_sigma=3.0, rng=np.random.default_rng(4))
    assert np.array_equal(a, b)
    bg = a[:60, :60].astype(float)
    assert bg.std() == pytest.approx(3.0, rel=0.1)
    assert bg.mean() == pytest.approx(220.0, abs=0.2)


def test_similarity_and_its_inverse():
    H = similarity_plane_to_image(0.05, 30.0, (100.0, 50.0))
    assert H @ np.array([0, 0, 1.0]) == pytest.approx([100, 50, 1])
    # 1 mm along plane x -> 20 px turned 30 deg clockwise in the image (y down)
    p = H @ np.array([1.0, 0, 1])
    assert p[:2] - [100, 50] == pytest.approx([20 * np.cos(np.pi / 6), 20 * np.sin(np.pi / 6)])
    inv = homography_image_to_plane(H)
    xy = np.random.default_rng(0).uniform(-5, 5, (10, 2))
    px = np.column_stack([xy, np.ones(10)]) @ H.T
    assert inv(px[:, :2] / px[:, 2:]) == pytest.approx(xy)


def test_homography_with_perspective_roundtrip():
    H = np.array([[20.0, 1.0, 300], [-0.5, 19.0, 200], [1e-3, -2e-3, 1]])
    inv = homography_image_to_plane(H)
    xy = np.array([[1.0, 2.0], [-3.0, 4.0]])
    q = np.column_stack([xy, np.ones(2)]) @ H.T
    assert inv(q[:, :2] / q[:, 2:]) == pytest.approx(xy)


def test_ring_element_order_is_clockwise_msb_first():
    # only element 0 (MSB) printed; elements run clockwise in the image (y down) from angle_deg
    cov = ring_mark_coverage((0, 0), 0b100000000000, bits=12)
    r = 5.5  # mid-ring, mm
    ang = np.deg2rad([15.0, -15.0, 45.0])  # element 0, element 11, element 1
    pts = np.column_stack([r * np.cos(ang), r * np.sin(ang)])
    assert list(cov(pts)) == [1.0, 0.0, 0.0]
    # centre circle printed, gap blank, outside blank
    assert list(cov(np.array([[0.0, 0.0], [3.5, 0.0], [7.0, 0.0]]))) == [1.0, 0.0, 0.0]
    rotated = ring_mark_coverage((0, 0), 0b100000000000, bits=12, angle_deg=90.0)
    a = np.deg2rad(105.0)
    assert rotated(np.array([[r * np.cos(a), r * np.sin(a)]]))[0] == 1.0


def test_board_coverage_equals_each_mark():
    board = make_board(3, 4, pitch_mm=16.0)
    cov = board_coverage(board)
    rng = np.random.default_rng(1)
    pts = rng.uniform(-8, 56, (4000, 2))
    expected = np.zeros(len(pts))
    for r in range(3):
        for c in range(4):
            expected = np.maximum(expected, ring_mark_coverage(board.mark_mm(r, c), board.codes[r][c])(pts))
    assert np.array_equal(cov(pts), expected)


@pytest.mark.parametrize("which", ["disk", "ring"])
def test_render_pattern_matches_full_supersampling(which):
    # the adaptive sampler equals brute-force supersampling for features wider than a pixel
    if which == "disk":
        cov = disk_coverage((0.0, 0.0), 1.0)
        H = similarity_plane_to_image(0.1, 0.0, (15.3, 14.7))
    else:
        cov = ring_mark_coverage((0.0, 0.0), 0b101100111000, angle_deg=7.0)
        H = np.array([[3.0, 0.4, 20.3], [-0.3, 2.9, 19.6], [2e-3, -3e-3, 1.0]])
    shape = (40, 42)
    img = render_pattern(cov, shape, homography_image_to_plane(H), supersample=4)
    inv = homography_image_to_plane(H)
    offs = (np.arange(4) + 0.5) / 4 - 0.5
    ys, xs = np.mgrid[0:shape[0], 0:shape[1]]
    pix = np.column_stack([xs.ravel(), ys.ravel()]).astype(float)
    acc = sum(cov(inv(pix + (ox, oy))) for ox in offs for oy in offs) / 16
    brute = np.clip(np.rint(220 - 190 * acc), 0, 255).reshape(shape)
    assert np.count_nonzero(brute != 220) > 100
    assert np.array_equal(img, brute)


def test_bad_shape_rejected():
    from kinid.errors import DataError

    with pytest.raises(DataError, match="image_shape must be positive"):
        render_disk((0, 10), (1, 1), 1)
    with pytest.raises(ValueError, match="pixel_mm"):
        similarity_plane_to_image(0.0)
