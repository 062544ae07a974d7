"""Compare a model with measurements and find which effect is missing.

Score (Lagrange-multiplier) test of every candidate effect at the current fit:
with whitened residuals r (orthogonal to the model's Jacobian J₀ at the
optimum) and a candidate's whitened Jacobian block C, the block's part not
explained by the model is C⊥ = (I − Q₀Q₀ᵀ) C and adding the candidate lowers
the sum of squares, to first order, by Δ = rᵀ C⊥ (C⊥ᵀ C⊥)⁺ C⊥ᵀ r. With σ
known, Δ ~ χ²_k under "no such effect"; with σ estimated, an F test. All
candidates' blocks come from one Pinocchio pass: a candidate's column is its
error joint's column times the basis value.

The verdict is ``missing-effect`` when the best candidate passes a Bonferroni
threshold α / (number of live candidates), or when the residual is not
consistent with the noise (χ² test at α); otherwise ``noise``.
:func:`forward_select` adds the best candidate, refits the full nonlinear
model and rescores the rest until the verdict is ``noise``.

References
----------
C. R. Rao, "Large sample tests of statistical hypotheses concerning several
parameters ...", Proc. Cambridge Phil. Soc. 44, 1948 (score test).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg

from kinid.checks import check_positive
from kinid.threads import blas_single_threaded

from .effects import candidate_library, check_effects
from .fit import FitResult, fit
from .noise import Noise, resolve_noise

from .machine import Machine, check_machine, evaluate
from .observations import Observations, check_observations, exact_duplicates
from .residuals import design, effect_columns, joint_values

__all__ = ["Candidate", "Diagnosis", "diagnose", "score_candidates", "forward_select", "SelectionStep", "noise_from_replicates", "ALPHA"]

#: Family-wise significance level of the verdict.
ALPHA = 0.01
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


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose`.

    Attributes
    ----------
    fit : FitResult
        The current model refitted on these data.
    verdict : {"missing-effect", "noise"}
    rms_um : float
        Residual RMS per coordinate, µm.
    noise : Noise
        σ and its source (``noise_um``, ``noise_source``).
    chi2_p : float
        P-value of the residual sum of squares against σ (NaN if σ was estimated from the residuals).
    threshold : float
        Bonferroni threshold on a candidate's p-value.
    candidates : tuple of Candidate
        Live candidates best first, then aliased and invisible ones.
    studentized : array (N,)
        Externally studentized residual norm of each alignment (χ-like, 3 dof).
    leverage : array (N,)
        Leverage of each alignment (sum over its 3 coordinates of the hat matrix diagonal).
    outliers : tuple of int
        Rows whose studentized residual is beyond the Bonferroni χ²₃ quantile.
    axis_residuals_um : array (N, 3)
        The same residuals as readings of the prismatic axes: measured minus
        the readings at which the model puts the tool point on the mark, µm.
    axis_names : tuple of str
        The axes of ``axis_residuals_um``.
    note : str
        When the verdict needs a word more: a σ given too small for these data.
    """

    fit: FitResult
    verdict: str
    rms_um: float
    noise: Noise
    chi2_p: float
    threshold: float
    candidates: tuple
    studentized: np.ndarray
    leverage: np.ndarray
    outliers: tuple
    axis_residuals_um: np.ndarray = None
    axis_names: tuple = ()
    note: str = ""

    @property
    def noise_um(self) -> float:
        """σ of one residual coordinate, µm."""
        return self.noise.value_um

    @property
    def noise_source(self) -> str:
        """Where σ came from: given, replicates, fit or residuals."""
        return self.noise.source

    @property
    def live(self) -> list:
        return [c for c in self.candidates if c.status == "live"]

    marks: tuple = ()

    def by_mark(self):
        """(mark, alignments, RMS in the workpiece frame, RMS per solved axis) for each mark, µm."""
        out = []
        marks = np.asarray(self.marks)
        for mark in dict.fromkeys(self.marks):
            sel = marks == mark
            rw = float(np.sqrt(np.mean(self.fit.residuals_um[sel] ** 2)))
            ra = np.sqrt(np.mean(self.axis_residuals_um[sel] ** 2, axis=0))
            out.append((mark, int(sel.sum()), rw, ra))
        return out

    def summary(self) -> dict:
        """The JSON object of ``kinid diagnose --json`` (docs/cli.md)."""
        return {
            "verdict": self.verdict,
            "rms_um": float(self.rms_um),
            "noise_um": float(self.noise_um),
            "note": self.note,
            "candidates": [{"effect": c.effect, "rms_after_um": float(c.rms_after_um), "p_value": float(c.p_value)} for c in self.live],
            "set_aside": [{"line": a.line, "mark": a.mark, "residual_um": float(a.residual_um), "sigmas": float(a.sigmas)}
                          for a in self.fit.set_aside],
        }

    def text(self, top: int = 10) -> str:
        """A readable report."""
        f = self.fit
        lines = [
            f"model: {len(f.effects)} effects, {f.rank} identifiable parameters; {f.residuals_um.shape[0]} alignments",
            f"residual RMS {self.rms_um:.3f} µm per coordinate; noise σ {self.noise_um:.3f} µm ({self.noise_source})"
            + (f"; χ² test of the residual against σ: p = {self.chi2_p:.3g}" if np.isfinite(self.chi2_p) else ""),
        ]
        if self.verdict == "noise" and self.note:
            lines.append(f"verdict: noise — {self.note}")
        elif self.verdict == "noise":
            lines.append("verdict: noise — no candidate effect is significant and the residual is consistent with the noise")
        else:
            best = self.live[0] if self.live else None
            if best is not None and best.p_value < self.threshold:
                lines.append(f"verdict: missing-effect — best candidate {best.effect} (p = {_p(best)} < {self.threshold:.3g})")
                lines.append(f"  add it:  kinid identify ... --add {best.effect}")
            else:
                lines.append("verdict: missing-effect — the residual exceeds the noise, but no candidate in the library explains it")
        lines.append("")
        w = max([len(c.effect) for c in self.live[:top]] + [6])
        lines.append(f"{'rank':>4}  {'effect':<{w}}  {'k':>2}  {'Δχ²':>10}  {'p-value':>9}  {'RMS after':>9}  size ± std")
        for i, c in enumerate(self.live[:top], 1):
            lines.append(
                f"{i:>4}  {c.effect:<{w}}  {c.k:>2}  {c.statistic:10.1f}  {_p(c, 2):>9}  {c.rms_after_um:8.3f} µm  {c.size:.4g} ± {c.size_std:.2g} {c.size_unit}"
            )
            if c.note:
                lines.append(f"{'':>4}  {'':<{w}}  ({c.note})")
        aliased = [c for c in self.candidates if c.status != "live"]
        if aliased:
            lines.append("")
            lines.append(f"{len(aliased)} candidates cannot be tested with these data:")
            for c in aliased[:top]:
                why = f"aliased with {', '.join(c.aliases_with)}" if c.status == "aliased" else "invisible to this measurement plan"
                lines.append(f"  {c.effect}: {why}")
            if len(aliased) > top:
                lines.append(f"  ... and {len(aliased) - top} more")
        marks = list(dict.fromkeys(self.marks))
        if marks and len(marks) <= MARKS_SHOWN:
            lines.append("")
            axes = f"; readings {', '.join(self.axis_names)} measured − model" if len(self.axis_names) == 3 else ""
            lines.append(f"residuals by mark (RMS per coordinate, µm{axes}):")
            for mark, n, rw, ra in self.by_mark():
                tail = ("   axes " + "  ".join(f"{v:7.3f}" for v in ra)) if axes else ""
                lines.append(f"  {mark:<8} {n:4d} alignments   workpiece frame {rw:7.3f}{tail}")
        if self.outliers:
            lines.append("")
            lines.append(f"possible outliers (studentized residual beyond the Bonferroni χ²₃ bound): rows {', '.join(str(i + 1) for i in self.outliers[:20])}")
        missing = joints_the_urdf_lacks(f.machine)
        if missing and self.verdict == "missing-effect":
            lines.append("")
            lines.append("the URDF has no error joint that can vary with the position of these axes, so no candidate "
                         "can describe their position-dependent errors:")
            lines += [f"  - {axis}: add {', '.join(codes)} directly after joint {axis} (docs/machines.md)"
                      for axis, codes in missing]
        if f.set_aside:
            lines.append("")
            lines.append(f"set aside as gross errors before fitting ({len(f.set_aside)}; --no-robust keeps them):")
            lines += [f"  - {a.describe()}" for a in f.set_aside]
        if f.aliases:
            lines.append("")
            lines.append("held fixed (not identifiable from these data):")
            lines += [f"  - {a.message}" for a in f.aliases]
        return "\n".join(lines)


