"""Benchmark: ``identify --auto`` (forward selection) on 3 360 alignments, in-process wall time.

The patent plan (336 alignments) measured 10 times with 1 µm noise on the B/C machine, a 13.3 mm lead of X
hidden (a period the library does not list); one BLAS thread. Prints the time of the default fit, of one
diagnosis, and of the whole selection, with what it added. To compare two versions of kinid on this
shared machine, run this file under each alternately (``PYTHONPATH=<other checkout> python …``) and
compare medians.

Run: ``python benchmarks/bench_auto_scale.py [--repeat N]``
"""
import argparse
import statistics
import time

import numpy as np


def main():
    from threadpoolctl import threadpool_limits

    from kinid.identification import default_model, diagnose, fit, forward_select, load_machine, simulate
    from kinid.identification.observations import Observations
    from kinid.identification.simulate import patent_plan
    from kinid.urdf import path

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    m = load_machine(path("five_axis_bc"))
    effects = default_model(m)
    rng = np.random.default_rng(5)
    theta = rng.normal(0, 15.0, sum(e.n_params for e in effects))
    base = patent_plan(m)
    plan = Observations(base.marks * 10, np.tile(base.w_mm, (10, 1)), np.tile(base.axes, (10, 1)))
    obs = simulate(m, plan, effects, theta, noise_um=1.0, rng=rng)
    # the lead: at reading x the carriage stands at x + e(x); the reading that put the tool on the mark is
    # then the one with x + e(x) = the aligned position (as benchmarks/bench_auto.py does)
    k = m.axis_names.index("X")
    x0 = obs.axes[:, k].copy()
    x = x0.copy()
    for _ in range(30):
        x = x0 - 2.5e-3 * np.sin(2 * np.pi * x / 13.3 + 0.7)
    axes = obs.axes.copy()
    axes[:, k] = x
    obs = Observations(obs.marks, obs.w_mm, axes, obs.t_s, obs.directions, obs.lines, "<bench>")
    times = {"fit": [], "diagnose": [], "auto": []}
    with threadpool_limits(1):
        for _ in range(args.repeat):
            t = time.perf_counter()
            fit(m, obs, effects, noise_um=1.0)
            times["fit"].append(time.perf_counter() - t)
            t = time.perf_counter()
            diagnose(m, obs, effects, noise_um=1.0)
            times["diagnose"].append(time.perf_counter() - t)
            t = time.perf_counter()
            steps = forward_select(m, obs, effects, noise_um=1.0)
            times["auto"].append(time.perf_counter() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    print(f"{len(obs)} alignments: fit {med['fit']:.3f} s, diagnose {med['diagnose']:.3f} s "
          f"({med['diagnose'] / med['fit']:.1f} fits), --auto {med['auto']:.3f} s ({med['auto'] / med['fit']:.1f} fits); "
          f"added {[s.added for s in steps[1:]]} (median of {args.repeat})")


if __name__ == "__main__":
    main()
