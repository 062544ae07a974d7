"""Benchmark: kinid's fit against scipy's ``least_squares`` at its measured best, and against the Pinocchio calls
the fit makes.

Two problems, both fitted with the default model:

- **near-linear**: the README example (``examples/errors.json`` on the B/C five-axis machine, the patent's plan of
  336 alignments, σ 1 µm), and the plan run 10 times (3 360 alignments, fresh noise);
- **hard**: the arm measured from a frame metres away, turned tens of degrees, with 100 µm / µrad location errors
  (``bench_arm_far_frame.py``'s draw 0, 60 poses): kinid starts from the measurement frame in closed form.

Per problem, timed in CPU time (``time.process_time``), one BLAS thread (threadpoolctl), in interleaved rounds
(one run of each contender per round, so machine load hits all alike), medians printed:

- kinid's ``fit`` (design, identifiability analysis, covariance and observability at the solution included);
- scipy ``least_squares`` in every configuration of ``method`` (lm, trf), ``x_scale`` (1.0, "jac") and the
  Jacobian's source: "one pass" (``fun`` computes the residuals and the Jacobian in one Pinocchio pass and keeps
  the Jacobian; ``jac`` returns it) or "own pass" (``fun`` the residuals only, ``jac`` its own pass). Every
  configuration gets kinid's own analytic Jacobian, restricted to the parameters the fit identifies, on kinid's
  reduced machine (the error joints in use only, ``fit_pass.reduced``), on a prebuilt design, from the start the
  fit iterates from (zero; on the hard problem kinid's closed-form start, not timed for scipy; there also each
  method and scale once from zero, not a peer: whether scipy gets there without the start). Each configuration's
  sum of squares is checked against kinid's; the fastest that reaches it (relative difference ≤ 1e-6) is the peer;
- the floor: the ``forwardKinematics`` calls one kinid fit makes (counted during a fit, on the model it calls
  them on), made bare on the same configurations (``computeJointJacobians`` calls counted too: none).

Printed: every configuration with its time, evaluations and cost; kinid / peer and kinid / floor.

Run: ``python benchmarks/bench_identify.py [ROUNDS]`` (default 7 rounds; about 2 minutes on a shared machine).
"""
import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import json  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from dataclasses import replace  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pinocchio as pin  # noqa: E402
import scipy  # noqa: E402
import scipy.optimize  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from kinid.identification.fitting.fit import fit  # noqa: E402
from kinid.identification.fitting.fit_pass import reduced  # noqa: E402
from kinid.identification.fitting.residuals import design, effect_columns, joint_values  # noqa: E402
from kinid.identification.fitting.simulate import SECONDS_PER_ALIGNMENT, errors_from_mapping, patent_plan, simulate  # noqa: E402
from kinid.identification.fitting.start import closed_form_start  # noqa: E402
from kinid.identification.fitting.identifiability import analyse  # noqa: E402
from kinid.identification.fitting.fit_pass import model_pass_qr  # noqa: E402
from kinid.identification.model.machine import _configurations, axes_to_si, errors_to_si, evaluate, load_machine  # noqa: E402
from kinid.urdf import path  # noqa: E402

#: (method, x_scale, Jacobian source) of the scipy configurations measured.
CONFIGS = tuple((m, x, j) for m in ("lm", "trf") for x in (1.0, "jac") for j in ("one pass", "own pass"))
#: A configuration reaches kinid's optimum when its sum of squares is within this relative difference.
SAME_COST_RTOL = 1e-6


def repeated_plan(m, times):
    """The patent plan run ``times`` times in a row (same poses, later clock readings)."""
    plan = patent_plan(m)
    n = len(plan) * times
    return replace(plan, marks=plan.marks * times, w_mm=np.tile(plan.w_mm, (times, 1)), axes=np.tile(plan.axes, (times, 1)),
                   t_s=np.arange(n) * SECONDS_PER_ALIGNMENT, lines=tuple(range(1, n + 1)))