#: The readable report lists the residual by mark for at most this many marks.
MARKS_SHOWN = 20


def _p(c, digits: int = 3) -> str:
    """A p-value for text: its value, or its power of ten where the value underflows."""
    return f"{c.p_value:.{digits}g}" if c.p_value > 0 else f"1e{c.log10_p:.0f}"


def joints_the_urdf_lacks(machine: Machine) -> list:
    """(axis, codes) for each motion axis with no error joint whose value may vary with its position.

    For such an axis the URDF needs position-dependent error joints ``E<d><axis>``
    (or location joints on the axis's own line) before its errors can be found.
    """
    from .effects import axis_dependent_joints

    covered = {axis for _, axis in axis_dependent_joints(machine)}
    out = []
    for a in machine.axes:
        if a.name not in covered:
            out.append((a.name, [f"E{d}{a.name}" for d in "XYZABC"]))
    return out


def noise_from_replicates(machine: Machine, obs: Observations, r_um: np.ndarray):
    """Pooled σ (µm per coordinate) from alignments repeated at the same pose, or None.

    Rows are replicates when they have the same mark, the same readings of the
    preset (non-prismatic) axes and the same approach directions. Rows that
    repeat another row exactly (every reading equal) are one measurement
    copied, not replicates, and are left out.
    """
    preset = [j for j, a in enumerate(machine.axes) if a.kind != "prismatic"]
    copies = {i for i, _ in exact_duplicates(obs)}  # an exact copy is the same measurement, not a replicate
    keys = {}
    for i in range(len(obs)):
        if i in copies:
            continue
        key = (obs.marks[i], *np.round(obs.axes[i, preset], 9), *(obs.directions[a][i] for a in sorted(obs.directions)))
        keys.setdefault(key, []).append(i)
    ss, dof = 0.0, 0
    for rows in keys.values():
        if len(rows) > 1:
            g = r_um[rows]
            ss += float(np.sum((g - g.mean(axis=0)) ** 2))
            dof += 3 * (len(rows) - 1)
    return (np.sqrt(ss / dof), dof) if dof else None


