"""Benchmark: forward selection (`kinid identify --auto`) on data the candidate library did not foresee.

For each case (hidden effects put into the readings by plain formulas, 1 µm
noise, the B/C machine), printed side by side in one run:

- the time of the default-model fit and of one selection step (diagnosis:
  library score test, period search, map proposal, then the refit);
- what `--auto` added;
- the held-out 3-D RMS of the readings on unseen poses: default model,
  `--auto`, and a fit with the true structure (the hidden effect named exactly;
  for the bump, which no effect describes exactly, the same machine without
  the bump).

Run: ``python benchmarks/bench_auto.py``
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import time  # noqa: E402
from dataclasses import replace  # noqa: E402

import numpy as np  # noqa: E402

from kinid.identification import default_model, diagnose, fit, forward_select, load_machine, parse_effect  # noqa: E402
from kinid.identification.fitting.alignment import solve_axes  # noqa: E402
from kinid.identification.fitting.simulate import errors_from_mapping, patent_plan, simulate  # noqa: E402
from kinid.urdf import path  # noqa: E402

M = load_machine(path("five_axis_bc"))
X, C = M.axis_names.index("X"), M.axis_names.index("C")


def x_error(obs, e):
    x0 = obs.axes[:, X].copy()
    x = x0.copy()
    for _ in range(30):
        x = x0 - e(x) * 1e-3
    axes = obs.axes.copy()
    axes[:, X] = x
    return replace(obs, axes=axes)


def lead(P, amp=2.5, phase=0.7):
    return lambda x: amp * np.sin(2 * np.pi * x / P + phase)


def bump(x):
    return 4.0 * np.exp(-(((x + 15.0) / 6.0) ** 2))


def held_out(result, truth):
    cols = [M.axis_names.index(a) for a in "XYZ"]
    poses = replace(truth, axes=np.where(np.isin(np.arange(truth.axes.shape[1]), cols), np.nan, truth.axes))
    pred = solve_axes(M, result.effects, result.theta, poses)
    return float(np.sqrt(np.mean(np.sum((pred.axes[:, cols] - truth.axes[:, cols]) ** 2, axis=1)))) * 1e3


def case(name, make, truth_effects, plan=None, held_plan=None, misread=False):
    rng = np.random.default_rng(sum(map(ord, name)))  # a fixed seed per case
    truth = {e.code: float(rng.normal(0, 15.0)) for e in default_model(M)}
    truth.update({"EX0W": 600.0, "EY0W": -400.0, "EC0W": 5000.0})
    effects, theta = errors_from_mapping(truth, M)
    plan = plan or patent_plan(M)
    held_plan = held_plan or patent_plan(M, tilt_deg=(-50, -20, 10, 40), turn_deg=tuple(range(5, 360, 40)))
    obs = make(simulate(M, plan, effects, theta, noise_um=1.0, rng=rng), effects, theta, rng)
    held = make(simulate(M, held_plan, effects, theta, rng=rng), effects, theta, rng, held=True)
    if misread:
        axes = obs.axes.copy()
        axes[141, M.axis_names.index("Y")] += 0.025
        obs = replace(obs, axes=axes)
    t = time.perf_counter()
    base = fit(M, obs, noise_um=1.0)
    t_fit = time.perf_counter() - t
    t = time.perf_counter()
    dg = diagnose(M, obs, default_model(M), noise_um=1.0, result=base)
    step_effects = default_model(M) + [parse_effect(dg.live[0].effect, M)] if dg.live else default_model(M)
    fit(M, obs, step_effects, noise_um=1.0, theta0=np.r_[base.theta, np.zeros(sum(e.n_params for e in step_effects) - len(base.theta))])
    t_step = time.perf_counter() - t
    steps = forward_select(M, obs, default_model(M), noise_um=1.0)
    if truth_effects is None:  # the bump: the same machine without it
        ref = held_out(fit(M, simulate(M, plan, effects, theta, noise_um=1.0, rng=rng), noise_um=1.0),
                       simulate(M, held_plan, effects, theta, rng=rng))
    else:
        clean = obs if not misread else obs.subset(np.array([i for i in range(len(obs)) if i != 141]))
        ref = held_out(fit(M, clean, default_model(M) + [parse_effect(n, M) for n in truth_effects], noise_um=1.0), held)
    added = ", ".join(s.added for s in steps[1:]) or "nothing"
    print(f"{name:<26} {t_fit * 1e3:7.0f} ms {t_step * 1e3:8.0f} ms   {held_out(base, held):7.3f} {held_out(steps[-1].fit, held):7.3f} "
          f"{ref:7.3f} µm   {added}" + (f"; set aside line {steps[-1].fit.set_aside[0].line}" if steps[-1].fit.set_aside else ""))


def main():
    obs = simulate(M, patent_plan(M), [], np.zeros(0), noise_um=1.0, rng=np.random.default_rng(0))
    diagnose(M, obs, default_model(M), noise_um=1.0)  # warm-up: imports and solver set-up out of the timings
    print(f"{'case':<26} {'fit':>10} {'one step':>11}   {'held-out 3-D RMS: default, --auto, true structure':<50}  added")
    case("listed lead 10 mm", lambda o, *a, **k: x_error(o, lead(10.0)), ["EXX:periodic:10"])
    case("unlisted lead 13.3 mm", lambda o, *a, **k: x_error(o, lead(13.3)), ["EXX:periodic:13.3"])
    case("local bump of X", lambda o, *a, **k: x_error(o, bump), None)
    case("misread + lead 7.3 mm", lambda o, *a, **k: x_error(o, lead(7.3, phase=2.0)), ["EXX:periodic:7.3"], misread=True)
    case("no effect, σ given 1 µm", lambda o, e, t, rng, held=False: o if held else replace(
        o, axes=o.axes + np.where(np.isin(np.arange(o.axes.shape[1]), [M.axis_names.index(a) for a in "XYZ"]),
                                  rng.normal(0, 1.2e-3, o.axes.shape), 0.0)), [])


if __name__ == "__main__":
    main()
