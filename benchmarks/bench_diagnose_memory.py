"""Benchmark: peak memory and time of a diagnosis against the number of alignments, blocked vs one block.

Each case runs in a fresh process: simulate N alignments (the 336-alignment
plan repeated, 1 µm noise, a hidden 10 mm lead error of X), fit the default
model, then ``diagnose`` (score test of the whole candidate library). The
process's peak resident memory (``ru_maxrss``) and the diagnosis wall time
are printed side by side for

- *blocked*: candidates scored in blocks of ``SCORE_BLOCK_BYTES`` (64 MB), as kinid does;
- *one block*: all candidate columns at once, as before blocking (the block size set to 1 TB).

Run: ``python benchmarks/bench_diagnose_memory.py [N ...]`` (default 3360 33600 200000;
one block is skipped above 40 000 alignments, where it needs several GB).
"""
from __future__ import annotations

import os
import subprocess
import sys

CHILD = r"""
import resource, sys, time, numpy as np
import importlib
sums = importlib.import_module("kinid.identification.diagnosis.score_sums")  # where the score test's block size is read
from kinid.identification import load_machine, default_model, fit, diagnose
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.urdf import path
n, block = int(sys.argv[1]), float(sys.argv[2])
sums.SCORE_BLOCK_BYTES = block
m = load_machine(path("five_axis_bc"))
plan = patent_plan(m)
plan = plan.subset(np.arange(n) % len(plan))
effects, theta = errors_from_mapping({"EX0C": 12.0, "EA0B": -25.0, "EXX:periodic:10": [2.2, 1.2]}, m)
obs = simulate(m, plan, effects, theta, noise_um=1.0, rng=np.random.default_rng(0))
result = fit(m, obs, noise_um=1.0)
base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
t = time.perf_counter()
d = diagnose(m, obs, default_model(m), noise_um=1.0, result=result)
elapsed = time.perf_counter() - t
peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
print(f"{elapsed:.2f} {peak / 1024:.0f} {base / 1024:.0f} {d.candidates[0].effect}")
"""


def main() -> None:
    sizes = [int(a) for a in sys.argv[1:]] or [3360, 33600, 200000]
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    print("diagnose (score test of the candidate library) after a fit; peak RSS of the whole process")
    print(f"{'alignments':>10}  {'blocked: time':>14} {'peak MB':>8}  {'one block: time':>16} {'peak MB':>8}  best candidate")
    for n in sizes:
        row = []
        for block in (64 * 1024**2, 1e12):
            if block > 1e9 and n > 40000:
                row.append(None)
                continue
            out = subprocess.run([sys.executable, "-c", CHILD, str(n), str(block)], env=env, capture_output=True,
                                 text=True, check=True).stdout.split()
            row.append(out)
        b, o = row
        one = f"{float(o[0]):14.2f} s {o[1]:>8}" if o else f"{'(skipped)':>16} {'':>8}"
        print(f"{n:>10}  {float(b[0]):12.2f} s {b[1]:>8}  {one}  {b[3]}")


if __name__ == "__main__":
    main()
