"""The fit's Levenberg–Marquardt step (CasADi's qrqp through the function's buffers): the step the normal equations
give, the bounds kept, and one thread's call never reading another's numbers."""
import sys
import threading

import numpy as np

from kinid.identification.fitting.lm_step import lm_step


def _problem(seed, m=12, n=7):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(m, n)), rng.normal(size=m)


def test_unbounded_step_is_the_normal_equations_solution():
    for seed in range(5):
        Js, r = _problem(seed)
        lam = 10.0 ** -seed
        n = Js.shape[1]
        want = np.linalg.solve(Js.T @ Js + lam * np.eye(n), -Js.T @ r)
        got = lm_step(Js, r, lam, np.full(n, -np.inf), np.full(n, np.inf))
        assert np.allclose(got, want, rtol=1e-9, atol=1e-12)


def test_bounded_step_keeps_the_bounds_and_is_optimal_within_them():
    Js, r = _problem(7)
    n = Js.shape[1]
    free = np.linalg.solve(Js.T @ Js, -Js.T @ r)
    lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
    hi[0] = free[0] - 0.5 * abs(free[0]) - 0.1  # the unbounded step's first value is out of bounds
    got = lm_step(Js, r, 0.0, lo, hi)
    assert got[0] == np.clip(got[0], -np.inf, hi[0]) and abs(got[0] - hi[0]) < 1e-9  # at its bound
    g = Js.T @ (Js @ got + r)  # the gradient: zero on the free values, pushing outwards on the bound one
    assert np.allclose(g[1:], 0.0, atol=1e-9) and g[0] < 0


def test_threads_get_their_own_steps():
    problems = [_problem(seed, m=10 + seed % 2, n=5) for seed in range(4)]  # two sizes shared by two threads each
    inf = np.full(5, np.inf)
    alone = [lm_step(Js, r, 1e-3, -inf, inf) for Js, r in problems]
    seen = [[] for _ in problems]

    def work(k):
        Js, r = problems[k]
        for _ in range(3000):
            seen[k].append(lm_step(Js, r, 1e-3, -inf, inf))

    threads = [threading.Thread(target=work, args=(k,)) for k in range(len(problems))]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # threads take turns every few bytecodes: between a call's writing and its reading
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        sys.setswitchinterval(interval)
    for k, steps in enumerate(seen):
        assert len(steps) == 3000 and all(np.array_equal(s, alone[k]) for s in steps)
