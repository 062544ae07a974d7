"""Rendered image sequences end to end: library, video source and ``kinid contour``."""
import csv
import json

import numpy as np
import pytest

from kinid.cli import main
from kinid.errors import DataError
from kinid.stages.contour.frames import open_frames
from kinid.stages.contour.measure import measure_contour
from kinid.stages.contour.paths import CirclePath, contour_error
from kinid.stages.contour.simulate import circle_motion, render_sequence, simulation_camera
from kinid.stages.contour.track import FrameSettings
from kinid.vision.board import make_board, save_board
from kinid.vision.camera import save_camera

# 512 x 512 frames, 30 um object-side pixel (15.4 mm field), a fine board (6 mm pitch) so that 2-6 marks are in view
SIZE, PIXEL_MM, RADIUS_MM, N = (512, 512), 0.03, 8.0, 24
BOARD = make_board(rows=10, cols=10, pitch_mm=6.0, center_d_mm=2.0, ring_inner_d_mm=3.6, ring_outer_d_mm=5.2)
BLANK = 5


@pytest.fixture(scope="module")
def seq(tmp_path_factory):
    root = tmp_path_factory.mktemp("contour")
    frames = root / "frames"
    frames.mkdir()
    cam = simulation_camera(SIZE, PIXEL_MM, k1=-0.08)
    motion = circle_motion(N, RADIUS_MM, fps=80.0, lag_deg=0.03, spike_um=6.0, spike_width_deg=20.0,
                           scale_x_ppm=150.0)
    s = render_sequence(frames, BOARD, cam, motion, blank_frames=(BLANK,), noise_sigma=2.0,
                        rng=np.random.default_rng(11))
    save_board(BOARD, root / "board.json")
    save_camera(cam, root / "camera.json")
    return root, cam, s


def _ref_out_of_view(s):
    p = np.asarray(s.reference_start_mm) + s.track_mm
    half = SIZE[0] * PIXEL_MM / 2 - BOARD.ring_outer_d_mm / 2
    return np.any(np.abs(p) > half, axis=1)


def test_track_and_contour_error_match_the_truth_after_the_reference_left_the_view(seq):
    root, cam, s = seq
    m = measure_contour(root / "frames", BOARD, FrameSettings(camera=cam), workers=1)
    tr = m.track
    assert tr.not_located == (BLANK,)
    ok = tr.located
    assert tr.reference_rc == s.reference_rc
    gone = _ref_out_of_view(s) & ok
    assert gone.sum() >= N // 3
    err_um = (tr.xy_mm - s.track_mm) * 1e3
    assert np.sqrt(np.mean(np.sum(err_um[ok] ** 2, axis=1))) < 0.5
    assert np.sqrt(np.mean(np.sum(err_um[gone] ** 2, axis=1))) < 0.5
    assert tr.angle_deg == pytest.approx(s.board_angle_deg, abs=2e-3)
    assert 1e3 / tr.scale == pytest.approx(PIXEL_MM * 1e3, rel=1e-4)  # ideal pixel, um
    truth = contour_error(s.track_mm, CirclePath())
    de = (m.contour.error_um - truth.error_um)[ok]
    assert np.sqrt(np.mean(de ** 2)) < 0.5
    assert truth.max_um > 4.0  # the simulated errors are far above the accuracy checked
    assert np.isnan(m.contour.error_um[BLANK])
    assert len(m.t_s) == N and np.isnan(m.t_s).all()  # a folder carries no frame rate


def test_pixel_mm_mode_and_video_source_agree(seq, tmp_path):
    import cv2

    root, cam, s = seq
    video = tmp_path / "seq.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), 80.0, SIZE, False)
    assert writer.isOpened()
    for p in s.paths:
        writer.write(cv2.imread(p, cv2.IMREAD_GRAYSCALE))
    writer.release()
    source = open_frames(video)
    assert source.kind == "video" and source.fps == pytest.approx(80.0)
    settings = FrameSettings(pixel_mm=PIXEL_MM)
    from_video = measure_contour(source, BOARD, settings, workers=2)
    from_folder = measure_contour(root / "frames", BOARD, settings, workers=1)
    np.testing.assert_array_equal(from_video.track.xy_mm, from_folder.track.xy_mm)
    np.testing.assert_allclose(from_video.t_s, np.arange(N) / 80.0)
    ok = from_video.track.located
    err_um = (from_video.track.xy_mm - s.track_mm)[ok] * 1e3
    assert np.sqrt(np.mean(np.sum(err_um ** 2, axis=1))) < 0.5


