"""When the plan's order makes time follow an axis: which axes, whether the effect found is driven by time or by
such an axis, and whether a drift (or warm-up) and an error of that axis explain the data alike."""
from __future__ import annotations

import numpy as np

from ..model import Machine, basis_of, parse_effect
from ..data import Observations

__all__ = ["time_follows", "TIME_CONFOUND", "ALIKE_CHI2", "time_or_axis", "inseparable_by_time"]

#: |correlation| of time with an axis's readings beyond which the plan's order confounds them.
TIME_CONFOUND = 0.8


def time_follows(obs: Observations, machine: Machine) -> tuple:
    """(axis, correlation) for every axis whose readings follow time in ``obs`` (|r| ≥ TIME_CONFOUND)."""
    if obs.t_s is None or len(obs) < 3 or np.ptp(obs.t_s) <= 0:
        return ()
    out = []
    for k, a in enumerate(machine.axes):
        q = obs.axes[:, k]
        if np.all(np.isfinite(q)) and np.ptp(q) > 0:
            rho = float(np.corrcoef(obs.t_s, q)[0, 1])
            if abs(rho) >= TIME_CONFOUND:
                out.append((a.name, rho))
    return tuple(out)


#: Two candidates whose χ² drops differ by less than this explain the data alike (χ²₂ at 1 %).
ALIKE_CHI2 = 9.21


def time_or_axis(machine, candidate, axes) -> str:
    """``time`` for a candidate driven by time, ``axis`` for one driven by the position of one of ``axes``, else
    ``""``."""
    e = parse_effect(candidate.effect, machine)
    driver = basis_of(e).driver
    if driver == "time":
        return "time"
    if driver in ("position", "positions") and (e.axis in axes or set(e.args) & axes):
        return "axis"
    return ""


def inseparable_by_time(machine, live, follows) -> str:
    """When time follows an axis: the best candidate and the best of the other kind (an error driven by time against
    one driven by that axis's position) if they explain the data alike; "" otherwise."""
    if not follows or not live:
        return ""
    axes = {a for a, _ in follows}

    def kind(c):
        return time_or_axis(machine, c, axes)

    best = live[0]
    mine = kind(best)
    if not mine:
        return ""
    other = next((c for c in live[1:] if kind(c) not in ("", mine)), None)
    if other is None or best.statistic - other.statistic >= ALIKE_CHI2:
        return ""
    axis = ", ".join(sorted(axes))
    return (f"{best.effect} and {other.effect} explain these data alike (χ² drops {best.statistic:.1f} and "
            f"{other.statistic:.1f}): time follows {axis} in the order of these alignments, so an error that grows with "
            f"time and one of {axis}'s position cannot be told apart (--auto adds neither) — measure "
            f"in another order (serpentine or random over {axis}, or a reference pose repeated through the run) to "
            f"tell them apart")
