"""Streaming frame sources and an ordered, bounded 2-process map of :func:`process_frame`.

Frames come from a folder (image files in name order) or a video file (read
with ``cv2.VideoCapture``), one at a time. :func:`map_frames` keeps at most
``2 * workers`` batches of frames in flight, so memory stays flat however long the
sequence, and yields results in frame order.

For a folder the workers read the files themselves (only the path crosses the
process boundary); video frames are decoded in the parent and sent as arrays.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinid.errors import DataError, ImageError
from kinid.files import read_image

__all__ = ["IMAGE_SUFFIXES", "FrameSource", "open_frames", "map_frames", "map_frames_dask"]

#: File name endings read as frames from a folder (case-insensitive).
IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".bmp", ".jpg", ".jpeg", ".pgm", ".ppm", ".webp")


@dataclass(frozen=True)
class FrameSource:
    """A sequence of frames.

    Attributes
    ----------
    kind : {"folder", "video"}
    path : str
        The folder or video file.
    files : tuple of str
        Image files in name order (folder), empty for a video.
    count : int or None
        Number of frames (a video's count is the container's claim).
    fps : float or None
        The video container's frame rate (None for a folder).
    """

    kind: str
    path: str
    files: tuple
    count: int | None
    fps: float | None

    def __iter__(self):
        """Frames one at a time: for a folder the file paths, for a video grey uint8 arrays."""
        if self.kind == "folder":
            yield from self.files
            return
        import cv2

        cap = cv2.VideoCapture(self.path)
        try:
            while True:
                ok, frame = cap.read()
                if not ok:
                    break
                if frame.ndim == 3:
                    frame = cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)
                yield frame
        finally:
            cap.release()


def open_frames(path) -> FrameSource:
    """Open a folder of images or a video file.

    Raises
    ------
    DataError
        The path does not exist, the folder holds no image file, or the video
        cannot be opened.
    """
    p = Path(path)
    if p.is_dir():
        files = sorted(str(f) for f in p.iterdir() if f.is_file() and f.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise DataError(f"no image files ({', '.join(IMAGE_SUFFIXES)}) in the frames folder", path=p)
        return FrameSource("folder", str(p), tuple(files), len(files), None)
    if not p.exists():
        raise DataError("frames folder or video file does not exist", path=p)
    import cv2

    cap = cv2.VideoCapture(str(p))
    try:
        if not cap.isOpened():
            raise DataError("cannot open as a video file (expected a folder of images or a video)", path=p)
        count = int(cap.get(cv2.CAP_PROP_FRAME_COUNT))
        fps = float(cap.get(cv2.CAP_PROP_FPS))
    finally:
        cap.release()
    return FrameSource("video", str(p), (), count if count > 0 else None, fps if fps > 0 else None)


def _work(item, board, settings):
    """Worker: process one frame given as a file path or an array."""
    from .track import FrameResult, process_frame

    if isinstance(item, str):
        try:
            img = read_image(item)
        except ImageError as exc:
            empty = np.zeros((0, 2))
            return FrameResult(0, (0, 0), (), empty, empty, empty, f"cannot read image: {exc.message}: {item}")
    else:
        img = item
    return process_frame(img, board, settings)


_WORKER = {}
#: Modules the fork server imports once, so that worker start-up is quick.
_PRELOAD = ("numpy", "cv2", "scipy.special", "kinid.vision.board", "kinid.vision.ringcode", "kinid.stages.contour.track")


#: How often a worker looks whether the process that started it is still there, s.
PARENT_CHECK_S = 0.5


def _init_worker(board, settings, parent_pid=None):
    """Worker start-up: one OpenCV thread; board and settings sent once, not with every frame; the worker ends
    itself when ``parent_pid`` (the process that made the pool) is gone — killed, it cannot shut its pool down,
    and a worker of the fork server is not its child, so no signal would reach it."""
    import cv2

    cv2.setNumThreads(1)
    _WORKER["board"], _WORKER["settings"] = board, settings
    if parent_pid is not None:
        import threading

        threading.Thread(target=_end_with, args=(parent_pid,), daemon=True, name="kinid-parent-watch").start()


def _end_with(pid: int) -> None:
    import os
    import time

    while True:
        time.sleep(PARENT_CHECK_S)
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            os._exit(1)
        except OSError:  # alive, another user's (cannot happen for our parent, but never end a worker by mistake)
            pass


def _work_batch(items):
    return [_work(item, _WORKER["board"], _WORKER["settings"]) for item in items]


def _batches(source, size):
    batch = []
    for item in source:
        batch.append(item)
        if len(batch) == size:
            yield batch
            batch = []
    if batch:
        yield batch


def map_frames(source, board, settings, *, workers=2, batch=2, progress=None):
    """Process every frame of ``source`` in order; yields :class:`~stages.contour.track.FrameResult`.

    Parameters
    ----------
    source : FrameSource or iterable
        Frames (file paths or arrays) in time order.
    board : vision.board.Board
    settings : stages.contour.track.FrameSettings
    workers : int
        Worker processes (1: in this process, no pool).
    batch : int
        Frames per task sent to a worker (fewer round trips).
    progress : kinid.progress.Progress or None
        Updated once per frame.

    Yields
    ------
    FrameResult
        One per frame, in frame order. At most ``(2 * workers + 1) * batch``
        frames are held at any time.
    """
    workers, batch = int(workers), int(batch)
    if workers < 1:
        raise DataError(f"workers must be >= 1, got {workers}", column="workers")
    if batch < 1:
        raise DataError(f"batch must be >= 1, got {batch}", column="batch")
    if workers == 1:
        for item in source:
            r = _work(item, board, settings)
            if progress is not None:
                progress.update()
            yield r
        return
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    # not "fork": forking a parent whose OpenCV / BLAS thread pools are running can deadlock the child
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(_PRELOAD))  # workers fork from a server that has these imported
    pending = deque()
    with ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                             initargs=(board, settings, os.getpid())) as pool:
        try:
            for items in _batches(source, batch):
                pending.append(pool.submit(_work_batch, items))
                if len(pending) >= 2 * workers:
                    for r in pending.popleft().result():
                        if progress is not None:
                            progress.update()
                        yield r
            while pending:
                for r in pending.popleft().result():
                    if progress is not None:
                        progress.update()
                    yield r
        except BrokenProcessPool as exc:
            raise RuntimeError(
                "a frame worker process died before it started; a script that calls measure_contour or "
                "map_frames with workers > 1 must run it under `if __name__ == \"__main__\":` (worker "
                "processes re-import the main module), or pass workers=1"
            ) from exc
        finally:
            for f in pending:
                f.cancel()


def _work_batch_on(items, board, settings):
    """A Dask task: a batch of frames on a worker of a Dask cluster (one OpenCV thread, as the local pool)."""
    import cv2

    cv2.setNumThreads(1)
    return [_work(item, board, settings) for item in items]


#: Seconds to wait for a remote scheduler's answer, and for its first worker.
SCHEDULER_TIMEOUT_S = 20.0


def _remote_client(Client, scheduler):
    """A client of the scheduler at ``scheduler`` that has a worker, or TimeoutError within SCHEDULER_TIMEOUT_S each.

    Dask's own time-out covers the connection but not an address that accepts it and never answers (any TCP
    server), so the client is made in a daemon thread watched here; a scheduler without workers would take
    the frames and never return them."""
    import gc
    import threading

    box = {}

    def connect():
        try:
            box["client"] = Client(scheduler, timeout=f"{SCHEDULER_TIMEOUT_S:g}s")
        except BaseException as exc:  # handed to the caller's thread, without the frames of the failed client
            exc.__traceback__ = exc.__context__ = exc.__cause__ = None
            box["error"] = exc
            # the failed client's finaliser closes it under a lock every Dask client shares: run it here, where this
            # thread holds none. Left to a later garbage collection, it can run inside another client's start,
            # which holds that lock, and wait for it forever (seen in the tests, under load: every later use of
            # Dask in the process hung)
            gc.collect()

    thread = threading.Thread(target=connect, name="kinid-dask-connect", daemon=True)
    thread.start()
    thread.join(SCHEDULER_TIMEOUT_S + 5.0)
    if "error" in box:
        raise box["error"]
    if "client" not in box:
        raise TimeoutError(f"no answer in {SCHEDULER_TIMEOUT_S + 5.0:g} s: is it a Dask scheduler?")
    client = box["client"]
    try:
        client.wait_for_workers(1, timeout=SCHEDULER_TIMEOUT_S)
    except TimeoutError:
        client.close(timeout=SCHEDULER_TIMEOUT_S)  # bounded: a busy scheduler must not hold the one-line refusal
        raise TimeoutError(f"the scheduler has no worker after {SCHEDULER_TIMEOUT_S:g} s") from None
    return client


def map_frames_dask(source, board, settings, scheduler, *, workers=2, batch=4, progress=None):
    """:func:`map_frames` on a Dask cluster: ``scheduler`` is its address, or ``"local"`` for a local cluster.

    The frames are read by the workers from their file names (a folder source; the workers must see the
    same paths), ``board`` and ``settings`` are sent once, at most ``4 * workers`` batches are in flight,
    and the results come back in frame order, identical to the local pool's.

    Raises
    ------
    DataError
        When Dask is not installed, the source is a video, or the scheduler cannot be reached.
    """
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise DataError("a Dask scheduler needs Dask: pip install 'kinid[dask]'") from None
    if getattr(source, "kind", "folder") != "folder":
        raise DataError("a Dask cluster reads the frames by file name: give a folder of images, not a video")
    workers, batch = int(workers), int(batch)
    if workers < 1 or batch < 1:
        raise DataError(f"workers and batch must be >= 1, got {workers} and {batch}", column="workers")
    cluster = None
    try:
        if scheduler == "local":
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
            client = Client(cluster)
        else:
            client = _remote_client(Client, scheduler)
    except (OSError, TimeoutError, ValueError, TypeError) as exc:
        if cluster is not None:
            cluster.close(timeout=SCHEDULER_TIMEOUT_S)
        hint = "; a tls:// scheduler needs Dask's TLS settings (distributed.comm.tls in a Dask config file)" if (
            isinstance(exc, TypeError)) else ""
        raise DataError(f"cannot reach the Dask scheduler at {scheduler!r} ({exc}){hint}", parameter="scheduler") from None
    try:
        b, s = client.scatter([board, settings], broadcast=True)
        in_flight = max(4 * workers, 4 * len(client.scheduler_info().get("workers", {})))
        pending = deque()
        for items in _batches(source, batch):
            pending.append(client.submit(_work_batch_on, list(items), b, s, pure=False))
            if len(pending) >= in_flight:
                for r in pending.popleft().result():
                    if progress is not None:
                        progress.update()
                    yield r
        while pending:
            for r in pending.popleft().result():
                if progress is not None:
                    progress.update()
                yield r
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
