"""Benchmark of ``kinid observe`` on 2048 x 2048 frames (prints figures).

Run: ``python benchmarks/bench_observe.py`` (about two minutes, most of it rendering).

A run of 24 frames of 2048 x 2048 pixels (0.01 mm pixels, a 20 mm field) of the tests' hand-written
B/C machine is rendered once (tests/bc_camera_sim.py). Then, interleaved in one process, repeated:

- *reading alone*: every PNG decoded into memory with kinid's image reader (the floor any observe
  must pay: OpenCV's PNG decoder behind a header check);
- *observe*: the whole ``observe`` call (reading, ring-code detection and decoding, the nearest
  mark, offsets, the misread check against the nominal machine).

Printed: images per second of each and the ratio (the decode and locate overhead on top of reading).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import bc_camera_sim as sim  # noqa: E402

from kinid.files import read_image  # noqa: E402
from kinid.identification import load_machine  # noqa: E402
from kinid.identification.data.observe import load_sensor, observe, read_run_log  # noqa: E402
from kinid.threads import single_blas_thread  # noqa: E402
from kinid.urdf import path  # noqa: E402
from kinid.vision import load_board  # noqa: E402


def main(n_frames=24, repeats=3):
    sim.IMAGE_PX, sim.PIXEL_MM = 2048, 0.01
    folder = Path(tempfile.mkdtemp())
    poses = sim.plan(tilts=(-40.0, 0.0, 40.0), turns=(0.0, 180.0))[:n_frames]
    t = time.perf_counter()
    sim.write_run(folder, poses, rng=np.random.default_rng(0))
    print(f"rendered {len(poses)} frames of 2048 x 2048 in {time.perf_counter() - t:.0f} s")
    machine = load_machine(path("five_axis_bc"))
    board, sensor = load_board(folder / "board.json"), load_sensor(folder / "sensor.json")
    log = read_run_log(folder / "log.csv", machine)
    names = [folder / n for n in log.images]
    read_s, observe_s = [], []
    with single_blas_thread():
        for _ in range(repeats):
            t = time.perf_counter()
            for n in names:
                read_image(n)
            read_s.append(time.perf_counter() - t)
            t = time.perf_counter()
            result = observe(machine, board, sensor, log)
            observe_s.append(time.perf_counter() - t)
    assert len(result.observations) == len(names), result.rejected
    r, o = min(read_s), min(observe_s)
    print(f"reading alone (kinid.files.read_image, OpenCV PNG decoder): {len(names) / r:6.1f} images/s "
          f"(best of {repeats}; all runs {', '.join(f'{len(names) / x:.1f}' for x in read_s)})")
    print(f"kinid observe (read + detect + decode + offsets):          {len(names) / o:6.1f} images/s "
          f"(best of {repeats}; all runs {', '.join(f'{len(names) / x:.1f}' for x in observe_s)})")
    print(f"observe / reading alone: {o / r:.2f}x the time")


if __name__ == "__main__":
    main()
