"""Is a periodic effect's period determined by the positions the data visit?

On few distinct positions of an axis, periodic errors of very different periods take nearly the same values
there: an A/C table whose plan repeats the same six table angles at every tilt visits X at six positions, and a
2, 10 and 20 mm lead then fit alike (residual 0.571, 0.572, 0.574 µm) while they differ everywhere between
those positions. The continuous period search guards itself (it searches no period shorter than twice the
positions' spacing); a period of the candidate library has no such guard. Before a periodic effect is added,
every period of the same error joint from :data:`~kinid.identification.diagnosis.periods.MIN_PERIOD_MM` (or ``_DEG``) to
twice the travel seen (and, on a rotary axis, every whole number of cycles per turn) is scored (the score test
at the fit, no refit); a period outside the effect's own peak
(its frequency more than one cycle over the span away) whose χ² drop falls short of the effect's by less than
:data:`TWIN_DELTA` (what two alternatives of two parameters differ by at 1 %) is a twin, and the period is not
determined. As in the period search, the longest of periods
that alias on a regular grid of positions is the convention: for a period at or above twice the positions'
spacing only periods there are twins; one below it has to beat every period.
"""
from __future__ import annotations

import math

import numpy as np

from ..model import Machine
from ..data import Observations, distinct_positions

__all__ = ["period_twins", "TWIN_DELTA", "TWIN_PERIODS"]

#: A period whose χ² drop falls short of the effect's by less than this explains the data as well: the data cannot
#: tell the two apart (χ²₂ at 0.99: two periodic effects of two parameters each, compared at the same σ).
TWIN_DELTA = 9.21
#: Periods scored per check (log-spaced).
TWIN_PERIODS = 160


def period_twins(machine: Machine, obs: Observations, result, effect: str, sigma: float, *, d_errors=None,
                 q0=None, side=None) -> tuple:
    """Periods (in the axis's unit) of the same error joint that explain the residual about as well as
    ``effect`` (``E??:periodic:P``), outside its own peak; empty when the period is determined."""
    from ..model import basis_of
    from ..model import parse_effect
    from .periods import MIN_PERIOD_DEG, MIN_PERIOD_MM
    from .scoring import score_candidates

    e = parse_effect(effect, machine)
    if basis_of(e).chosen != "period":
        return ()
    joint = machine.error_joint(e.code)
    period = float(effect.split(":")[2])
    q = obs.axes[:, machine.axis_names.index(joint.axis)]
    span = float(np.ptp(q))
    if span <= 0:
        return ()
    rotary = machine.axis(joint.axis).kind != "prismatic"
    low = MIN_PERIOD_DEG if rotary else MIN_PERIOD_MM
    high = 360.0 if rotary else 2.0 * span
    periods = np.geomspace(low, max(high, low * 1.01), TWIN_PERIODS)
    if rotary:  # and every whole number of cycles per turn (a gear of n teeth): the twins the selection prefers
        periods = np.union1d(periods, 360.0 / np.arange(1, math.floor(360.0 / low) + 1))
    far = np.abs(1.0 / periods - 1.0 / period) > 1.0 / span  # outside the effect's own peak
    # as the period search: on a grid of positions, periods below twice its spacing alias onto longer ones, and
    # the longest is taken by convention; a period at or above that limit only competes with those there too
    distinct = distinct_positions(q)
    limit = 2.0 * float(np.median(np.diff(distinct))) if distinct.size > 1 else np.inf
    if period >= limit:
        far &= periods >= limit
    names = [f"{e.code}:periodic:{p:.6g}" for p in periods[far]]
    scored = score_candidates(machine, obs, result, [parse_effect(effect, machine)] +
                              [parse_effect(n, machine) for n in names], sigma, sigma_known=False,
                              d_errors=d_errors, q0=q0, side=side)
    by_name = {c.effect: c for c in scored}
    own = by_name[effect].statistic if effect in by_name else 0.0
    if not own > 0:
        return ()
    return tuple(float(n.split(":")[2]) for n in names
                 if n in by_name and by_name[n].status == "live" and by_name[n].statistic > own - TWIN_DELTA)
