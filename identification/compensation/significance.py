"""Whether a fitted effect is known well enough to compensate: its parameters, or the curve a table would hold.

Compensating an effect replaces its true error by the fit's estimation error. That helps only where the effect is
known better than it is large:

- **a constant or direction-dependent effect**: a parameter must exceed its expanded uncertainty, |value| > k·σ
  (k = :data:`kinid.stats.K_EXPANDED`), for at least one parameter of the effect;
- **a position-dependent error joint** (:func:`curves_not_significant`): its table holds the sum of its effects, so
  that sum is judged, written whole or not at all. Over its axis's measured range (the readings and an even grid
  between them, where the controller's table interpolates) the RMS of the curve must exceed 2 U, U the RMS its
  error stays below with 95 % confidence (:data:`CURVE_CONFIDENCE`, from the parameters' covariance). A table
  leaves its curve's error e where no table leaves the true curve t; it is worse than none when |e| > |t|, and a
  curve that passes (|t + e| > 2 U) is then one whose |e| > U: for any true curve, at most 5 % of the fits write a
  table worse than none.

What this replaced, as measured (benchmarks/proving_compensation.py, docs/compensation.md): each effect judged
alone, its curve's RMS against k = 2 times the RMS of its standard deviation. That bounded nothing: a true curve
about as large as its error passed only when the noise added to it (a B table's period of 51.4° read at four
tilts: 13 % of 30 noise draws of one machine wrote it, each table worse than none; the fit's σ covered, mean χ² 1.97
for 2 parameters). And an effect written without a correlated partner left out (``EBB:periodic:360`` beside
``EBB:poly1`` over a tilt of 100°, each alone uncertain, their sum known) wrote a value the fit found only with
the partner: 4 310 µrad left where the truth was 287.
"""
from __future__ import annotations

import numpy as np

from kinid.stats import K_EXPANDED, chi2_isf

__all__ = ["not_significant", "curves_not_significant", "error_rms_quantile", "CURVE_GRID", "CURVE_CONFIDENCE"]

#: Points of the even grid over an axis's measured range at which a curve and its uncertainty are compared.
CURVE_GRID = 201
#: The confidence with which a compensated curve's error stays below the RMS the rule compares it with.
CURVE_CONFIDENCE = 0.95


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


def curves_not_significant(result, implausible=()) -> dict:
    """The position-dependent effects of ``result`` judged by their joint's curve: effect name -> why its joint's
    table is not written (its curve is not known better than it is large, or it holds an effect of a size no machine
    has: ``implausible``, names), or None (written). An effect not in the dict (no correlation kept, no measured
    range of its axis) is judged by its parameters alone (:func:`not_significant`).

    A joint's table holds the sum of its effects (``EBB:periodic:72`` + ``EBB:poly1``): what a table leaves is that
    sum's error, so the sum is judged, with the parameters' covariance, and written whole or not at all. Writing
    one effect without a correlated partner left out writes a value the fit found only together with the partner.
    """
    from ..model import basis_of

    corr = getattr(result, "correlation", None)
    if corr is None:
        return {}
    joints, k = {}, 0
    for e in result.effects:
        sl = slice(k, k + e.n_params)
        k += e.n_params
        if basis_of(e).positional and e.axis in result.axis_ranges and np.any(result.identifiable[sl]):
            joints.setdefault((e.code, e.axis), []).append((e, sl))  # a step at another axis's position: its own
    out, corr, std = {}, np.asarray(corr, float), np.asarray(result.std, float)
    for members in joints.values():
        names = [e.name for e, _ in members]
        odd = [n for n in names if n in implausible]
        idx = np.concatenate([np.arange(sl.start, sl.stop)[np.asarray(result.identifiable[sl], bool)]
                              for _, sl in members])
        cov = corr[np.ix_(idx, idx)] * np.outer(std[idx], std[idx])
        if odd:
            out.update({n: f"its joint's table also holds {', '.join(odd)}, of a size no machine has: the joint's "
                           f"curve is not known" for n in names if n not in odd})
        elif np.all(np.isfinite(cov)):
            why = _joint_curve_not_significant(result, members, idx, cov)
            out.update({n: why for n in names})
    return out


def _joint_curve_not_significant(result, members, idx, cov) -> str | None:
    """Why the sum of the effects ``members`` of one joint (their identified parameters ``idx``, covariance ``cov``)
    is not known better than it is large over its axis's measured range, or None."""
    from ..model import basis_values

    axis = members[0][0].axis
    lo, hi = result.axis_ranges[axis]
    x = np.union1d(np.linspace(lo, hi, CURVE_GRID), np.asarray(result.axis_readings.get(axis, ()), float))
    machine = result.machine
    poses = np.zeros((x.size, len(machine.axes)))
    poses[:, machine.axis_names.index(axis)] = x
    B = np.hstack([basis_values(e, machine, poses)[:, np.asarray(result.identifiable[sl], bool)] for e, sl in members])
    curve = B @ np.asarray(result.values, float)[idx]
    rms = float(np.sqrt(np.mean(curve**2)))
    u_rms = error_rms_quantile(B, cov, CURVE_CONFIDENCE)
    # a table leaves the curve's error e where none leaves the true curve t: worse than none needs |e| > |t|, and
    # with |t + e| > 2U (the rule) that needs |e| > U — which happens with probability 1 − CURVE_CONFIDENCE at most
    if not u_rms > 0 or rms > 2.0 * u_rms:
        return None
    sum_of = f" ({members[0][0].code}'s curve: {' + '.join(e.name for e, _ in members)})" if len(members) > 1 else ""
    return (f"not significant as a curve: over {axis}'s measured range its RMS {rms:.3g}{sum_of} is within "
            f"2 × {u_rms:.3g}, the RMS its error stays below with {CURVE_CONFIDENCE:.0%} confidence; a table could "
            f"leave more error than no compensation")


def error_rms_quantile(B, cov, confidence: float) -> float:
    """The RMS over the rows of ``B`` (n, p) that the error of the curve ``B @ θ`` stays below with ``confidence``,
    for θ's error ~ N(0, ``cov``).

    The mean square of the error is Σ λᵢ zᵢ², zᵢ standard normal, λᵢ the eigenvalues of ``B cov Bᵀ / n``; its
    quantile is that of the scaled χ² with the same mean and variance (Welch–Satterthwaite: a·χ²_ν, a = Σλ²/Σλ,
    ν = (Σλ)²/Σλ²; Satterthwaite, Biometrics Bulletin 2 (1946) 110; Box, Ann. Math. Stat. 25 (1954) 290).
    One parameter: ν = 1 and the quantile is exact (1.96 σ at 95 %).
    """
    w, V = np.linalg.eigh(cov)
    root = V * np.sqrt(np.clip(w, 0.0, None))
    lam = np.linalg.svd(B @ root, compute_uv=False) ** 2 / B.shape[0]
    total = float(np.sum(lam))
    if not total > 0:
        return 0.0
    a, nu = float(np.sum(lam**2)) / total, total**2 / float(np.sum(lam**2))
    return float(np.sqrt(a * chi2_isf(1.0 - confidence, nu)))
