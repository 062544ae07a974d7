"""Compare a model with measurements and find which effect is missing.

Every candidate effect is scored at the refitted model
(:mod:`~kinid.identification.diagnosis.scoring`: the score test, free periods, maps and
local errors); leverages and studentized residuals come from
:mod:`~kinid.identification.fitting.leverage`.

The verdict is ``missing-effect`` when the best candidate passes a Bonferroni
threshold α / (number of live candidates), or when the residual is not
consistent with the noise (χ² test at α); otherwise ``noise``.
:func:`~kinid.identification.diagnosis.selection.forward_select` adds the best
candidate, refits the full nonlinear model and rescores the rest until the
verdict is ``noise``.

References
----------
C. R. Rao, "Large sample tests of statistical hypotheses concerning several
parameters ...", Proc. Cambridge Phil. Soc. 44, 1948 (score test).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinid.checks import check_positive
from kinid.stats import chi2_isf, chi2_sf
from kinid.threads import blas_single_threaded

from ..model import (Machine, check_effects, check_machine, chosen_of, implausible_candidate, share_of_limit,
                     warning_lines)
from ..data import Observations, check_observations
from ..fitting import (FitResult, Noise, axis_residuals, fit, hat_diagonal, model_pass, noise_from_replicates,
                       resolve_noise, studentized)
from .local_errors import proposed_maps
from .scoring import Candidate, _f_log10_p, fit_side
from .searched import score_all
from .structure import structure_left
from .time_order import TIME_CONFOUND, inseparable_by_time, time_follows, time_or_axis  # noqa: F401 (re-exported)

__all__ = ["Candidate", "Diagnosis", "diagnose", "time_follows", "TIME_CONFOUND", "noise_from_replicates",
           "axis_residuals", "joints_the_urdf_lacks", "ALPHA"]


#: Family-wise significance level of the verdict.
ALPHA = 0.01
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
    hat : array (N, 3)
        The hat matrix's diagonal, per coordinate (what the set-aside of gross errors studentizes with).
    outliers : tuple of int
        Rows whose studentized residual is beyond the Bonferroni χ²₃ quantile.
    axis_residuals_um : array (N, 3)
        The same residuals as readings of the prismatic axes: measured minus
        the readings at which the model puts the tool point on the mark, µm.
    axis_names : tuple of str
        The axes of ``axis_residuals_um``.
    note : str
        When the verdict needs a word more: a σ given too small for these data, or structure left that
        no candidate describes.
    structure : Structure or None
        The nearest-neighbour test of the residuals (:mod:`~kinid.identification.diagnosis.structure`), run when
        no candidate is significant.
    time_follows : tuple of (axis, correlation)
        Axes whose readings the plan's order makes follow time (|correlation| ≥
        :data:`TIME_CONFOUND`): a drift and an error of that axis look alike in these data.
    undetermined : str
        When the best candidate is periodic and the positions measured do not determine its period
        (:mod:`~kinid.identification.diagnosis.ambiguity`): which periods fit as well, and what to measure.
    twins : tuple of float
        Those periods (the best candidate's unit).
    inseparable : str
        When time follows an axis and the best candidate is a drift or warm-up while an error of that axis
        explains the data about as well (or the reverse): the two, and the plan's order as the cause.
    time_matters : bool
        The candidate advised is driven by time or by an axis time follows: the text says that the two look
        alike here (when it is an error of another axis, the order of the plan does not concern it).
    advised : (Candidate or None, tuple of (Candidate, Implausible))
        The best live candidate a machine could have, and the better-ranked ones passed over with the size they
        would need (:func:`advise`); ``undetermined`` and ``inseparable`` are about the one advised.
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
    structure: object = None
    time_follows: tuple = ()
    undetermined: str = ""
    twins: tuple = ()
    inseparable: str = ""
    time_matters: bool = False

    @property
    def noise_um(self) -> float:
        """σ of one residual coordinate, µm."""
        return self.noise.value_um

    @property
    def noise_source(self) -> str:
        """Where σ came from: given, replicates, fit or residuals."""
        return self.noise.source

    def __repr__(self) -> str:
        best = f"; best {self.live[0].effect} (p = {_p(self.live[0])})" if self.live else ""
        return (f"Diagnosis({self.verdict}: RMS {self.rms_um:.4g} µm, σ {self.noise_um:.4g} µm ({self.noise_source})"
                f"{best}; .text() for the report)")

    @property
    def live(self) -> list:
        return [c for c in self.candidates if c.status == "live"]

    marks: tuple = ()
    hat: np.ndarray = None
    advised: tuple = (None, ())

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
        out = {
            "verdict": self.verdict,
            "rms_um": float(self.rms_um),
            "noise_um": float(self.noise_um),
            "note": self.note,
            **({"undetermined": self.undetermined} if self.undetermined else {}),
            **({"inseparable": self.inseparable} if self.inseparable else {}),
            "candidates": [{"effect": c.effect, "rms_after_um": float(c.rms_after_um), "p_value": float(c.p_value)} for c in self.live],
            "set_aside": [{"line": a.line, "mark": a.mark, "residual_um": float(a.residual_um), "sigmas": float(a.sigmas)}
                          for a in self.fit.set_aside],
        }
        if self.time_follows:
            out["time_follows"] = [{"axis": a, "correlation": float(rho)} for a, rho in self.time_follows]
        if self.structure is not None:
            st = self.structure
            out["structure"] = {"ratio": float(st.ratio), "p_value": float(st.p_value), "along": st.along, "axis": st.axis,
                                "axes": list(st.axes)}
        passed = self.advised[1] if self.verdict != "noise" else ()
        if passed:  # only when better candidates than the one advised need sizes no machine has (docs/cli.md)
            out["passed_over"] = [{"effect": c.effect, "size": float(a.size), "limit": a.limit, "unit": a.unit}
                                  for c, a in passed]
        odd = self.fit.implausible()
        if odd:  # only when the fit needs sizes no machine has (docs/cli.md)
            out["implausible"] = [{"effect": a.effect, "size": float(a.size), "limit": a.limit, "unit": a.unit,
                                   "undetermined": a.undetermined} for a in odd]
        return out

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
            best, passed = self.advised
            significant = best is not None and best.p_value < self.threshold
            if significant and self.undetermined:
                lines.append(f"verdict: missing-effect — {self.undetermined}")
            elif significant:
                lines.append(f"verdict: missing-effect — best candidate {best.effect} (p = {_p(best)} < {self.threshold:.3g})")
                lines.append(f"  add it:  kinid identify ... --add {best.effect}")
            elif passed and passed[0][0].p_value < self.threshold:
                lines.append(f"verdict: missing-effect — the best candidate, {passed_over(*passed[0])}: "
                             f"{passed[0][1].remedy}")
            elif self.note:
                lines.append(f"verdict: missing-effect — {self.note}")
            else:
                lines.append("verdict: missing-effect — the residual exceeds the noise, but no candidate in the library explains it")
        lines.append("")
        w = max([len(c.effect) for c in self.live[:top]] + [6])
        flagged = {} if self.verdict == "noise" else {id(c): odd for c, odd in self.advised[1]}
        lines.append(f"{'rank':>4}  {'effect':<{w}}  {'k':>2}  {'Δχ²':>10}  {'p-value':>9}  {'RMS after':>9}  size ± std (1σ)")
        for i, c in enumerate(self.live[:top], 1):
            lines.append(
                f"{i:>4}  {c.effect:<{w}}  {c.k:>2}  {c.statistic:10.1f}  {_p(c, 2):>9}  {c.rms_after_um:8.3f} µm  {c.size:.4g} ± {c.size_std:.2g} {c.size_unit}"
            )
            if c.note:
                lines.append(f"{'':>4}  {'':<{w}}  ({c.note})")
            if id(c) in flagged:
                lines.append(f"{'':>4}  {'':<{w}}  (would need {flagged[id(c)].describe()}: a size no machine has, "
                             f"not advised)")
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
        odd = f.implausible()
        if odd:
            lines.append("")
            lines += warning_lines(odd, prefix="the fit needs ")
        missing = joints_the_urdf_lacks(f.machine)
        if missing and self.verdict == "missing-effect":
            lines.append("")
            lines.append("the URDF has no error joint that can vary with the position of these axes, so no candidate "
                         "can describe their position-dependent errors:")
            lines += [f"  - {axis}: add {', '.join(codes)} directly after joint {axis} (docs/machines.md)"
                      for axis, codes in missing]
        if self.inseparable:
            lines.append("")
            lines.append(f"inseparable: {self.inseparable}")
        if self.time_follows and self.time_matters:
            lines.append("")
            axes = ", ".join(f"{a} (correlation {rho:+.2f})" for a, rho in self.time_follows)
            lines.append(f"time follows {axes} in the order of these alignments: a drift or warm-up and an error "
                         f"of that axis look alike here, and an effect found on one may be the other; to tell them "
                         f"apart, measure the plan in another order (serpentine or random over that axis, or a "
                         f"reference pose repeated through the run)")
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
    from ..model import axis_dependent_joints

    covered = {axis for _, axis in axis_dependent_joints(machine)}
    out = []
    for a in machine.axes:
        if a.name not in covered:
            out.append((a.name, [f"E{d}{a.name}" for d in "XYZABC"]))
    return out


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
        the residuals (:func:`~kinid.identification.fitting.noise.resolve_noise`).
    carried_noise : Noise, optional
        The σ an earlier fit carried (a saved fit's, or the previous step of a
        selection); used when it was not itself estimated from residuals.
    alpha : float
        Family-wise significance level.
    result : FitResult, optional
        An existing fit of ``effects`` on ``obs`` (skips the refit).
    """
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
    d_errors, d_axes, q0 = model_pass(machine, obs, result)
    # Candidates are judged by the F test, which estimates σ from the residual left beside each candidate:
    # a σ given too small would make every candidate look significant by χ² (and one given too large, none).
    # The given σ still judges the residual as a whole (χ² below) and sizes the uncertainties.
    side = fit_side(machine, obs, result, sigma, d_errors, q0)  # shared by every score test below
    scored = score_all(machine, obs, result, sigma, False, d_errors, q0, side)
    scored += proposed_maps(machine, obs, result, scored, sigma, False, d_errors, q0, side)
    location = {j.code for j in machine.error_joints if j.location}
    # best first; exact ties (identical columns) go to the location error, the more physical reading, then to the
    # smallest size for a machine: of errors the data cannot tell apart (a period of B read as a roll, a pitch or a
    # straightness of B's axis) the one that needs 2 µm rather than 2·10⁴ µrad
    live = sorted([c for c in scored if c.status == "live"], key=lambda c: (
        round(c.log10_p, 6), c.effect.split(":")[0] not in location, float(f"{c.rms_after_um:.9g}"),
        share_of_limit(machine, c.effect.split(":")[0], c.size, c.size_unit)))
    rest = [c for c in scored if c.status != "live"]
    threshold = alpha / max(len(live), 1)
    chi2_p = chi2_sf(float(np.sum(r**2)) / sigma**2, result.dof) if known else float("nan")
    significant = bool(live) and live[0].p_value < threshold
    verdict = "missing-effect" if significant or (known and chi2_p < alpha) else "noise"
    note = ""
    structure = None
    f_passes = True
    if known and chi2_p < alpha:
        # The residual exceeds the given σ. Structure, or a σ given too small? The F test of the best
        # candidates does not depend on σ at all.
        dof = max(result.dof, 1)
        rss = float(np.sum(r**2)) / sigma**2
        f_passes = any(_f_log10_p(c, rss, dof) + math.log10(c.trials) < math.log10(threshold) for c in live[:5])
    if not significant or not f_passes:
        # No candidate explains more than noise would. Structure outside the library, or noise (and, when
        # the residual exceeds a given σ, a σ given too small)? Neighbouring alignments tell, with no σ.
        structure = structure_left(r, obs.axes, obs.t_s, names=tuple(a.name for a in machine.axes))
        if structure is not None and structure.p_value < alpha:
            verdict = "missing-effect"
            note = f"an effect no candidate describes remains: {structure.describe()}"
        elif not f_passes:
            apparent = np.sqrt(rss / dof) * sigma
            if structure is not None:  # above the σ given, yet white: the σ given looks too small, not an effect
                verdict = "noise"      # "most structured along" an axis the neighbour test did not single out
                note = (f"the σ given looks too small: the residual is {apparent / sigma:.2g}× the noise σ given (χ² "
                        f"p {f'= {chi2_p:.2g}' if chi2_p > 0 else '< 1e-300'}) yet white — no candidate passes the F "
                        f"test and neighbouring alignments agree no more than noise would (p = "
                        f"{structure.p_value:.2g}): the noise is about {apparent:.2g} µm, not {sigma:.2g} µm as given "
                        f"(give --noise-um {apparent:.2g}, or let identify estimate it)")
            else:  # too few alignments for the neighbour test: an effect no candidate singles out, or a σ larger
                # than given; the data alone cannot tell, so the verdict stays missing-effect and says both
                verdict = "missing-effect"
                note = (f"the residual exceeds the noise σ given (χ² p = {chi2_p:.2g}) and no candidate explains it: "
                        f"an effect remains that the data cannot single out, or the noise is about {apparent:.2g} µm, "
                        f"not {sigma:.2g} µm as given (if so, give --noise-um {apparent:.2g})")
    advised = advise(machine, live, result.axis_ranges)
    best, passed = advised
    chosen = best is not None and best.p_value < threshold  # the candidate advised, significant
    undetermined, twins = _undetermined(machine, obs, result, best, sigma, d_errors, q0, side) if chosen else ("", ())
    follows = time_follows(obs, machine)
    # from the candidate advised on: those passed over are the ones ranked before it
    inseparable = inseparable_by_time(machine, live[len(passed):], follows) if chosen else ""
    matters = chosen and bool(time_or_axis(machine, best, {a for a, _ in follows}))
    hat = hat_diagonal(q0)
    stud, lev = studentized(result, None, sigma, h=hat)
    bound = chi2_isf(alpha / len(obs), 3)
    outliers = tuple(int(i) for i in np.flatnonzero(stud**2 > bound))
    rms = float(np.sqrt(np.mean(r**2)))
    axis_r, axis_names = axis_residuals(machine, obs, result, d_axes=d_axes)
    return Diagnosis(fit=result, verdict=verdict, note=note, rms_um=rms, noise=noise, chi2_p=chi2_p, threshold=threshold,
                     candidates=tuple(live + rest), studentized=stud, leverage=lev, outliers=outliers,
                     axis_residuals_um=axis_r, axis_names=axis_names, marks=tuple(obs.marks), hat=hat,
                     structure=structure, time_follows=follows, undetermined=undetermined, twins=twins,
                     inseparable=inseparable, advised=advised, time_matters=matters)


