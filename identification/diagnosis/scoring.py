"""Scoring candidate effects at a fit, and proposing the ones the library does not list.

Score (Lagrange-multiplier) test of every candidate effect at the current fit:
with whitened residuals r (orthogonal to the model's Jacobian J₀ at the
optimum) and a candidate's whitened Jacobian block C, the block's part not
explained by the model is C⊥ = (I − Q₀Q₀ᵀ) C and adding the candidate lowers
the sum of squares, to first order, by Δ = rᵀ C⊥ (C⊥ᵀ C⊥)⁺ C⊥ᵀ r. With σ
known, Δ ~ χ²_k under "no such effect"; with σ estimated, an F test. All
candidates' blocks come from one Pinocchio pass: a candidate's column is its
error joint's column times the basis value.

Beyond the library (:func:`score_all`): free periods found by the period search
(:mod:`~kinid.identification.diagnosis.periods`) and time constants; the diagnosis adds
non-parametric maps and local errors where no parametric candidate explains the
residual (:mod:`~kinid.identification.diagnosis.local_errors`).

References
----------
C. R. Rao, "Large sample tests of statistical hypotheses concerning several
parameters ...", Proc. Cambridge Phil. Soc. 44, 1948 (score test).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kinid.stats import chi2_logsf, f_logsf, f_logsf_each
from kinid.threads import blas_single_threaded

from ..model import Machine, basis_of, param_codes
from ..data import Observations
from ..fitting import FitResult, design, effect_columns, model_pass
from . import score_sums
from .score_sums import (EXACT_COLUMNS, Memo, basis_values_once, column_groups, group_sums, model_products,
                         projected_exactly)

__all__ = ["Candidate", "FitSide", "fit_side", "score_candidates", "ALIAS_TOL", "INVISIBLE_LEVER_M"]


#: log 10, as numpy gives it (the p-values' digits as before).
_LN10 = np.log(10)


#: A candidate whose block keeps less than this fraction of its norm after projection is aliased.
ALIAS_TOL = 1e-6


#: A rotation whose lever arm to the tool point (RMS over the data) is below this, in metres, is
#: invisible: even 1 mrad of it moves the point by less than 0.1 µm. (Translations have lever 1.)
INVISIBLE_LEVER_M = 1e-4


@dataclass(frozen=True)
class Candidate:
    """Score of one candidate effect.

    Attributes
    ----------
    effect : str
    status : {"live", "aliased", "invisible"}
    k : int
        Parameters of the effect (degrees of freedom of the test).
    statistic : float
        Predicted drop of the whitened sum of squares (χ² units).
    p_value, log10_p : float
    rms_after_um : float
        Predicted residual RMS per coordinate after adding it, µm.
    size : float
        Estimated size: the coefficient (k = 1), the amplitude √(a² + b²)
        (periodic) or the largest term's effect over the data (poly), in ``size_unit``.
    size_std : float
    size_unit : str
    aliases_with : tuple of str
        For ``aliased``: the model parameters it cannot be told from.
    note : str
        How the candidate was found when it is not from the library (a period search).
    trials : float
        Alternatives searched to find it (its p-value is multiplied by this); 1 for the library.
    coefficients, coefficient_std : tuple of float
        For ``live``: its parameters' values the test estimates (the effect's units) — the least-squares values
        of the candidate added to the model, to first order — and their standard deviations.
    """

    effect: str
    status: str
    k: int
    statistic: float
    p_value: float
    log10_p: float
    rms_after_um: float
    size: float
    size_std: float
    size_unit: str
    aliases_with: tuple = ()
    note: str = ""
    trials: float = 1.0
    coefficients: tuple = ()
    coefficient_std: tuple = ()



#: A candidate whose projected Gram matrix (columns scaled to unit norm) has an eigenvalue below this is scored
#: again from its explicitly projected columns: the Gram matrix from sums over alignments, CᵀC − AᵀA, loses the
#: digits that the projection off a model which nearly explains the candidate cancels.
EXACT_BELOW = 1e-4


@dataclass(frozen=True)
class FitSide:
    """What the score test of any candidate needs of the fit (:func:`fit_side`): made once per fit and σ, and
    shared by every :func:`score_candidates` call at that fit (a diagnosis makes about ten, a τ search dozens).

    Attributes
    ----------
    result, sigma : the fit and the σ that whitens
    d_errors, q0 : the error-joint Jacobian at the fit and the model's orthonormal basis (see score_candidates)
    r : array (3N,)
        Whitened residual, projected exactly off the model.
    J0 : array (3N, rank)
        Whitened identifiable model columns; ``G0`` its Gram matrix, ``model_names`` its parameters.
    lever : array (n_errors,)
        RMS lever arm of each error joint to the tool point, m/rad (1 for translations).
    visible_floor : float
        Norm below which a candidate's column is invisible.
    memo : what the score tests at this fit compute once (:class:`Memo`)
    """

    result: FitResult
    sigma: float
    d_errors: np.ndarray
    q0: np.ndarray
    r: np.ndarray
    J0: np.ndarray
    G0: np.ndarray
    model_names: list
    lever: np.ndarray
    visible_floor: float
    memo: Memo = field(default_factory=Memo, compare=False, repr=False)

    def joint_series(self, joint: int) -> tuple:
        """Series over the alignments of error joint ``joint`` (:func:`~.score_sums.joint_series`), computed once."""
        def make():
            q0r = self.memo.get("q0r", lambda: self.q0.T @ self.r, always=True)
            return score_sums.joint_series(self.d_errors[:, :, joint] / self.sigma, self.q0, self.r, q0r)
        return self.memo.get(("series", joint), make)


def fit_side(machine: Machine, obs: Observations, result: FitResult, sigma: float, d_errors=None, q0=None) -> FitSide:
    """The fit's side of the score test (:class:`FitSide`); ``d_errors`` and ``q0`` computed if not given."""
    if d_errors is None or q0 is None:
        d_errors, _, q0 = model_pass(machine, obs, result)
    d0 = design(machine, result.effects, obs)
    r = result.residuals_um.ravel() / sigma
    J0 = effect_columns(d_errors, d0).reshape(result.residuals_um.size, -1)[:, result.identifiable] / sigma
    r = r - q0 @ (q0.T @ r)  # exactly orthogonal to the model (it is, to first order, at the optimum)
    lever = np.sqrt(np.einsum("nkj,nkj->j", d_errors, d_errors) / d_errors.shape[0])  # per error joint: m/rad or 1
    visible_floor = 1e-12 * max(1.0, float(np.abs(J0).max()) if J0.size else 1.0)
    model_names = [n for n, ok in zip(result.param_names, result.identifiable) if ok]
    return FitSide(result, sigma, d_errors, q0, r, J0, J0.T @ J0, model_names, lever, visible_floor)


