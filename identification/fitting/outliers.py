"""Gross misreads set aside: one slipped alignment must neither bias the fit nor invent effects.

An alignment whose externally studentized residual is beyond the Bonferroni
bound of χ²₃ at ``alpha`` (10⁻⁵ over all alignments: about 6.1 σ for 336
alignments) is a gross error, not noise: it is set aside and the model
refitted, until no alignment is beyond the bound (a few rounds at most). σ is
a robust estimate from the residuals (1.4826 × the median absolute residual
coordinate), whatever σ was given: the misread itself does not inflate the σ
it is judged against, a σ given too large does not hide misreads (10 µm is
3.6 σ of a σ given as 2.7 µm where the noise is 1 µm), and with the model
still incomplete, structure raises the robust scale with the residuals, so
that it is not taken for misreads.

Only misreads go, not structure. Up to ``free_fraction`` of the alignments
(2 %) may be set aside on the bound alone. Beyond that, up to ``max_fraction``
(10 %), the rows beyond the bound must stand apart from the rest: the
smallest of them at least ``GAP`` times the largest studentized residual
kept. Misreads do (10–40 µm against a few σ of noise); a missing effect
spreads its residuals over a continuum of sizes, and then nothing is set
aside. A local error spread over neighbouring alignments stays in the data
for the diagnosis to describe.
"""
from __future__ import annotations

import numpy as np

from ..data import Observations, SetAside

__all__ = ["SetAside", "set_aside_outliers", "set_aside_with_fit", "OUTLIER_ALPHA"]

#: Family-wise level of the gross-error test over all alignments.
OUTLIER_ALPHA = 1e-5
#: Beyond the free share, rows set aside must exceed every kept row's studentized residual by this factor.
GAP = 1.25


def set_aside_outliers(machine, obs: Observations, effects, *, noise_um=None, alpha: float = OUTLIER_ALPHA,
                       free_fraction: float = 0.02, max_fraction: float = 0.10, rounds: int = 4):
    """Fit, set aside the alignments beyond the gross-error bound, refit; repeat.

    Returns
    -------
    kept : Observations
        The alignments kept.
    set_aside : tuple of SetAside
        In the order they were set aside.
    """
    kept, out, _ = set_aside_with_fit(machine, obs, effects, noise_um=noise_um, alpha=alpha, free_fraction=free_fraction,
                                      max_fraction=max_fraction, rounds=rounds)
    return kept, out


def set_aside_with_fit(machine, obs: Observations, effects, *, noise_um=None, alpha: float = OUTLIER_ALPHA,
                       free_fraction: float = 0.02, max_fraction: float = 0.10, rounds: int = 4, first=None,
                       first_hat=None):
    """:func:`set_aside_outliers`, and the fit of ``effects`` on the alignments kept (None when the last round set
    rows aside: those kept were not fitted again). ``first``: a fit of ``effects`` on ``obs`` the first round
    takes instead of fitting (the selection has one when it stops, and uses the fit returned for its first step);
    ``first_hat``: its hat matrix's diagonal (N, 3), if known (a diagnosis of ``first`` has it)."""
    from kinid.stats import chi2_isf

    from .leverage import leverages, studentized
    from .fit import fit

    index = np.arange(len(obs))
    kept = obs
    out = []
    result = None
    for _ in range(rounds):
        result = first if first is not None and kept is obs else fit(machine, kept, effects, noise_um=noise_um)
        r = result.residuals_um
        # the scale of these residuals, not the σ given: a σ given too large would hide the misreads; structure
        # left by an incomplete model raises this scale with the residuals of many rows
        sigma = 1.4826 * float(np.median(np.abs(r)))
        if not sigma > 0:
            break
        h = first_hat if first_hat is not None and result is first else leverages(machine, kept, result)
        stud, _ = studentized(result, None, sigma, h=h)
        bound = chi2_isf(alpha / len(kept), 3)
        bad = np.flatnonzero(stud**2 > bound)
        total = len(out) + bad.size
        if bad.size == 0 or total > max(1, int(max_fraction * len(obs))):
            break  # nothing beyond the bound, or too much of it to be misreads: structure
        if total > max(1, int(free_fraction * len(obs))):
            kept_largest = float(np.max(np.delete(stud, bad), initial=0.0))
            if float(np.min(stud[bad])) < GAP * kept_largest:
                break  # no gap between the rows beyond the bound and the rest: a continuum, structure
        worst = bad[np.argsort(-stud[bad])]
        for i in worst:
            row = int(index[i])
            out.append(SetAside(row, obs.lines[row] if obs.lines else None, obs.marks[row],
                                float(np.linalg.norm(r[i])), float(stud[i])))
        keep = np.setdiff1d(np.arange(len(kept)), bad)
        index = index[keep]
        kept = kept.subset(keep)
        result = None  # the rows kept are not fitted yet
    return kept, tuple(out), result
