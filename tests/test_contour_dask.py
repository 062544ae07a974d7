"""``kinid contour --scheduler``: frames mapped on a local Dask cluster give the local pool's tracks, bit for bit."""
from __future__ import annotations

import csv

import numpy as np
import pytest

from kinid.cli import main
from kinid.stages.contour.measure import measure_contour
from kinid.stages.contour.simulate import circle_motion, render_sequence, simulation_camera
from kinid.stages.contour.track import FrameSettings
from kinid.vision.board import make_board, save_board

pytest.importorskip("dask.distributed")

SIZE, PIXEL_MM, N = (512, 512), 0.03, 12
BOARD = make_board(rows=10, cols=10, pitch_mm=6.0, center_d_mm=2.0, ring_inner_d_mm=3.6, ring_outer_d_mm=5.2)


@pytest.fixture(autouse=True)
def _no_connection_left_behind():
    """A scheduler that never answers leaves kinid's connecting thread running past its time-out: each test waits
    for it to give up before the next one starts a client (its failed client is closed in that thread)."""
    import threading

    yield
    for thread in threading.enumerate():
        if thread.name == "kinid-dask-connect":
            thread.join(60.0)


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    root = tmp_path_factory.mktemp("dask")
    (root / "frames").mkdir()
    cam = simulation_camera(SIZE, PIXEL_MM, k1=0.0)
    render_sequence(root / "frames", BOARD, cam, circle_motion(N, 4.0, fps=50.0), noise_sigma=2.0,
                    rng=np.random.default_rng(5))
    save_board(BOARD, root / "board.json")
    return root


def test_local_dask_cluster_gives_the_pools_tracks_bit_for_bit(frames):
    settings = FrameSettings(pixel_mm=PIXEL_MM, bits=BOARD.bits)
    pool = measure_contour(frames / "frames", BOARD, settings, workers=2)
    dask = measure_contour(frames / "frames", BOARD, settings, workers=2, scheduler="local")
    assert int(pool.track.located.sum()) == N
    assert np.array_equal(pool.track.xy_mm, dask.track.xy_mm)
    assert np.array_equal(pool.contour.error_um, dask.contour.error_um)


def test_contour_cli_with_scheduler(frames, tmp_path, capsys):
    args = ["contour", "--data", str(frames / "frames"), "--board", str(frames / "board.json"),
            "--pixel-um", str(PIXEL_MM * 1e3)]
    assert main([*args, "--out", str(tmp_path / "a.csv")]) == 0
    assert main([*args, "--out", str(tmp_path / "b.csv"), "--scheduler", "local"]) == 0
    assert (tmp_path / "a.csv").read_text() == (tmp_path / "b.csv").read_text()
    assert len(list(csv.reader(open(tmp_path / "b.csv")))) == N + 1


def test_unreachable_scheduler_is_one_line(frames, tmp_path, capsys):
    status = main(["contour", "--data", str(frames / "frames"), "--board", str(frames / "board.json"),
                   "--pixel-um", str(PIXEL_MM * 1e3), "--out", str(tmp_path / "a.csv"), "--scheduler", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert status == 2 and "cannot reach the Dask scheduler at 'tcp://127.0.0.1:9'" in err and err.count("\n") == 1, err


@pytest.mark.parametrize("kind", ["tls", "silent", "no workers"])
def test_a_scheduler_that_cannot_serve_is_one_line_within_the_time_out(frames, tmp_path, capsys, monkeypatch, kind):
    """A tls:// address without TLS settings, an address that accepts the connection and never answers (any TCP
    server), and a scheduler without a worker: each one line naming --scheduler, exit 2, within the time-out."""
    import socket
    import time

    import kinid.stages.contour.frames as frames_module

    monkeypatch.setattr(frames_module, "SCHEDULER_TIMEOUT_S", 2.0)
    cleanup = []
    if kind == "tls":
        address = "tls://127.0.0.1:9"
    elif kind == "silent":
        server = socket.socket()
        server.bind(("127.0.0.1", 0))
        server.listen(8)
        cleanup.append(server.close)
        address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    else:
        from dask.distributed import LocalCluster

        cluster = LocalCluster(n_workers=0, processes=False, dashboard_address=None)
        cleanup.append(lambda: cluster.close(timeout=10))  # bounded: once hung the whole suite under load
        address = cluster.scheduler_address
    try:
        started = time.monotonic()
        status = main(["contour", "--data", str(frames / "frames"), "--board", str(frames / "board.json"),
                       "--pixel-um", str(PIXEL_MM * 1e3), "--out", str(tmp_path / "a.csv"), "--scheduler", address])
        seconds = time.monotonic() - started
    finally:
        for close in cleanup:
            close()
    err = capsys.readouterr().err
    assert status == 2 and "--scheduler" in err and "cannot reach the Dask scheduler" in err, err
    assert len([line for line in err.splitlines() if line.strip()]) == 1, err
    assert seconds < 30 and not (tmp_path / "a.csv").exists()


def test_a_refused_connection_leaves_no_client_that_hangs_a_later_one():
    """A tls:// address without TLS settings makes Dask's client fail in its constructor; its finaliser closes it
    under a lock every client shares. Collected inside a later client's start (which holds that lock), it waited
    for the lock forever: the suite hung under load. Here the later start collects the garbage on purpose (as a
    collection at that moment would), in a process of its own, bounded in time."""
    import subprocess
    import sys

    script = """
import gc
import kinid.stages.contour.frames as frames
from dask.distributed import Client, LocalCluster
from distributed.utils import LoopRunner

gc.disable()  # the failed clients stay garbage until collected on purpose
for _ in range(2):
    try:
        frames._remote_client(Client, "tls://127.0.0.1:9")
    except TypeError:
        pass
start = LoopRunner._start_unlocked
def collecting_start(self):
    gc.collect()
    return start(self)
LoopRunner._start_unlocked = collecting_start
LocalCluster(n_workers=0, processes=False, dashboard_address=None).close(timeout=10)
print("started and closed")
"""
    try:
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("a local cluster after a refused connection hung")
    assert done.returncode == 0 and "started and closed" in done.stdout, done.stderr[-2000:]