def _model_pass(machine: Machine, obs: Observations, result: FitResult):
    """One Pinocchio pass at the fit: error-joint and axis Jacobians, and an orthonormal basis
    ``Q0`` (3N, rank) of the identifiable model columns — shared by the score test, the
    leverages and the axis residuals."""
    d0 = design(machine, result.effects, obs)
    _, d_errors, d_axes = evaluate(machine, obs.axes, joint_values(machine, d0, result.theta), offsets_mm=obs.offsets_mm)
    J0 = effect_columns(d_errors, d0).reshape(3 * len(obs), -1)[:, result.identifiable]
    Q0 = scipy.linalg.qr(J0, mode="economic")[0] if J0.shape[1] else np.zeros((J0.shape[0], 0))
    return d_errors, d_axes, Q0


#: A warm-started refit taking more iterations than this is redone from a cold start.
WARM_START_ITERATIONS = 15


def _set_aside(machine, obs, effects, noise_um, progress, before: tuple):
    """``obs`` without its gross errors and the tuple of all set aside so far (rows of the original data)."""
    from .outliers import set_aside_outliers

    kept, new = set_aside_outliers(machine, obs, effects, noise_um=noise_um)
    if not new:
        return obs, before
    if before:  # rows of ``obs`` -> rows of the data as read: keep the first record's numbering
        rows = [i for i in range(len(obs) + len(before)) if i not in {a.row for a in before}]
        new = tuple(replace(a, row=rows[a.row]) for a in new)
    if progress is not None:
        for a in new:
            print(f"  set aside as a gross error: {a.describe()}", file=progress, flush=True)
    return kept, before + new


#: Memory for one block of candidate columns in the score test, bytes (diagnosis memory stays flat in N).
SCORE_BLOCK_BYTES = 64 * 1024 * 1024


