"""Errors no parametric candidate describes: a non-parametric map over an axis's measured range, or a local
error in a window of it, proposed as candidates of the diagnosis (:func:`proposed_maps`).

A map (``CODE:map:<step>:<from>:<to>``) needs readings at every knot; a local error
(``CODE:local:<step>:<from>:<to>``, cubic B-splines zero at and beyond the window's ends) needs them only
inside its window. Windows are tried inside the best maps and on the joints of the best candidates of any
kind, with knots every half, one and two map steps, and on every other joint, at a tenth of the test's level,
with knots every map step; around the likeliest of them with knots twice as close as its own; where they hold
more distinct positions of the axis than they have parameters. Each proposal's p-value is multiplied by the
maps or windows tried (over its share of the level), and it must beat the best parametric candidate by more
than its extra parameters would gain by chance.
"""
from __future__ import annotations

import math

import numpy as np

from kinid.stats import chi2_isf

from ..data import distinct_positions
from .scoring import score_candidates

__all__ = ["proposed_maps", "local_windows", "window_found_on"]


#: A proposed map must gain over the best parametric candidate more χ² than its extra parameters would
#: at this level.
MAP_GAIN_ALPHA = 1e-3


#: Readings (weighted by the knot's hat function) every knot of a proposed map must rest on.
MAP_MIN_SUPPORT = 3.0


#: Knot intervals over the measured range of an axis in a proposed map.
MAP_INTERVALS = 40


def _nice_step(span: float) -> float:
    """A round step (1, 2 or 5 × 10^k) close to span / MAP_INTERVALS."""
    raw = span / MAP_INTERVALS
    k = math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * 10**k >= raw:
            return m * 10**k
    return 10 ** (k + 1)  # pragma: no cover


def proposed_maps(machine, obs, result, scored, sigma, known, d_errors, q0, side=None) -> list:
    """The best non-parametric map (``CODE:map:<step>:<from>:<to>`` over the measured range), or a local error
    inside one, as a candidate.

    It competes with the parametric candidates on its p-value, so a map wins only where no parametric
    effect describes the structure. Local errors are tried inside the best maps and on the joints of the
    best candidates of any kind, and at LOCAL_ELSEWHERE_SHARE of the level on every other joint (windows whose
    coefficients rest on readings).
    """
    from dataclasses import replace

    from ..model import axis_dependent_joints

    maps, grids, axes = [], {}, {}
    for code, axis in axis_dependent_joints(machine):
        grid = _map_grid(machine, obs, code, axis, axes)
        if grid is None:
            continue
        whole, q, distinct, support = grid
        grids[code] = (whole, q, distinct)
        # a whole map needs readings at every knot; else they cluster at a few positions and a knot is a guess
        if distinct.size >= 2 * MAP_INTERVALS and support.min() >= MAP_MIN_SUPPORT:
            maps.append(whole)
    have = {c.effect for c in scored}
    fresh = [m for m in maps if m.name not in have]
    live = sorted((c for c in score_candidates(machine, obs, result, fresh, sigma, sigma_known=known, d_errors=d_errors,
                                               q0=q0, side=side) if c.status == "live"), key=lambda c: c.log10_p)
    best = live[0] if live else None
    # where to look for a local error: inside the best maps, and on the joints of the best candidates of any
    # kind (a local error of an axis read at too few positions for a whole map shows first as a long period
    # or a polynomial of its joint)
    codes = [c.effect.split(":")[0] for c in live[:LOCAL_MAPS]] + [
        c.effect.split(":")[0] for c in sorted((c for c in scored if c.status == "live"), key=lambda c: c.log10_p)[:LOCAL_MAPS]]
    codes = [c for c in dict.fromkeys(codes) if c in grids]
    # and, at a share of the test's level, on every other joint: a local error on few positions of its axis (a bump
    # narrower than the spacing of the readings) stands out on a few rows only, which no parametric candidate of
    # its joint describes, so its joint need not be among the best candidates
    others = [c for c in grids if c not in codes]
    found = []
    for tier, share, steps, home in ((codes, 1.0 - LOCAL_ELSEWHERE_SHARE, LOCAL_STEPS, codes[0] if codes else None),
                                     (others, LOCAL_ELSEWHERE_SHARE, LOCAL_ELSEWHERE_STEPS, None)):
        best_local, windows = _likeliest_window(machine, obs, result, tier, grids, sigma, known, d_errors, q0, side,
                                                home, steps)
        if best_local is not None:  # the best of the windows tried on these joints, at this tier's share of α
            found.append((best_local.log10_p + math.log10(len(windows) / share), best_local, windows, share))
    if found:
        log10_local, best_local, windows, share = min(found, key=lambda f: f[0])
        if best is None or log10_local < best.log10_p + math.log10(len(fresh)):
            if not _beats_parametric(best_local, scored):
                return []
            said = score_candidates(machine, obs, result, [next(w for w in windows if w.name == best_local.effect)],
                                    sigma, sigma_known=known, d_errors=d_errors, q0=q0, side=side)[0]
            return [replace(best_local, note=said.note, p_value=min(1.0, 10.0**min(0.0, log10_local)),
                            log10_p=min(0.0, log10_local), trials=len(windows) / share)]  # in words, the one kept
    if best is None or not _beats_parametric(best, scored):
        return []
    log10_p = min(0.0, best.log10_p + math.log10(len(fresh)))  # the best of len(fresh) maps
    return [replace(best, p_value=min(1.0, 10.0**log10_p), log10_p=log10_p, trials=float(len(fresh)))]


