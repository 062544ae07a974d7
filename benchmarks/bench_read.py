"""Benchmark: reading an observation file against ``np.loadtxt`` of the same file, and ``kinid identify`` on it.

The files are those of bench_identify_memory.py (the patent's plan on the B/C machine repeated with fresh reading
noise, every row distinct). In one process with one BLAS thread, for each size: ``np.loadtxt`` of the numeric
columns; kinid's column reader (kinid/csv_columns.py); ``read_observations`` (the reader, the travel check, the
unit check); ``exact_duplicates``. Then ``kinid identify --noise-um 1`` in a child process: its CPU time and peak
resident memory (``resource.getrusage(RUSAGE_CHILDREN)`` of a probe process that runs only it). CPU seconds, not
wall time, so that a machine shared with other work gives the same ratios.

Run: ``python benchmarks/bench_read.py [--rows 100000 1000000]``
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MPLBACKEND", "Agg")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_identify_memory import write_rows  # noqa: E402

_PROBE = ("import resource, subprocess, sys; subprocess.run(sys.argv[1:], check=True, stdout=subprocess.DEVNULL); "
          "r = resource.getrusage(resource.RUSAGE_CHILDREN); print(r.ru_utime + r.ru_stime, r.ru_maxrss)")


def cpu(f):
    """(result, CPU seconds of this process) of ``f()``."""
    started = time.process_time()
    out = f()
    return out, time.process_time() - started


def identify(urdf: str, data: Path, out: Path):
    """(CPU seconds, peak MB, wall seconds) of ``kinid identify`` on ``data`` in a child process, or the error."""
    started = time.perf_counter()
    run = subprocess.run([sys.executable, "-c", _PROBE, sys.executable, "-m", "kinid", "identify", "--machine", urdf,
                          "--data", str(data), "--noise-um", "1", "--out", str(out)],
                         capture_output=True, text=True, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"})
    if run.returncode:
        raise SystemExit(f"kinid identify failed: {run.stderr.strip().splitlines()[-1:]}")
    seconds, peak_kb = run.stdout.split()
    return float(seconds), int(peak_kb) / 1024, time.perf_counter() - started


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, nargs="+", default=[100_000, 1_000_000])
    args = ap.parse_args(argv)
    from kinid.csv_columns import read_csv_columns
    from kinid.identification.data.observations import exact_duplicates, read_observations
    from kinid.identification.model.machine import load_machine
    from kinid.urdf import path as urdf_path

    urdf = str(urdf_path("five_axis_bc"))
    machine = load_machine(urdf)
    print("CPU seconds, one BLAS thread; ratios to np.loadtxt of the same file")
    print(f"{'alignments':>11} {'file':>7} {'loadtxt':>8} {'columns':>14} {'read_obs':>14} {'duplicates':>10} "
          f"{'identify':>15} {'peak memory':>11}")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.rows:
            data = Path(tmp) / f"obs_{n}.csv"
            write_rows(data, n)
            header = data.open().readline().strip().split(",")
            numeric = [k for k, h in enumerate(header) if h != "mark"]
            table, t_load = cpu(lambda: np.loadtxt(data, delimiter=",", skiprows=1, usecols=numeric))
            columns, t_cols = cpu(lambda: read_csv_columns(data, texts=("mark",)))
            same = np.array_equal(table, np.column_stack([columns.numbers(header[k]) for k in numeric]))
            del table, columns
            obs, t_obs = cpu(lambda: read_observations(data, machine))
            _, t_dup = cpu(lambda: exact_duplicates(obs))
            del obs
            t_id, peak_mb, wall = identify(urdf, data, Path(tmp) / "fit.json")
            print(f"{n:>11,} {data.stat().st_size / 1e6:>4.0f} MB {t_load:>7.2f}s {t_cols:>6.2f}s {t_cols / t_load:>5.1f}x "
                  f"{t_obs:>6.2f}s {t_obs / t_load:>5.1f}x {t_dup:>9.2f}s {t_id:>6.1f}s {t_id / t_load:>6.1f}x "
                  f"{peak_mb:>8.0f} MB{'' if same else '  (columns differ from loadtxt!)'}  [identify wall {wall:.0f} s]")
            data.unlink()


if __name__ == "__main__":
    main()
