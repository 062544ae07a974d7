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
The largest part of that choice, a period searched among hundreds, is made
again on each turn's training blocks (``choose``): the best searched period
of noise on the B/C table gained 1.4 standard errors on average (16 seeds)
chosen on all data, −0.1 chosen per turn (a turn that finds the candidate's
period again, within what its data determine, keeps the candidate's fit);
the likeliest of ~1 700 local windows +0.65 and −0.9 (12 seeds; a turn
chooses among the windows its training rows hold up). A searched candidate must pass
both: its period generalises (``MIN_GAIN_SE``), and so does the way it was
found — chosen without the held-out block, it must still predict it better
than the model without it (the nested gain above zero). The nested check
alone would ask too much where a plan samples an axis at few positions:
there a training set's best period can be another alias than the whole
set's (a 14.4 mm lead read at 18 positions of Y: 14.3 mm on all alignments,
36 mm on each training set).
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
    mean drop of the alignments' held-out squared errors in standard errors of that mean (``gain_se``). When the
    candidate was chosen by the data (a period searched), also the gain of the candidate each turn chose on its
    training blocks alone (``chosen_gain_se``) and those candidates (``chosen``)."""

    folds: int
    rms_without_um: float
    rms_with_um: float
    gain_se: float = float("inf")
    chosen_gain_se: float | None = None
    chosen: tuple = ()

    @property
    def improves(self) -> bool:
        """The candidate predicts the held-out blocks better by MIN_GAIN_SE, and, chosen on the training blocks
        alone, it still predicts them better than the model without it."""
        return (self.rms_with_um < self.rms_without_um and self.gain_se >= MIN_GAIN_SE
                and (self.chosen_gain_se is None or self.chosen_gain_se > 0))

    @property
    def change(self) -> float:
        """Relative change of the held-out RMS (negative: better)."""
        return self.rms_with_um / self.rms_without_um - 1.0 if self.rms_without_um > 0 else 0.0

    def __str__(self) -> str:
        text = (f"held-out blocks {self.change:+.0%} ({self.rms_without_um:.3f} → {self.rms_with_um:.3f} µm, "
                f"{self.folds}-fold, gain {self.gain_se:.1f} standard errors")
        if self.chosen_gain_se is None:
            return text + ")"
        chosen = ", ".join(dict.fromkeys(name.split(":", 2)[-1] for name in self.chosen))
        return text + (f"; {self.chosen_gain_se:.1f} with the {self.what_chosen} chosen on each turn's training "
                       f"blocks alone: {chosen})")

    @property
    def what_chosen(self) -> str:
        """What each turn chose: ``period`` (a periodic candidate), ``window`` (a local one) or ``effect``."""
        kind = self.chosen[0].split(":")[1] if self.chosen and self.chosen[0].count(":") >= 2 else ""
        return {"periodic": "period", "local": "window"}.get(kind, "effect")


def cross_validate(machine, obs: Observations, effects, candidate, *, folds: int = 4, noise_um=None,
                   theta0=None, choose=None, always_choose: bool = False) -> CrossValidation:
    """Held-out RMS of ``effects`` and of ``effects + [candidate]``, fitted on all blocks but one in turn.
    ``choose(training rows, training data, fit of effects on them)``, if given, is the candidate of each turn:
    what the data chose (a period searched) chosen again on the training blocks alone; its gain is
    ``chosen_gain_se``, measured once the candidate passes (or ``always_choose``)."""
    from .fit import fit
    from .residuals import design, residuals

    n = len(obs)
    order = np.argsort(obs.t_s, kind="stable") if obs.t_s is not None else np.arange(n)
    ss = np.zeros(2)
    count = 0
    per_row = np.full((3, n), np.nan)  # each alignment's held-out squared error: without, with, with the turn's own
    turns = []

    def start(model, theta):
        if theta is None:
            return None
        size = sum(e.n_params for e in model)
        return np.r_[theta, np.zeros(max(size - len(theta), 0))][:size]

    def held_out(m, model, tr, te, test, theta):
        result = fit(machine, tr, model, noise_um=noise_um, theta0=start(model, theta))
        r = residuals(machine, design(machine, model, te), te, result.theta, jacobian=False)
        per_row[m, test] = np.sum(r**2, axis=1)
        return result, float(np.sum(r**2))

    for k in range(folds):
        test = np.sort(order[k::folds])
        train = np.setdiff1d(np.arange(n), test)
        if test.size == 0 or train.size == 0:
            continue
        tr, te = obs.subset(train), obs.subset(test)
        (without, ss0), (with_, ss1) = (held_out(m, model, tr, te, test, theta0)
                                        for m, model in enumerate((list(effects), list(effects) + [candidate])))
        ss += (ss0, ss1)
        count += 3 * test.size
        turns.append((tr, te, test, without, with_))
    rms = np.sqrt(ss / max(count, 1))
    gain = _gain_se(per_row[0] - per_row[1])
    if choose is None or not (always_choose or rms[1] < rms[0] and gain >= MIN_GAIN_SE):
        return CrossValidation(folds, float(rms[0]), float(rms[1]), gain)
    # the candidate passes: is the way it was chosen as good, chosen without the held-out block?
    chosen = []
    for tr, te, test, without, with_ in turns:
        own = choose(np.setdiff1d(np.arange(n), test), tr, without)
        chosen.append(own.name)
        if own.name == candidate.name:  # the same effect: the same fit
            per_row[2, test] = per_row[1, test]
        else:
            held_out(2, list(effects) + [own], tr, te, test, with_.theta)
    return CrossValidation(folds, float(rms[0]), float(rms[1]), gain, _gain_se(per_row[0] - per_row[2]), tuple(chosen))


def _gain_se(gain) -> float:
    """The mean of the alignments' drops of held-out squared error, in standard errors of that mean."""
    gain = gain[np.isfinite(gain)]
    se = float(np.std(gain, ddof=1) / np.sqrt(gain.size)) if gain.size > 1 else 0.0
    return float(np.mean(gain) / se) if se > 0 else (float("inf") if gain.size and np.mean(gain) > 0 else 0.0)