def _likeliest_window(machine, obs, result, codes, grids, sigma, known, d_errors, q0, side, home, steps):
    """(the likeliest local error on the joints ``codes`` — near ties, within a factor LOCAL_TIE in p, to the joint
    ``home`` — scored without its note, and the windows tried for it), or (None, windows) if none is live."""
    windows = [w for c in codes for w in _local_windows(*grids[c], machine, steps)]
    if not windows:
        return None, windows
    local = [c for c in score_candidates(machine, obs, result, windows, sigma, sigma_known=known, d_errors=d_errors,
                                         q0=q0, side=side, notes=False) if c.status == "live"]
    if not local:
        return None, windows

    def likeliest(found):
        return min(found, key=lambda c: c.log10_p - (math.log10(LOCAL_TIE) if home and c.effect.startswith(home + ":")
                                                     else 0.0))

    best_local = likeliest(local)
    # then with knots twice as close around it: a bump narrower than the knots of the windows tried along a long
    # axis is described by none of them, and finer windows everywhere would cost more than the rest of the test
    code = best_local.effect.split(":")[0]
    finer = _windows_around(*grids[code], next(w for w in windows if w.name == best_local.effect), machine, windows)
    if finer:
        windows += finer
        local += [c for c in score_candidates(machine, obs, result, finer, sigma, sigma_known=known, d_errors=d_errors,
                                              q0=q0, side=side, notes=False) if c.status == "live"]
        best_local = likeliest(local)
    return best_local, windows


def _map_grid(machine, obs, code: str, axis: str, axes=None):
    """(the whole map of error joint ``code`` over the range its axis's readings cover, the readings, their distinct
    positions, the readings each of the map's knots rests on), or None where the axis is read at too few positions
    for maps and local errors. ``axes``: a dict keeping what is the same for every joint of an axis."""
    from kinid.errors import DataError

    from ..model import parse_effect

    if axes is None or axis not in axes:
        q = obs.axes[:, machine.axis_names.index(axis)]
        lo, hi = float(np.min(q)), float(np.max(q))
        distinct = distinct_positions(q)  # jitter of the readings is not a finer sampling
        grid = None
        if hi > lo and distinct.size >= LOCAL_MIN_POSITIONS:
            step = _nice_step(hi - lo)
            lo, hi = math.floor(lo / step) * step, math.ceil(hi / step) * step
            knots = np.arange(lo, hi + step / 2, step)
            grid = (step, lo, hi, q, distinct, _hat_support(q, knots[0], step, len(knots)))
        if axes is None:
            axes = {}
        axes[axis] = grid
    if axes[axis] is None:
        return None
    step, lo, hi, q, distinct, support = axes[axis]
    try:
        whole = parse_effect(f"{code}:map:{step:g}:{lo:g}:{hi:g}", machine)
    except DataError:
        return None
    return whole, q, distinct, support


def local_windows(machine, obs, code: str, near=None) -> list:
    """The local windows the diagnosis tries on error joint ``code`` with the readings of ``obs`` (its axis read at
    too few positions: none); with ``near`` (a local error of that joint), also the finer ones it tries around its
    likeliest window: knots twice as close around ``near`` where that has the knots of the windows tried
    everywhere, else (``near`` is one of the finer ones) its own knots around it."""
    grid = _map_grid(machine, obs, code, machine.error_joint(code).axis)
    if grid is None:
        return []
    out = _local_windows(*grid[:3], machine)
    return out if near is None else out + _windows_around(*grid[:3], near, machine, out)


