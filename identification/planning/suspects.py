"""Effects the data hint at without establishing them, and the alignments that would settle them.

A plan is sized for the model it is made for, not for the power to detect what that model lacks. An error below
what the measured alignments detect leaves the diagnosis's best candidate close to its threshold: not significant,
so the fit does not add it and a sequential design has nothing to plan for, while the error, a few tenths of a
micrometre at the tool, is already what the target allows. A **suspect** is such a candidate: live, its p-value
within :data:`SUSPECT_FACTOR` of the diagnosis's (Bonferroni) threshold, not in the model. The alignments to add
are then also those that make each suspect, of the size the data estimate, detectable by the same test with
probability :data:`SUSPECT_POWER`: the second fit adds it if it is there and refutes it if it was noise. A suspect
that alone would need more than :data:`SUSPECT_SHARE` of the measured alignments added is named, not planned for.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .plan import covariance_if_added

__all__ = ["Suspect", "suspects_of", "suspect_power", "estimated_columns", "add_until_detected", "SUSPECT_FACTOR",
           "SUSPECT_POWER", "MAX_SUSPECTS", "SUSPECT_SHARE"]

#: A live candidate whose p-value is at most this many times the diagnosis's threshold is a suspect.
SUSPECT_FACTOR = 10.0
#: Probability with which the added alignments detect each suspect at its estimated size.
SUSPECT_POWER = 0.8
#: Suspects planned for at most (the best p-values, one per error joint).
MAX_SUSPECTS = 3
#: A suspect is planned for only if, alone, it reaches SUSPECT_POWER within this share of the alignments measured:
#: one that needs more (an effect the candidates barely separate from the model: hundreds of alignments for a hint)
#: would cost more than the loop's budget of 1.3 times what the true model needs (docs/plan.md).
SUSPECT_SHARE = 0.3


@dataclass(frozen=True)
class Suspect:
    """A candidate effect the data hint at (:func:`suspects_of`).

    Attributes
    ----------
    effect : str
        Its name (``EXY:poly2``).
    coefficients, coefficient_std : tuple of float
        Its parameters as the score test estimates them and their standard deviations, the effect's units (a
        parameter the model already holds, its column in the model's span, has both at zero).
    p_value : float
        The score test's p-value.
    threshold : float
        The diagnosis's threshold on a candidate's p-value (α over the candidates tested): the level the added
        alignments are planned to detect it at.
    """

    effect: str
    coefficients: tuple
    coefficient_std: tuple
    p_value: float
    threshold: float


def suspects_of(diagnosis, model=(), factor: float = SUSPECT_FACTOR, at_most: int = MAX_SUSPECTS) -> tuple:
    """The suspects of a diagnosis (a :class:`~kinid.identification.diagnosis.Diagnosis` of the final model): live
    candidates with ``p ≤ factor × threshold`` not in ``model`` (effect names), the best first, one per error joint,
    at most ``at_most``; empty where σ says the residual is noise beyond doubt or nothing comes close."""
    have = {getattr(e, "name", e) for e in model}
    out, joints = [], set()
    for c in sorted((c for c in diagnosis.candidates if c.status == "live"), key=lambda c: c.p_value):
        if c.p_value > factor * diagnosis.threshold or len(out) >= at_most:
            break
        joint = c.effect.partition(":")[0]
        if c.effect in have or joint in joints or not c.coefficients or not np.all(np.isfinite(c.coefficients)):
            continue
        joints.add(joint)
        out.append(Suspect(c.effect, tuple(float(v) for v in c.coefficients),
                           tuple(float(v) for v in c.coefficient_std), float(c.p_value), float(diagnosis.threshold)))
    return tuple(out)


def _lambda(J_model, J_effect, coefficients) -> float:
    """Non-centrality of the test of an effect of these ``coefficients`` given the model (Jacobians whitened, the
    rows measured): ``|R c|²``, ``R`` the effect's columns less their least-squares fit by the model's — the signal
    the model cannot absorb (0 for an effect in the model's span)."""
    X = J_model.reshape(-1, J_model.shape[2])
    Z = J_effect.reshape(-1, J_effect.shape[2])
    R = Z - X @ np.linalg.lstsq(X, Z, rcond=None)[0]
    lam = float(np.sum((R @ coefficients) ** 2))
    return lam if np.isfinite(lam) else 0.0


def suspect_power(J_model, J_effect, coefficients, alpha: float) -> float:
    """Power of the diagnosis's F test (σ from the residuals) at level ``alpha`` to detect an effect of exactly
    these ``coefficients`` (its units) on the rows of ``J_model`` and ``J_effect`` (both whitened, (N, 3, ·))."""
    from scipy.special import fdtri, ncfdtr

    k = J_effect.shape[2]
    dof = J_model.shape[0] * 3 - J_model.shape[2] - k
    if dof < 1:
        return 0.0
    lam = _lambda(J_model, J_effect, np.asarray(coefficients, float))
    return float(1.0 - ncfdtr(k, dof, lam, fdtri(k, dof, 1.0 - alpha)))


def estimated_columns(J_effect, coefficient_std, tol: float = 1e-6):
    """Which of an effect's parameters its score test estimated: those whose standard deviation times their
    column's norm (``J_effect`` whitened, (N, 3, k)) is at least ``tol`` of the largest; the others lie in the
    model's span (the test held them at zero) and belong with the model."""
    scale = np.asarray(coefficient_std, float) * np.linalg.norm(J_effect.reshape(-1, J_effect.shape[2]), axis=0)
    return scale >= tol * max(float(scale.max()), 1e-300)


def add_until_detected(index, blocks: dict, power: float, limit: int, each_at_most: int | None = None):
    """Add rows to ``index`` until each block reaches ``power``: ``blocks`` maps a name to (the model's whitened
    Jacobian (N, 3, P), the effect's (N, 3, k), its coefficients, α), over the same N rows. The weakest block
    first, the row that raises its non-centrality most; a block that even every row leaves below ``power`` is not
    planned for, nor, with ``each_at_most``, one that alone would need more than that many rows added. At most
    ``limit`` rows are added. Returns (index, {name: power reached})."""
    reachable = {n: b for n, b in blocks.items() if _power_of(b, slice(None)) >= power}
    if each_at_most is not None:  # alone, within that many rows
        reachable = {n: b for n, b in reachable.items() if _power_of(b, _grow(index, {n: b}, power, each_at_most)) >= power}
    index = _grow(index, reachable, power, limit)
    return np.array(index, int), {n: _power_of(b, index) for n, b in blocks.items()}


def _power_of(b, rows):
    return suspect_power(b[0][rows], b[1][rows], b[2], b[3])


def _grow(index, blocks: dict, power: float, limit: int) -> list:
    """``index`` with at most ``limit`` rows added for ``blocks`` (:func:`add_until_detected`), the weakest first."""
    index = list(index)
    powers = {n: _power_of(b, index) for n, b in blocks.items()}
    for _ in range(limit):
        short = {n: p for n, p in powers.items() if p < power}
        if not short:
            break
        weakest = min(short, key=short.get)
        J, Je, c, _ = blocks[weakest]
        c = np.asarray(c, float)
        new_ee = covariance_if_added(np.concatenate([J, Je], axis=2), index, Je.shape[2])  # the effect's, row added
        score = np.einsum("i,nij,j->n", c, np.linalg.pinv(new_ee), c)
        score[index] = -np.inf
        index.append(int(np.argmax(score)))
        powers = {n: _power_of(b, index) for n, b in blocks.items()}
    return index
