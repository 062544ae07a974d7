"""Tests of vision.ringcode: the patent's example, decoding and centres on independently rendered marks."""
import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.vision.board import make_board, match_to_board
from kinid.vision.render import (board_coverage, homography_image_to_plane, render_pattern, ring_mark_coverage,
                           similarity_plane_to_image)
from kinid.vision.ringcode import canonical_code, decode_from_segments, detect_markers

UP, SHIFT = 8, 4
CLASSES = sorted({canonical_code(v) for v in range(1, 4095)})


def draw_mark(shape, centre_px, code_bits, r_centre_px, *, bits=12, angle_deg=0.0, low=30, high=220, blur_px=0.8,
              noise=2.0, rng=None, H=None):
    """Independent renderer: OpenCV drawing at 8x (pie slices, circles), optional warp, INTER_AREA down.

    Ring Ø9-Ø13 around a Ø5 centre circle (the monocular contour method), i.e. 1.8 and 2.6 centre radii. Element k
    (bit n-1-k) spans angle_deg + k*360/n .. + (k+1)*360/n, angles clockwise in the image (OpenCV's).
    H (3x3) optionally maps the drawn (low-resolution) pixel positions to image pixels.
    """
    h, w = shape
    canvas = np.full((h * UP, w * UP), high, np.uint8)
    c = tuple(int(round(((v + 0.5) * UP - 0.5) * 2 ** SHIFT)) for v in centre_px)
    rc, ri, ro = (int(round(f * r_centre_px * UP * 2 ** SHIFT)) for f in (1.0, 1.8, 2.6))
    step = 360.0 / bits
    for k in range(bits):
        if (code_bits >> (bits - 1 - k)) & 1:
            cv2.ellipse(canvas, c, (ro, ro), 0, angle_deg + k * step, angle_deg + (k + 1) * step, int(low), -1,
                        cv2.LINE_AA, SHIFT)
    cv2.circle(canvas, c, ri, int(high), -1, cv2.LINE_AA, SHIFT)
    cv2.circle(canvas, c, rc, int(low), -1, cv2.LINE_AA, SHIFT)
    img = canvas.astype(np.float32)
    if H is not None:
        S = np.array([[UP, 0, (UP - 1) / 2], [0, UP, (UP - 1) / 2], [0, 0, 1.0]])
        img = cv2.warpPerspective(img, S @ H @ np.linalg.inv(S), (w * UP, h * UP), flags=cv2.INTER_LINEAR,
                                  borderValue=float(high))
    img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    if noise > 0:
        img = img + rng.normal(0.0, noise, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def test_patent_example_decodes_to_199():
    # printed segments of 3 and 2 elements, centroid angles 195 and 165 degrees -> gaps 4 and 3
    assert decode_from_segments([3, 2], [195, 165]) == 199
    assert format(199, "012b") == "000011000111"
    assert canonical_code(0b111000011000) == 199


def test_patent_example_rendered_mark_decodes_to_199():
    rng = np.random.default_rng(0)
    img = draw_mark((90, 90), (44.6, 45.2), 0b111000011000, 12.0, angle_deg=37.0, rng=rng)
    (m,) = detect_markers(img)
    assert m.code == 199 and m.bits == "000011000111"


def test_decode_from_segments_rejects_inconsistent_input():
    with pytest.raises(ValueError, match="one gap angle per segment"):
        decode_from_segments([3, 2], [195])
    with pytest.raises(ValueError, match="add up to"):
        decode_from_segments([3, 2], [180, 180])


def test_canonical_code_equals_the_smallest_rotation_also_when_cached():
    values = np.arange(1 << 12)
    rotations = np.stack([((values << k) | (values >> (12 - k))) & 0xFFF for k in range(12)])
    truth = rotations.min(axis=0)
    for _ in range(2):  # the second pass answers from the cache
        assert [canonical_code(int(v)) for v in values] == truth.tolist()


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), blur=st.floats(0.5, 6.0), level=st.floats(0.4, 0.6))
def test_outline_bounds_the_pixel_count_of_a_component(seed, blur, level):
    # the blob search skips a component whose outline area + half its perimeter + 1 is under the
    # smallest blob area: that sum must never be below the component's pixel count
    rng = np.random.default_rng(seed)
    mask = (cv2.GaussianBlur(rng.random((120, 120)), (0, 0), blur) > level).astype(np.uint8)
    contours, hier = cv2.findContours(mask, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_SIMPLE)
    _, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
    for i in (np.flatnonzero(hier[0][:, 3] < 0) if hier is not None else []):
        c = contours[i]
        x, y = c[0, 0]
        pixels = stats[labels[y, x], cv2.CC_STAT_AREA]
        assert pixels <= cv2.contourArea(c) + 0.5 * cv2.arcLength(c, True) + 1.0