def advise(machine: Machine, live, axis_ranges) -> tuple:
    """(the best of the live candidates ``live`` (best first) a machine could have, or None; the better ones passed
    over, as (candidate, :class:`~kinid.identification.model.plausibility.Implausible`)). A candidate whose size at the
    values the score test estimates is beyond what a machine has
    (:func:`~kinid.identification.model.plausibility.implausible_candidate`, over the fitted ranges ``axis_ranges``) is
    not one to add: nearly aliased with the model, it explains a little more of the residual than a plausible
    candidate only with such a size (a pitch of 1.2 mrad/mm where a scale error of 0.06 µm/mm explains the same) —
    the rule ``--auto`` applies to a fitted addition, applied before adding it."""
    passed = []
    for c in live:
        odd = implausible_candidate(machine, c, axis_ranges)
        if odd is None:
            return c, tuple(passed)
        passed.append((c, odd))
    return None, tuple(passed)


def passed_over(c, odd) -> str:
    """A candidate passed over (:func:`advise`) and the size it would need, in words."""
    return f"{c.effect} (p = {c.p_value:.2g}), would need {odd.describe()}"


def _undetermined(machine, obs, result, best, sigma, d_errors, q0, side=None):
    """Why the best candidate's period is not determined by the positions measured, and the periods that fit as
    well; ("", ()) when it is."""
    from .ambiguity import period_twins
    from ..data import distinct_positions

    parts = best.effect.split(":")
    if chosen_of(best.effect) != "period":
        return "", ()
    twins = period_twins(machine, obs, result, best.effect, sigma, d_errors=d_errors, q0=q0, side=side)
    if not twins:
        return "", ()
    axis = machine.error_joint(parts[0]).axis
    positions = distinct_positions(obs.axes[:, machine.axis_names.index(axis)]).size
    unit = "°" if machine.axis(axis).kind != "prismatic" else " mm"
    shown = ", ".join(f"{p:.4g}" for p in sorted(twins, reverse=True)[:6]) + (" …" if len(twins) > 6 else "")
    return (f"{best.effect} is significant (p = {best.p_value:.2g}) but its period is not determined: periods "
            f"{shown}{unit} explain the data about as well on the {positions} positions of {axis} measured, and "
            f"differ between them — measure {axis} at more positions (kinid plan --detect {best.effect}=SIZE)"), twins
