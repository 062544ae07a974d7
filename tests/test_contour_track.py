"""Joint rotation/scale + per-frame translation: the reference mark's track from synthetic detections."""
import math
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from kinid.errors import DataError
from kinid.stages.contour.simulate import circle_motion, simulation_camera
from kinid.stages.contour.track import FrameResult, FrameSettings, TrackBuilder, consistent_marks, estimate_track
from kinid.vision.board import make_board

BOARD = make_board()  # the patent's board: 14 x 14 marks, 16 mm pitch
PIXEL_MM = 0.025
SIZE = (1600, 1600)  # 40 mm field: one to four whole marks in view


def detections(track_mm, *, angle_deg=0.8, scale=1.0, noise_mm=0.0, rng=None, blank=(), start_mm=(-104.6, -95.3),
               field_mm=40.0, margin_mm=6.5):
    """Per-frame FrameResults of marks whose ring lies inside the field (plane coordinates = px * PIXEL_MM).

    ``start_mm``: board origin in the camera frame (mm from the image centre) in frame 0.
    """
    c = scale * complex(math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg)))
    rows, cols = np.mgrid[0:BOARD.rows, 0:BOARD.cols]
    b = (cols.ravel() + 1j * rows.ravel()) * BOARD.pitch_mm
    codes = np.asarray(BOARD.codes).ravel()
    centre_px = complex((SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2)
    out = []
    for k, d in enumerate(np.asarray(track_mm)):
        t = complex(*start_mm) + complex(*d)
        z = c * b + scale * t  # mm from the image centre (scale: error of the nominal pixel size)
        half = field_mm / 2 - margin_mm
        sel = (np.abs(z.real) < half) & (np.abs(z.imag) < half)
        if k in blank or not sel.any():
            e = np.zeros((0, 2))
            out.append(FrameResult(0, SIZE, (), e, e, e, "no ring-coded mark decoded"))
            continue
        zs = z[sel]
        if noise_mm:
            zs = zs + rng.normal(0, noise_mm, zs.size) + 1j * rng.normal(0, noise_mm, zs.size)
        px = zs / PIXEL_MM + centre_px
        pixels = np.column_stack([px.real, px.imag])
        out.append(FrameResult(int(sel.sum()), SIZE, tuple(int(v) for v in codes[sel]),
                               np.column_stack([b[sel].real, b[sel].imag]), pixels * PIXEL_MM, pixels))
    return out


def truth_track(n=60, radius=50.0):
    m = circle_motion(n, radius, lag_deg=0.05, spike_um=8.0, scale_x_ppm=60.0)
    return m.xy_mm - m.xy_mm[0]


def test_exact_recovery_without_noise_including_after_the_reference_left_the_view():
    truth = truth_track()
    res = detections(truth)
    track = estimate_track(res, BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    assert track.located.all()
    np.testing.assert_allclose(track.xy_mm, truth, atol=1e-9)
    assert track.angle_deg == pytest.approx(0.8, abs=1e-9)
    assert track.scale == pytest.approx(1.0, abs=1e-12)
    # reference: the mark nearest the image centre in frame 0; later frames do not show it
    ref_code = BOARD.codes[track.reference_rc[0]][track.reference_rc[1]]
    assert track.reference_code == ref_code
    first = res[0]
    d = np.hypot(first.pixels[:, 0] - (SIZE[0] - 1) / 2, first.pixels[:, 1] - (SIZE[1] - 1) / 2)
    assert first.codes[int(np.argmin(d))] == ref_code
    gone = [k for k, r in enumerate(res) if ref_code not in r.codes]
    assert len(gone) > len(res) // 2
    assert min(track.n_marks) >= 1 and max(track.n_marks) >= 2


def test_noise_stays_within_the_reported_sigma():
    truth = truth_track()
    rng = np.random.default_rng(7)
    noise_mm = 0.2e-3  # 0.2 um per coordinate (0.008 px at 25 um pixels)
    track = estimate_track(detections(truth, noise_mm=noise_mm, rng=rng), BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    err_um = (track.xy_mm - truth) * 1e3
    assert track.residual_rms == pytest.approx(noise_mm, rel=0.3)
    z = (err_um / track.sigma_um[:, None])[1:]
    assert 0.4 < np.sqrt(np.mean(z ** 2)) < 1.6
    assert np.sqrt(np.mean(np.sum(err_um ** 2, axis=1))) < 0.5


def test_scale_comes_from_the_board_not_the_nominal_pixel():
    truth = truth_track(n=30)
    with pytest.warns(UserWarning, match=r"pixel size \+3\.00% different from --pixel-um"):
        track = estimate_track(detections(truth, scale=1.03), BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    np.testing.assert_allclose(track.xy_mm, truth, atol=1e-9)
    assert track.scale == pytest.approx(1.03)


def test_frames_without_marks_are_reported_not_dropped():
    truth = truth_track(n=30)
    track = estimate_track(detections(truth, blank=(0, 4, 5)), BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    assert track.not_located == (0, 4, 5)
    assert track.reasons[4] == "no ring-coded mark decoded"
    assert len(track.located) == 30 and np.isnan(track.xy_mm[[0, 4, 5]]).all()
    # relative to the first located frame
    np.testing.assert_allclose(track.xy_mm[1:4], truth[1:4] - truth[1], atol=1e-9)
    np.testing.assert_allclose(track.xy_mm[6:], truth[6:] - truth[1], atol=1e-9)


def test_no_frame_located_is_an_error():
    with pytest.raises(DataError, match="no frame located: none of the 3 frames"):
        estimate_track(detections(truth_track(n=3), blank=(0, 1, 2)), BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    with pytest.raises(DataError, match="no frames to process"):
        TrackBuilder(BOARD, FrameSettings(pixel_mm=PIXEL_MM)).finish()


def test_one_mark_per_frame_needs_the_board_aligned():
    truth = truth_track(n=20, radius=30.0)
    res = detections(truth, angle_deg=0.0, field_mm=20.0, start_mm=(-96.0, -96.0))
    assert max(r.n for r in res) == 1
    with pytest.warns(UserWarning, match="no frame shows two marks"):
        track = estimate_track(res, BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    np.testing.assert_allclose(track.xy_mm[track.located], truth[track.located], atol=1e-9)
    with pytest.raises(DataError, match="no frame shows two marks of the board"):
        estimate_track(res, BOARD, FrameSettings(camera=simulation_camera(SIZE, PIXEL_MM)))


def test_settings_are_validated():
    with pytest.raises(DataError, match="exactly one of pixel_mm and camera"):
        FrameSettings()
    with pytest.raises(DataError, match="pixel_mm must be a positive number of mm per pixel, got -1"):
        FrameSettings(pixel_mm=-1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        FrameSettings(pixel_mm=0.02, refine="centroid", roi_px=(0, 0, 10, 10))


@settings(max_examples=25, deadline=None)
@given(angle=st.floats(-3.0, 3.0), scale=st.floats(0.97, 1.03), sx=st.floats(-3.0, 3.0), sy=st.floats(-3.0, 3.0))
def test_any_board_rotation_scale_and_placement_is_recovered_exactly(angle, scale, sx, sy):
    truth = truth_track(n=16, radius=30.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the scale warning
        track = estimate_track(detections(truth, angle_deg=angle, scale=scale, start_mm=(-104.6 + sx, -95.3 + sy)),
                               BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    ok = track.located
    k0 = int(np.argmax(ok))
    np.testing.assert_allclose(track.xy_mm[ok], truth[ok] - truth[k0], atol=1e-8)
    assert track.angle_deg == pytest.approx(angle, abs=1e-8)
    assert track.scale == pytest.approx(scale, rel=1e-10)


def test_camera_of_another_image_size_is_questioned():
    res = detections(truth_track(n=6))
    with pytest.warns(UserWarning, match="frames are 1600 x 1600 px but the camera was calibrated at 768 x 768 px"):
        estimate_track(res, BOARD, FrameSettings(camera=simulation_camera((768, 768), PIXEL_MM)))


def test_a_mark_off_its_place_is_dropped_within_a_frame():
    b = np.array([[0, 0], [16, 0], [0, 16], [16, 16], [32, 16]], float)
    a = 0.9 * np.exp(1j * 0.3)
    z = a * (b[:, 0] + 1j * b[:, 1]) + (5 - 3j)
    plane = np.column_stack([z.real, z.imag])
    assert consistent_marks(b, plane, 0.02).all()
    plane[3, 1] += 0.05
    np.testing.assert_array_equal(consistent_marks(b, plane, 0.02), [True, True, True, False, True])
    assert consistent_marks(b[:2], plane[:2] + [[0, 0], [0, 1.0]], 0.02).all()  # two marks: cannot tell


def test_a_frame_whose_marks_disagree_with_the_sequence_is_reported():
    truth = truth_track(n=30)
    res = detections(truth)
    k = next(i for i, r in enumerate(res) if r.n >= 2 and i > 0)
    r = res[k]
    plane = r.plane.copy()
    plane[0] += 0.1  # 0.1 mm = 4 px off: a partly hidden mark
    res[k] = FrameResult(r.n, r.image_size, r.codes, r.board_mm, plane, r.pixels)
    track = estimate_track(res, BOARD, FrameSettings(pixel_mm=PIXEL_MM))
    assert track.not_located == (k,)
    assert "marks disagree with the board's layout by" in track.reasons[k]
    ok = track.located
    np.testing.assert_allclose(track.xy_mm[ok], truth[ok], atol=1e-9)
