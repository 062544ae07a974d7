"""Benchmark: identification of the patent's plan (7 B x 12 C x 4 marks = 336 alignments, default model).

Prints, side by side in one run:
- in-process kinid fit (Pinocchio Jacobians + CasADi LM steps), median wall time;
- the same problem with scipy.optimize.least_squares given the same analytic
  (Pinocchio) Jacobian, its trust-region reflective method with ``x_scale="jac"``
  — scipy configured as its best user would; finite differences shown for
  reference;
- ``kinid identify`` through the command line (process start included);
- Pinocchio evaluations per second (with and without Jacobians).

Run: ``python benchmarks/bench_identify.py``
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import scipy.optimize

from kinid.identification.effects import default_model
from kinid.identification.fit import fit
from kinid.identification.machine import evaluate, load_machine
from kinid.identification.observations import write_observations
from kinid.identification.residuals import design, residuals
from kinid.identification.simulate import errors_from_mapping, patent_plan, simulate
from kinid.urdf import path


def timed(f, repeat=5):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times), out


def main():
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(0)
    truth = {e.code: float(rng.normal(0, 20)) for e in default_model(m)}
    truth.update({"EX0W": 1200.0, "EY0W": -800.0, "EC0W": 8700.0})
    effects, theta = errors_from_mapping(truth, m)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=rng)
    print(f"problem: {len(obs)} alignments, {len(default_model(m))} default-model parameters")

    med, best, res = timed(lambda: fit(m, obs, noise_um=1.0))
    print(f"kinid fit (in-process):           median {med*1e3:7.1f} ms, best {best*1e3:7.1f} ms, {res.iterations} iterations, RMS {res.rms_um:.4f} µm")

    d = design(m, res.effects, obs)
    free = res.identifiable

    def fun(x):
        t = np.zeros(d.n_params)
        t[free] = x
        return residuals(m, d, obs, t, jacobian=False).ravel()

    def jac(x):
        t = np.zeros(d.n_params)
        t[free] = x
        _, J, _ = residuals(m, d, obs, t, jacobian=True)
        return J.reshape(-1, d.n_params)[:, free]

    med_f, best_f, sol_f = timed(lambda: scipy.optimize.least_squares(fun, np.zeros(free.sum()), jac="2-point", x_scale="jac", xtol=1e-12, ftol=1e-12), repeat=3)
    # scipy's default tolerances (1e-8) stop as soon as the sum of squares settles, like kinid's LM
    med_s, best_s, sol = timed(lambda: scipy.optimize.least_squares(fun, np.zeros(free.sum()), jac=jac, x_scale="jac"), repeat=5)
    rms_s = np.sqrt(np.mean(sol.fun**2))
    print(f"scipy least_squares, analytic J:  median {med_s*1e3:7.1f} ms, best {best_s*1e3:7.1f} ms, {sol.nfev} evaluations, {sol.njev} Jacobians, RMS {rms_s:.4f} µm")
    print(f"scipy least_squares, 2-point FD:  median {med_f*1e3:7.1f} ms, best {best_f*1e3:7.1f} ms, {sol_f.nfev} evaluations (reference only)")
    ss_kinid = float(np.sum(fun(res.values[free]) ** 2))
    ss_scipy = float(np.sum(sol.fun**2))
    k = int(np.argmax(np.abs(sol.x - res.values[free])))
    name = [n for n, ok in zip(res.param_names, free) if ok][k]
    print(f"  -> kinid / scipy (analytic J) time ratio {med/med_s:.2f}; largest |Δθ| {abs(sol.x[k] - res.values[free][k]):.2e} ({name}, σ {res.std[free][k]:.2e}); "
          f"sum of squares kinid {ss_kinid:.9g} vs scipy {ss_scipy:.9g} µm²")

    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "obs.csv"
        write_observations(csv, obs, m)
        cmd = [sys.executable, "-m", "kinid", "identify", "--machine", str(path("five_axis_bc")), "--data", str(csv), "--noise-um", "1", "--out", str(Path(tmp) / "fit.json")]
        med_c, best_c, _ = timed(lambda: subprocess.run(cmd, check=True, capture_output=True), repeat=3)
        print(f"kinid identify (command line):    median {med_c*1e3:7.1f} ms, best {best_c*1e3:7.1f} ms (process start and imports included)")

    errors = np.zeros(len(m.error_joints))
    med_j, _, _ = timed(lambda: evaluate(m, obs.axes, errors), repeat=5)
    med_p, _, _ = timed(lambda: evaluate(m, obs.axes, errors, jacobian=False), repeat=5)
    print(f"Pinocchio evaluations: {len(obs)/med_j:,.0f}/s with Jacobians, {len(obs)/med_p:,.0f}/s without")


if __name__ == "__main__":
    main()
