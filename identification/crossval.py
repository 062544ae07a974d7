"""Cross-validation of an added effect: does it predict alignments its fit did not see?

A p-value says an effect explains more of these residuals than noise would;
it does not say the effect generalises. Before forward selection adds an
effect, the alignments are dealt into ``folds`` blocks in measurement order
(every ``folds``-th alignment to the same block, so that each block spans the
whole plan and the whole time); each block is predicted by the model fitted
on the others, with and without the effect. The effect is accepted only if
the held-out sum of squares falls by more than its own scatter would let it
fall by chance: the mean over alignments of the drop of each one's held-out
squared error must exceed ``MIN_GAIN_SE`` standard errors of that mean. The
candidate tested is the best of many, chosen on all the data, the held-out
blocks included, so its held-out gain is biased upwards: on pure noise (the
A/C table, the patent plan, 12 seeds) the best candidate lowered the held-out
sum of squares 11 times in 12, by one standard error 5 times, by two never.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .observations import Observations

__all__ = ["CrossValidation", "cross_validate", "MIN_GAIN_SE"]

#: The held-out gain an effect must bring, in standard errors of the mean gain per alignment.
MIN_GAIN_SE = 2.0


@dataclass(frozen=True)
class CrossValidation:
    """Held-out residual RMS per coordinate (µm) without and with the candidate, over ``folds`` blocks, and the
    mean drop of the alignments' held-out squared errors in standard errors of that mean (``gain_se``)."""

    folds: int
    rms_without_um: float
    rms_with_um: float
    gain_se: float = float("inf")

    @property
    def improves(self) -> bool:
        return self.rms_with_um < self.rms_without_um and self.gain_se >= MIN_GAIN_SE

    @property
    def change(self) -> float:
        """Relative change of the held-out RMS (negative: better)."""
        return self.rms_with_um / self.rms_without_um - 1.0 if self.rms_without_um > 0 else 0.0

    def __str__(self) -> str:
        return (f"held-out blocks {self.change:+.0%} ({self.rms_without_um:.3f} → {self.rms_with_um:.3f} µm, "
                f"{self.folds}-fold, gain {self.gain_se:.1f} standard errors)")


def cross_validate(machine, obs: Observations, effects, candidate, *, folds: int = 4, noise_um=None,
                   theta0=None) -> CrossValidation:
    """Held-out RMS of ``effects`` and of ``effects + [candidate]``, fitted on all blocks but one in turn."""
    from .fit import fit
    from .residuals import design, residuals

    n = len(obs)
    order = np.argsort(obs.t_s, kind="stable") if obs.t_s is not None else np.arange(n)
    ss = np.zeros(2)
    count = 0
    per_row = np.full((2, n), np.nan)  # each alignment's held-out squared error, without and with
    models = (list(effects), list(effects) + [candidate])
    for k in range(folds):
        test = np.sort(order[k::folds])
        train = np.setdiff1d(np.arange(n), test)
        if test.size == 0 or train.size == 0:
            continue
        tr, te = obs.subset(train), obs.subset(test)
        for m, model in enumerate(models):
            start = None
            if theta0 is not None:
                start = np.r_[theta0, np.zeros(sum(e.n_params for e in model) - len(theta0))][:sum(e.n_params for e in model)]
            result = fit(machine, tr, model, noise_um=noise_um, theta0=start)
            r = residuals(machine, design(machine, model, te), te, result.theta, jacobian=False)
            ss[m] += float(np.sum(r**2))
            per_row[m, test] = np.sum(r**2, axis=1)
        count += 3 * test.size
    rms = np.sqrt(ss / max(count, 1))
    gain = (per_row[0] - per_row[1])[np.isfinite(per_row[0] - per_row[1])]
    se = float(np.std(gain, ddof=1) / np.sqrt(gain.size)) if gain.size > 1 else 0.0
    gain_se = float(np.mean(gain) / se) if se > 0 else (float("inf") if gain.size and np.mean(gain) > 0 else 0.0)
    return CrossValidation(folds, float(rms[0]), float(rms[1]), gain_se)
