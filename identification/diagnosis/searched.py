"""The candidates a diagnosis scores (:func:`score_all`): the library's, and those found by search rather than
listed — the best free period of the position-dependent joints, warm-up time constants off the library's grid and
steps at a searched position (:mod:`~kinid.identification.diagnosis.steps`), each with its p-value multiplied by
the trials the search made — and the refined time constant of a warm-up the selection adds. All are judged by the score test (:func:`~kinid.identification.diagnosis.scoring.score_candidates`)."""
from __future__ import annotations

import math

import numpy as np

from ..model import Machine, candidate_library, chosen_of
from ..data import Observations
from ..fitting import FitResult, model_pass
from .periods import bounded_minimum
from .scoring import score_candidates

__all__ = ["score_all", "found_periods", "found_time_constants", "refined_time_constant", "period_found_on",
           "FOUND_PERIODS",
           "PERIOD_GAIN_MIN", "TAU_GRID", "TAU_JOINTS", "TAU_REFINE_FACTOR"]


#: Joints whose best searched period is scored as a candidate (the strongest first).
FOUND_PERIODS = 4


#: χ² gain a free period needs over the joint's best listed period (χ²₁ at p = 0.001).
PERIOD_GAIN_MIN = 10.83


def found_periods(machine, obs, result, scored, sigma, known, d_errors, q0, side=None) -> list:
    """Candidates at periods the library does not list, found by :func:`~kinid.identification.diagnosis.periods.search_periods`.

    Each is scored like a library candidate, then its p-value is multiplied by
    the number of independent periods searched for its joint.
    """
    from dataclasses import replace

    from kinid.errors import DataError

    from ..model import LINEAR_PERIODS_MM, ROTARY_PERIODS_DEG, parse_effect
    from .periods import search_periods

    r = result.residuals_um.ravel() / sigma
    r = r - q0 @ (q0.T @ r)
    have = {c.effect for c in scored}
    # the best χ² drop of a listed period, per joint: a free period must beat it by more than one
    # extra parameter gains by chance (χ²₁ at 0.001), else the listed period is the simpler account
    listed_best = {}
    for c in scored:
        if c.status == "live" and chosen_of(c.effect) == "period":
            code = c.effect.split(":")[0]
            listed_best[code] = max(listed_best.get(code, 0.0), c.statistic)
    out = []
    estimates = search_periods(machine, obs, r, d_errors, q0, sigma, refine=FOUND_PERIODS,
                               joint_series=side.joint_series if side is not None and side.result is result
                               and side.sigma == sigma else None)
    joints = max(len(estimates), 1)  # the best of every joint's search is taken: the trials multiply
    for est in estimates[:FOUND_PERIODS]:
        listed = ROTARY_PERIODS_DEG if est.unit == "deg" else LINEAR_PERIODS_MM
        if est.effect in have or any(abs(est.period - p) <= max(2 * est.period_std, 1e-9 * p) for p in listed):
            continue  # the library's own candidate covers it
        if est.statistic - listed_best.get(est.code, 0.0) < PERIOD_GAIN_MIN:
            continue
        try:
            effect = parse_effect(est.effect, machine)
        except DataError:
            continue
        c = score_candidates(machine, obs, result, [effect], sigma, sigma_known=known, d_errors=d_errors, q0=q0,
                             side=side)[0]
        if c.status != "live":
            continue
        trials = est.trials * joints
        log10_p = min(0.0, c.log10_p + math.log10(trials))
        note = (f"period found by search: {est.period:.4g} ± {est.period_std:.2g} {est.unit} (1σ) "
                f"(p-value × {trials:.0f}: {est.trials:.0f} periods of {joints} joints searched)")
        out.append(replace(c, p_value=min(1.0, 10.0**log10_p), log10_p=log10_p, note=note, trials=trials))
        have.add(est.effect)
    return out


#: Warm-up time constants searched per joint (log grid from a minute to three times the run) and the joints
#: searched: those whose best listed warm-up candidate is strongest.
TAU_GRID = 24
TAU_JOINTS = 3


def found_time_constants(machine, obs, result, scored, sigma, known, d_errors, q0, side=None) -> list:
    """Warm-up candidates at time constants the library does not list: for the joints whose listed warm-up
    scores best, the χ² drop over a log grid of τ, refined by a bounded search in log τ; the p-value is
    multiplied by the τ and joints searched. Proposed only where it gains over the listed τ."""
    from dataclasses import replace

    from kinid.errors import DataError

    from ..model import parse_effect

    if obs.t_s is None or not np.ptp(obs.t_s) > 0:
        return []
    listed = {}
    for c in scored:
        if c.status == "live" and chosen_of(c.effect) == "time constant":
            code = c.effect.split(":")[0]
            if code not in listed or c.statistic > listed[code].statistic:
                listed[code] = c
    codes = sorted(listed, key=lambda k: -listed[k].statistic)[:TAU_JOINTS]
    span = float(np.max(obs.t_s))
    if not codes or not span > 60.0:
        return []
    grid = np.geomspace(60.0, 3.0 * span, TAU_GRID)
    have = {c.effect for c in scored}

    def score(code, taus):
        try:
            effects = [parse_effect(f"{code}:warmup:{t:.5g}", machine) for t in taus]
        except DataError:
            return []
        return score_candidates(machine, obs, result, effects, sigma, sigma_known=known, d_errors=d_errors, q0=q0,
                                side=side)

    out = []
    for code in codes:
        on_grid = score(code, grid)
        if not on_grid:
            continue
        k = int(np.argmax([c.statistic if c.status == "live" else -np.inf for c in on_grid]))
        lo, hi = np.log(grid[max(k - 1, 0)]), np.log(grid[min(k + 1, len(grid) - 1)])
        best_u, _ = bounded_minimum(lambda u: -(score(code, [np.exp(u)]) or [on_grid[k]])[0].statistic, lo, hi,
                                    xatol=0.01, maxiter=20)
        c = score(code, [np.exp(best_u)])[0]
        if c.status != "live" or c.statistic < on_grid[k].statistic:
            c = on_grid[k]
        if c.status != "live" or c.effect in have or c.statistic - listed[code].statistic < PERIOD_GAIN_MIN:
            continue
        trials = float(TAU_GRID * len(codes))
        log10_p = min(0.0, c.log10_p + math.log10(trials))
        tau = c.effect.rpartition(":")[2]
        note = f"time constant found by search: τ = {tau} s (p-value × {trials:.0f}: {TAU_GRID} τ of {len(codes)} joints)"
        out.append(replace(c, p_value=min(1.0, 10.0**log10_p), log10_p=log10_p, note=note, trials=trials))
    return out