@blas_single_threaded
def score_candidates(machine: Machine, obs: Observations, result: FitResult, candidates, sigma: float, *, sigma_known: bool,
                     d_errors=None, q0=None, side: FitSide | None = None, notes: bool = True):
    """Score test of each candidate effect at the fit ``result`` (see module docstring).

    A candidate's column is its error joint's column times a basis value, so every sum over alignments the
    test needs is a sum over the N alignments of basis values times a few series of its joint (computed once
    per joint and fit, :func:`~.score_sums.joint_series`), not over the 3N coordinates of each column. The
    candidates of one joint are summed together (:func:`~.score_sums.column_groups`); local errors on one knot
    grid share its B-splines, and each window's sums are a sub-block of the grid's.

    Parameters
    ----------
    d_errors : array (N, 3, n_errors), optional
        Error-joint Jacobian at the fit (computed if not given).
    q0 : array (3N, rank), optional
        Orthonormal basis of the identifiable model columns (computed if not given).
    side : FitSide, optional
        The fit's side of the test, made once by :func:`fit_side` for many calls (made here if not given, or if
        it is of another fit or σ).
    notes : bool
        Say in words where a local candidate's error is (:attr:`Candidate.note`); False for a search that keeps
        only the best of hundreds.

    Returns
    -------
    list of Candidate, in the order of ``candidates``.
    """

    if side is None or side.result is not result or side.sigma != sigma:
        side = fit_side(machine, obs, result, sigma, d_errors, q0)
    d_errors, Q0, r, J0, lever, visible_floor = side.d_errors, side.q0, side.r, side.J0, side.lever, side.visible_floor
    M = result.residuals_um.size
    rss = float(r @ r)
    test = _Test(machine, result, sigma, sigma_known, M, rss, J0, side.model_names, side.G0, notes)
    n = len(obs)
    out = [None] * len(candidates)
    # by k: chunks of (positions, effects, units, alive, scale, projected Gram matrices, joint, products with r)
    pending = {}
    joint, series = None, None
    for group in column_groups(machine, obs, candidates, side.memo):
        units = [e.param_units(machine)[-1] for _, e, _ in group.members]  # a polynomial sizes its highest term
        if lever[group.joint] < INVISIBLE_LEVER_M:
            for (i, e, _), unit in zip(group.members, units):
                out[i] = Candidate(e.name, "invisible", e.n_params, 0.0, 1.0, 0.0, result.rms_um, np.nan, np.nan, unit)
            continue
        if group.joint != joint:  # the groups come joint by joint: one joint's series at a time
            joint = group.joint
            series = side.joint_series(joint)
        norm2, A, bvec, blocks = group_sums(group, series, n, side.memo)
        for k, (ms, grams) in blocks.items():  # the members of k columns at once
            index = np.array([group.members[m][2] for m in ms]).reshape(len(ms), k)
            norm_c = np.sqrt(norm2[index])
            visible = np.any(norm_c > visible_floor, axis=1)
            for m in np.flatnonzero(~visible).tolist():
                i, e, _ = group.members[ms[m]]
                out[i] = Candidate(e.name, "invisible", e.n_params, 0.0, 1.0, 0.0, result.rms_um, np.nan, np.nan,
                                   units[ms[m]])
            if not visible.any():
                continue
            kept = np.flatnonzero(visible)
            norm_c = norm_c[kept]
            # a column that vanishes on this plan (a sine sampled at its zeros) carries nothing: drop it
            # rather than blow its rounding noise up to unit length
            alive = norm_c > np.maximum(visible_floor, 1e-9 * norm_c.max(axis=1))[:, None]
            members = [ms[m] for m in kept.tolist()]
            pending.setdefault(k, []).append((
                [group.members[m][0] for m in members], [group.members[m][1] for m in members],
                [units[m] for m in members], alive, np.where(alive, norm_c, 1.0), grams[kept], joint,
                bvec[index[kept]]))
    for i, e in enumerate(candidates):  # an effect spread over several joints (the gravity compliance)
        if basis_of(e).joints is not None:
            out[i] = _score_spread(machine, obs, e, side, test)
    # the eigen-decompositions of the normalized Gram matrices and the tests, all candidates of one size at once
    for k in sorted(pending):
        chunks = pending[k]
        positions = [i for chunk in chunks for i in chunk[0]]
        effects = [e for chunk in chunks for e in chunk[1]]
        joints = [chunk[6] for chunk in chunks for _ in chunk[0]]
        alive, scale, grams, bvec = (np.concatenate([chunk[f] for chunk in chunks]) for f in (3, 4, 5, 7))
        both = alive[:, :, None] & alive[:, None, :]
        gs = np.where(both, grams / (scale[:, :, None] * scale[:, None, :]), 0.0)
        w, V = np.linalg.eigh(gs)
        products = [None] * len(effects)
        exact = {}  # the sums lose the digits a projection off a model that nearly explains the candidate cancels
        for m in np.flatnonzero(w.min(axis=1) < EXACT_BELOW):
            exact.setdefault(joints[m], []).append(m)
        batch = max(EXACT_COLUMNS // k, 1)  # one joint's candidates of k parameters projected together, so many
        for j, ms in [(j, ms[a:a + batch]) for j, ms in exact.items() for a in range(0, len(ms), batch)]:
            col = d_errors[:, :, j] / sigma
            basis = np.concatenate([basis_values_once(machine, obs, effects[m], slice(0, n), side.memo) for m in ms],
                                   axis=1)
            grams_m, bvec[ms] = projected_exactly(col, basis, k, Q0, r)
            for m, gram, b in zip(ms, grams_m, range(0, basis.shape[1], k)):
                gs[m], w[m], V[m] = _normalized(gram, alive[m], scale[m])
                # the product with the model's columns serves only aliased candidates, all scored exactly (an
                # aliased candidate's eigenvalues are below ALIAS_TOL² < EXACT_BELOW)
                products[m] = lambda col=col, basis=basis[:, b:b + k]: model_products(col, basis, J0)
        judged = test.judge(effects, [u for chunk in chunks for u in chunk[2]], alive, scale, gs, w, V, bvec, products)
        for i, c in zip(positions, judged):
            out[i] = c
    return out


def _score_spread(machine, obs, e, side: FitSide, test) -> Candidate:
    """The score test of an effect whose parameters sit on several error joints, from its explicitly projected
    columns (a few: one per joint)."""
    codes = machine.error_codes
    joints = [codes.index(c) for c in param_codes(e, machine)]
    basis = basis_values_once(machine, obs, e, slice(0, len(obs)), side.memo)
    C = (side.d_errors[:, :, joints] * basis[:, None, :]).reshape(-1, basis.shape[1]) / side.sigma
    Cp = C - side.q0 @ (side.q0.T @ C)
    norm_c = np.sqrt(np.einsum("ij,ij->j", C, C))
    unit = e.param_units(machine)[-1]
    if not np.any(norm_c > side.visible_floor):
        return Candidate(e.name, "invisible", e.n_params, 0.0, 1.0, 0.0, side.result.rms_um, np.nan, np.nan, unit)
    alive = norm_c > max(side.visible_floor, 1e-9 * norm_c.max())
    scale = np.where(alive, norm_c, 1.0)
    gs, w, V = _normalized(Cp.T @ Cp, alive, scale)
    return test.judge([e], [unit], alive[None], scale[None], gs[None], w[None], V[None], (Cp.T @ side.r)[None],
                      [lambda: side.J0.T @ C])[0]


def _normalized(gram, alive, scale) -> tuple:
    """The Gram matrix with its live columns scaled to unit norm (dead ones zero), and its eigen-decomposition."""
    gs = np.where(np.outer(alive, alive), gram / np.outer(scale, scale), 0.0)
    w, V = np.linalg.eigh(gs)
    return gs, w, V


@dataclass(frozen=True)
class _Test:
    """What judging one candidate needs of the fit: the model's columns, the residual's sum of squares."""

    machine: Machine
    result: FitResult
    sigma: float
    sigma_known: bool
    M: int
    rss: float
    J0: np.ndarray
    model_names: list
    G0: np.ndarray
    notes: bool = True

    def judge(self, effects, units, alive, scale, gs, w, V, bvec, products) -> list:
        """The candidates ``effects`` of k parameters each, from their projected, normalized Gram matrices ``gs``
        (m, k, k) (eigen-decompositions w (m, k), V (m, k, k)), their projected columns' products with the
        residual ``bvec`` (m, k) and, for an aliased one, a function ``products[i]`` that gives its product with
        the model's columns: a list of Candidate."""
        result, machine, sigma, M, rss = self.result, self.machine, self.sigma, self.M, self.rss
        k = gs.shape[1]
        ratio = np.where(alive, np.sqrt(np.maximum(np.diagonal(gs, axis1=1, axis2=2), 0.0)), 0.0)
        sv = np.sqrt(np.maximum(w, 0.0))
        keep = sv > ALIAS_TOL
        aliased = ~keep.any(axis=1) | (ratio.max(axis=1) < ALIAS_TOL)
        kk = keep.sum(axis=1)
        sk = np.where(keep, sv, 1.0)
        proj = np.where(keep, np.einsum("mij,mi->mj", V, bvec / scale) / sk, 0.0)  # U_kᵀ r, without forming U
        delta = np.einsum("mj,mj->m", proj, proj)
        # size of the effect: least-squares coefficients of the projected block, restricted to the
        # directions the data see (a column that degenerates on this plan adds nothing, not 1e15)
        beta = -np.einsum("mij,mj->mi", V, proj / sk) / scale  # r is model − measurement
        cov = np.einsum("mij,mj,mlj->mil", V, np.where(keep, 1.0 / sk**2, 0.0), V) / (scale[:, :, None] * scale[:, None, :])
        rms_after = (np.sqrt(np.maximum(rss - delta, 0.0) / M) * sigma).tolist()
        coef_std = np.sqrt(np.maximum(np.diagonal(cov, axis1=1, axis2=2), 0.0)).tolist()
        deltas, kept, coefficients = delta.tolist(), kk.tolist(), beta.tolist()
        if not self.sigma_known:  # the F tests of all (not aliased) at once
            tested = ~aliased
            dof2 = M - result.rank - kk[tested]
            F = np.zeros(len(kk))
            F[tested] = (delta[tested] / kk[tested]) / np.maximum((rss - delta[tested]) / dof2, 1e-300)
            f_log_sf = np.zeros(len(kk))
            f_log_sf[tested] = f_logsf_each(F[tested], kk[tested], dof2)
            f_log_sf, F = f_log_sf.tolist(), F.tolist()
        out = []
        for m, (e, unit) in enumerate(zip(effects, units)):
            if aliased[m]:
                out.append(Candidate(e.name, "aliased", k, 0.0, 1.0, 0.0, result.rms_um, np.nan, np.nan, unit,
                                     self._aliases(products[m](), k)))
                continue
            d, kd = deltas[m], kept[m]
            if self.sigma_known:
                log_sf = _chi2_logsf(d, kd)
            else:
                log_sf = f_log_sf[m]
                if not math.isfinite(log_sf):  # far in the tail, where F·k is χ²_k for large dof2
                    log_sf = _chi2_logsf(F[m] * kd, kd)
            basis = basis_of(e)
            size, size_std = basis.size(e, beta[m], cov[m])
            note = "" if basis.note is None or not self.notes else basis.note(e, beta[m], _axis_unit(machine, e.axis))
            out.append(Candidate(e.name, "live", k, d, float(np.exp(log_sf)), float(log_sf / _LN10), rms_after[m],
                                 size, size_std, unit, note=note, coefficients=tuple(coefficients[m]),
                                 coefficient_std=tuple(coef_std[m])))
        return out

    def _aliases(self, BJ, k) -> tuple:
        """The model parameters (at most three) an aliased candidate, of products BJ with the model's columns,
        cannot be told from."""
        G0, J0 = self.G0, self.J0
        coef = np.linalg.lstsq(G0, BJ, rcond=None)[0] if J0.shape[1] else np.zeros((0, k))
        weight = np.abs(coef).max(axis=1) * np.sqrt(np.diag(G0)) if coef.size else np.zeros(0)
        order = np.argsort(-weight)
        return tuple(self.model_names[i] for i in order[:3] if weight[i] > 1e-3 * max(weight.max(), 1e-300))


def _axis_unit(machine, axis: str) -> str:
    return "mm" if machine.axis(axis).kind == "prismatic" else "deg"


def _f_log10_p(c: Candidate, rss: float, dof: int) -> float:
    """log10 p of candidate ``c`` by the F test, σ estimated from the residuals (whitened rss, dof)."""
    dof2 = max(dof - c.k, 1)
    F = (c.statistic / c.k) / max((rss - c.statistic) / dof2, 1e-300)
    log_sf = f_logsf(F, c.k, dof2)
    if not np.isfinite(log_sf):
        log_sf = _chi2_logsf(F * c.k, c.k)
    return log_sf / math.log(10)


#: log P(χ²_k > x), finite far into the tail (kept under this name for callers of the score test).
_chi2_logsf = chi2_logsf
