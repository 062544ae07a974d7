"""Render the example measurement run in examples/run/ (images, run log, sensor and board files).

    .venv/bin/python examples/make_run.py --out examples/run

The machine is the test suite's hand-written B/C double turntable (tests/bc_camera_sim.py), with a
10 mm-lead screw error of X, C-axis offsets, a tool length error and a camera turned 0.8 mrad on the
tool; the operator stops within about 0.1 mm of each mark. 36 images: tilts -40, 0, 40 degrees, table
angles 0, 120, 240 degrees, four marks; 1 grey level of image noise.
"""
import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
import bc_camera_sim as sim  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="folder to write")
    parser.add_argument("--seed", type=int, default=5)
    args = parser.parse_args()
    poses = sim.plan(tilts=(-40.0, 0.0, 40.0), turns=(0.0, 120.0, 240.0))
    sim.write_run(args.out, poses, rng=np.random.default_rng(args.seed), image_noise=1.0)
    print(f"{len(poses)} images, log.csv, sensor.json and board.json written to {args.out}")


if __name__ == "__main__":
    main()