def test_cli_json_csv_plot(seq, tmp_path, capsys):
    root, cam, s = seq
    out, png = tmp_path / "track.csv", tmp_path / "polar.png"
    status = main(["contour", "--data", str(root / "frames"), "--board", str(root / "board.json"), "--camera",
                   str(root / "camera.json"), "--path", "circle", "--fps", "80", "--out", str(out), "--json",
                   "--plot", str(png)])
    assert status == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)
    assert list(summary) == ["frames", "located", "rms_error_um", "max_error_um"]
    assert summary["frames"] == N and summary["located"] == N - 1
    assert "1 of 24 frame(s) not located" in captured.err
    assert ": 5 (frame 5: no ring-coded mark decoded)" in captured.err
    rows = list(csv.reader(out.read_text().splitlines()))
    assert rows[0] == ["frame", "t_s", "x_mm", "y_mm", "error_um"]
    assert len(rows) == N + 1
    assert rows[1 + BLANK] == [str(BLANK), f"{BLANK / 80:.6f}", "", "", ""]
    data = np.array([[float(v) for v in r] for i, r in enumerate(rows[1:]) if i != BLANK])
    keep = np.arange(N) != BLANK
    assert np.abs(data[:, 2:4] - s.track_mm[keep]).max() < 1.5e-3
    err = data[:, 4]
    assert summary["rms_error_um"] == pytest.approx(np.sqrt(np.mean(err ** 2)), abs=1e-3)
    assert summary["max_error_um"] == pytest.approx(np.max(np.abs(err)), abs=1e-3)
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_report_and_polyline_path(seq, tmp_path, capsys):
    root, cam, s = seq
    # the programmed circle as a fine polygon, in track coordinates (relative to the first actual position)
    m = s.motion
    centre = np.array([0.0, 0.0]) - m.xy_mm[0]
    phi = np.linspace(0, 2 * np.pi, 1441)
    poly = tmp_path / "path.csv"
    poly.write_text("x_mm,y_mm\n" + "\n".join(f"{centre[0] + RADIUS_MM * np.cos(a):.9f},"
                                               f"{centre[1] + RADIUS_MM * np.sin(a):.9f}" for a in phi) + "\n")
    out = tmp_path / "track.csv"
    status = main(["contour", "--data", str(root / "frames"), "--board", str(root / "board.json"), "--pixel-um",
                   str(PIXEL_MM * 1e3), "--path", "polyline", "--path-file", str(poly), "--out", str(out)])
    assert status == 0
    text = capsys.readouterr().out
    assert "located 23" in text and "contour error" in text
    rows = [r for r in csv.DictReader(out.read_text().splitlines()) if r["x_mm"]]
    xy = np.array([[float(r["x_mm"]), float(r["y_mm"])] for r in rows])
    err = np.array([float(r["error_um"]) for r in rows])
    # travel with the angle increasing (clockwise as seen): the right-hand side is inside
    radial_um = (np.hypot(*(xy - centre).T) - RADIUS_MM) * 1e3
    np.testing.assert_allclose(err, -radial_um, atol=0.1)


@pytest.mark.parametrize("args, message", [
    (["--board", "BAD"], "board.json: codes: missing"),
    (["--data", "EMPTY"], "no image files"),
    (["--centre", "1;2"], "--centre expects two numbers X,Y in mm, got '1;2'"),
    (["--path", "polyline"], "--path polyline needs --path-file"),
    (["--pixel-um", "-30"], "--pixel-um must be a positive number"),
])
def test_cli_bad_input_exits_2_with_one_line(seq, tmp_path, capsys, args, message):
    root, cam, s = seq
    bad = tmp_path / "board.json"
    bad.write_text(json.dumps({k: v for k, v in json.loads((root / "board.json").read_text()).items()
                               if k != "codes"}))
    empty = tmp_path / "empty"
    empty.mkdir()
    opts = {"--data": str(root / "frames"), "--board": str(root / "board.json"), "--pixel-um": str(PIXEL_MM * 1e3),
            "--out": str(tmp_path / "t.csv")}
    extra = []
    for k, v in zip(args[::2], args[1::2]):
        v = {"BAD": str(bad), "EMPTY": str(empty)}.get(v, v)
        if k in opts:
            opts[k] = v
        else:
            extra += [k, v]
    argv = ["contour"] + [x for kv in opts.items() for x in kv] + extra
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("kinid contour: ")
    assert not (tmp_path / "t.csv").exists()


def test_downsampled_and_windowed_decoding_stay_within_accuracy(seq):
    root, cam, s = seq
    for settings in (FrameSettings(camera=cam, downsample=2), FrameSettings(camera=cam, roi_px=(40, 40, 432, 432))):
        m = measure_contour(root / "frames", BOARD, settings, workers=1)
        ok = m.track.located
        assert ok.sum() >= N - 2
        err_um = (m.track.xy_mm - s.track_mm)[ok] * 1e3
        assert np.sqrt(np.mean(np.sum(err_um ** 2, axis=1))) < 0.5
    with pytest.raises(DataError, match="downsample must be an integer >= 1, got 0"):
        FrameSettings(pixel_mm=PIXEL_MM, downsample=0)


def test_auto_downsample_keeps_the_centre_circle_above_20_px(seq):
    from kinid.stages.contour.frames import open_frames
    from kinid.stages.contour.measure import choose_downsample

    root, cam, s = seq
    source = open_frames(root / "frames")
    # this board's centre circle is 2 mm: (1 mm / PIXEL_MM) px in radius
    radius_px = BOARD.center_d_mm / 2 / PIXEL_MM
    assert choose_downsample(source, BOARD, FrameSettings(camera=cam)) == max(1, min(2, int(radius_px // 20)))
    # the patent board (5 mm centre circle): radius ~83 px at 30 µm -> 2; 25 px at 100 µm -> 1
    patent = make_board()
    assert choose_downsample(source, patent, FrameSettings(pixel_mm=0.03), probe_frames=0) == 2
    assert choose_downsample(source, patent, FrameSettings(pixel_mm=0.1), probe_frames=0) == 1
    m = measure_contour(root / "frames", BOARD, FrameSettings(camera=cam, downsample=None), workers=1)
    ok = m.track.located
    err_um = (m.track.xy_mm - s.track_mm)[ok] * 1e3
    assert np.sqrt(np.mean(np.sum(err_um ** 2, axis=1))) < 0.5