class Counted:
    """Counts the Pinocchio kinematics calls (by model) while active."""

    NAMES = ("forwardKinematics", "computeJointJacobians")

    def __enter__(self):
        self.calls = {name: {} for name in self.NAMES}
        self.models = {}
        self.originals = {name: getattr(pin, name) for name in self.NAMES}
        for name, f in self.originals.items():
            setattr(pin, name, self._counting(name, f))
        return self

    def _counting(self, name, f):
        def wrapper(model, *args, **kwargs):
            self.calls[name][id(model)] = self.calls[name].get(id(model), 0) + 1
            self.models[id(model)] = model
            return f(model, *args, **kwargs)
        return wrapper

    def __exit__(self, *exc):
        for name, f in self.originals.items():
            setattr(pin, name, f)


def scipy_problem(mr, dr, obs, free, theta0):
    """(residuals only, residuals and Jacobian) of the free parameters on the reduced machine, at x (free values)."""
    def point(x):
        t = theta0.copy()
        t[free] = x
        return joint_values(mr, dr, t)

    def r_only(x):
        return ((evaluate(mr, obs.axes, point(x), jacobian=False, offsets_mm=obs.offsets_mm) - obs.w_mm) * 1e3).ravel()

    def r_and_J(x):
        p, G, _ = evaluate(mr, obs.axes, point(x), offsets_mm=obs.offsets_mm, axes_jacobian=False)
        return ((p - obs.w_mm) * 1e3).ravel(), effect_columns(G, dr)[:, :, free].reshape(len(p) * 3, -1)

    return r_only, r_and_J


def scipy_run(config, r_only, r_and_J, x0):
    method, x_scale, source = config
    if source == "own pass":
        return scipy.optimize.least_squares(r_only, x0, jac=lambda x: r_and_J(x)[1], method=method, x_scale=x_scale)
    kept = {}

    def fun(x):
        r, J = r_and_J(x)
        kept["x"], kept["J"] = x.copy(), J
        return r

    def jac(x):
        return kept["J"] if "x" in kept and np.array_equal(kept["x"], x) else r_and_J(x)[1]

    return scipy.optimize.least_squares(fun, x0, jac=jac, method=method, x_scale=x_scale)