def test_canonical_code_is_min_rotation():
    assert canonical_code(0b100000000000) == 1
    assert canonical_code(0b101, n=3) == 0b011
    with pytest.raises(ValueError, match="bits_value"):
        canonical_code(4096)


@pytest.mark.parametrize("low,high", [(30, 220), (220, 30)])
def test_decode_rate_and_centre_rms_independent_renderer(low, high):
    rng = np.random.default_rng(21 if low < high else 22)
    err = []
    for _ in range(50):
        code = int(rng.choice(CLASSES))
        r = rng.uniform(5, 22)
        size = int(2 * 2.6 * r + 24)
        c = (size / 2 + rng.uniform(-3, 3), size / 2 + rng.uniform(-3, 3))
        img = draw_mark((size, size), c, code, r, angle_deg=rng.uniform(0, 360), low=low, high=high,
                        blur_px=rng.uniform(0.5, 1.0), noise=2.0, rng=rng)
        found = detect_markers(img)
        assert [m.code for m in found] == [code]
        err.append((found[0].x_px - c[0], found[0].y_px - c[1]))
        assert found[0].radius_px == pytest.approx(r, rel=0.02)
    assert float(np.sqrt(np.mean(np.square(err)))) < 0.01


def _ellipse_centre(H, c, r):
    """Centre of the image (under homography H) of the circle of radius r about c."""
    C = np.array([[1, 0, -c[0]], [0, 1, -c[1]], [-c[0], -c[1], c[0] ** 2 + c[1] ** 2 - r * r]])
    Hi = np.linalg.inv(H)
    Cp = Hi.T @ C @ Hi
    return np.linalg.solve(Cp[:2, :2], -Cp[:2, 2])


def test_mild_perspective_decodes_and_centres_on_the_ellipse():
    rng = np.random.default_rng(31)
    err, bias = [], []
    for _ in range(15):
        code = int(rng.choice(CLASSES))
        r = rng.uniform(9, 20)
        size = int(2 * 2.6 * r * 1.3 + 30)
        c = (size / 2, size / 2)
        T = np.array([[1, 0, -c[0]], [0, 1, -c[1]], [0, 0, 1.0]])
        th, k = rng.uniform(0, 2 * np.pi), rng.uniform(0.1, 0.3) / size
        A = np.array([[1 + rng.uniform(-.1, .1), rng.uniform(-.1, .1), 0],
                      [rng.uniform(-.1, .1), 1 + rng.uniform(-.1, .1), 0], [k * np.cos(th), k * np.sin(th), 1]])
        H = np.linalg.inv(T) @ A @ T
        img = draw_mark((size, size), c, code, r, angle_deg=rng.uniform(0, 360), H=H, noise=2.0, rng=rng)
        found = detect_markers(img)
        assert [m.code for m in found] == [code]
        e = _ellipse_centre(H, c, r)
        p = H @ np.array([c[0], c[1], 1.0])
        err.append((found[0].x_px - e[0], found[0].y_px - e[1]))
        bias.append(np.hypot(*(e - p[:2] / p[2])))
    # the locator returns the centre of the imaged ellipse ...
    assert float(np.sqrt(np.mean(np.square(err)))) < 0.01
    # ... which is not the projected centre of the circle (documented perspective bias)
    assert max(bias) > 0.02


