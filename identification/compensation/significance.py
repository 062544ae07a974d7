"""Whether a fitted effect is known well enough to compensate: its parameters, and the curve a table would hold.

Compensating an effect replaces its true error by the fit's estimation error. That helps only where the effect is
known better than it is large:

- **a parameter** must exceed its expanded uncertainty, |value| > k·σ (k = :data:`kinid.stats.K_EXPANDED`), for at
  least one parameter of the effect;
- **the curve** of a position-dependent effect must also exceed its own: over its axis's measured range (the
  readings and an even grid between them, where the controller's table interpolates) the RMS of the curve must
  exceed k times the RMS of its standard deviation, computed with the parameters' correlation. Several parameters
  each near their σ can pass the first test while their sum, the table, is noise — or, for a period that the
  readings sample at one phase, a curve that is any value between the readings.
"""
from __future__ import annotations

import numpy as np

from kinid.stats import K_EXPANDED

__all__ = ["not_significant", "curve_not_significant", "CURVE_GRID"]

#: Points of the even grid over an axis's measured range at which a curve and its uncertainty are compared.
CURVE_GRID = 201


def not_significant(values, std) -> str | None:
    """Why an effect of these identified parameter values and standard deviations is not significant (every
    |value| ≤ k·σ), or None (significant, or σ unknown)."""
    std = np.asarray(std, float)
    v = np.abs(np.asarray(values, float))
    if v.size == 0 or not (np.all(np.isfinite(std)) and np.all(std > 0)):
        return None
    ratio = float(np.max(v / std))
    if ratio > K_EXPANDED:
        return None
    return (f"not significant: |value| ≤ its expanded uncertainty (k = {K_EXPANDED:g}); "
            f"largest |value|/σ {ratio:.2g}")


def curve_not_significant(result, effect, sl: slice) -> str | None:
    """Why the curve of the position-dependent ``effect`` (its parameters ``sl`` of ``result``) is not known better
    than it is large over its axis's measured range, or None (it is; or the fit keeps no correlation or range)."""
    from ..model import basis_of, basis_values

    corr = getattr(result, "correlation", None)
    axis = effect.axis
    if corr is None or not basis_of(effect).positional or axis not in result.axis_ranges:
        return None
    ok = np.asarray(result.identifiable[sl], bool)
    std = np.asarray(result.std[sl], float)
    c = np.asarray(corr, float)[sl, sl]
    if not ok.any() or not np.all(np.isfinite(std[ok])) or not np.all(np.isfinite(c[np.ix_(ok, ok)])):
        return None
    lo, hi = result.axis_ranges[axis]
    x = np.union1d(np.linspace(lo, hi, CURVE_GRID), np.asarray(result.axis_readings.get(axis, ()), float))
    machine = result.machine
    poses = np.zeros((x.size, len(machine.axes)))
    poses[:, machine.axis_names.index(axis)] = x
    B = basis_values(effect, machine, poses)[:, ok]
    cov = c[np.ix_(ok, ok)] * np.outer(std[ok], std[ok])
    curve = B @ np.asarray(result.values[sl], float)[ok]
    var = np.einsum("np,pq,nq->n", B, cov, B)
    rms, u_rms = float(np.sqrt(np.mean(curve**2))), float(np.sqrt(np.mean(np.clip(var, 0.0, None))))
    if not u_rms > 0 or rms > K_EXPANDED * u_rms:
        return None
    return (f"not significant as a curve: over {axis}'s measured range its RMS {rms:.3g} is within its expanded "
            f"uncertainty's RMS {K_EXPANDED * u_rms:.3g} (k = {K_EXPANDED:g}); a table would move the axis by noise")
