"""Benchmark: peak memory of ``kinid identify`` as a process, against the number of alignments.

The patent's plan is simulated once on the B/C machine (location errors, 1 µm noise); the file of N alignments
repeats it with fresh reading noise on X, Y, Z (every row distinct) and a running ``t_s``. Each file is then
identified by ``kinid identify --noise-um 1`` in a child process; its peak resident memory (``ru_maxrss`` of the
children) and wall time are printed. The fit holds the Jacobian only as the R factor of its QR, a chunk of
alignments at a time (identification/fitting/fit_pass.py), the reader keeps numbers as arrays (kinid/csv_columns.py), and
the leverages of the misread check are streamed too: memory grows with the residuals and the readings, eight
bytes a number.

Run: ``python benchmarks/bench_identify_memory.py [--rows 100000 1000000]``
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def write_rows(path: Path, n: int, seed: int = 0) -> None:
    from kinid.identification.model.effects import default_model
    from kinid.identification.model.machine import load_machine
    from kinid.identification.data.observations import observations_text
    from kinid.identification.fitting.simulate import patent_plan, simulate
    from kinid.urdf import path as urdf_path

    machine = load_machine(urdf_path("five_axis_bc"))
    rng = np.random.default_rng(seed)
    effects = default_model(machine)
    theta = rng.normal(0.0, 15.0, sum(e.n_params for e in effects))
    base = simulate(machine, patent_plan(machine), effects, theta, noise_um=0.0, rng=rng, directions=False)
    text = observations_text(base, machine).splitlines()
    header, body = text[0], [line.split(",") for line in text[1:] if not line.startswith("#")]
    cols = header.split(",")
    solved = [cols.index(c) for c in ("x_mm", "y_mm", "z_mm")]
    t_col = cols.index("t_s") if "t_s" in cols else None
    with open(path, "w") as f:
        f.write(header + "\n")
        for k in range(n):
            cells = list(body[k % len(body)])
            for j in solved:
                cells[j] = f"{float(cells[j]) + rng.normal(0.0, 1e-3):.9f}"
            if t_col is not None:
                cells[t_col] = f"{15.0 * k:.3f}"
            f.write(",".join(cells) + "\n")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, nargs="+", default=[100_000, 1_000_000])
    args = ap.parse_args(argv)
    from kinid.urdf import path as urdf_path

    urdf = str(urdf_path("five_axis_bc"))
    print("kinid identify --noise-um 1 on the B/C machine; peak resident memory of the child process")
    print(f"{'alignments':>11} {'file':>9} {'peak memory':>12} {'wall time':>10}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.rows:
            data = Path(tmp) / f"obs_{n}.csv"
            write_rows(data, n)
            size = data.stat().st_size
            started = time.perf_counter()
            # each child's peak is measured in a fresh process of its own (ru_maxrss of children is a maximum)
            probe = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, "
                     "stdout=subprocess.DEVNULL); print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)")
            out = subprocess.run([sys.executable, "-c", probe, sys.executable, "-m", "kinid", "identify", "--machine",
                                  urdf, "--data", str(data), "--noise-um", "1", "--out", str(Path(tmp) / "fit.json")],
                                 capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
            seconds = time.perf_counter() - started
            if out.returncode:
                print(f"{n:>11,} failed: {out.stderr.strip().splitlines()[-1] if out.stderr.strip() else out.returncode}")
                continue
            peak_mb = int(out.stdout.strip().splitlines()[-1]) / 1024
            print(f"{n:>11,} {size / 1e6:>7.0f} MB {peak_mb:>9.0f} MB {seconds:>8.0f} s")
            data.unlink()


if __name__ == "__main__":
    main()
