"""Benchmark: diagnosis on the patent's plan (336 alignments) with a hidden lead-screw error.

Prints, side by side in one run:
- scoring the whole default candidate library by the score test (one Pinocchio pass);
- one forward-selection round (score, add the best, refit the nonlinear model);
- refitting every candidate one by one (the naive way to rank the library).

Run: ``python benchmarks/bench_diagnose.py [--limit N]`` (N: refit only the first N candidates and extrapolate).
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse
import statistics
import time

import numpy as np

from kinid.identification import diagnose
from kinid.identification.diagnosis.scoring import score_candidates
from kinid.identification.model.effects import candidate_library, default_model
from kinid.identification.fitting.fit import fit
from kinid.identification.model.machine import load_machine
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate
from kinid.urdf import path


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--limit", type=int, default=None)
    args = ap.parse_args()
    m = load_machine(path("five_axis_bc"))
    rng = np.random.default_rng(0)
    truth = {e.code: float(rng.normal(0, 20)) for e in default_model(m)}
    truth["EXX:periodic:10"] = [2.0, 1.0]
    effects, theta = errors_from_mapping(truth, m)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=rng)
    base = fit(m, obs, noise_um=1.0)
    lib = candidate_library(m, base.effects, has_directions=bool(obs.directions), has_time=obs.t_s is not None)
    print(f"{len(obs)} alignments; library of {len(lib)} candidates ({sum(e.n_params for e in lib)} columns)")

    times = []
    for _ in range(5):
        t = time.perf_counter()
        scored = score_candidates(m, obs, base, lib, 1.0, sigma_known=True)
        times.append(time.perf_counter() - t)
    best = min((c for c in scored if c.status == "live"), key=lambda c: c.log10_p)
    print(f"score test of the whole library:   median {statistics.median(times)*1e3:7.1f} ms (best candidate {best.effect}, predicted RMS {best.rms_after_um:.4f} µm)")

    t = time.perf_counter()
    dg = diagnose(m, obs, base.effects, noise_um=1.0, result=base)
    from kinid.identification.model.effects import parse_effect

    refit = fit(m, obs, list(base.effects) + [parse_effect(dg.live[0].effect, m)], noise_um=1.0)
    t_round = time.perf_counter() - t
    print(f"one forward-selection round:       {t_round*1e3:7.1f} ms (diagnose + refit; RMS {base.rms_um:.3f} -> {refit.rms_um:.3f} µm)")

    todo = lib if args.limit is None else lib[: args.limit]
    t = time.perf_counter()
    rms = {}
    for e in todo:
        rms[e.name] = fit(m, obs, list(base.effects) + [e], noise_um=1.0).rms_um
    t_all = time.perf_counter() - t
    if len(todo) < len(lib):
        print(f"refit every candidate one by one:  {t_all:7.1f} s for {len(todo)} -> about {t_all * len(lib) / len(todo):.0f} s for all {len(lib)}")
    else:
        naive_best = min(rms, key=rms.get)
        print(f"refit every candidate one by one:  {t_all:7.1f} s (best {naive_best}, RMS {rms[naive_best]:.4f} µm)")
    print(f"  -> the score test is {t_all * len(lib) / len(todo) / statistics.median(times):.0f}x faster than refitting the library")


if __name__ == "__main__":
    main()
