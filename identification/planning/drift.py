"""Drift checks: the plan's first alignment measured again at intervals over the run, so that a drift or a warm-up
is seen apart from the geometry (ISO 230-3's drift check: a reference pose at the start, during and at the end).

A warm-up during the run is a time effect. Without a reading that repeats, its power in the diagnosis rests on the
order alone: every other alignment is at another pose, and the geometry's effects take a share of what time did.
Where the fit names no time effect, the constant offsets take the warm-up's mean over the run, and the cold machine
(t = 0) is predicted off by it. The reference read again at the same pose differs only by the drift and the noise.

How many: the run's duration enters through the time effects' shapes at the readings' times (a drift grows with
``t``, a warm-up as ``1 − e^(−t/τ)``), the noise through the whitening. Each **time probe** is a time candidate of
the diagnosis's library (a drift of every error joint, a warm-up of every location error at its time constants);
its size is how far, left out of the fit, it moves the cold machine's prediction: the model's parameters fitted to
it over the plan's readings, evaluated over the candidates' poses at t = 0 (2·RMS per coordinate, µm, the scale of
the target and of :mod:`~kinid.identification.planning.reach`). The fewest checks at which every probe the checks
can reach is detected with the power asked, by the diagnosis's F test at its Bonferroni level, are taken, at most
:data:`MAX_CHECK_SHARE` of the chosen alignments; where even the most reach none, the most. A probe the most checks
still leave below the power is named, not planned for.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .order import Order, TravelModel, with_checks
from .reach import _lambda_min, _power, _shapes

__all__ = ["DriftChecks", "drift_checks", "MAX_CHECK_SHARE", "MIN_CHECKS"]

#: The checks add at most this share of the plan's chosen alignments. The loop (benchmarks/proving_loop.py, seed 1,
#: warm-up 4–8 µm) at 0.25 and 0.5: B/C 10 scenarios 0.508 and 0.558 µm (before 0.626), gantry 20 scenarios 1.168
#: and 0.926 µm (before 1.221); at 0.25 the first plans' checks are the cap (docs/plan.md).
MAX_CHECK_SHARE = 0.25
#: Fewest readings of the reference when the checks are asked for: the start, the middle, the end.
MIN_CHECKS = 3
#: Time (s) at which the probes' Jacobians are taken, then scaled by their shapes at each reading's time.
_T_UNIT_S = 3600.0


@dataclass(frozen=True)
class DriftChecks:
    """The plan's drift checks (:func:`drift_checks`).

    Attributes
    ----------
    count : int
        Readings of the reference alignment (the run's first) over the run, the first and the last included.
    interval_s : float
        Longest time between two readings of it, s.
    size_um : float
        The time effect's size probed: how far, left out of the fit, it moves the cold machine's prediction (2·RMS per
        coordinate over the candidates' poses), µm; 0 when the count was given.
    power : float
        The power asked.
    weakest : str
        The time probe detected least surely among those the checks reach ("" where they reach none).
    weakest_power : float
    unreachable : tuple of str
        Time probes even the most checks leave below ``power``.
    most : int
        The most checks tried (:data:`MAX_CHECK_SHARE` of the chosen alignments); 0 when the count was given.
    probes : int
        Time probes (the diagnosis's time candidates that move the cold machine's prediction); 0 when the count was
        given.
    """

    count: int
    interval_s: float
    size_um: float
    power: float
    weakest: str
    weakest_power: float
    unreachable: tuple
    most: int = 0
    probes: int = 0


def _time_probes(machine, effects, chosen, noise_um: float):
    """(names, whitened Jacobians (n, 3, 1) at ``t = _T_UNIT_S`` over ``chosen``, their shape functions of t, the
    library's size)."""
    from ..fitting import design, residuals
    from ..model import basis_of, candidate_library

    library = candidate_library(machine, effects, has_directions=False, has_time=True)
    probes = [e for e in library if basis_of(e).driver == "time"]
    obs = replace(chosen, t_s=np.full(len(chosen), _T_UNIT_S))
    d = design(machine, probes, obs)
    _, Je, _ = residuals(machine, d, obs, np.zeros(d.n_params))
    names, blocks, shapes, start = [], [], [], 0
    for e in probes:
        k = e.n_params
        values = basis_of(e).values
        at_unit = float(np.ravel(values(e, None, np.array([_T_UNIT_S]), None))[0])
        names.append(e.name)
        blocks.append(Je[:, :, start:start + k] / noise_um / at_unit)
        shapes.append(lambda t, e=e, values=values: np.asarray(values(e, None, t, None), float)[:, 0])
        start += k
    return names, blocks, shapes, len(library)


def _powers(J_rows, J_volume, t_s, rows, probes, size_um: float, noise_um: float, alpha: float) -> dict:
    """Each time probe's power on the plan's rows (``J_rows`` the model's whitened Jacobian there, ``rows`` their
    index into the chosen alignments, ``t_s`` their times) at the size where, left out of the model, it moves the
    cold machine's prediction (``J_volume``, whitened, at t = 0) by ``size_um`` (2·RMS per coordinate)."""
    names, blocks, shapes, _ = probes
    X = J_rows.reshape(-1, J_rows.shape[2])
    V = J_volume.reshape(-1, J_volume.shape[2]) * noise_um
    out = {}
    for name, Je, shape in zip(names, blocks, shapes):
        Je_rows = Je[rows] * shape(t_s)[:, None, None]
        Z = Je_rows.reshape(-1, Je_rows.shape[2])
        cold = V @ np.linalg.lstsq(X, Z, rcond=None)[0]  # what the model's parameters take of it, at t = 0, µm
        T = _shapes((cold.T @ cold / len(cold), float(np.linalg.eigvalsh(Z.T @ Z / len(Z)).max()) * noise_um**2))
        if T.shape[1] == 0:
            continue
        lam, _ = _lambda_min(J_rows, Je_rows, T, size_um / 2.0)
        out[name] = _power(lam, T.shape[1], 3 * len(rows) - J_rows.shape[2] - T.shape[1], alpha)
    return out


def drift_checks(machine, effects, chosen, J_chosen, J_volume, order: Order, X, linear, wraps, travel: TravelModel,
                 names, *, noise_um: float, size_um: float | None, power: float, alpha_total: float,
                 count: int | None = None) -> tuple[Order, DriftChecks]:
    """``order`` (of the ``chosen`` alignments, readings ``X``; ``J_chosen`` the model's whitened Jacobian over them,
    ``J_volume`` over the candidates' poses, the cold machine's volume) with its reference read ``count`` times over the run, or (``count`` None) the fewest times that detect every time
    probe of ``size_um`` with ``power`` (module docstring). Returns (the order, :class:`DriftChecks`)."""
    def ordered(k):
        return with_checks(order, X, k, linear, wraps, travel, names)

    def interval(o):
        at = o.t_s[o.index == o.reference]
        return float(np.diff(at).max()) if len(at) > 1 else float(o.total_s)

    if count is not None or size_um is None:
        k = MIN_CHECKS if count is None else count
        o = ordered(k)
        return o, DriftChecks(int(np.sum(o.index == o.reference)), interval(o), 0.0, power, "", 1.0, ())
    probes = _time_probes(machine, effects, chosen, noise_um)
    alpha = alpha_total / max(probes[3], 1)

    def powers(o):
        return _powers(J_chosen[o.index], J_volume, o.t_s, o.index, probes, size_um, noise_um, alpha)

    most = max(MIN_CHECKS, int(MAX_CHECK_SHARE * len(chosen)))
    at_most = powers(ordered(most))
    reachable = {n for n, p in at_most.items() if p >= power}
    lo, hi = MIN_CHECKS, most
    best = ordered(lo if reachable else most)  # none reachable: as many as the plan allows, for what they can see
    now = powers(best)
    if reachable and any(now[n] < power for n in reachable):  # the fewest that reach: powers grow with the checks
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if all(p >= power for n, p in powers(ordered(mid)).items() if n in reachable):
                hi = mid
            else:
                lo = mid
        best = ordered(hi)
        now = powers(best)
    live = {n: p for n, p in now.items() if n in reachable}
    weakest = min(live, key=live.get) if live else ""
    return best, DriftChecks(int(np.sum(best.index == best.reference)), interval(best), float(size_um), power,
                             weakest, float(live.get(weakest, 0.0)), tuple(sorted(set(now) - reachable)), most,
                             len(now))
