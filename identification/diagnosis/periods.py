"""Periods the candidate library does not list: a continuous search, then the period refined.

(and every location joint equivalent to one, see
:func:`~kinid.identification.model.derived.axis_dependent_joints`).

A lead-screw error with an inch lead (12.7 mm), a 12.3 mm lead or a gear with
seven teeth per table turn (360/7 = 51.43°) is periodic in its axis, but at a
period the library does not hold. For every position-dependent error joint
``E<d><k>`` the score test of ``E<d><k>:periodic:P`` is evaluated on a dense
grid of frequencies, at the fit, in closed form (no refit per period):

    Δ(P) = bᵀ G⁻¹ b,  b = [sᵀr, cᵀr],  G = Gram matrix of the sine and cosine
    columns s, c after projecting them off the model's Jacobian,

with r the whitened residual (orthogonal to the model). Δ is the χ² drop the
effect would bring. The best grid period of each joint is refined by a bounded
scalar search, and its standard deviation follows from the curvature of Δ
(the χ² of the model with P as a parameter is rss − Δ(P), so var P = 2 / −Δ''(P)).

Searching many periods makes a large Δ likelier by chance: the p-value of a
found period is multiplied by the number of independent periods searched
(the travel over the shortest period, per joint), so the search does not
raise false alarms on noise.

The shortest period searched is twice the smallest spacing of the axis's
positions (on a regular grid of positions a shorter period aliases onto a
longer one; on an irregular one the periods that fit alike are named by
:mod:`~kinid.identification.diagnosis.ambiguity`; readings within 0.1 % of the axis's
span count as one position: the jitter of solved readings is no finer
sampling), and at least 2 mm or 1° (a gear of 360 teeth).

Every sum is over alignments, O(N · periods · rank), in chunks of periods:
memory stays flat in the number of alignments.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model import Machine
from ..data import Observations, distinct_positions, position_starts

__all__ = ["PeriodEstimate", "search_periods", "MIN_PERIOD_MM", "MIN_PERIOD_DEG", "period_name"]

#: Shortest period searched on linear axes, mm (the library's shortest), and on rotary axes, deg.
MIN_PERIOD_MM = 2.0
MIN_PERIOD_DEG = 1.0
#: Grid density: frequencies spaced 1 / (OVERSAMPLE × span of the axis readings).
OVERSAMPLE = 6
#: Memory per array of one chunk of frequencies, bytes (a chunk holds N × chunk values; memory flat in N).
CHUNK_BYTES = 8 * 1024 * 1024
#: On the frequency grid, readings within this share of the shortest period searched count as one position (a
#: phase error of at most π·10⁻³: the grid's Δ moves by ~10⁻⁵ of itself, and only points at the peak refined).
GRID_MERGE = 1e-3
#: With ``refine=k``, the joints refined are those whose Δ on the grid is at least this share of the k-th largest:
#: refining raises a joint's Δ by a few per cent (at most 6 % on the grids of the speed benchmark's data and its
#: subsets; the grid is oversampled), so no joint left on its grid peak can rise among the k best.
REFINE_SHARE = 0.5


@dataclass(frozen=True)
class PeriodEstimate:
    """The best period found for one error joint.

    Attributes
    ----------
    code, axis : str
        Error joint and its axis.
    period, period_std : float
        Refined period and its standard deviation, mm or deg.
    statistic : float
        χ² drop Δ at the refined period.
    trials : float
        Independent periods searched for this joint (the p-value's multiplier).
    unit : str
        ``mm`` or ``deg``.
    """

    code: str
    axis: str
    period: float
    period_std: float
    statistic: float
    trials: float
    unit: str

    @property
    def effect(self) -> str:
        return f"{self.code}:periodic:{period_name(self.period, self.period_std)}"


def period_name(period: float, std: float) -> str:
    """The period as written in an effect name: enough digits that rounding moves it by < std / 10."""
    if not (np.isfinite(std) and std > 0):
        return f"{period:.4g}"
    decimals = max(0, min(6, int(math.ceil(-math.log10(std / 10.0)))))
    text = f"{period:.{decimals}f}"
    return text.rstrip("0").rstrip(".") if "." in text else text


def _delta(S, C, w, nrm, g):
    """Δ (J, F) of J joints at F frequencies from the sines S and cosines C (N, F) of their phases at the
    readings; per joint w, nrm (N, J), g (N, J, rank)."""
    J = w.shape[1]
    bs, bc = w.T @ S, w.T @ C
    ss = nrm.T @ (S * S)
    cc = nrm.T @ (C * C)
    sc = nrm.T @ (S * C)
    G = g.reshape(g.shape[0], -1).T
    Ps, Pc = (G @ S).reshape(J, -1, S.shape[1]), (G @ C).reshape(J, -1, S.shape[1])  # (J, rank, F)
    return _closed_form(bs, bc, ss, cc, ss - np.sum(Ps * Ps, axis=1), cc - np.sum(Pc * Pc, axis=1),
                        sc - np.sum(Ps * Pc, axis=1))


#: A sine or cosine column that keeps less than this share of its squared norm after the projection off the model
#: is aliased, as in the score test (ALIAS_TOL² of :mod:`~kinid.identification.diagnosis.scoring`): what is left of it is
#: rounding, and Δ from it would be noise (up to 1e270).
DEAD_SHARE = 1e-12


def _closed_form(bs, bc, ss, cc, g11, g22, g12):
    """Δ = bᵀ G⁻¹ b from b = (bs, bc), the sine's and cosine's squared norms ss, cc and their projected Gram
    matrix G = [[g11, g12], [g12, g22]], elementwise."""
    live_s, live_c = g11 > DEAD_SHARE * ss, g22 > DEAD_SHARE * cc
    bs, g11 = np.where(live_s, bs, 0.0), np.where(live_s, g11, 0.0)
    bc, g22 = np.where(live_c, bc, 0.0), np.where(live_c, g22, 0.0)
    g12 = np.where(live_s & live_c, g12, 0.0)
    det = g11 * g22 - g12 * g12
    scale = np.maximum(g11 * g22, 1e-300)
    ok = det > 1e-10 * scale
    out = np.zeros(det.shape)
    out[ok] = (g22[ok] * bs[ok] ** 2 - 2 * g12[ok] * bs[ok] * bc[ok] + g11[ok] * bc[ok] ** 2) / det[ok]
    # where sine and cosine columns coincide after projection, one column is all the data see
    one = ~ok & (g11 + g22 > 0)
    out[one] = np.maximum(bs[one] ** 2 / np.maximum(g11[one], 1e-300), bc[one] ** 2 / np.maximum(g22[one], 1e-300))
    return out


def _delta_each(freq, q, W, NRM, G):
    """Δ (J,) of each of J joints at its own frequency ``freq[j]``, each phase's sine and cosine evaluated directly;
    per joint, rows of W, NRM (J, N) and G (J, rank, N)."""
    phase = 2.0 * np.pi * (freq[:, None] * q[None, :])  # (J, N)
    S, C = np.sin(phase), np.cos(phase)
    Ps, Pc = np.matmul(G, S[:, :, None])[:, :, 0], np.matmul(G, C[:, :, None])[:, :, 0]  # (J, rank)
    ss, cc = np.einsum("jn,jn->j", NRM, S * S), np.einsum("jn,jn->j", NRM, C * C)
    return _closed_form(np.einsum("jn,jn->j", W, S), np.einsum("jn,jn->j", W, C), ss, cc,
                        ss - np.sum(Ps * Ps, axis=1), cc - np.sum(Pc * Pc, axis=1),
                        np.einsum("jn,jn->j", NRM, S * C) - np.sum(Ps * Pc, axis=1))


#: Frequencies of a grid whose sines and cosines are evaluated directly; the next ones follow by rotation.
ROTATION_BLOCK = 32


def _grid_phasors(q, freq):
    """(S, C) = sin and cos (N, F) of 2π q f over the evenly spaced frequencies ``freq``: the first ROTATION_BLOCK
    columns directly, each next block as the previous one rotated by the phase of ROTATION_BLOCK grid steps (a
    recurrence in complex numbers: no sine or cosine of the full N × F matrix)."""
    first = np.exp(2j * np.pi * np.outer(q, freq[:ROTATION_BLOCK]))
    out = np.empty((q.size, freq.size), complex)
    out[:, :first.shape[1]] = first
    if freq.size > ROTATION_BLOCK:
        turn = np.exp(2j * np.pi * q * (freq[ROTATION_BLOCK] - freq[0]))[:, None]
        for k in range(ROTATION_BLOCK, freq.size, ROTATION_BLOCK):
            width = min(ROTATION_BLOCK, freq.size - k)
            np.multiply(out[:, k - ROTATION_BLOCK:k - ROTATION_BLOCK + width], turn, out=out[:, k:k + width])
    return np.ascontiguousarray(out.imag), np.ascontiguousarray(out.real)


def _axis_groups(joints):
    """The searched joints (index, joint) grouped by their axis, in the order of first appearance."""
    groups = {}
    for j, joint in joints:
        groups.setdefault(joint.axis, []).append((j, joint))
    return groups


def search_periods(machine: Machine, obs: Observations, residual_w: np.ndarray, d_errors: np.ndarray,
                   q0: np.ndarray, sigma: float = 1.0, codes=None, range_of: Observations | None = None,
                   joint_series=None, refine: int | None = None) -> list:
    """Best period of every position-dependent error joint, refined, best first.

    Parameters
    ----------
    residual_w : array (3N,)
        Whitened residual (÷ σ), orthogonal to the model's columns.
    d_errors : array (N, 3, n_errors)
        Error-joint Jacobian at the fit (whitened here, one joint at a time, by ``sigma``).
    q0 : array (3N, rank)
        Orthonormal basis of the model's identifiable columns.
    codes : set of str, optional
        Search only these error joints.
    range_of : Observations, optional
        The readings whose positions set the periods searched (the shortest, the longest), if not ``obs``'s: a
        part of a data set is searched over the whole set's range.
    joint_series : callable (error joint index) -> tuple, optional
        The series of the score test's fit side (:meth:`~kinid.identification.diagnosis.scoring.FitSide.joint_series`) at
        these residuals, σ and basis: what the search sums, computed once for both (here if not given).
    refine : int, optional
        Refine only the joints that can be among the ``refine`` best (:data:`REFINE_SHARE`); the others' estimates
        are their grid peaks (period on the grid, ``period_std`` NaN). Default: refine every joint.

    Returns
    -------
    list of PeriodEstimate, by decreasing Δ.
    """
    from ..model import axis_dependent_joints

    varying = {code for code, _ in axis_dependent_joints(machine) if codes is None or code in codes}
    found = {}

    if joint_series is None:  # the score test's series of each joint (squared norm, products with r and q0)
        from .score_sums import joint_series as series_of

        def joint_series(j):
            return series_of(d_errors[:, :, j] / sigma, q0, residual_w, None)

    def stacked(joints):  # per joint (N, J): products with the residual, squared norms; (N, J, rank) with q0's rows
        parts = [joint_series(j)[:3] for j in joints]
        return tuple(np.stack(s, axis=1) for s in ([p[1] for p in parts], [p[0] for p in parts], [p[2] for p in parts]))

    grids = []  # per axis: its readings, joints searched, frequency grid, their Δ on it, and what refining needs
    # the joints of one axis share its readings, so the sines and cosines of the frequency grid: one per axis
    for axis, group in _axis_groups([(j, joint) for j, joint in enumerate(machine.error_joints)
                                     if joint.code in varying]).items():
        a = machine.axis(axis)
        k = machine.axis_names.index(axis)
        q = obs.axes[:, k]
        # the positions that set the range searched; the jitter of solved readings is not a finer sampling
        unique = distinct_positions(np.round((obs if range_of is None else range_of).axes[:, k], 3))
        if unique.size < 6:
            continue
        span = float(unique[-1] - unique[0])
        rotary = a.kind != "prismatic"
        # no period shorter than twice the smallest spacing of the positions: on a regular grid of
        # positions, shorter periods alias onto longer ones and cannot be told apart (Nyquist)
        spacing = float(np.min(np.diff(unique)))
        p_min = max(MIN_PERIOD_DEG if rotary else MIN_PERIOD_MM, 2.0 * spacing)
        p_max = 360.0 if rotary else span
        if span <= 0 or p_max <= p_min:
            continue
        w, nrm, g = stacked([j for j, _ in group])
        live = np.any(nrm > 0, axis=0)  # a joint these readings do not move is not searched
        joints = [j for (j, _), moved in zip(group, live) if moved]
        if not joints:
            continue
        w, nrm, g = w[:, live], nrm[:, live], g[:, live]
        # the grid only points at the best frequency (refined, and Δ evaluated, on the exact positions): readings
        # within GRID_MERGE of the shortest period are one there (a plan measured again, read micrometres apart)
        near = _collapsed(q, w, nrm, g, within=GRID_MERGE * p_min)
        extent = max(span, 360.0) if rotary else span
        df = 1.0 / (OVERSAMPLE * extent)
        freq = np.arange(1.0 / p_max, 1.0 / p_min + df / 2, df)
        chunk = max(int(CHUNK_BYTES // (8 * near[0].size)), 4)
        deltas = np.concatenate([_delta(*_grid_phasors(near[0], freq[k:k + chunk]), *near[1:])
                                 for k in range(0, len(freq), chunk)], axis=1)
        trials = max(extent * (1.0 / p_min - 1.0 / p_max), 1.0)
        grids.append((q, joints, freq, deltas, df, trials, "deg" if rotary else "mm"))
    peaks = sorted((float(p) for grid in grids for p in grid[3].max(axis=1)), reverse=True)
    bar = REFINE_SHARE * peaks[refine - 1] if refine is not None and len(peaks) >= refine else -np.inf
    for q, joints, freq, deltas, df, trials, unit in grids:
        peak = deltas.max(axis=1)
        kept = np.flatnonzero(peak >= bar)
        if kept.size:
            exact = _collapsed(q, *stacked([joints[i] for i in kept]))
            for i, estimate in zip(kept, _refined([machine.error_joints[joints[i]] for i in kept], freq, deltas[kept],
                                                  df, *exact, trials, unit)):
                found[joints[i]] = estimate
        for i in np.flatnonzero((peak < bar) & (peak > 0)):  # cannot be among the best: its grid peak
            joint = machine.error_joints[joints[i]]
            found[joints[i]] = PeriodEstimate(joint.code, joint.axis, float(1.0 / freq[np.argmax(deltas[i])]),
                                              float("nan"), float(peak[i]), float(trials), unit)
    out = [found[j] for j in sorted(found) if found[j] is not None]  # in the joints' order (ties keep it)
    # by decreasing Δ; joints whose columns coincide on these data tie to rounding (9 digits): the first joint first
    out.sort(key=lambda e: -float(f"{e.statistic:.9g}"))
    return out


def _collapsed(q, *series, within: float = 0.0) -> tuple:
    """(positions, series...): readings ``q`` that repeat exactly (a rotary axis read at a few angles) — or, with
    ``within``, that lie within it of the lowest of them — taken once (at the middle of their range), and each
    series (N, ...) summed over the readings at each position; every sum of the search is one over positions."""
    order = np.argsort(q, kind="stable")  # the readings of one position in their order
    qs = q[order]
    starts = position_starts(qs, within) if within > 0 else np.flatnonzero(np.r_[True, qs[1:] != qs[:-1]])
    if starts.size == q.size:
        return (q, *series)
    ends = np.r_[starts[1:], q.size] - 1
    return (0.5 * (qs[starts] + qs[ends]), *(np.add.reduceat(s[order], starts, axis=0) for s in series))


def _refined(joints, freq, deltas, df, q, w, nrm, g, trials, unit) -> list:
    """The PeriodEstimate of each of ``joints`` (of one axis) from its Δ on the grid ``freq`` (a row of ``deltas``):
    the best grid period refined by a bounded scalar search, its standard deviation from the curvature of Δ; None
    if Δ is nowhere positive. The joints' searches run side by side, each step's Δ computed for all at once."""
    best = np.argmax(deltas, axis=1)
    live = [i for i, k in enumerate(best) if deltas[i, k] > 0]
    out = [None] * len(joints)
    if not live:
        return out
    f_best = freq[best].astype(float)
    searches = {}
    for i in live:
        lo, hi = freq[max(best[i] - 1, 0)], freq[min(best[i] + 1, len(freq) - 1)]
        if hi > lo:
            searches[i] = _bounded_minimum(lo, hi, df * 1e-6)
    # per joint, contiguous: W, NRM (J, N), G (J, rank, N); each step evaluates the joints still searching, at once
    # (searches end after 8 to 30 steps; a joint's Δ is the same number whichever others are evaluated beside it)
    series = (np.ascontiguousarray(w.T), np.ascontiguousarray(nrm.T), np.ascontiguousarray(g.transpose(1, 2, 0)))
    at = f_best.copy()  # the abscissa each search asks about
    for i, search in searches.items():
        at[i] = next(search)
    rows, sub = None, None
    while searches:
        if rows != list(searches):  # the joints searching changed: their series, gathered once
            rows = list(searches)
            sub = series if len(rows) == len(joints) else tuple(x[rows] for x in series)
        values = -_delta_each(at[rows], q, *sub)
        for i, value in zip(rows, values):
            try:
                at[i] = searches[i].send(float(value))
            except StopIteration as done:
                at[i] = f_best[i] = done.value
                del searches[i]
    sub = [x[live] for x in series]
    d_best = _delta_each(f_best, q, *series)[live]
    on_grid = _delta_each(freq[best[live]], q, *sub)  # the grid's own Δ is from readings merged
    worse = d_best < on_grid
    period = 1.0 / np.where(worse, freq[best[live]], f_best[live])
    d_best = np.where(worse, on_grid, d_best)
    # curvature of Δ in the period: var P = 2 / (−Δ'')
    h = period * 1e-4
    d2 = (_delta_each(1.0 / (period + h), q, *sub) - 2 * d_best + _delta_each(1.0 / (period - h), q, *sub)) / h**2
    for m, i in enumerate(live):
        std = math.sqrt(2.0 / -d2[m]) if d2[m] < 0 else float("nan")
        out[i] = PeriodEstimate(joints[i].code, joints[i].axis, float(period[m]), std, float(d_best[m]), float(trials),
                                unit)
    return out


def bounded_minimum(f, x1: float, x2: float, xatol: float, maxiter: int = 500) -> tuple:
    """(x, f(x)) at the minimum of ``f`` on [x1, x2]: ``scipy.optimize.minimize_scalar(f, bounds=(x1, x2),
    method="bounded", options={"xatol": xatol, "maxiter": maxiter})`` step for step, without importing
    scipy.optimize (0.16 s of a process that needs nothing else of it)."""
    search = _bounded_minimum(x1, x2, xatol, maxiter)
    x = next(search)
    seen = {}
    try:
        while True:
            seen[x] = f(x)
            x = search.send(seen[x])
    except StopIteration as done:
        return done.value, seen[done.value]


def _bounded_minimum(x1: float, x2: float, xatol: float, maxiter: int = 500):
    """The bounded search of ``scipy.optimize.minimize_scalar(method="bounded")`` (Brent's method: golden sections
    and parabolic steps) for the minimum of a function on [x1, x2], as a generator: it yields each abscissa where it
    needs the function's value, is sent that value, and returns the minimum's abscissa; so the searches of many
    joints run side by side. A transcription of scipy's ``_minimize_scalar_bounded``, step for step."""
    sqrt_eps = math.sqrt(2.2e-16)
    golden_mean = 0.5 * (3.0 - math.sqrt(5.0))
    a, b = x1, x2
    fulc = a + golden_mean * (b - a)
    nfc, xf = fulc, fulc
    rat = e = 0.0
    x = xf
    fx = yield x
    num = 1
    ffulc = fnfc = fx
    xm = 0.5 * (a + b)
    tol1 = sqrt_eps * abs(xf) + xatol / 3.0
    tol2 = 2.0 * tol1
    while abs(xf - xm) > (tol2 - 0.5 * (b - a)):
        golden = True
        if abs(e) > tol1:  # a parabola through the three best points
            golden = False
            r = (xf - nfc) * (fx - ffulc)
            q = (xf - fulc) * (fx - fnfc)
            p = (xf - fulc) * q - (xf - nfc) * r
            q = 2.0 * (q - r)
            if q > 0.0:
                p = -p
            q = abs(q)
            r = e
            e = rat
            if abs(p) < abs(0.5 * q * r) and p > q * (a - xf) and p < q * (b - xf):  # an acceptable parabola
                rat = (p + 0.0) / q
                x = xf + rat
                if (x - a) < tol2 or (b - x) < tol2:
                    rat = tol1 * (np.sign(xm - xf) + ((xm - xf) == 0))
            else:
                golden = True
        if golden:
            e = (a - xf) if xf >= xm else (b - xf)
            rat = golden_mean * e
        x = xf + (np.sign(rat) + (rat == 0)) * max(abs(rat), tol1)
        fu = yield x
        num += 1
        if fu <= fx:
            if x >= xf:
                a = xf
            else:
                b = xf
            fulc, ffulc = nfc, fnfc
            nfc, fnfc = xf, fx
            xf, fx = x, fu
        else:
            if x < xf:
                a = x
            else:
                b = x
            if fu <= fnfc or nfc == xf:
                fulc, ffulc = nfc, fnfc
                nfc, fnfc = x, fu
            elif fu <= ffulc or fulc == xf or fulc == nfc:
                fulc, ffulc = x, fu
        xm = 0.5 * (a + b)
        tol1 = sqrt_eps * abs(xf) + xatol / 3.0
        tol2 = 2.0 * tol1
        if num >= maxiter:
            break
    return xf
