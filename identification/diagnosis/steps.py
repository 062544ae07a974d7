"""Steps at a searched position: an error joint whose value jumps where an axis passes a position nobody named.

A step (``EZZ:step:Y:40``, :mod:`~kinid.identification.model.step`) is listed nowhere: its position is searched. For
every error joint the readings move and every axis read at ``2 × MIN_SIDE_POSITIONS`` distinct positions or more
(:func:`~kinid.identification.data.positions_of`), the score test of the step is evaluated between every two
neighbouring positions with at least MIN_SIDE_POSITIONS on each side, in closed form (no refit per position): with
the readings sorted by the axis, the step's column on the side away from the axis's zero is the joint's column there,
so its product with the whitened residual ``r``, its squared norm and its products with the model's orthonormal
basis ``Q₀`` are sums over the rows beyond a cut — cumulative sums over the positions of the joint's series
(:func:`~kinid.identification.diagnosis.score_sums.joint_series`), and

    Δ(p) = (b − aᵀ Q₀ᵀr)² / (n − aᵀa),   b = Σ colᵀ r,  n = Σ |col|²,  a = Σ Q₀ᵀ col  over the rows beyond p,

the χ² drop the step would bring. It costs O(N · rank) per joint and axis. The best cuts of the FOUND_STEPS best
(joint, axis) pairs are scored by the score test like any candidate, their p-values multiplied by the number of cuts
searched over every pair (the best of all of them is taken), so the search raises no more false alarms on noise than
the threshold allows.

Between two neighbouring readings a step anywhere fits alike: the data place it only within that interval. The
candidate is named at a short number inside it (:func:`step_name`) and its note says the interval.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ..data import positions_of

__all__ = ["StepCut", "search_steps", "found_steps", "step_found_on", "step_name", "step_interval",
           "FOUND_STEPS", "MIN_SIDE_POSITIONS"]

#: (joint, axis) pairs whose best cut is scored as a candidate (the strongest first).
FOUND_STEPS = 4
#: Distinct positions of the axis a step needs on each side (one position alone is the error at that position).
MIN_SIDE_POSITIONS = 2
#: A cut whose column keeps less than this share of its squared norm after the projection off the model is aliased:
#: what is left of it is rounding (the score test scores nearly aliased ones exactly, these are not proposed).
ALIASED_SHARE = 1e-8


@dataclass(frozen=True)
class StepCut:
    """The best cut found for one (error joint, axis) pair.

    Attributes
    ----------
    code, axis : str
        Error joint and the axis whose position the step follows.
    low, high : float
        The neighbouring readings of the axis the step lies between (mm or deg): where in between, the data do not say.
    statistic : float
        χ² drop Δ at that cut.
    cuts : int
        Cuts searched for this pair.
    """

    code: str
    axis: str
    low: float
    high: float
    statistic: float
    cuts: int

    @property
    def effect(self) -> str:
        return f"{self.code}:step:{self.axis}:{step_name(self.low, self.high)}"


def step_name(low: float, high: float) -> str:
    """A position between the readings ``low`` < ``high`` as written in a step's name: the shortest decimal in the
    middle half of the interval (``38.13``, ``41.87`` -> ``40``), else the middle to 6 significant digits."""
    width = high - low
    for decimals in range(-3, 7):
        x = round(0.5 * (low + high), decimals) + 0.0  # (+ 0.0: no "-0")
        if low + 0.25 * width <= x <= high - 0.25 * width:
            return f"{x:.{max(decimals, 0)}f}"
    return f"{0.5 * (low + high):.6g}"


def _cut_sums(order, starts, series):
    """Per cut between positions k and k + 1 (P − 1 cuts): the sums of ``series`` (nrm, rw, g) over the rows at or
    below it and over all rows."""
    below, total = [], []
    for x in series:
        s = np.add.reduceat(x[order], starts, axis=0)
        below.append(np.cumsum(s, axis=0)[:-1])
        total.append(s.sum(axis=0))
    return below, total


def _deltas(beyond_zero, below, total, q0r):
    """Δ (P − 1,) of each cut, the step's column on the side away from the axis's zero (``beyond_zero``: rows above
    the cut)."""
    nrm, rw, g = (np.where(beyond_zero.reshape((-1,) + (1,) * (b.ndim - 1)), t - b, b) for b, t in zip(below, total))
    proj = nrm - np.einsum("pr,pr->p", g, g)
    b = rw - g @ q0r
    live = proj > ALIASED_SHARE * np.maximum(nrm, 1e-300)
    return np.where(live, b * b / np.where(live, proj, 1.0), 0.0)


def search_steps(machine, obs, joint_series, codes=None, axes=None, lever=None, lever_floor: float = 0.0) -> list:
    """The best cut of every (error joint, axis) pair the data can test (a cut not aliased with the model), best
    first (:class:`StepCut`).

    Parameters
    ----------
    joint_series : callable (error joint index) -> tuple
        The score test's series of each joint at the fit (nrm, rw, g, Q₀ᵀr: :func:`~.score_sums.joint_series`).
    codes, axes : set of str, optional
        Search only these error joints and axes (default: every one).
    lever, lever_floor : array (n_errors,), float
        Joints whose RMS lever arm is below the floor are invisible, not searched.
    """
    out = []
    cuts_of = {}
    for k, a in enumerate(machine.axes):
        if (axes is not None and a.name not in axes) or not np.all(np.isfinite(obs.axes[:, k])):
            continue  # (an axis the data do not read)
        q = positions_of(obs.axes[:, k])
        order = np.argsort(q, kind="stable")
        qs = q[order]
        starts = np.flatnonzero(np.r_[True, qs[1:] != qs[:-1]])
        if starts.size < 2 * MIN_SIDE_POSITIONS:
            continue
        raw = obs.axes[order, k]
        low = np.maximum.reduceat(raw, starts)[:-1]  # the readings either side of each cut
        high = np.minimum.reduceat(raw, starts)[1:]
        at = np.array([float(step_name(lo, hi)) for lo, hi in zip(low, high)])  # as the candidate will be named
        cuts_of[a.name] = (order, starts, low, high, at >= 0.0)
    side = slice(MIN_SIDE_POSITIONS - 1, -(MIN_SIDE_POSITIONS - 1) or None)
    for j, joint in enumerate(machine.error_joints):
        if (codes is not None and joint.code not in codes) or (lever is not None and lever[j] < lever_floor):
            continue
        series = joint_series(j)
        if not np.any(series[0] > 0):
            continue
        for axis, (order, starts, low, high, beyond_zero) in cuts_of.items():
            below, total = _cut_sums(order, starts, series[:3])
            delta = _deltas(beyond_zero, below, total, series[3])[side]
            if not delta.size or not np.max(delta) > 0:
                continue
            i = int(np.argmax(delta))
            out.append(StepCut(joint.code, axis, float(low[side][i]), float(high[side][i]), float(delta[i]),
                               int(delta.size)))
    # by decreasing Δ; joints whose columns coincide on these data tie to rounding (TIE_SHARE): a joint of the axis
    # the step follows first (where a step is at home: a scale's or a rail's joint), then the machine's, then set-ups
    out.sort(key=lambda c: -c.statistic)
    ties = [[]]
    for c in out:
        if ties[-1] and not _same(ties[-1][0], c):
            ties.append([])
        ties[-1].append(c)
    return [c for tie in ties for c in sorted(tie, key=lambda c: _home(machine, c))]


#: Cuts of one interval whose Δ agree to this share are one column of several joints: they coincide on these data
#: but for the fit's own small rotations (three translations in Z of an XYZ stage: EZ0J1, EZ0J2, EZ0T differ by 1e-5).
TIE_SHARE = 1e-4


def _same(a, b) -> bool:
    return (a.axis, a.low, a.high) == (b.axis, b.low, b.high) and abs(a.statistic - b.statistic) <= \
        TIE_SHARE * max(a.statistic, b.statistic)


def _home(machine, cut) -> int:
    axis = machine.error_joint(cut.code).axis
    return 0 if axis == cut.axis else 2 if axis in ("W", "T") else 1


def step_interval(machine, obs, name: str):
    """(low, high): the readings of the step ``name``'s axis either side of its position in ``obs`` (None for a side
    with no reading)."""
    from ..model import parse_effect

    e = parse_effect(name, machine)
    q = obs.axes[:, machine.axis_names.index(e.axis)]
    at = float(e.args[0])
    below, above = q[q <= at], q[q > at]
    return (float(below.max()) if below.size else None, float(above.min()) if above.size else None)


def found_steps(machine, obs, result, scored, sigma, known, d_errors, q0, side) -> list:
    """Step candidates at searched positions (:func:`search_steps`): the best cut of each of the FOUND_STEPS best
    (joint, axis) pairs, scored like a library candidate, its p-value multiplied by every cut searched."""
    from kinid.errors import DataError

    from ..model import parse_effect
    from .scoring import INVISIBLE_LEVER_M, score_candidates

    cuts = search_steps(machine, obs, side.joint_series, lever=side.lever, lever_floor=INVISIBLE_LEVER_M)
    trials = float(sum(c.cuts for c in cuts))
    have = {c.effect for c in scored}
    effects, found = [], []
    for cut in cuts:
        if len(effects) == FOUND_STEPS:
            break
        try:
            effect = parse_effect(cut.effect, machine)
        except DataError:  # (a position the basis refuses)
            continue
        if effect.name not in have and not any(_same(cut, other) for other in found):  # coinciding joints: one
            effects.append(effect)
            found.append(cut)
    out = []
    scored_here = score_candidates(machine, obs, result, effects, sigma, sigma_known=known, d_errors=d_errors,
                                   q0=q0, side=side) if effects else []
    for c, cut in zip(scored_here, found):
        if c.status != "live":
            continue
        log10_p = min(0.0, c.log10_p + math.log10(max(trials, 1.0)))
        unit = "mm" if machine.axis(cut.axis).kind == "prismatic" else "°"
        note = (f"step position found by search: between the readings {cut.axis} = {cut.low:.6g} and {cut.high:.6g} "
                f"{unit}, where in between the data do not say (p-value × {trials:.0f}: every cut between two "
                f"readings of {len({c.axis for c in cuts})} axes for {len({c.code for c in cuts})} joints)")
        out.append(replace(c, p_value=min(1.0, 10.0**log10_p), log10_p=log10_p, note=note, trials=trials))
    return out


def step_found_on(machine, obs, result, name: str, d_errors=None):
    """The step the search finds best for the error joint and axis of step ``name`` in the residuals of ``result``
    on ``obs`` (a turn's training blocks: the held-out check chooses its position again on them), as an effect name;
    ``name`` itself where the best cut is the interval it lies in, or where none is found."""
    from kinid.errors import DataError

    from ..fitting import model_pass
    from ..model import parse_effect
    from .score_sums import joint_series

    e = parse_effect(name, machine)
    d_errors, _, q0 = model_pass(machine, obs, result, d_errors)
    r = result.residuals_um.ravel()
    r = r - q0 @ (q0.T @ r)
    q0r = q0.T @ r
    cuts = search_steps(machine, obs, lambda i: joint_series(d_errors[:, :, i], q0, r, q0r), codes={e.code},
                        axes={e.axis})
    if not cuts or cuts[0].low <= float(e.args[0]) < cuts[0].high:
        return name
    try:
        return parse_effect(cuts[0].effect, machine).name
    except DataError:  # (a position the basis refuses)
        return name
