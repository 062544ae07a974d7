"""Periods the candidate library does not list: a continuous search, then the period refined.

(and every location joint equivalent to one, see
:func:`~kinid.identification.effects.axis_dependent_joints`).

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

The shortest period searched is twice the usual spacing of the axis's
readings (on a regular grid of positions a shorter period aliases onto a
longer one; readings within 0.001 mm or 0.001° count as one position), and at
least 2 mm or 1° (a gear of 360 teeth).

Every sum is over alignments, O(N · periods · rank), in chunks of periods:
memory stays flat in the number of alignments.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .machine import Machine
from .observations import Observations

__all__ = ["PeriodEstimate", "search_periods", "MIN_PERIOD_MM", "MIN_PERIOD_DEG", "period_name"]

#: Shortest period searched on linear axes, mm (the library's shortest), and on rotary axes, deg.
MIN_PERIOD_MM = 2.0
MIN_PERIOD_DEG = 1.0
#: Grid density: frequencies spaced 1 / (OVERSAMPLE × span of the axis readings).
OVERSAMPLE = 6
#: Memory per array of one chunk of frequencies, bytes (a chunk holds N × chunk values; memory flat in N).
CHUNK_BYTES = 8 * 1024 * 1024


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
    g11 = ss - np.sum(Ps * Ps, axis=1)
    g22 = cc - np.sum(Pc * Pc, axis=1)
    g12 = sc - np.sum(Ps * Pc, axis=1)
    det = g11 * g22 - g12 * g12
    scale = np.maximum(g11 * g22, 1e-300)
    ok = det > 1e-10 * scale
    out = np.zeros(det.shape)
    out[ok] = (g22[ok] * bs[ok] ** 2 - 2 * g12[ok] * bs[ok] * bc[ok] + g11[ok] * bc[ok] ** 2) / det[ok]
    # where sine and cosine columns coincide after projection, one column is all the data see
    one = ~ok & (g11 + g22 > 0)
    out[one] = np.maximum(bs[one] ** 2 / np.maximum(g11[one], 1e-300), bc[one] ** 2 / np.maximum(g22[one], 1e-300))
    return out


def _delta_at(freq, q, w, nrm, g):
    """Δ (J, F) at the frequencies ``freq``, each phase's sine and cosine evaluated directly."""
    phase = 2.0 * np.pi * np.outer(q, freq)  # (N, F)
    return _delta(np.sin(phase), np.cos(phase), w, nrm, g)


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
                   q0: np.ndarray, sigma: float = 1.0) -> list:
    """Best period of every position-dependent error joint, refined, best first.

    Parameters
    ----------
    residual_w : array (3N,)
        Whitened residual (÷ σ), orthogonal to the model's columns.
    d_errors : array (N, 3, n_errors)
        Error-joint Jacobian at the fit (whitened here, one joint at a time, by ``sigma``).
    q0 : array (3N, rank)
        Orthonormal basis of the model's identifiable columns.

    Returns
    -------
    list of PeriodEstimate, by decreasing Δ.
    """
    n = len(obs)
    rank = q0.shape[1]
    Q = q0.reshape(n, 3, rank)
    R = residual_w.reshape(n, 3)
    from .effects import axis_dependent_joints

    varying = {code for code, _ in axis_dependent_joints(machine)}
    found = {}
    # the joints of one axis share its readings, so the sines and cosines of the frequency grid: one per axis
    for axis, group in _axis_groups([(j, joint) for j, joint in enumerate(machine.error_joints)
                                     if joint.code in varying]).items():
        a = machine.axis(axis)
        q = obs.axes[:, machine.axis_names.index(axis)]
        unique = np.unique(np.round(q, 3))  # jitter of the readings is not a finer sampling
        if unique.size < 6:
            continue
        span = float(unique[-1] - unique[0])
        rotary = a.kind != "prismatic"
        # no period shorter than twice the usual spacing of the readings: on a regular grid of
        # positions, shorter periods alias onto longer ones and cannot be told apart (Nyquist)
        spacing = float(np.median(np.diff(unique)))
        p_min = max(MIN_PERIOD_DEG if rotary else MIN_PERIOD_MM, 2.0 * spacing)
        p_max = 360.0 if rotary else span
        if span <= 0 or p_max <= p_min:
            continue
        series = {}
        for j, joint in group:
            col = d_errors[:, :, j] / sigma  # (N, 3)
            nrm = np.sum(col * col, axis=1)
            if np.any(nrm > 0):
                series[j] = (np.sum(col * R, axis=1), nrm, np.einsum("nkr,nk->nr", Q, col))
        if not series:
            continue
        w, nrm, g = (np.stack(s, axis=1) for s in zip(*series.values()))  # (N, J), (N, J), (N, J, rank)
        extent = max(span, 360.0) if rotary else span
        df = 1.0 / (OVERSAMPLE * extent)
        freq = np.arange(1.0 / p_max, 1.0 / p_min + df / 2, df)
        chunk = max(int(CHUNK_BYTES // (8 * n)), 4)
        deltas = np.concatenate([_delta(*_grid_phasors(q, freq[k:k + chunk]), w, nrm, g)
                                 for k in range(0, len(freq), chunk)], axis=1)
        trials = max(extent * (1.0 / p_min - 1.0 / p_max), 1.0)
        for i, j in enumerate(series):
            found[j] = _refined(machine.error_joints[j], freq, deltas[i], df, q, *(s[:, i:i + 1] for s in (w, nrm, g)),
                                trials, "deg" if rotary else "mm")
    out = [found[j] for j in sorted(found) if found[j] is not None]  # in the joints' order (ties keep it)
    out.sort(key=lambda e: -e.statistic)
    return out


def _refined(joint, freq, delta, df, q, w, nrm, g, trials, unit):
    """The PeriodEstimate of ``joint`` from its Δ on the grid ``freq``: the best grid period refined by a
    bounded scalar search, its standard deviation from the curvature of Δ; None if Δ is nowhere positive."""
    from scipy.optimize import minimize_scalar

    k = int(np.argmax(delta))
    if not delta[k] > 0:
        return None
    lo, hi = freq[max(k - 1, 0)], freq[min(k + 1, len(freq) - 1)]

    def negative(f):
        return -float(_delta_at(np.array([f]), q, w, nrm, g)[0, 0])

    f_best = minimize_scalar(negative, bounds=(lo, hi), method="bounded",
                             options={"xatol": df * 1e-6}).x if hi > lo else freq[k]
    d_best = -negative(f_best)
    if d_best < delta[k]:
        f_best, d_best = freq[k], float(delta[k])
    period = 1.0 / f_best
    # curvature of Δ in the period: var P = 2 / (−Δ'')
    h = period * 1e-4
    d2 = (-negative(1.0 / (period + h)) - 2 * d_best - negative(1.0 / (period - h))) / h**2
    std = math.sqrt(2.0 / -d2) if d2 < 0 else float("nan")
    return PeriodEstimate(joint.code, joint.axis, float(period), std, float(d_best), float(trials), unit)
