"""Benchmark: identification of the patent's plan (7 B x 12 C x 4 marks = 336 alignments, default model).

Prints, side by side in one run, with one BLAS thread for everything
(threadpoolctl ``threadpool_limits(1)``):

- the in-process kinid fit (Pinocchio Jacobians + CasADi LM steps), median wall time;
- the same problem with ``scipy.optimize.least_squares`` given the same residual
  and the same analytic (Pinocchio) Jacobian, in all four configurations
  ``method="lm"`` / ``"trf"``, each with ``x_scale="jac"`` and with
  ``x_scale=1.0`` (passed explicitly: since scipy 1.16 ``lm``'s default *is*
  ``"jac"``), scipy's default tolerances. Each configuration's sum of squares is
  checked against kinid's (relative difference printed) and kinid is compared
  with the FASTEST configuration that reaches kinid's cost; the chosen peer is
  named beside the ratio. Timings are interleaved (one kinid fit, then one run of
  each scipy configuration, repeated) so machine load hits all alike;
- kinid's floor: the bare Pinocchio ``computeJointJacobians`` calls for the same
  poses, one per pose for every pass of the model over the data the fit makes
  (counted during the fit), timed in the same interleaved rounds; for reference
  also the bare ``forwardKinematics`` calls, which is what kinid asks of
  Pinocchio per pose (it forms the Jacobian columns it needs from the joint
  placements, in numpy);
- the same comparison at 3 360 alignments (the plan repeated 10 times with fresh
  noise);
- at 336 alignments, finite differences for reference, ``kinid identify``
  through the command line (process start included) and Pinocchio evaluations
  per second (with and without Jacobians).

kinid's timed fit includes work the scipy runs do not (building the design,
the identifiability analysis, the covariance and observability at the
solution); the scipy runs are timed on a prebuilt design.

Run: ``python benchmarks/bench_identify.py``
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
import scipy  # noqa: E402
import scipy.optimize  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

from kinid.identification.model.effects import default_model  # noqa: E402
from kinid.identification.fitting.fit import fit  # noqa: E402
from kinid.identification.model import machine as machine_module  # noqa: E402
from kinid.identification.model.machine import _configurations, axes_to_si, evaluate, load_machine  # noqa: E402
from kinid.identification.data.observations import write_observations  # noqa: E402
from kinid.identification.fitting.residuals import design, residuals  # noqa: E402
from kinid.identification.fitting.simulate import SECONDS_PER_ALIGNMENT, errors_from_mapping, patent_plan, simulate  # noqa: E402
from kinid.urdf import path  # noqa: E402

#: (method, x_scale) of the scipy configurations measured.
CONFIGS = (("lm", "jac"), ("lm", 1.0), ("trf", "jac"), ("trf", 1.0))
#: A configuration counts as reaching kinid's optimum when its sum of squares is within this relative difference.
SAME_COST_RTOL = 1e-6


def label(method, x_scale):
    return f"method={method!r}, x_scale={x_scale!r}"


def timed(f, repeat=5):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t)
    return statistics.median(times), min(times), out


def repeated_plan(m, times):
    """The patent plan run ``times`` times in a row (same poses, later clock readings)."""
    plan = patent_plan(m)
    n = len(plan) * times
    return replace(plan, marks=plan.marks * times, w_mm=np.tile(plan.w_mm, (times, 1)), axes=np.tile(plan.axes, (times, 1)),
                   t_s=np.arange(n) * SECONDS_PER_ALIGNMENT, lines=tuple(range(1, n + 1)))


def compare(m, obs, repeat):
    """kinid's fit against the four scipy configurations on ``obs``; returns what the later sections need."""
    print(f"\n== {len(obs)} alignments, {len(default_model(m))} default-model parameters, "
          f"{3 * len(obs)} residuals; {repeat} interleaved rounds ==")
    res = fit(m, obs, noise_um=1.0)  # warm-up, and the design/free set the scipy runs use
    d = design(m, res.effects, obs)
    free = res.identifiable
    names = [n for n, ok in zip(res.param_names, free) if ok]

    def fun(x):
        t = np.zeros(d.n_params)
        t[free] = x
        return residuals(m, d, obs, t, jacobian=False).ravel()

    def jac(x):
        t = np.zeros(d.n_params)
        t[free] = x
        _, J, _ = residuals(m, d, obs, t, jacobian=True)
        return J.reshape(-1, d.n_params)[:, free]

    x0 = np.zeros(free.sum())
    passes = pinocchio_passes(m, obs)
    qs = _configurations(m, axes_to_si(m, obs.axes), np.zeros((len(obs), len(m.error_joints))))
    model, data = m.model, m.model.createData()

    def floor(kinematics):
        def run():
            for _ in range(passes):
                for q in qs:
                    kinematics(model, data, q)
        return run

    floors = {"floor": floor(pin.computeJointJacobians), "floor_fk": floor(pin.forwardKinematics)}
    runs = {"kinid": lambda: fit(m, obs, noise_um=1.0), **floors}
    for method, xs in CONFIGS:
        # scipy's default tolerances (1e-8): it stops as soon as the sum of squares settles, like kinid's LM
        runs[(method, xs)] = (lambda method=method, xs=xs:
                              scipy.optimize.least_squares(fun, x0, jac=jac, method=method, x_scale=xs))
    for f in runs.values():  # warm-up of every path
        f()
    times = {k: [] for k in runs}
    out = {}
    for _ in range(repeat):
        for k, f in runs.items():
            t = time.perf_counter()
            out[k] = f()
            times[k].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    best = {k: min(v) for k, v in times.items()}

    res = out["kinid"]
    ss_kinid = float(np.sum(fun(res.values[free]) ** 2))
    print(f"kinid fit (in-process):                      median {med['kinid']*1e3:8.1f} ms, best {best['kinid']*1e3:8.1f} ms, "
          f"{res.iterations} iterations, sum of squares {ss_kinid:.9g} µm², RMS {res.rms_um:.4f} µm")
    print(f"floor: {passes} passes x {len(obs)} bare computeJointJacobians calls: median {med['floor']*1e3:8.1f} ms, "
          f"best {best['floor']*1e3:8.1f} ms -> kinid {med['kinid']/med['floor']:.2f}x its floor (median), "
          f"{best['kinid']/best['floor']:.2f}x (best); the same count of forwardKinematics calls (what kinid calls): "
          f"median {med['floor_fk']*1e3:.1f} ms")
    same = []
    for key in runs:
        if key == "kinid" or key in floors:
            continue
        sol = out[key]
        ss = float(np.sum(fun(sol.x) ** 2))
        rel = (ss - ss_kinid) / ss_kinid
        dx = np.abs(sol.x - res.values[free]) / res.std[free]
        k = int(np.argmax(dx))
        ok = abs(rel) <= SAME_COST_RTOL
        if ok:
            same.append(key)
        print(f"scipy {label(*key):30s}         median {med[key]*1e3:8.1f} ms, best {best[key]*1e3:8.1f} ms, "
              f"{sol.nfev:3d} evaluations, {sol.njev} Jacobians, sum of squares {ss:.9g} µm² "
              f"(rel. diff. to kinid {rel:+.1e}{'' if ok else ', NOT the same optimum'}), "
              f"largest |Δθ|/σ {dx[k]:.1e} ({names[k]}), status {sol.status}")
    if not same:
        print("  -> no scipy configuration reached kinid's sum of squares: no ratio given")
        return res, fun, free
    peer = min(same, key=lambda k: med[k])
    ratio = med["kinid"] / med[peer]
    verdict = "kinid faster" if ratio < 1 else "kinid SLOWER"
    print(f"  -> fastest scipy configuration reaching kinid's cost: {label(*peer)} ({med[peer]*1e3:.1f} ms median); "
          f"kinid / that peer time ratio {ratio:.2f} ({verdict}); "
          f"kinid {med['kinid']*1e3:.1f} ms vs scipy " + ", ".join(f"{k[0]}/{k[1]} {med[k]*1e3:.1f}" for k in runs
                                                                   if k != "kinid" and k not in floors)
          + " ms")
    return res, fun, free


