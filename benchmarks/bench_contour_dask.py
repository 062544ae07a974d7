"""Frames per second of ``kinid contour``'s frame mapping: the local process pool and a local Dask cluster.

Run: ``python benchmarks/bench_contour_dask.py`` (needs ``pip install 'kinid[dask]'``; about a minute).

A sequence of 96 frames of 1024 x 1024 pixels (the patent's 16 mm board, 30 µm object-side pixels, a 20 mm
circle) is rendered once; then, interleaved in one process, 3 times each:

- *pool*: ``measure_contour(..., workers=2)`` — kinid's forkserver pool of 2 processes, frames in batches of 2;
- *dask*: ``measure_contour(..., workers=2, scheduler="local")`` — a ``dask.distributed.LocalCluster`` of
  2 worker processes with 1 thread each, batches of 4 frames, started and closed inside each call
  (the cluster's start-up is part of its time; it is printed separately).

Both read the PNG files in the workers and return the same tracks (checked bit for bit). On one machine the
cluster can only add overhead; it is there for sequences that outgrow one machine.
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from kinid.stages.contour.measure import measure_contour
from kinid.stages.contour.simulate import circle_motion, render_sequence, simulation_camera
from kinid.stages.contour.track import FrameSettings
from kinid.vision import make_board


def main(n_frames=96, repeats=3):
    board = make_board()
    folder = Path(tempfile.mkdtemp()) / "frames"
    folder.mkdir()
    cam = simulation_camera((1024, 1024), 0.03, k1=0.0)
    t = time.perf_counter()
    render_sequence(folder, board, cam, circle_motion(n_frames, 10.0), rng=np.random.default_rng(0))
    print(f"rendered {n_frames} frames of 1024 x 1024 in {time.perf_counter() - t:.0f} s")
    settings = FrameSettings(pixel_mm=0.03, bits=board.bits, downsample=2)
    times = {"pool": [], "dask": []}
    tracks = {}
    for _ in range(repeats):
        for name, scheduler in (("pool", None), ("dask", "local")):
            t = time.perf_counter()
            m = measure_contour(folder, board, settings, workers=2, scheduler=scheduler)
            times[name].append(time.perf_counter() - t)
            tracks[name] = m.track.xy_mm
    from dask.distributed import Client, LocalCluster

    t = time.perf_counter()
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as c, Client(c):
        startup = time.perf_counter() - t
    same = np.array_equal(tracks["pool"], tracks["dask"])
    print("configuration: 2 worker processes each, 1 OpenCV thread per worker, frames read by the workers")
    for name, label in (("pool", "kinid pool (forkserver, batches of 2)"),
                        ("dask", "Dask LocalCluster (batches of 4, start-up included)")):
        best = min(times[name])
        print(f"{label:<52} {n_frames / best:6.1f} frames/s (best of {repeats}; all "
              f"{', '.join(f'{n_frames / x:.1f}' for x in times[name])})")
    print(f"Dask LocalCluster start-up and close alone: {startup:.2f} s; tracks identical: {same}")


if __name__ == "__main__":
    main()