def test_no_wrong_code_when_cut_by_the_border():
    rng = np.random.default_rng(41)
    decoded = 0
    for i in range(100):
        code = int(rng.choice(CLASSES))
        r = rng.uniform(5, 20)
        size = int(2 * 2.6 * r + 30)
        cut = rng.uniform(0.2, 2.5) * r  # centre's distance from one border: the ring (2.6 r) is cut
        c = [size / 2, size / 2]
        c[i % 2] = cut if (i // 2) % 2 else size - 1 - cut
        img = draw_mark((size, size), c, code, r, angle_deg=rng.uniform(0, 360), low=30 if i % 3 else 220,
                        high=220 if i % 3 else 30, blur_px=rng.uniform(0.5, 1.2), noise=2.0, rng=rng)
        found = detect_markers(img)
        assert all(m.code == code for m in found)
        decoded += len(found)
    assert decoded == 0  # every one of these rings leaves the image: dropped


def test_board_rendered_by_project_renderer_rotated():
    board = make_board()
    rng = np.random.default_rng(51)
    H = similarity_plane_to_image(0.1, 14.0, (110.0, 40.0))
    img = render_pattern(board_coverage(board), (480, 640), homography_image_to_plane(H), blur_px=0.8,
                         noise_sigma=2.0, rng=rng)
    found = detect_markers(img)
    visible = 0
    for r in range(board.rows):
        for c in range(board.cols):
            p = H @ np.array([*board.mark_mm(r, c), 1.0])
            ro = 6.5 / 0.1 + 2
            visible += bool(ro <= p[0] <= 639 - ro and ro <= p[1] <= 479 - ro)
    assert visible >= 6 and len(found) == visible
    matches = match_to_board(board, found)
    assert len(matches) == visible
    for mt in matches:
        p = H @ np.array([*board.mark_mm(mt.row, mt.col), 1.0])
        assert np.hypot(mt.x_px - p[0], mt.y_px - p[1]) < 0.03


def test_blank_and_noise_images_give_nothing():
    rng = np.random.default_rng(61)
    assert detect_markers(np.full((100, 100), 128, np.uint8)) == []
    assert detect_markers(np.clip(rng.normal(128, 20, (200, 200)), 0, 255).astype(np.uint8)) == []
    # a plain disk without a ring is not a mark
    ys, xs = np.mgrid[0:100, 0:100]
    disk = np.where((xs - 50) ** 2 + (ys - 50) ** 2 < 100, 30, 220).astype(np.uint8)
    assert detect_markers(disk) == []


def test_other_bit_counts():
    rng = np.random.default_rng(71)
    img = draw_mark((100, 100), (50.3, 49.8), 0b10110010, 12.0, bits=8, angle_deg=11.0, rng=rng)
    (m,) = detect_markers(img, bits=8)
    assert m.code == canonical_code(0b10110010, 8)


@settings(max_examples=6, deadline=None, database=None, derandomize=True)
@given(dx=st.floats(-1.0, 1.0), dy=st.floats(-1.0, 1.0), angle=st.floats(0.0, 360.0))
def test_subpixel_shift_of_a_mark_moves_its_centre_by_the_same_amount(dx, dy, angle):
    cov = ring_mark_coverage((0.0, 0.0), 0b110001110000, angle_deg=angle)

    def centre(offset):
        H = similarity_plane_to_image(0.25, 0.0, offset)  # centre circle radius 10 px
        img = render_pattern(cov, (80, 80), homography_image_to_plane(H), blur_px=0.8, supersample=16)
        (m,) = detect_markers(img)
        assert m.code == 199
        return np.array([m.x_px, m.y_px])

    moved = centre((40.2 + dx, 39.7 + dy)) - centre((40.2, 39.7))
    # noise-free 8-bit images: grey-level rounding alone moves each centre by up to ~0.003 px
    assert moved == pytest.approx([dx, dy], abs=6e-3)


def test_image_types_give_the_same_marks():
    rng = np.random.default_rng(81)
    img = draw_mark((90, 90), (44.6, 45.2), 0b111000011000, 12.0, angle_deg=37.0, rng=rng)
    ref = detect_markers(img)
    assert [m.code for m in ref] == [199]
    for other in (img / 255.0, img.astype(np.uint16) * 257, np.dstack([img] * 3)):
        (m,) = detect_markers(other)
        assert m.code == 199
        assert (m.x_px, m.y_px) == pytest.approx((ref[0].x_px, ref[0].y_px), abs=1e-3)