def pinocchio_passes(m, obs) -> int:
    """How many passes of the model over ``obs`` one kinid fit makes (Pinocchio calls counted, / N)."""
    calls = 0
    originals = {name: getattr(pin, name) for name in ("forwardKinematics", "computeJointJacobians")}

    def counting(f):
        def wrapper(*args, **kwargs):
            nonlocal calls
            calls += 1
            return f(*args, **kwargs)
        return wrapper

    try:
        for name, f in originals.items():
            setattr(machine_module.pin, name, counting(f))
        fit(m, obs, noise_um=1.0)
    finally:
        for name, f in originals.items():
            setattr(machine_module.pin, name, f)
    return max(1, round(calls / len(obs)))


def main():
    print(f"numpy {np.__version__}, scipy {scipy.__version__}; one BLAS thread (threadpool_limits(1))")
    t_start = time.perf_counter()
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(0)
    truth = {e.code: float(rng.normal(0, 20)) for e in default_model(m)}
    truth.update({"EX0W": 1200.0, "EY0W": -800.0, "EC0W": 8700.0})
    effects, theta = errors_from_mapping(truth, m)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=rng)
    obs10 = simulate(m, repeated_plan(m, 10), effects, theta, noise_um=1.0, rng=rng)  # fresh noise on every row

    with threadpool_limits(1):
        res, fun, free = compare(m, obs, repeat=7)
        med_f, best_f, sol_f = timed(lambda: scipy.optimize.least_squares(fun, np.zeros(free.sum()), jac="2-point", method="trf",
                                                                          x_scale="jac", xtol=1e-12, ftol=1e-12), repeat=3)
        print(f"scipy trf/jac, 2-point FD (tol 1e-12):       median {med_f*1e3:8.1f} ms, best {best_f*1e3:8.1f} ms, "
              f"{sol_f.nfev} evaluations (reference only, not a peer)")

        compare(m, obs10, repeat=5)

        print("\n== 336 alignments: command line and Pinocchio throughput ==")
        with tempfile.TemporaryDirectory() as tmp:
            csv = Path(tmp) / "obs.csv"
            write_observations(csv, obs, m)
            cmd = [sys.executable, "-m", "kinid", "identify", "--machine", str(path("five_axis_bc")), "--data", str(csv),
                   "--noise-um", "1", "--out", str(Path(tmp) / "fit.json")]
            med_c, best_c, _ = timed(lambda: subprocess.run(cmd, check=True, capture_output=True), repeat=3)
            print(f"kinid identify (command line):    median {med_c*1e3:7.1f} ms, best {best_c*1e3:7.1f} ms "
                  f"(process start and imports included)")

        errors = np.zeros(len(m.error_joints))
        med_j, _, _ = timed(lambda: evaluate(m, obs.axes, errors), repeat=5)
        med_p, _, _ = timed(lambda: evaluate(m, obs.axes, errors, jacobian=False), repeat=5)
        print(f"Pinocchio evaluations: {len(obs)/med_j:,.0f}/s with Jacobians, {len(obs)/med_p:,.0f}/s without")
    print(f"\ntotal benchmark time {time.perf_counter() - t_start:.1f} s")


if __name__ == "__main__":
    main()
