"""Benchmark: a 200-alignment fit through the Python API, BLAS threads left at their default.

kinid limits BLAS to one thread around the fit's and the diagnosis's dense
linear algebra (``kinid.threads``), because on these small matrices threaded
BLAS costs more than it gives, the more so on a loaded machine. This prints,
side by side in one run (each column a fresh process, interleaved):

- *library limit off*: default BLAS threads, ``KINID_BLAS_THREADS=none``
  (what a Python user got before the limit moved into the library);
- *library limit on*: default BLAS threads, kinid's own limit (today's default);
- *one thread from the environment*: ``OPENBLAS_NUM_THREADS=1`` set before numpy
  loads (the reference the library should match).

Run: ``python benchmarks/bench_threads.py [repeats]``
"""
from __future__ import annotations

import os
import statistics
import subprocess
import sys

CHILD = r"""
import time, numpy as np
from kinid.identification import load_machine, fit, default_model
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.urdf import path
m = load_machine(path("five_axis_bc"))
rng = np.random.default_rng(0)
truth = {e.code: float(rng.normal(0, 20)) for e in default_model(m)}
effects, theta = errors_from_mapping(truth, m)
plan = patent_plan(m)
obs = simulate(m, plan.subset(np.arange(200)), effects, theta, noise_um=1.0, rng=rng)
fit(m, obs, noise_um=1.0)   # warm-up: imports, CasADi solver construction
times = []
for _ in range(5):
    t = time.perf_counter(); fit(m, obs, noise_um=1.0); times.append(time.perf_counter() - t)
print(min(times))
"""


def run(env_changes: dict) -> float:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS",
                                                              "MKL_NUM_THREADS", "KINID_BLAS_THREADS")}
    env.update(env_changes)
    out = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip())


def main() -> None:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    cases = {
        "library limit off, default threads": {"KINID_BLAS_THREADS": "none"},
        "library limit on, default threads": {},
        "OPENBLAS_NUM_THREADS=1 (reference)": {"OPENBLAS_NUM_THREADS": "1"},
    }
    results = {name: [] for name in cases}
    for _ in range(repeats):
        for name, env in cases.items():
            results[name].append(run(env))
    import numpy  # noqa: F401 - load its BLAS to name it
    from threadpoolctl import threadpool_info

    blas = [(i["internal_api"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]
    print(f"200-alignment fit of the default model, best of 5 in each of {repeats} fresh processes; "
          f"BLAS {blas} on {os.cpu_count()} cores")
    ref = statistics.median(results["OPENBLAS_NUM_THREADS=1 (reference)"])
    for name, times in results.items():
        med = statistics.median(times)
        print(f"{name:38s} median {med * 1e3:8.1f} ms   {med / ref:5.2f}x the reference")


if __name__ == "__main__":
    main()
