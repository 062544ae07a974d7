"""Benchmark: does a planned measurement keep its promise, and how does its choice compare?

On the shipped B/C machine, 1 µm reading noise, candidates: the 4 marks of the patent's plan at every
B in -60…60° (10° steps) and C in 0…345° (15° steps), 1248 candidate alignments. Side by side:

- **kinid plan** for a tool-point target U = 0.5 µm (k = 2, per coordinate, RMS over the candidates'
  poses): greedy I-optimal choice with exchange, trimmed to the fewest alignments, ordered in blocks;
- **D-optimal, as FIGAROH selects calibration poses**: the convex relaxation max log det Σ w_c J_cᵀJ_c,
  Σ w = 1, w ≥ 0 (cvxpy with its default conic solver, as FIGAROH uses picos), rounded to the same count by
  the largest weights;
- **random**: the same count drawn at random from the candidates (the median of 20 draws' promise);
- **the patent's plan**: 7 B × 12 C × 4 marks = 336 alignments in its axis-major order.

For each: the promised U, the simulated held-out error over 20 seeds (the truth in plain numpy,
benchmarks/proving_truth.py: every location error drawn, the set-up of board and tool in millimetres,
1 µm noise on every coordinate; kinid fits the default model; the error of its predicted tool point at
every candidate pose), the share of held-out coordinates within U, the machine time (the same travel
model for every plan, each in its own order) and the time to choose.

Run: ``python benchmarks/bench_plan.py [--seeds 20]``
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import proving_truth as truth  # noqa: E402

MARKS_MM = np.array([[40.0, 40.0, 0.0], [-40.0, 40.0, 0.0], [-40.0, -40.0, 0.0], [40.0, -40.0, 0.0]])
B_DEG = np.arange(-60.0, 61.0, 10.0)
C_DEG = np.arange(0.0, 360.0, 15.0)
NOISE_UM = 1.0
TARGET_UM = 0.5


def true_errors(tm, rng, n) -> dict:
    """Every location error of the URDF drawn: ±30 µm / µrad, the set-up of board and tool ±500 (mm-scale
    offsets, 0.03° rotations)."""
    out = {}
    for code in tm.errors:
        if code[2] == "0":
            big = code.endswith("W") or code.endswith("T")
            out[code] = np.full(n, rng.uniform(-1, 1) * (500.0 if big else 30.0))
    return out


def _true_points(machine, tm, obs, errors: dict) -> np.ndarray:
    """The true tool point (mm) at each row's readings, with constant error values ``errors`` (µm / µrad) or
    per-row arrays."""
    n = len(obs)
    values = {k: np.broadcast_to(np.asarray(v, float), (n,)) for k, v in errors.items()}
    return truth.tool_point_mm(tm, {a: obs.axes[:, j] for j, a in enumerate(machine.axis_names)}, values, n)


def _volume_error_um(machine, tm, volume_obs, result, errors: dict) -> np.ndarray:
    """Errors (µm, (N, 3)) of the tool point ``result`` predicts at the volume's poses, t = 0, against the truth
    with constant ``errors``."""
    from kinid.identification.data.observations import Observations
    from kinid.identification.fitting.residuals import design, residuals

    vol = Observations(volume_obs.marks, _true_points(machine, tm, volume_obs, errors), volume_obs.axes,
                       np.zeros(len(volume_obs)), {}, (), "<volume>")
    return residuals(machine, design(machine, result.effects, vol), vol, result.theta, jacobian=False)


def held_out(machine, text: str, plan_obs, volume_obs, seed: int, noise_um: float = NOISE_UM) -> np.ndarray:
    """Errors (µm, (N_volume, 3)) of the tool point kinid predicts at the volume's poses after fitting the default
    model to the plan's alignments simulated on a machine with errors drawn from ``seed`` (plain-numpy truth)."""
    from kinid.identification import default_model, fit
    from kinid.identification.data.observations import Observations

    tm = truth.read_urdf(text)
    rng = np.random.default_rng(seed)
    n = len(plan_obs)
    errors = {k: v[0] for k, v in true_errors(tm, rng, 1).items()}
    p = _true_points(machine, tm, plan_obs, errors) + rng.normal(0.0, noise_um, (n, 3)) * 1e-3
    data = Observations(plan_obs.marks, p, plan_obs.axes, plan_obs.t_s, {}, (), "<simulated plan>")
    result = fit(machine, data, default_model(machine), noise_um=noise_um)
    return _volume_error_um(machine, tm, volume_obs, result, errors)


