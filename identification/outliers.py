"""Gross misreads set aside: one slipped alignment must neither bias the fit nor invent effects.

An alignment whose externally studentized residual is beyond the Bonferroni
bound of χ²₃ at ``alpha`` (10⁻⁵ over all alignments: about 6.1 σ for 336
alignments) is a gross error, not noise: it is set aside and the model
refitted, until no alignment is beyond the bound (a few rounds at most). σ is
the given one, or else a robust estimate from the residuals (1.4826 × the
median absolute residual coordinate), so that the misread itself does not
inflate the σ it is judged against; when the model is still incomplete and
the robust scale exceeds the given σ, the larger is used, so that structure
is not taken for misreads.

Only isolated rows go: when more than ``max_fraction`` of the alignments
would be set aside, the residual has structure (a missing effect), not
misreads, and nothing is set aside. A local error spread over neighbouring
alignments stays in the data for the diagnosis to describe.
"""
from __future__ import annotations

import numpy as np

from .observations import Observations, SetAside

__all__ = ["SetAside", "set_aside_outliers", "OUTLIER_ALPHA"]

#: Family-wise level of the gross-error test over all alignments.
OUTLIER_ALPHA = 1e-5


def set_aside_outliers(machine, obs: Observations, effects, *, noise_um=None, alpha: float = OUTLIER_ALPHA,
                       max_fraction: float = 0.02, rounds: int = 4):
    """Fit, set aside the alignments beyond the gross-error bound, refit; repeat.

    Returns
    -------
    kept : Observations
        The alignments kept.
    set_aside : tuple of SetAside
        In the order they were set aside.
    """
    from kinid.stats import chi2_isf

    from .leverage import model_pass, studentized
    from .fit import fit

    index = np.arange(len(obs))
    kept = obs
    out = []
    for _ in range(rounds):
        result = fit(machine, kept, effects, noise_um=noise_um)
        r = result.residuals_um
        robust_um = 1.4826 * float(np.median(np.abs(r)))
        # the larger of the given σ and the robust scale: with the model still incomplete, structure
        # (not a misread) raises the residuals of many rows, and must not set them aside
        sigma = robust_um if noise_um is None else max(float(noise_um), robust_um)
        if not sigma > 0:
            break
        _, _, q0 = model_pass(machine, kept, result)
        stud, _ = studentized(result, q0, sigma)
        bound = chi2_isf(alpha / len(kept), 3)
        bad = np.flatnonzero(stud**2 > bound)
        if bad.size == 0 or len(out) + bad.size > max(1, int(max_fraction * len(obs))):
            break  # nothing beyond the bound, or too much of it to be misreads: structure
        worst = bad[np.argsort(-stud[bad])]
        for i in worst:
            row = int(index[i])
            out.append(SetAside(row, obs.lines[row] if obs.lines else None, obs.marks[row],
                                float(np.linalg.norm(r[i])), float(stud[i])))
        keep = np.setdiff1d(np.arange(len(kept)), bad)
        index = index[keep]
        kept = kept.subset(keep)
    return kept, tuple(out)