def compare(title, m, obs, effects, rounds, *, noise_um=None, hard=False):
    """Time kinid, every scipy configuration and the floor on one problem; print the table."""
    kw = {"noise_um": noise_um} if noise_um else {}
    res = fit(m, obs, effects, **kw)
    d = design(m, res.effects, obs)
    mr, dr = reduced(m, d)
    free = res.identifiable
    theta0 = np.zeros(d.n_params)
    if hard:  # scipy starts where kinid's iterations start: the closed-form frame (not timed for scipy)
        ps = model_pass_qr(mr, dr, obs, theta0)
        ident = analyse(ps.R, d.param_names(), rows=ps.r.size)
        theta0 = closed_form_start(mr, dr, obs, theta0, free=ident.identifiable, aliases=ident.aliases).theta
    r_only, r_and_J = scipy_problem(mr, dr, obs, free, theta0)
    x0 = theta0[free].copy()
    theta0 = np.where(free, 0.0, theta0)  # scipy moves the free ones; the held stay at 0, as in the fit

    with Counted() as counted:
        fit(m, obs, effects, **kw)
    fk = counted.calls["forwardKinematics"]
    jj = sum(counted.calls["computeJointJacobians"].values())
    (model_id, n_calls), = fk.items()  # one model: the reduced one
    model = counted.models[model_id]
    qs = _configurations(mr, axes_to_si(mr, obs.axes), errors_to_si(mr, joint_values(mr, dr, np.where(free, res.values, 0))))
    assert model.nq == qs.shape[1]
    data = model.createData()
    calls = [qs[i % len(qs)] for i in range(n_calls)]

    def floor():
        for q in calls:
            pin.forwardKinematics(model, data, q)

    runs = {"kinid": lambda: fit(m, obs, effects, **kw), "floor": floor}
    for c in CONFIGS:
        runs[c] = lambda c=c: scipy_run(c, r_only, r_and_J, x0)
    out = {k: f() for k, f in runs.items()}  # warm-up of every path
    times = {k: [] for k in runs}
    for _ in range(rounds):
        for k, f in runs.items():
            t = time.process_time()
            f()
            times[k].append(time.process_time() - t)
    med = {k: statistics.median(v) for k, v in times.items()}
    ss_kinid = float(np.sum(r_only(res.values[free]) ** 2))
    print(f"\n== {title}: {len(obs)} alignments, {len(free)} parameters ({int(free.sum())} identified), "
          f"{rounds} interleaved rounds, CPU time, medians ==")
    print(f"kinid fit                                     {med['kinid'] * 1e3:8.2f} ms  {res.iterations} iterations, "
          f"sum of squares {ss_kinid:.9g} µm², {res.message}")
    print(f"floor: {n_calls} forwardKinematics calls ({n_calls / len(obs):g} per alignment) on the model the fit "
          f"calls (nq {model.nq}; the machine's {m.model.nq}); computeJointJacobians calls: {jj}: "
          f"{med['floor'] * 1e3:.2f} ms")
    same = []
    for c in CONFIGS:
        sol = out[c]
        ss = float(np.sum(r_only(sol.x) ** 2))
        rel = (ss - ss_kinid) / ss_kinid
        ok = abs(rel) <= SAME_COST_RTOL
        same += [c] if ok else []
        print(f"scipy method={c[0]!r:5} x_scale={c[1]!r:5} {c[2]:8}     {med[c] * 1e3:8.2f} ms  {sol.nfev:3d} "
              f"evaluations, {sol.njev} Jacobians, sum of squares {ss:.9g} µm² (rel. diff. to kinid {rel:+.1e}"
              f"{'' if ok else ', NOT the same optimum'}), status {sol.status}")
    floor_ratio = med["kinid"] / med["floor"]
    if not same:
        print(f"  -> no scipy configuration reached kinid's optimum: no peer. kinid {floor_ratio:.2f}x its floor")
        return
    if hard:  # the same configurations from zero, once each: does scipy get there without kinid's start?
        r_zero, rJ_zero = scipy_problem(mr, dr, obs, free, np.zeros(d.n_params))
        for c in CONFIGS[::2]:
            t = time.process_time()
            sol = scipy_run(c, r_zero, rJ_zero, np.zeros(free.sum()))
            t = time.process_time() - t
            rel = (float(np.sum(sol.fun ** 2)) - ss_kinid) / ss_kinid
            print(f"  from zero: scipy method={c[0]!r:5} x_scale={c[1]!r:5} {c[2]}: {t * 1e3:7.2f} ms, {sol.nfev} "
                  f"evaluations, sum of squares rel. diff. to kinid {rel:+.1e}"
                  f"{'' if abs(rel) <= SAME_COST_RTOL else ' (NOT the same optimum)'}")
    peer = min(same, key=lambda c: med[c])
    ratio = med[peer] / med["kinid"]
    print(f"  -> peer (fastest reaching kinid's cost): method={peer[0]!r}, x_scale={peer[1]!r}, {peer[2]}, "
          f"{med[peer] * 1e3:.2f} ms: kinid {ratio:.2f}x {'faster' if ratio >= 1 else 'SLOWER'} than it; "
          f"kinid {floor_ratio:.2f}x its floor, the peer {med[peer] / med['floor']:.2f}x")


def main(rounds: int = 7):
    import bench_arm_far_frame as far

    print(f"numpy {np.__version__}, scipy {scipy.__version__}, pinocchio {pin.__version__}; one BLAS thread")
    started = time.perf_counter()
    m = load_machine(path("five_axis_bc"))
    effects, theta = errors_from_mapping(json.loads((ROOT / "examples" / "errors.json").read_text()), m)
    rng = np.random.default_rng(0)
    obs = simulate(m, patent_plan(m), effects, theta, noise_um=1.0, rng=rng)
    obs10 = simulate(m, repeated_plan(m, 10), effects, theta, noise_um=1.0, rng=rng)
    arm, tm, arm_effects, arm_free = far.arm()
    train, _, _, _ = far.draw(arm, tm, arm_free, 0)
    with threadpool_limits(1):
        compare("README example (near-linear), sigma 1 um given", m, obs, None, rounds, noise_um=1.0)
        compare("README example x10 (near-linear), sigma 1 um given", m, obs10, None, max(3, rounds // 2), noise_um=1.0)
        compare("arm, far turned frame, draw 0 (hard), sigma from the residuals", arm, train, arm_effects, rounds,
                hard=True)
    print(f"\ntotal benchmark time {time.perf_counter() - started:.1f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:2]))
