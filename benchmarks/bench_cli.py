"""Benchmark: start-up cost of the command line, the lazy roof against an eager one.

Before the roof imported verb modules lazily, building the ``kinid`` parser
imported every verb module (identification, vision, the four stage methods).
This benchmark measures, side by side in one run and interleaved so that load
on the machine hits both alike, the wall time of

- ``kinid --help``;
- ``kinid identify`` on the 336-alignment plan (fit of the default model),

once through the lazy roof (``kinid.cli.main``) and once through an "eager"
start that first imports every module listed in ``kinid.cli.VERBS`` — what the
old roof did — and then calls the same ``main``. Each run is a fresh Python
process (process start-up included in both columns).

Run: ``python benchmarks/bench_cli.py [repeats]``
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EAGER = ("import importlib, sys; from kinid.cli import VERBS, main; "
         "[importlib.import_module(v.module) for v in VERBS.values()]; sys.exit(main(sys.argv[1:]))")
LAZY = "import sys; from kinid.cli import main; sys.exit(main(sys.argv[1:]))"


def wall(code: str, args, env) -> float:
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=env)
    elapsed = time.perf_counter() - t
    if out.returncode != 0:
        raise SystemExit(f"failed: {' '.join(args)}\n{out.stderr}")
    return elapsed


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 7
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", MPLBACKEND="Agg")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "errors.json").write_text('{"EX0C": 12.0, "EA0B": -25.0, "EXX:periodic:10": [1.5, -0.8]}')
        from kinid.urdf import path

        urdf = str(path("five_axis_bc"))
        subprocess.run([sys.executable, "-m", "kinid", "simulate", "--machine", urdf, "--errors",
                        str(tmp / "errors.json"), "--noise-um", "1", "--out", str(tmp / "obs.csv")],
                       check=True, capture_output=True, env=env)
        cases = {
            "kinid --help": ["--help"],
            "kinid identify (336 rows)": ["identify", "--machine", urdf, "--data", str(tmp / "obs.csv"),
                                          "--noise-um", "1", "--out", str(tmp / "fit.json")],
        }
        print(f"median wall time of {repeats} fresh processes each, interleaved (s)")
        print(f"{'command':30s} {'eager imports':>14s} {'lazy roof':>10s} {'lazy/eager':>11s}")
        for name, args in cases.items():
            eager, lazy = [], []
            for _ in range(repeats):
                eager.append(wall(EAGER, args, env))
                lazy.append(wall(LAZY, args, env))
            e, l_ = statistics.median(eager), statistics.median(lazy)
            print(f"{name:30s} {e:14.3f} {l_:10.3f} {l_ / e:10.0%}")


if __name__ == "__main__":
    main()