#: An added warm-up's time constant is refined within this factor either side of the candidate's.
TAU_REFINE_FACTOR = 3.0


def refined_time_constant(machine: Machine, obs: Observations, result: FitResult, name: str, sigma: float,
                          d_errors=None) -> str:
    """``CODE:warmup:<τ>`` with τ refined to the one whose candidate explains most of the residuals of ``result``
    (a log grid within TAU_REFINE_FACTOR of the candidate's τ, then a bounded search in log τ); any other name as
    it is. A warm-up is proposed at the τ of the library's grid (a factor 3 apart) or of the search, whose trials
    penalty may keep a better τ out; fitted at a τ off the machine's, its amplitude misses the growth between.
    ``d_errors``: the error-joint Jacobian to score with (else one pass at ``result``)."""
    from ..model import parse_effect
    from .scoring import fit_side

    code, _, tau = (name.split(":") + ["", ""])[:3]
    if chosen_of(name) != "time constant" or obs.t_s is None:
        return name
    d_errors, _, q0 = model_pass(machine, obs, result, d_errors)
    side = fit_side(machine, obs, result, sigma, d_errors, q0)  # one for the thirty-odd τ scored

    def named(log_tau) -> str:  # four significant digits, never in exponent notation
        digits = np.format_float_positional(math.exp(log_tau), precision=4, unique=False, fractional=False, trim="-")
        return f"{code}:warmup:{digits}"

    def statistic(log_tau) -> float:
        c = score_candidates(machine, obs, result, [parse_effect(named(log_tau), machine)], sigma, sigma_known=False,
                             d_errors=d_errors, q0=q0, side=side)[0]
        return c.statistic if c.status == "live" else -math.inf

    grid = np.log(float(tau)) + np.linspace(-1.0, 1.0, 13) * math.log(TAU_REFINE_FACTOR)
    values = [statistic(u) for u in grid]
    k = int(np.argmax(values))
    found_u, found = bounded_minimum(lambda u: -statistic(u), grid[max(k - 1, 0)], grid[min(k + 1, len(grid) - 1)],
                                     xatol=0.01, maxiter=20)
    best_u, best = (found_u, -found) if -found > values[k] else (grid[k], values[k])
    return named(best_u) if best > values[len(grid) // 2] else name  # the middle of the grid: τ as given


def period_found_on(machine: Machine, obs: Observations, result: FitResult, code: str, range_of=None,
                    d_errors=None):
    """The :class:`~kinid.identification.diagnosis.periods.PeriodEstimate` the search finds best for error joint ``code`` in
    the residuals of ``result`` on ``obs`` (over the periods the positions of ``range_of`` set, if given; with the
    error-joint Jacobian ``d_errors`` if given, else one at ``result``), or None.
    The held-out check chooses a periodic candidate's period on its training blocks with this: chosen on every
    alignment, the period of the best of many is fitted to the held-out blocks' noise too, and predicts them
    better than it would new ones."""
    from .periods import search_periods

    d_errors, _, q0 = model_pass(machine, obs, result, d_errors)
    r = result.residuals_um.ravel()
    found = search_periods(machine, obs, r - q0 @ (q0.T @ r), d_errors, q0, codes={code}, range_of=range_of)
    return found[0] if found else None


def score_all(machine: Machine, obs: Observations, result: FitResult, sigma: float, known: bool, d_errors, q0,
              side=None) -> list:
    """The candidates scored at ``result``: the library's, and the free periods, time constants and step positions
    found (the diagnosis adds the proposed maps and local errors, :mod:`~kinid.identification.diagnosis.local_errors`)."""
    from ..data import positions_per_axis
    from .scoring import fit_side
    from .steps import found_steps

    library = candidate_library(machine, result.effects, has_directions=bool(obs.directions),
                                has_time=obs.t_s is not None, positions=positions_per_axis(machine, obs))
    scored = score_candidates(machine, obs, result, library, sigma, sigma_known=known, d_errors=d_errors, q0=q0,
                              side=side)
    scored += found_periods(machine, obs, result, scored, sigma, known, d_errors, q0, side)
    scored += found_time_constants(machine, obs, result, scored, sigma, known, d_errors, q0, side)
    scored += found_steps(machine, obs, result, scored, sigma, known, d_errors, q0,
                          side or fit_side(machine, obs, result, sigma, d_errors, q0))
    return scored