def warm_up_run(machine, pool, obs, seed):
    """A warm-up of the tool side in x (8 µm, τ 25 min) on top of drawn location errors; identify --auto; the error
    of the cold machine kinid predicts at the candidates (3-D RMS, µm) and whether it added a time effect."""
    from kinid.identification import default_model, forward_select
    from kinid.identification.data.observations import Observations

    tm = truth.read_urdf(Path(machine.path).read_text())
    rng = np.random.default_rng(seed)
    n = len(obs)
    cold = {k: v[0] for k, v in true_errors(tm, rng, 1).items()}
    warm = dict(cold, EX0T=cold["EX0T"] + 8.0 * (1.0 - np.exp(-obs.t_s / 1500.0)))
    p = _true_points(machine, tm, obs, warm) + rng.normal(0.0, 1.0, (n, 3)) * 1e-3
    data = Observations(obs.marks, p, obs.axes, obs.t_s, {}, tuple(range(2, n + 2)), "<simulated>")
    final = forward_select(machine, data, default_model(machine), noise_um=1.0)[-1].fit
    r = _volume_error_um(machine, tm, pool, final, cold)
    timed = any(":warmup:" in e.name or e.name.endswith(":drift") for e in final.effects)
    return float(np.sqrt(np.mean(np.sum(r**2, axis=1)))), timed


def axis_major(machine, pool, rows, outer):
    """The candidates ``rows`` axis-major (``outer[0]`` the outer loop, then ``outer[1]``…), timed by the default
    travel model: how a grid is usually run."""
    from dataclasses import replace

    from kinid.identification.planning.order import TravelModel, move_times_s
    from kinid.identification.planning.pool import axis_motion

    names = machine.axis_names
    key = np.lexsort(tuple(pool.axes[rows, names.index(a)] for a in reversed(outer)))
    obs = pool.subset(np.asarray(rows)[key])
    linear, wraps = axis_motion(machine)
    travel = TravelModel()
    moves = move_times_s(obs.axes[:-1], obs.axes[1:], linear, wraps, travel)
    return replace(obs, t_s=np.r_[0.0, np.cumsum(moves + travel.align_s)])


