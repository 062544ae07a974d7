"""Frame sources and the ordered, bounded process-pool map."""
import pickle

import cv2
import numpy as np
import pytest

from kinid.errors import DataError
from kinid.stages.contour.frames import map_frames, open_frames
from kinid.stages.contour.simulate import simulation_camera
from kinid.stages.contour.track import FrameSettings, process_frame
from kinid.vision.board import make_board

BOARD = make_board(rows=4, cols=4)
SETTINGS = FrameSettings(pixel_mm=0.02)


def test_folder_in_name_order_and_unreadable_frames_reported(tmp_path):
    for k in (10, 2, 1):
        cv2.imwrite(str(tmp_path / f"f{k:02d}.png"), np.full((8, 20 + k), 200, np.uint8))
    (tmp_path / "notes.txt").write_text("not a frame")
    (tmp_path / "f99.png").write_bytes(b"garbage")
    src = open_frames(tmp_path)
    assert src.kind == "folder" and src.count == 4 and src.fps is None
    assert [p.rsplit("/", 1)[1] for p in src.files] == ["f01.png", "f02.png", "f10.png", "f99.png"]
    res = list(map_frames(src, BOARD, SETTINGS, workers=1))
    assert [r.image_size for r in res[:3]] == [(21, 8), (22, 8), (30, 8)]
    assert [r.n for r in res] == [0, 0, 0, 0]
    assert res[0].reason == "no ring-coded mark decoded"
    assert res[3].reason.startswith("cannot read image") and res[3].reason.endswith("f99.png")


def test_pool_keeps_order_and_bounds_frames_in_flight():
    consumed = []
    yielded = []

    def frames():
        for k in range(12):
            consumed.append(k)
            assert len(consumed) - len(yielded) <= (2 * 2 + 1) * 3  # (2 x workers + 1) batches of 3
            yield np.full((6, 10 + k), 100, np.uint8)

    for r in map_frames(frames(), BOARD, SETTINGS, workers=2, batch=3):
        yielded.append(r.image_size[0])
    assert yielded == [10 + k for k in range(12)]


def test_process_frame_inputs_are_picklable_and_pure():
    settings = FrameSettings(camera=simulation_camera((64, 64), 0.03), bits=BOARD.bits)
    clone_board, clone_settings = pickle.loads(pickle.dumps((BOARD, settings)))
    assert clone_board == BOARD
    img = np.full((64, 64), 90, np.uint8)
    a = process_frame(img, BOARD, settings)
    b = process_frame(img, clone_board, clone_settings)
    assert a.n == b.n == 0 and a.reason == b.reason
    assert pickle.loads(pickle.dumps(a)).image_size == (64, 64)


def test_bad_sources(tmp_path):
    with pytest.raises(DataError, match="frames folder or video file does not exist"):
        open_frames(tmp_path / "nope")
    (tmp_path / "empty").mkdir()
    with pytest.raises(DataError, match=r"empty: no image files \(\.png"):
        open_frames(tmp_path / "empty")
    (tmp_path / "x.avi").write_text("not a video")
    with pytest.raises(DataError, match="cannot open as a video file"):
        open_frames(tmp_path / "x.avi")
    with pytest.raises(DataError, match="workers must be >= 1, got 0"):
        list(map_frames([], BOARD, SETTINGS, workers=0))
    with pytest.raises(DataError, match="batch must be >= 1, got 0"):
        list(map_frames([], BOARD, SETTINGS, batch=0))


def _descendants(pid: int) -> set:
    """Every process below ``pid`` (from /proc), children of children included."""
    import os

    parents = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    parents[int(entry)] = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                pass
    found, frontier = set(), {pid}
    while frontier:
        frontier = {p for p, pp in parents.items() if pp in frontier} - found
        found |= frontier
    return found


@pytest.mark.skipif(not __import__("os").path.isdir("/proc"), reason="needs /proc to find the worker processes")
def test_worker_processes_end_when_kinid_is_killed(tmp_path):
    """``kinid contour --workers 2`` killed with SIGKILL (it cannot shut its pool down): its fork server, workers
    and resource tracker are gone within seconds, not left running."""
    import os
    import signal
    import subprocess
    import sys
    import time

    from kinid.cli import main

    assert main(["contour", "--simulate", "--sim-frames", "120", "--workers", "1", "--keep", str(tmp_path / "run")]) == 0
    run = tmp_path / "run"
    p = subprocess.Popen([sys.executable, "-m", "kinid", "contour", "--data", str(run / "frames"), "--board",
                          str(run / "board.json"), "--camera", str(run / "camera.json"), "--out",
                          str(tmp_path / "t.csv"), "--workers", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline, helpers = time.monotonic() + 60, set()
    while len(helpers) < 3 and time.monotonic() < deadline and p.poll() is None:  # workers and their fork server
        time.sleep(0.1)
        helpers = _descendants(p.pid)
    assert len(helpers) >= 3 and p.poll() is None, (helpers, p.poll())
    p.send_signal(signal.SIGKILL)
    p.wait(timeout=30)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline and any(os.path.exists(f"/proc/{h}") for h in helpers):
        time.sleep(0.2)
    alive = [h for h in helpers if os.path.exists(f"/proc/{h}")]
    for h in alive:  # do not leave them to the next test
        os.kill(h, signal.SIGKILL)
    assert not alive, f"{len(alive)} of {len(helpers)} helper processes still running 15 s after the kill"
