"""Candidates the data cannot tell apart, judged by the held-out check as one family.

The score test ranks candidates by their p-values, and several often explain the residual within chance of each
other: on a B head whose plan reads Z at four positions, each tied to a tilt, a B scale (``EBB:poly1``), X moving
with B (``EXB:poly1``), a Z scale (``EZZ:poly1``) and Y moving with Z (``EYZ:poly1``) drop the χ² by 976.6–976.9
(p ≈ 1e-99). The best of them by a hair was the Z scale, nearly aliased with the model: fitted on three held-out
blocks it predicts the fourth no better (a gain of 1.8 standard errors), while the B scale, the error the machine
has, gains 15.1. Judging the best alone, ``--auto`` added nothing and the effect was said but dropped.

A **twin** of the best candidate is a live candidate a machine could have (its size at the values the score test
estimates within the limits), significant, not in the model, of no more parameters than the best, whose χ² drop
falls short of the best's by less than chance (:func:`chance_of`: the spread of the best's own drop), at most
:data:`MAX_TWINS` of them: those of the library first, then by p-value (a step's position or a period searched
among thousands last). When the best fails the held-out check, each twin is checked as it would be added; the
family passes when one of them passes the check at the family's bar (:func:`family_bar_se`: the one-sided tail of
:data:`~kinid.identification.fitting.crossval.MIN_GAIN_SE` shared among the members checked, Bonferroni), and the
first that does in that order is added. What the data cannot separate is said, not chosen: the twins that predict
the held-out blocks as well and those that do not are named (:class:`Family`, :func:`family_words`).

Measured on the loop's B head (benchmarks/proving_loop.py, seed 1, scenario 3): choosing by the largest held-out
gain added a step of X at a searched position (15.2 standard errors against the B scale's 15.1); by p-value alone,
twins of more parameters than the best allowed, a quadratic of Z, read at four positions that every held-out block
holds too, so that the blocks cannot refuse it between them (held-out 2·RMS over the volume 1.9 µm, the B scale's
0.6), and on the next step a period of Z at the family's bar.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from kinid.stats import chi2_isf, chi2_sf

from .ambiguity import TWIN_DELTA

__all__ = ["Family", "twins_of", "chance_of", "family_bar_se", "judge_family", "family_words", "MAX_TWINS"]

#: Twins checked at most when the best candidate fails the held-out check (each one check: about a fit's time).
MAX_TWINS = 8


@dataclass(frozen=True)
class Family:
    """The best candidate and its twins as the held-out check judged them.

    Attributes
    ----------
    best : str
        The best candidate by the score test (it failed the held-out check).
    added : str or None
        The member added (the first of those passing the family's bar in the twins' order, :func:`twins_of`), None
        if none passes.
    held_out : CrossValidation or None
        The check of ``added``.
    alike : tuple of str
        The other members that pass the family's bar too: they predict held-out blocks better as well, and the data
        cannot tell them from ``added``.
    refused : tuple of str
        The members that fit the data as well but do not predict held-out blocks better (``best`` among them).
    bar_se : float
        The family's bar, standard errors (:func:`family_bar_se`).
    """

    best: str
    added: str | None
    held_out: object
    alike: tuple
    refused: tuple
    bar_se: float


def twins_of(dg, best, model=(), at_most: int = MAX_TWINS) -> tuple:
    """The twins of ``best`` (a live candidate of the diagnosis ``dg``): live candidates, significant, not passed
    over for a size no machine has, not in ``model`` (effect names), of no more parameters than the best, whose χ²
    drop falls short of the best's by less than :func:`chance_of` it; those of the library first (a position or
    period searched among thousands last), then the best p-value, at most ``at_most``."""
    from ..model import implausible_candidate

    have = {getattr(e, "name", e) for e in model}
    machine, ranges = dg.fit.machine, dg.fit.axis_ranges
    out = []
    within = chance_of(best)
    for c in sorted(dg.live, key=lambda c: (c.trials > 1, c.p_value)):
        if len(out) >= at_most:
            break
        if (c.effect == best.effect or c.effect in have or c.p_value >= dg.threshold or c.k > best.k
                or c.statistic < best.statistic - within):
            continue
        if implausible_candidate(machine, c, ranges) is None:
            out.append(c)
    return tuple(out)


def chance_of(best) -> float:
    """How far short of the best candidate's χ² drop another's may fall and still fit the data within chance of it:
    the standard deviation of the best's own drop, a noncentral χ² of its ``k`` degrees of freedom at the
    noncentrality it measured, √(2k + 4·drop), and at least
    :data:`~kinid.identification.diagnosis.ambiguity.TWIN_DELTA` (the drops of two alternatives on noise). A drop of
    1 651 is uncertain by ±81: a B scale 17 short of a Z scale there fits as well."""
    return max(TWIN_DELTA, math.sqrt(2.0 * best.k + 4.0 * max(best.statistic, 0.0)))


def family_bar_se(members: int, bar_se: float | None = None) -> float:
    """The held-out gain (standard errors) one of ``members`` candidates checked must bring for the family to pass:
    the one-sided normal tail of ``bar_se`` (default
    :data:`~kinid.identification.fitting.crossval.MIN_GAIN_SE`) divided among them. One member: ``bar_se``; six:
    2.67 for 2."""
    if bar_se is None:
        from ..fitting import MIN_GAIN_SE as bar_se
    tail = 0.5 * chi2_sf(bar_se * bar_se, 1) / max(int(members), 1)  # P(z > bar) / members
    return math.sqrt(chi2_isf(2.0 * tail, 1))


def judge_family(best: str, best_cv, twins, check) -> Family:
    """The family of ``best`` (whose held-out check ``best_cv`` failed) and its ``twins`` (effect names), each
    checked by ``check(name) -> CrossValidation`` (the check the selection runs on a candidate it would add)."""
    bar = family_bar_se(1 + len(twins))
    judged = [(name, check(name)) for name in twins]
    passing = [(name, cv) for name, cv in judged if cv.improves and cv.gain_se >= bar]
    if not passing:
        return Family(best, None, None, (), (best,) + tuple(twins), bar)
    added, cv = passing[0]  # the twins' order: the library's first, then the p-value
    alike = tuple(name for name, _ in passing[1:])
    refused = (best,) + tuple(name for name, c in judged if not (c.improves and c.gain_se >= bar))
    return Family(best, added, cv, alike, refused, bar)


def family_words(family: Family) -> str:
    """What the held-out check made of a family, in words (for the selection's messages and its last words)."""
    if family.added is None:
        return (f"nor does any of its twins that fit the data within chance of it ({', '.join(family.refused[1:])}; "
                f"one of them needed a gain of {family.bar_se:.2g} standard errors)")
    text = (f"{family.added} was added of candidates that fit the data within chance of each other: it predicts "
            f"held-out alignments better (gain {family.held_out.gain_se:.1f} standard errors, {family.bar_se:.2g} "
            f"needed, one of {1 + len(family.alike) + len(family.refused)} checked); "
            f"{', '.join(family.refused)} {'does' if len(family.refused) == 1 else 'do'} not")
    if family.alike:
        text += (f"; {', '.join(family.alike)} {'predicts' if len(family.alike) == 1 else 'predict'} them as well: "
                 f"these data cannot tell {'it' if len(family.alike) == 1 else 'them'} from {family.added} — measure "
                 f"where they differ (kinid plan --detect {family.alike[0]}=SIZE)")
    return text