def _rests_on_readings(support, distinct, lo: float, hi: float) -> bool:
    """A window of knots from ``lo`` to ``hi`` whose B-splines centred at the knots rest on readings of ``support``
    (Σ of each one's values; the window's own knots) can be fitted: each coefficient's B-spline on a support of at
    least MAP_MIN_SUPPORT, and more ``distinct`` positions inside than the window has parameters (else the spline
    between the positions is a guess: coefficients of any size fit the same values). Its end knots carry no
    coefficient (the error is zero there) and need no readings of their own."""
    width = len(support) - 1  # knot intervals; width − 3 cubic B-splines lie in the window
    inside = np.count_nonzero((distinct > lo) & (distinct < hi))
    return np.min(support[2:width - 1]) >= MAP_MIN_SUPPORT and inside >= width - 3 + LOCAL_SPARE_POSITIONS


def _rest_on_readings(support, distinct, knots, width: int) -> np.ndarray:
    """For each window of ``width`` knot intervals on ``knots`` (the one from knot i, i < len(knots) − width):
    whether it rests on the readings, as :func:`_rests_on_readings` says of it, for every window at once (its
    B-splines' ``support`` at each knot, the ``distinct`` positions ascending)."""
    count = len(knots) - width
    if count <= 0:
        return np.zeros(0, bool)
    inner = np.lib.stride_tricks.sliding_window_view(support[2:], width - 3)[:count].min(axis=1)
    inside = (np.searchsorted(distinct, knots[width:], side="left")
              - np.searchsorted(distinct, knots[:count], side="right"))  # positions strictly inside each window
    return (inner >= MAP_MIN_SUPPORT) & (inside >= width - 3 + LOCAL_SPARE_POSITIONS)


def window_found_on(machine, obs, result, windows, d_errors=None):
    """Of the local errors ``windows``, the one the score test finds likeliest in the residuals of ``result`` on
    ``obs`` (σ from the residuals; with the error-joint Jacobian ``d_errors`` if given), or None; only windows that
    rest on the readings of ``obs`` as :func:`_local_windows` asks. The held-out check chooses a local candidate's
    window on its training blocks with this, as it does a period."""
    from ..fitting import model_pass

    readings = {}  # per axis: its readings and their distinct positions, found once

    def rests(w):
        if w.axis not in readings:
            q = obs.axes[:, machine.axis_names.index(w.axis)]
            readings[w.axis] = (q, distinct_positions(q))
        q, distinct = readings[w.axis]
        step = w.knots[1] - w.knots[0]
        return _rests_on_readings(_bspline_support(q, w.knots[0], step, len(w.knots)), distinct, w.knots[0],
                                  w.knots[-1])

    windows = [w for w in windows if rests(w)]
    if not windows:
        return None
    d_errors, _, q0 = model_pass(machine, obs, result, d_errors)
    live = [c for c in score_candidates(machine, obs, result, windows, 1.0, sigma_known=False, d_errors=d_errors,
                                        q0=q0, notes=False) if c.status == "live"]
    best = min(live, key=lambda c: c.log10_p, default=None)
    return None if best is None else next(w for w in windows if w.name == best.effect)


def _beats_parametric(candidate, scored) -> bool:
    """A map must beat the best parametric candidate by more than its extra parameters gain by chance."""

    parametric = [c for c in scored if c.status == "live"]
    top = max(parametric, key=lambda c: c.statistic, default=None)
    return not (top is not None and candidate.k > top.k and
                candidate.statistic - top.statistic < chi2_isf(MAP_GAIN_ALPHA, candidate.k - top.k))


#: Knot intervals of the local windows tried inside a proposed map (each zero at its ends).
LOCAL_WIDTHS = (5, 6, 7, 8, 10)
#: Local windows are tried inside this many of the best maps, and on the joints of as many best candidates.
LOCAL_MAPS = 3
#: ... and on every other joint at this share of the test's level (their p-values multiplied by the windows tried
#: there over this share; those above by theirs over the rest of it).
LOCAL_ELSEWHERE_SHARE = 0.1
#: ... with knots every map step only (and twice as close around the likeliest window).
LOCAL_ELSEWHERE_STEPS = (1.0,)
#: A local error on the best map's joint is preferred to one this many times likelier elsewhere.
LOCAL_TIE = 10.0
#: Local windows need the axis read at this many distinct positions at least.
LOCAL_MIN_POSITIONS = 12
#: Knot steps of the local windows, in steps of the whole map (a local error narrower or wider than its knots
#: is described by many of them, or none); around the likeliest window, knots twice as close as its own are tried
#: too — everywhere, a quarter step of the map cost 37 % more time per diagnosis on the 3 360 alignments of
#: ``bench_diagnose_scale.py``; around it, no time the benchmark tells from its noise (4.7 against 4.8 fits).
LOCAL_STEPS = (0.5, 1.0, 2.0)
#: A local window holds at least this many distinct positions more than it has parameters.
LOCAL_SPARE_POSITIONS = 2