@blas_single_threaded
def score_candidates(machine: Machine, obs: Observations, result: FitResult, candidates, sigma: float, *, sigma_known: bool,
                     d_errors=None, q0=None):
    """Score test of each candidate effect at the fit ``result`` (see module docstring).

    Parameters
    ----------
    d_errors : array (N, 3, n_errors), optional
        Error-joint Jacobian at the fit (computed if not given).
    q0 : array (3N, rank), optional
        Orthonormal basis of the identifiable model columns (computed if not given).

    Returns
    -------
    list of Candidate, unsorted.
    """
    import scipy.stats  # here, not at module level: it costs half a second to import

    if d_errors is None or q0 is None:
        d_errors, _, q0 = _model_pass(machine, obs, result)
    d0 = design(machine, result.effects, obs)
    M = result.residuals_um.size
    r = result.residuals_um.ravel() / sigma
    J0 = effect_columns(d_errors, d0).reshape(M, -1)[:, result.identifiable] / sigma
    Q0 = q0
    r = r - Q0 @ (Q0.T @ r)  # exactly orthogonal to the model (it is, to first order, at the optimum)
    rss = float(r @ r)
    p0 = result.rank
    model_names = [n for n, ok in zip(result.param_names, result.identifiable) if ok]
    lever = np.sqrt(np.einsum("nkj,nkj->j", d_errors, d_errors) / d_errors.shape[0])  # per error joint: m/rad or 1
    visible_floor = 1e-12 * max(1.0, float(np.abs(J0).max()) if J0.size else 1.0)
    codes = machine.error_codes
    out = []
    # Candidates in blocks of columns, each block streamed over chunks of alignments, so that memory
    # stays flat in the number of alignments: only sums over alignments are kept (norms, the model
    # projection Q0ᵀC, the Gram matrix of each candidate's projected columns and their product with r).
    blocks, current, width = [], [], 0
    budget = max(int(SCORE_BLOCK_BYTES // (8 * 64 * 3 * 2)), 8)  # columns per block (chunks of >= 64 rows)
    for e in candidates:
        if current and width + e.n_params > budget:
            blocks.append(current)
            current, width = [], 0
        current.append(e)
        width += e.n_params
    if current:
        blocks.append(current)
    n = len(obs)
    G0 = J0.T @ J0
    for block in blocks:
        P = sum(e.n_params for e in block)
        rows = max(64, int(SCORE_BLOCK_BYTES // (8 * 3 * P * 2)))  # alignments per chunk
        chunks = [np.arange(a, min(a + rows, n)) for a in range(0, n, rows)]

        def columns(idx, block=block, P=P):
            d = design(machine, block, obs.subset(idx))
            C = d_errors[idx][:, :, d.joint_index]
            C *= d.basis[:, None, :]
            C /= sigma
            return C.reshape(3 * len(idx), P)

        norm2 = np.zeros(P)
        A = np.zeros((Q0.shape[1], P))
        BJ = np.zeros((J0.shape[1], P))
        for idx in chunks:
            C = columns(idx)
            m_rows = slice(3 * idx[0], 3 * idx[-1] + 3)  # the chunk's residual coordinates, contiguous
            norm2 += np.einsum("ij,ij->j", C, C)
            A += Q0[m_rows].T @ C
            BJ += J0[m_rows].T @ C
        spans = []
        start = 0
        for e in block:
            spans.append((start, start + e.n_params))
            start += e.n_params
        grams = [np.zeros((b - a, b - a)) for a, b in spans]
        bvec = np.zeros(P)
        for idx in chunks:
            m_rows = slice(3 * idx[0], 3 * idx[-1] + 3)
            Cp = columns(idx)
            Cp -= Q0[m_rows] @ A
            bvec += Cp.T @ r[m_rows]
            for g, (a, b) in zip(grams, spans):
                g += Cp[:, a:b].T @ Cp[:, a:b]
        for e, (a, b), gram in zip(block, spans, grams):
            k = e.n_params
            unit = e.param_units(machine)[0]
            norm_c = np.sqrt(norm2[a:b])
            if lever[codes.index(e.code)] < INVISIBLE_LEVER_M or not np.any(norm_c > visible_floor):
                out.append(Candidate(e.name, "invisible", k, 0.0, 1.0, 0.0, result.rms_um, np.nan, np.nan, unit))
                continue
            # a column that vanishes on this plan (a sine sampled at its zeros) carries nothing: drop it
            # rather than blow its rounding noise up to unit length
            alive = norm_c > max(visible_floor, 1e-9 * float(norm_c.max()))
            scale = np.where(alive, norm_c, 1.0)
            gs = np.where(np.outer(alive, alive), gram / np.outer(scale, scale), 0.0)
            ratio = np.where(alive, np.sqrt(np.maximum(np.diag(gs), 0.0)), 0.0)
            w, V = np.linalg.eigh(gs)
            sv = np.sqrt(np.maximum(w, 0.0))
            keep = sv > ALIAS_TOL
            if not keep.any() or ratio.max() < ALIAS_TOL:
                coef = np.linalg.lstsq(G0, BJ[:, a:b], rcond=None)[0] if J0.shape[1] else np.zeros((0, k))
                weight = np.abs(coef).max(axis=1) * np.sqrt(np.diag(G0)) if coef.size else np.zeros(0)
                order = np.argsort(-weight)
                names = tuple(model_names[i] for i in order[:3] if weight[i] > 1e-3 * max(weight.max(), 1e-300))
                out.append(Candidate(e.name, "aliased", k, 0.0, 1.0, 0.0, result.rms_um, np.nan, np.nan, unit, names))
                continue
            kk = int(keep.sum())
            Vk, sk = V[:, keep], sv[keep]
            proj = (Vk.T @ (bvec[a:b] / scale)) / sk  # U_kᵀ r, without forming U
            delta = float(proj @ proj)
            if sigma_known:
                log_sf = _chi2_logsf(delta, kk)
            else:
                dof2 = M - p0 - kk
                F = (delta / kk) / max((rss - delta) / dof2, 1e-300)
                log_sf = scipy.stats.f.logsf(F, kk, dof2)
                if not np.isfinite(log_sf):  # far in the tail, where F·k is χ²_k for large dof2
                    log_sf = _chi2_logsf(F * kk, kk)
            # size of the effect: least-squares coefficients of the projected block, restricted to the
            # directions the data see (a column that degenerates on this plan adds nothing, not 1e15)
            beta = -(Vk @ (proj / sk)) / scale  # r is model − measurement
            cov = (Vk / sk**2) @ Vk.T / np.outer(scale, scale)
            size, size_std = _size(e, beta, cov, obs, machine)
            rms_after = float(np.sqrt(max(rss - delta, 0.0) / M)) * sigma
            note = _map_description(e, beta, machine) if e.basis in ("map", "local") else ""
            out.append(Candidate(e.name, "live", k, delta, float(np.exp(log_sf)), float(log_sf / np.log(10)),
                                 rms_after, size, size_std, unit, note=note))
    return out


#: Joints whose best searched period is scored as a candidate (the strongest first).
FOUND_PERIODS = 4
#: χ² gain a free period needs over the joint's best listed period (χ²₁ at p = 0.001).
PERIOD_GAIN_MIN = 10.83


def _found_periods(machine, obs, result, scored, sigma, known, d_errors, q0) -> list:
    """Candidates at periods the library does not list, found by :func:`~kinid.identification.periods.search_periods`.

    Each is scored like a library candidate, then its p-value is multiplied by
    the number of independent periods searched for its joint.
    """
    from dataclasses import replace

    from kinid.errors import DataError

    from .effects import LINEAR_PERIODS_MM, ROTARY_PERIODS_DEG, parse_effect
    from .periods import search_periods

    r = result.residuals_um.ravel() / sigma
    r = r - q0 @ (q0.T @ r)
    have = {c.effect for c in scored}
    # the best χ² drop of a listed period, per joint: a free period must beat it by more than one
    # extra parameter gains by chance (χ²₁ at 0.001), else the listed period is the simpler account
    listed_best = {}
    for c in scored:
        if c.status == "live" and ":periodic:" in c.effect:
            code = c.effect.split(":")[0]
            listed_best[code] = max(listed_best.get(code, 0.0), c.statistic)
    out = []
    estimates = search_periods(machine, obs, r, d_errors, q0, sigma)
    joints = max(len(estimates), 1)  # the best of every joint's search is taken: the trials multiply
    for est in estimates[:FOUND_PERIODS]:
        listed = ROTARY_PERIODS_DEG if est.unit == "deg" else LINEAR_PERIODS_MM
        if est.effect in have or any(abs(est.period - p) <= max(2 * est.period_std, 1e-9 * p) for p in listed):
            continue  # the library's own candidate covers it
        if est.statistic - listed_best.get(est.code, 0.0) < PERIOD_GAIN_MIN:
            continue
        try:
            effect = parse_effect(est.effect, machine)
        except DataError:
            continue
        c = score_candidates(machine, obs, result, [effect], sigma, sigma_known=known, d_errors=d_errors, q0=q0)[0]
        if c.status != "live":
            continue
        trials = est.trials * joints
        log10_p = min(0.0, c.log10_p + math.log10(trials))
        note = (f"period found by search: {est.period:.4g} ± {est.period_std:.2g} {est.unit} "
                f"(p-value × {trials:.0f}: {est.trials:.0f} periods of {joints} joints searched)")
        out.append(replace(c, p_value=min(1.0, 10.0**log10_p), log10_p=log10_p, note=note, trials=trials))
        have.add(est.effect)
    return out


def _map_description(effect, beta, machine) -> str:
    """In words: where a map candidate's error is, and how large at its peak."""
    i = int(np.argmax(np.abs(beta)))
    unit = "mm" if machine.axis(effect.axis).kind == "prismatic" else "deg"
    width = effect.knots[1] - effect.knots[0]
    knots = effect.knots[2:-2] if effect.basis == "local" else effect.knots
    big = np.flatnonzero(np.abs(beta) > 0.5 * abs(beta[i]))
    extent = (big.max() - big.min() + 1) * width
    return (f"a local error of {effect.axis} near {effect.axis.lower()} = {knots[i]:+g} {unit}, "
            f"{abs(beta[i]):.2g} {'µm' if effect.unit == 'um' else 'µrad'} peak over about {extent:g} {unit}, "
            f"not described by any parametric effect")


#: A proposed map must gain over the best parametric candidate more χ² than its extra parameters would
#: at this level.
MAP_GAIN_ALPHA = 1e-3
#: Readings (weighted by the knot's hat function) every knot of a proposed map must rest on.
MAP_MIN_SUPPORT = 3.0
#: Knot intervals over the measured range of an axis in a proposed map.
MAP_INTERVALS = 40


def _nice_step(span: float) -> float:
    """A round step (1, 2 or 5 × 10^k) close to span / MAP_INTERVALS."""
    raw = span / MAP_INTERVALS
    k = math.floor(math.log10(raw))
    for m in (1, 2, 5, 10):
        if m * 10**k >= raw:
            return m * 10**k
    return 10 ** (k + 1)  # pragma: no cover


def _proposed_maps(machine, obs, result, scored, sigma, known, d_errors, q0) -> list:
    """The best non-parametric map (``CODE:map:<step>:<from>:<to>`` over the measured range) as a candidate.

    It competes with the parametric candidates on its p-value, so a map wins
    only where no parametric effect describes the structure (a local bump).
    """
    from kinid.errors import DataError

    from .effects import axis_dependent_joints, parse_effect

    maps = []
    for code, axis in axis_dependent_joints(machine):
        q = obs.axes[:, machine.axis_names.index(axis)]
        lo, hi = float(np.min(q)), float(np.max(q))
        if not hi > lo or np.unique(np.round(q, 9)).size < 2 * MAP_INTERVALS:
            continue
        step = _nice_step(hi - lo)
        lo, hi = math.floor(lo / step) * step, math.ceil(hi / step) * step
        knots = np.arange(lo, hi + step / 2, step)
        support = np.clip(1.0 - np.abs(q[:, None] - knots[None, :]) / step, 0.0, None).sum(axis=0)
        if support.min() < MAP_MIN_SUPPORT:
            continue  # readings clustered (a few preset positions): a knot between them would be a guess
        try:
            maps.append(parse_effect(f"{code}:map:{step:g}:{lo:g}:{hi:g}", machine))
        except DataError:
            continue
    have = {c.effect for c in scored}
    fresh = [m for m in maps if m.name not in have]
    live = [c for c in score_candidates(machine, obs, result, fresh, sigma, sigma_known=known, d_errors=d_errors,
                                        q0=q0) if c.status == "live"]
    if not live:
        return []
    best = min(live, key=lambda c: c.log10_p)
    # a local error: windows of the best map's knots, zero at their ends, scored the same way; fewer
    # parameters than the whole map, so a bump is described without a map's noise along the whole travel
    whole = next(m for m in fresh if m.name == best.effect)
    windows = _local_windows(whole, machine)
    local = [c for c in score_candidates(machine, obs, result, windows, sigma, sigma_known=known,
                                         d_errors=d_errors, q0=q0) if c.status == "live"] if windows else []
    if local:
        best_local = min(local, key=lambda c: c.log10_p)
        log10_local = best_local.log10_p + math.log10(len(windows) * len(fresh))
        if log10_local < best.log10_p + math.log10(len(fresh)):
            from dataclasses import replace as _replace

            return [_replace(best_local, p_value=min(1.0, 10.0**min(0.0, log10_local)), log10_p=min(0.0, log10_local),
                             trials=float(len(windows) * len(fresh)))] if _beats_parametric(best_local, scored) else []
    if not _beats_parametric(best, scored):
        return []
    log10_p = min(0.0, best.log10_p + math.log10(len(fresh)))  # the best of len(fresh) maps
    from dataclasses import replace

    return [replace(best, p_value=min(1.0, 10.0**log10_p), log10_p=log10_p, trials=float(len(fresh)))]


def _beats_parametric(candidate, scored) -> bool:
    """A map must beat the best parametric candidate by more than its extra parameters gain by chance."""
    import scipy.stats

    parametric = [c for c in scored if c.status == "live"]
    top = max(parametric, key=lambda c: c.statistic, default=None)
    return not (top is not None and candidate.k > top.k and
                candidate.statistic - top.statistic < scipy.stats.chi2.isf(MAP_GAIN_ALPHA, candidate.k - top.k))


#: Knot intervals of the local windows tried inside a proposed map (each zero at its ends).
LOCAL_WIDTHS = (5, 6, 7, 8, 10)


def _local_windows(whole, machine) -> list:
    """``CODE:local:<step>:<from>:<to>`` windows of ``LOCAL_WIDTHS`` knot intervals inside the map ``whole``."""
    from kinid.errors import DataError

    from .effects import parse_effect

    out = []
    coarse = whole.knots[1] - whole.knots[0]
    for step in (coarse,):
        knots = np.arange(whole.knots[0], whole.knots[-1] + step / 2, step)
        for width in LOCAL_WIDTHS:
            for i in range(0, len(knots) - width):
                try:
                    out.append(parse_effect(f"{whole.code}:local:{step:g}:{knots[i]:g}:{knots[i + width]:g}", machine))
                except DataError:
                    continue
    return out


def _f_log10_p(c: Candidate, rss: float, dof: int) -> float:
    """log10 p of candidate ``c`` by the F test, σ estimated from the residuals (whitened rss, dof)."""
    import scipy.stats

    dof2 = max(dof - c.k, 1)
    F = (c.statistic / c.k) / max((rss - c.statistic) / dof2, 1e-300)
    log_sf = float(scipy.stats.f.logsf(F, c.k, dof2))
    if not np.isfinite(log_sf):
        log_sf = _chi2_logsf(F * c.k, c.k)
    return log_sf / math.log(10)


def _chi2_logsf(x: float, k: int) -> float:
    """log P(χ²_k > x), finite far into the tail where scipy's value underflows to -inf.

    Beyond it, the upper incomplete gamma function's asymptotic series:
    log Q(a, z) = (a − 1) log z − z − log Γ(a) + log(1 + (a − 1)/z + (a − 1)(a − 2)/z² ...), a = k/2, z = x/2.
    """
    import math

    import scipy.stats

    value = float(scipy.stats.chi2.logsf(x, k))
    if np.isfinite(value):
        return value
    a, z = k / 2.0, x / 2.0
    series = 1.0 + (a - 1) / z + (a - 1) * (a - 2) / z**2
    return (a - 1) * math.log(z) - z - math.lgamma(a) + math.log(max(series, 1e-300))


def _size(effect, beta, cov, obs, machine):
    if effect.basis in ("map", "local"):  # the peak value of the map (the part the model does not already hold)
        i = int(np.argmax(np.abs(beta)))
        return float(beta[i]), float(np.sqrt(max(cov[i, i], 0.0)))
    if effect.basis == "periodic":
        amp = float(np.hypot(*beta))
        g = beta / amp if amp > 0 else np.array([1.0, 0.0])
        return amp, float(np.sqrt(max(g @ cov @ g, 0.0)))
    if effect.basis == "poly":
        j = effect.degree - 1
        return float(beta[j]), float(np.sqrt(max(cov[j, j], 0.0)))
    return float(beta[0]), float(np.sqrt(max(cov[0, 0], 0.0)))


@blas_single_threaded
def diagnose(machine: Machine, obs: Observations, effects, *, noise_um=None, carried_noise: Noise | None = None,
             alpha: float = ALPHA, theta0=None, result: FitResult | None = None) -> Diagnosis:
    """Refit ``effects`` on ``obs`` and rank the candidate library.

    Parameters
    ----------
    machine, obs, effects
    noise_um : float, optional
        σ per coordinate given by the user, µm. Default: from replicate
        alignments in the data, else ``carried_noise``, else estimated from
        the residuals (:func:`~kinid.identification.noise.resolve_noise`).
    carried_noise : Noise, optional
        The σ an earlier fit carried (a saved fit's, or the previous step of a
        selection); used when it was not itself estimated from residuals.
    alpha : float
        Family-wise significance level.
    result : FitResult, optional
        An existing fit of ``effects`` on ``obs`` (skips the refit).
    """
    import scipy.stats  # here, not at module level: it costs half a second to import

    check_machine(machine)
    check_observations(obs)
    effects = check_effects(machine, effects)
    if noise_um is not None:
        noise_um = check_positive("noise_um", noise_um)
    if result is None:
        result = fit(machine, obs, effects, theta0=theta0)
    r = result.residuals_um
    rep = None if noise_um is not None else noise_from_replicates(machine, obs, r)
    noise = resolve_noise(given_um=noise_um, replicates_um=None if rep is None else rep[0], carried=carried_noise,
                          residual_um=float(np.sqrt(np.sum(r**2) / max(result.dof, 1))))
    result = result.with_noise(noise)
    sigma, known = noise.value_um, noise.known
    library = candidate_library(machine, result.effects, has_directions=bool(obs.directions), has_time=obs.t_s is not None)
    d_errors, d_axes, q0 = _model_pass(machine, obs, result)
    scored = score_candidates(machine, obs, result, library, sigma, sigma_known=known, d_errors=d_errors, q0=q0)
    scored += _found_periods(machine, obs, result, scored, sigma, known, d_errors, q0)
    scored += _proposed_maps(machine, obs, result, scored, sigma, known, d_errors, q0)
    location = {j.code for j in machine.error_joints if j.location}
    # best first; exact ties (identical columns) go to the location error, the more physical reading
    live = sorted([c for c in scored if c.status == "live"], key=lambda c: (round(c.log10_p, 6), c.effect.split(":")[0] not in location, c.rms_after_um))
    rest = [c for c in scored if c.status != "live"]
    threshold = alpha / max(len(live), 1)
    chi2_p = float(scipy.stats.chi2.sf(np.sum(r**2) / sigma**2, result.dof)) if known else float("nan")
    significant = bool(live) and live[0].p_value < threshold
    verdict = "missing-effect" if significant or (known and chi2_p < alpha) else "noise"
    note = ""
    if known and chi2_p < alpha:
        # The residual exceeds the given σ. Structure, or a σ given too small? The F test of the best
        # candidates does not depend on σ at all: if none passes it, the excess is white noise.
        dof = max(result.dof, 1)
        rss = float(np.sum(r**2)) / sigma**2
        passes = [c for c in live[:5] if _f_log10_p(c, rss, dof) + math.log10(c.trials) < math.log10(threshold)]
        if not passes:
            verdict = "noise"
            note = (f"the residual looks like noise of about {np.sqrt(rss / dof) * sigma:.2g} µm, not "
                    f"{sigma:.2g} µm as given: no candidate explains more than white noise would")
    stud, lev = _studentized(result, q0, sigma)
    bound = scipy.stats.chi2.isf(alpha / len(obs), 3)
    outliers = tuple(int(i) for i in np.flatnonzero(stud**2 > bound))
    rms = float(np.sqrt(np.mean(r**2)))
    axis_r, axis_names = axis_residuals(machine, obs, result, d_axes=d_axes)
    return Diagnosis(fit=result, verdict=verdict, note=note, rms_um=rms, noise=noise, chi2_p=chi2_p, threshold=threshold,
                     candidates=tuple(live + rest), studentized=stud, leverage=lev, outliers=outliers,
                     axis_residuals_um=axis_r, axis_names=axis_names, marks=tuple(obs.marks))


def axis_residuals(machine: Machine, obs: Observations, result: FitResult, *, d_axes=None):
    """Residuals as readings of the prismatic axes (measured − model), µm; and the axes' names.

    To first order, the readings at which the model puts the tool point on the
    mark differ from the measured ones by A⁻¹ r, with A the Jacobian of the
    tool point with respect to those axes (``d_axes``: from :func:`evaluate`
    at the fit, computed if not given).
    """
    cols = [j for j, a in enumerate(machine.axes) if a.kind == "prismatic"]
    names = tuple(machine.axes[j].name for j in cols)
    if len(cols) != 3:
        return np.full((len(obs), 3), np.nan), names
    if d_axes is None:
        _, d_axes, _ = _model_pass(machine, obs, result)
    A = d_axes[:, :, cols]  # µm per mm
    return np.linalg.solve(A, result.residuals_um[:, :, None])[:, :, 0] * 1e3, names


def _studentized(result, q0, sigma):
    """Per-alignment studentized residual norm and leverage (hat matrix Q0 Q0ᵀ of the identifiable Jacobian)."""
    r = result.residuals_um
    N = r.shape[0]
    h = np.sum(q0**2, axis=1).reshape(N, 3)
    stud = np.sqrt(np.sum(r**2 / np.maximum(1 - h, 1e-12), axis=1)) / sigma
    return stud, h.sum(axis=1)


@dataclass(frozen=True)
class SelectionStep:
    """One step of forward selection: the model, its fit and its diagnosis, and what was added to reach it.

    ``stopped`` is empty but on the last step, where it says in words why the
    selection ended there. ``data`` are the alignments the step used (gross
    errors set aside).
    """

    added: str | None
    fit: FitResult
    diagnosis: Diagnosis
    stopped: str = ""
    data: Observations | None = None


@blas_single_threaded
def forward_select(machine: Machine, obs: Observations, effects, *, noise_um=None, alpha: float = ALPHA,
                   max_steps: int = 8, progress=None, robust: bool = True, folds: int = 4) -> list:
    """Add the best candidate, refit the full nonlinear model, rescore; until the verdict is ``noise``.

    Parameters
    ----------
    progress : file-like, optional
        Where to print one line per step (the RMS falling against σ).
    robust : bool
        Set gross errors aside (:func:`~kinid.identification.outliers.set_aside_outliers`)
        with the starting model and again with the final one.
    folds : int
        An effect is added only if it also lowers the held-out RMS of this many
        blocks of the data (:func:`~kinid.identification.crossval.cross_validate`); 0 skips the check.

    Returns
    -------
    list of SelectionStep
        The first step is the starting model.
    """
    check_machine(machine)
    check_observations(obs)
    effects = list(check_effects(machine, effects))
    if noise_um is not None:
        noise_um = check_positive("noise_um", noise_um)
    aside = ()
    if robust:
        obs, aside = _set_aside(machine, obs, effects, noise_um, progress, aside)
    added = None
    steps = []
    theta0 = None
    carried = None
    for _ in range(max_steps + 1):
        dg = diagnose(machine, obs, effects, noise_um=noise_um, carried_noise=carried, alpha=alpha, theta0=theta0)
        if theta0 is not None and (not dg.fit.success or dg.fit.iterations > WARM_START_ITERATIONS):
            # the warm start stalled: a cold start reaches the optimum the model has
            cold = diagnose(machine, obs, effects, noise_um=noise_um, carried_noise=carried, alpha=alpha)
            if cold.rms_um <= dg.rms_um:
                dg = cold
        dg = replace(dg, fit=replace(dg.fit, set_aside=aside))
        steps.append(SelectionStep(added, dg.fit, dg, data=obs))
        if progress is not None:
            what = "start" if added is None else f"+ {added}"
            print(f"  {what:<28} RMS {dg.rms_um:8.3f} µm   σ {dg.noise_um:.3f} µm   {dg.verdict}", file=progress, flush=True)
        best = dg.live[0] if dg.live else None
        stop = ""
        if dg.verdict == "noise":
            stop = dg.note or f"the residual is explained by noise of σ = {dg.noise}"
        elif best is None:
            stop = ("the data ask for more than the model holds, but no candidate of the library can be separated "
                    "from the model: see the aliased candidates")
        elif best.p_value >= dg.threshold:
            stop = (f"no candidate is significant: the best, {best.effect}, has p = {best.p_value:.2g} above the "
                    f"threshold {dg.threshold:.2g}")
        elif len(steps) > max_steps:
            stop = f"stopped after {max_steps} added effects (max_steps); the best next candidate is {best.effect}"
        elif folds:
            from .crossval import cross_validate
            from .effects import parse_effect as _parse

            cv = cross_validate(machine, obs, effects, _parse(best.effect, machine), folds=folds, noise_um=noise_um,
                                theta0=dg.fit.theta)
            if progress is not None:
                print(f"  {'':<28} next: {best.effect}, p = {best.p_value:.2g}, {cv}", file=progress, flush=True)
            if not cv.improves:
                stop = (f"the best candidate, {best.effect} (p = {best.p_value:.2g}), does not predict held-out "
                        f"data better: {cv}")
        if stop:
            if robust:  # a misread may stand out only once the model is complete
                kept, more = _set_aside(machine, obs, effects, noise_um, progress, aside)
                if more != aside:
                    obs, aside = kept, more
                    dg = diagnose(machine, obs, effects, noise_um=noise_um, carried_noise=carried, alpha=alpha,
                                  theta0=dg.fit.theta)
                    dg = replace(dg, fit=replace(dg.fit, set_aside=aside))
            steps[-1] = SelectionStep(added, dg.fit, dg, stopped=stop, data=obs)
            if progress is not None:
                print(f"  stopped: {stop}", file=progress, flush=True)
            break
        from .effects import parse_effect

        effects.append(parse_effect(best.effect, machine))
        theta0 = np.r_[dg.fit.theta, np.zeros(effects[-1].n_params)]
        added = best.effect
        carried = dg.noise if dg.noise.known else None
    return steps