def d_optimal(J, count):
    """FIGAROH's selection: the log-det relaxation over the candidates, rounded by the largest weights."""
    import cvxpy as cp

    A = J.reshape(len(J), 3, -1)
    d = np.sqrt(np.einsum("nip,nip->p", A, A) / len(A))
    A = A / d
    w = cp.Variable(len(A), nonneg=True)
    M = sum(w[c] * (A[c].T @ A[c]) for c in range(len(A)))
    cp.Problem(cp.Maximize(cp.log_det(M)), [cp.sum(w) == 1]).solve()
    return np.sort(np.argsort(-np.asarray(w.value))[:count])


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--drift-seeds", type=int, default=20)
    args = ap.parse_args(argv)
    from threadpoolctl import threadpool_limits

    from kinid.identification.model.machine import load_machine
    from kinid.identification.planning.plan import plan_measurement, tool_point_u_um, volume_weight
    from kinid.identification.planning.pool import axis_motion, candidate_jacobian, candidate_poses
    from kinid.identification.planning.order import TravelModel, order_for_time
    from kinid.identification.fitting.simulate import patent_plan
    from kinid.identification.fitting.alignment import solve_axes
    from kinid.urdf import path

    threadpool_limits(1)
    machine = load_machine(path("five_axis_bc"))
    text = Path(machine.path).read_text()
    pool = candidate_poses(machine, MARKS_MM, {"B": B_DEG, "C": C_DEG})
    travel = TravelModel()
    t0 = time.perf_counter()
    # the design compared with others of the same count, no drift drawn: without drift checks (proving_loop.py has them)
    plan = plan_measurement(machine, pool, target_um=TARGET_UM, noise_um=NOISE_UM, travel=travel, drift_checks=0)
    t_kinid = time.perf_counter() - t0
    J = plan.candidates.J
    W = volume_weight(J * NOISE_UM)
    n = len(plan.obs)
    print(f"machine five_axis_bc, noise σ {NOISE_UM} µm, {len(pool)} candidates (4 marks × B -60…60° step 10 × C "
          f"0…345° step 15); target U {TARGET_UM} µm (k = 2, per coordinate, RMS over the candidates' poses)")
    print(f"travel model: {travel.describe()}")
    linear, wraps = axis_motion(machine)
    rows = {}
    rows["kinid plan"] = (plan.chosen[plan.order.index], plan.order.total_s, t_kinid)
    try:
        t0 = time.perf_counter()
        dsel = d_optimal(J, len(plan.chosen))
        t_d = time.perf_counter() - t0
        o = order_for_time(pool.axes[dsel], machine.axis_names, linear, wraps, travel)
        rows["D-optimal (cvxpy log det, top weights)"] = (dsel[o.index], o.total_s, t_d)
    except ImportError:
        print("D-optimal peer skipped: cvxpy is not installed (pip install cvxpy)")
    rng = np.random.default_rng(0)
    draws = [rng.choice(len(pool), len(plan.chosen), replace=False) for _ in range(20)]
    us = [tool_point_u_um(J, W, d, NOISE_UM)[0] for d in draws]
    median = draws[int(np.argsort(us)[len(us) // 2])]
    o = order_for_time(pool.axes[median], machine.axis_names, linear, wraps, travel)
    rows["random (median of 20 draws)"] = (median[o.index], o.total_s, 0.0)
    patent = solve_axes(machine, [], np.zeros(0), patent_plan(machine))
    from kinid.identification.model.effects import default_model

    Jp, names_p, _ = candidate_jacobian(machine, default_model(machine), patent, NOISE_UM)
    print(f"\n{'plan':<40} {'alignments':>10} {'U promised':>11} {'held-out 2·RMS mean / worst of seeds':>37} "
          f"{'within ' + str(TARGET_UM) + ' µm':>12} {'machine time':>13} {'choice':>8}")
    for name, (rows_idx, total_s, t_sel) in rows.items():
        obs = pool.subset(rows_idx)
        u = tool_point_u_um(J, W, rows_idx, NOISE_UM)[0]
        _report(name, machine, text, obs, pool, u, total_s, t_sel, args.seeds)
    # the patent plan's promise over the same volume: its information, the candidates' weight
    M = np.einsum("nip,niq->pq", Jp, Jp)
    u_pat = 2 * np.sqrt(np.trace(np.linalg.solve(M, W)) / 3) if names_p == plan.candidates.names else float("nan")
    t_pat = order_for_time(patent.axes, machine.axis_names, linear, wraps, travel, blocks=1, reference=False)
    from kinid.identification.planning.order import move_times_s
    t_axis_major = float(move_times_s(patent.axes[:-1], patent.axes[1:], linear, wraps, travel).sum() + len(patent) * travel.align_s)
    _report("patent's plan (axis-major, as run)", machine, text, patent, pool, u_pat, t_axis_major, 0.0, args.seeds)
    print(f"(the patent's plan in the shortest tour: {t_pat.total_s / 60:.1f} min)")
    print(f"\nwarm-up during the run (EX0T grows 8 µm, τ 25 min), identify --auto, {args.drift_seeds} seeds: the same "
          f"alignments in kinid's order and axis-major (B outer, then C)")
    am = axis_major(machine, pool, plan.chosen, ("B", "C"))
    for name, obs in (("kinid's order", plan.obs), ("axis-major", am)):
        runs = [warm_up_run(machine, pool, obs, seed) for seed in range(100, 100 + args.drift_seeds)]
        errs = np.array([e for e, _ in runs])
        corr = max(abs(np.corrcoef(obs.t_s, obs.axes[:, j])[0, 1]) for j in range(obs.axes.shape[1]) if np.ptp(obs.axes[:, j]))
        print(f"  {name:<14} max |corr(time, axis)| {corr:.2f}: time effect added {sum(t for _, t in runs)}/{len(runs)}; "
              f"cold machine predicted at 3-D RMS mean {errs.mean():.3f} µm, worst {errs.max():.3f} µm")
    print(f"\nkinid's plan: {n} alignments ({len(plan.chosen)} chosen + {n - len(plan.chosen)} repeats of a reference); "
          f"the relaxation's bound: no plan of fewer than {plan.bound_count} alignments meets the target; efficiency "
          f"{plan.efficiency:.1%}; order: {plan.order.blocks} blocks, |correlation of time with an axis| ≤ "
          f"{plan.order.worst_correlation:.2f}")


def _report(name, machine, text, obs, pool, u, total_s, t_sel, seeds):
    errs = [held_out(machine, text, obs, pool, seed) for seed in range(seeds)]
    rms2 = np.array([2 * np.sqrt(np.mean(e**2)) for e in errs])
    within = np.mean(np.abs(np.concatenate([e.ravel() for e in errs])) <= TARGET_UM)
    print(f"{name:<40} {len(obs):>10} {u:>8.3f} µm {rms2.mean():>18.3f} / {rms2.max():.3f} µm {within:>19.1%} "
          f"{total_s / 60:>9.1f} min {t_sel:>6.2f} s")


if __name__ == "__main__":
    main()