def _knot_sums(q, first: float, step: float, count: int, pieces) -> np.ndarray:
    """Σ over readings ``q`` of the basis function at each of ``count`` knots every ``step`` from ``first``, where
    ``pieces(f)`` gives, for a reading a fraction f past its knot i, the (shift, value) of each function that is not
    zero there (at knot i + shift): O(N), no N × knots array."""
    x = (np.asarray(q, float) - first) / step
    i = np.floor(x).astype(np.int64)
    out = np.zeros(count)
    for shift, weight in pieces(x - i):
        index = i + shift
        inside = (index >= 0) & (index < count)
        out += np.bincount(index[inside], weights=weight[inside], minlength=count)
    return out


def _hat_support(q, first: float, step: float, count: int) -> np.ndarray:
    """Σ over readings ``q`` of each knot's hat function (1 at the knot, 0 a step away): the readings a whole map's
    knot rests on; each reading shares itself between the two knots around it."""
    return _knot_sums(q, first, step, count, lambda f: ((0, 1.0 - f), (1, f)))


def _bspline_support(q, first: float, step: float, count: int) -> np.ndarray:
    """Σ over readings ``q`` of each cubic B-spline centred at the knots: the readings a local error's coefficient
    rests on; each reading touches four B-splines."""
    return _knot_sums(q, first, step, count, lambda f: (
        (-1, (1 - f) ** 3 / 6), (0, (4 - 6 * f**2 + 3 * f**3) / 6), (1, (1 + 3 * f + 3 * f**2 - 3 * f**3) / 6),
        (2, f**3 / 6)))


def _windows_around(whole, q, distinct, near, machine, tried) -> list:
    """The windows the diagnosis tries around the local error ``near`` besides those ``tried`` everywhere (the map
    ``whole``'s windows, :func:`_local_windows`): with knots twice as close as its own where it has the knots of
    windows tried everywhere, else (it is one of these finer ones) with its own knots; from a step before its window
    to a step after it (inside the range of ``whole``), resting on the readings ``q`` (:func:`_rests_on_readings`)."""
    step = near.knots[1] - near.knots[0]
    factor = 0.5 if any(math.isclose(w.knots[1] - w.knots[0], step, rel_tol=1e-9) for w in tried) else 1.0
    lo, hi = max(near.knots[0] - step, whole.knots[0]), min(near.knots[-1] + step, whole.knots[-1])
    seen = {w.name for w in tried}
    return [w for w in _windows_at(whole.code, step * factor, lo, hi, q, distinct, machine) if w.name not in seen]


def _local_windows(whole, q, distinct, machine, steps=None) -> list:
    """``CODE:local:<step>:<from>:<to>`` windows of ``LOCAL_WIDTHS`` knot intervals inside the range of the map
    ``whole``, with knots every ``steps`` (default ``LOCAL_STEPS``) times its step, that rest on the readings
    ``q`` (with their ``distinct`` positions; :func:`_rests_on_readings`)."""
    lo, hi = whole.knots[0], whole.knots[-1]
    return [w for factor in (steps or LOCAL_STEPS)
            for w in _windows_at(whole.code, (whole.knots[1] - whole.knots[0]) * factor, lo, hi, q, distinct, machine)]


def _windows_at(code: str, step: float, lo: float, hi: float, q, distinct, machine) -> list:
    """``CODE:local:<step>:<from>:<to>`` windows of ``LOCAL_WIDTHS`` knot intervals between ``lo`` and ``hi`` with
    knots every ``step`` (on its multiples), that rest on the readings ``q`` (:func:`_rests_on_readings`)."""
    step = float(f"{step:.6g}")
    knots = np.arange(math.floor(lo / step) * step, hi + step / 2, step)
    support = _bspline_support(q, knots[0], step, len(knots))  # of the B-spline centred at each knot
    from ..model import local_effect

    joint = machine.error_joint(code)
    out = []
    for width in LOCAL_WIDTHS:
        for i in np.flatnonzero(_rest_on_readings(support, distinct, knots, width)).tolist():
            window = local_effect(joint, step, knots[i], knots[i + width])
            if window is not None:
                out.append(window)
    return out

