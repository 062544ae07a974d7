"""Identify effect parameters from alignment observations.

Levenberg–Marquardt on the nonlinear residuals: Pinocchio gives residuals and
Jacobians (:mod:`identification.residuals`); each step is a small quadratic
program — min ½‖J_s δ + r‖² + ½λ‖δ‖² on unit-scaled columns, with optional
bounds — solved by CasADi's ``qrqp`` active-set solver. Parameters the data
cannot separate are found first (:mod:`identification.identifiability`), held
fixed at zero and reported by name. The passes run on the machine with only the error joints in use
(:func:`~kinid.identification.fitting.fit_pass.reduced`); the iterations stop once the Gauss–Newton step left is
below what the noise can tell (:func:`~kinid.identification.fitting.lm_step.below_noise`): that step is taken with
a check of its residuals, without another Jacobian.

Units: parameters in the effects' units (µm, µrad, µm/mm ...), residuals µm.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from kinid.checks import check_positive
from kinid.errors import DataError
from kinid.threads import blas_single_threaded

from ..model import Machine, check_effects, check_machine, default_model, model_effects  # noqa: F401 (re-exported)
from ..data import Observations, check_observations
from .fit_pass import model_pass_qr, reduced, residuals_chunked
from .identifiability import RANK_TOL, analyse, identifiable_columns, observability
from .lm_step import below_noise, lm_step as _lm_step
from .noise import Noise, shared_std
from .residuals import design, residuals
from .start import TURN_RAD, closed_form_start, frame_turn_rad

__all__ = ["FitResult", "Noise", "fit", "evaluated_fit", "model_effects", "axis_readings", "FIT_FORMAT",
           "READING_DIGITS"]

FIT_FORMAT = "kinid-fit/1"
#: λ of the first step, and the largest at which a step is Gauss–Newton's (a larger λ shortens it).
LAMBDA_START = 1e-9


@dataclass(frozen=True)
class FitResult:
    """An identified model: fresh from :func:`fit`, or read back by :func:`load_fit`.

    Build it with keywords. A loaded fit has every field the file holds; its
    ``residuals_um`` is None (the data are not in the file).

    Attributes
    ----------
    machine : Machine
    effects : tuple of Effect
    param_names, units : tuple of str
    values : array (P,)
        Identified values; NaN where the parameter is not identifiable.
    std : array (P,)
        Standard deviations: the covariance at ``noise_um`` combined with ``shared_std``; NaN where held.
    identifiable : array (P,) of bool
    aliases : tuple of Alias
        The parameters held fixed, by name, with what they alias with.
    rank : int
    condition_number, o1, o3 : float
        Of the whitened, column-scaled Jacobian of the identifiable parameters.
    residuals_um : array (N, 3) or None
        Tool point − mark in the workpiece frame, µm (None for a loaded fit).
    n_observations : int
        N, the alignments fitted.
    rms_um : float
        RMS over all residual components, µm (comparable with a per-axis σ).
    noise : Noise
        σ used for the standard deviations, and its source (``noise_um`` and
        ``noise_source`` give the two parts).
    dof : int
        Residual degrees of freedom, 3N − rank.
    iterations : int
    success : bool
    message : str
    singular_values : array
        Of the whitened, column-scaled Jacobian of the identifiable parameters.
    set_aside : tuple of SetAside
        Alignments left out as gross errors before this fit
        (:mod:`~kinid.identification.fitting.outliers`), with their CSV lines.
    axis_ranges : dict axis name -> (low, high)
        The readings the fitted data span, mm / deg (where a compensation table
        may be trusted when the URDF gives an axis no limits).
    axis_readings : dict axis name -> array (k,)
        The distinct readings of each axis in the fitted data, ascending, to :data:`READING_DIGITS` decimals
        (mm / deg): where a compensation table is measured, and whether a rotary axis's readings go all the
        way round (empty for fits saved before kinid kept them).
    prior : str
        The prior of a maximum a posteriori fit, in words (empty for least squares).
    prior_std : array (P,) or None
        Its standard deviation per parameter (inf where none); None for least squares.
    shared_std : dict source -> array (P,)
        For each shared (type B) source of the observations' uncertainty
        (``Observations.shifts_mm``): the change of every parameter when the
        source is one standard deviation off; included in ``std``.
    correlation : array (P, P) or None
        The correlation of the parameters' estimates from the noise (NaN where held); None for a
        loaded fit (the file holds the standard deviations only).
    start : str
        How the iterations started where not from the values given: the measurement frame fitted in closed form
        (:mod:`~kinid.identification.fitting.start`), in words; empty otherwise.
    jacobian_r : array (P, P) or None
        R of ``J = QR``, J the data's (3N × P) Jacobian at the fit (µm per parameter unit, the prior's rows left out)
        from its last pass: the leverages and the pose advice use it instead of a pass of their own. None for a
        loaded or evaluated fit. ``jacobian_r_zero``: the same at every parameter zero (the nominal machine, what
        the pose advice judges), from the fit's first pass when it started there; else None.
    stated_std : dict
        The instrument's stated std checked against the residuals (``StdCheck.summary()``); empty without them.
    board_pose : dict
        With the laser beside the camera: ``passes`` (fits made), ``move_um`` (the last check's move of
        ``mark_dz_mm``, RMS), ``noise_um`` and ``settled`` of the depths judged with the fitted board pose.
    """

    machine: Machine
    effects: tuple
    param_names: tuple
    units: tuple
    values: np.ndarray
    std: np.ndarray
    identifiable: np.ndarray
    aliases: tuple
    rank: int
    condition_number: float
    o1: float
    o3: float
    residuals_um: np.ndarray | None
    n_observations: int
    rms_um: float
    noise: Noise
    dof: int
    iterations: int
    success: bool
    message: str
    singular_values: np.ndarray = field(default_factory=lambda: np.zeros(0))
    set_aside: tuple = ()
    axis_ranges: dict = field(default_factory=dict)
    axis_readings: dict = field(default_factory=dict)
    shared_std: dict = field(default_factory=dict)
    prior: str = ""
    prior_std: np.ndarray | None = None
    correlation: np.ndarray | None = None
    start: str = ""
    jacobian_r: np.ndarray | None = None
    jacobian_r_zero: np.ndarray | None = None
    stated_std: dict = field(default_factory=dict)
    board_pose: dict = field(default_factory=dict)

    @property
    def noise_um(self) -> float:
        """σ of one residual coordinate, µm."""
        return self.noise.value_um

    @property
    def noise_source(self) -> str:
        """Where σ came from: given, replicates, fit or residuals."""
        return self.noise.source

    def __repr__(self) -> str:
        return (f"FitResult({len(self.effects)} effects, rank {self.rank}/{len(self.param_names)}, "
                f"{self.n_observations} alignments, RMS {self.rms_um:.4g} µm, σ {self.noise_um:.4g} µm "
                f"({self.noise_source}); .table() for the values)")

    def with_noise(self, noise: Noise) -> "FitResult":
        """The same fit with the standard deviations at another σ (they scale with it)."""
        if noise == self.noise:
            return self
        scale = noise.value_um / self.noise.value_um if self.noise.value_um > 0 else float("nan")
        shared = sum((v**2 for v in self.shared_std.values()), np.zeros(len(self.std)))
        from_noise = np.sqrt(np.maximum(self.std**2 - shared, 0.0))
        return replace(self, noise=noise, std=np.sqrt((from_noise * scale) ** 2 + shared))

    @property
    def theta(self) -> np.ndarray:
        """Parameter vector for the model: identified values, 0 where held."""
        return np.where(self.identifiable, self.values, 0.0)

    @property
    def effect_names(self) -> tuple:
        return tuple(e.name for e in self.effects)

    def table(self) -> str:
        """Readable table: parameter, value, standard deviation, unit."""
        w = max([len(n) for n in self.param_names] + [9])
        lines = [f"{'parameter':<{w}}  {'value':>12}  {'std (1σ)':>10}  unit"]
        for n, v, s, u, ok in zip(self.param_names, self.values, self.std, self.units, self.identifiable):
            if ok:
                lines.append(f"{n:<{w}}  {v:12.4f}  {s:10.4f}  {u}")
            else:
                lines.append(f"{n:<{w}}  {'held':>12}  {'':>10}  {u}")
        lines.append("")
        held = len(self.param_names) - self.rank
        lines += [
            f"residual RMS {self.rms_um:.4f} µm per coordinate over {self.n_observations} alignments, σ = "
            f"{self.noise_um:.4f} µm ({self.noise_source}): what the model leaves against the noise; near σ, "
            f"nothing systematic is left",
            f"rank {self.rank}/{len(self.param_names)}: the data tell {self.rank} error terms apart"
            + (f"; {held} are held (below)" if held else ""),
            f"condition {self.condition_number:.3g}: the least certain combination of the terms (each scaled to its "
            f"column) is {self.condition_number:.3g}× less certain than the best; large (over ~1000) means the poses "
            f"hardly separate some terms",
            f"observability O1 {self.o1:.3g} (mean), O3 {self.o3:.3g} (weakest direction): how strongly the poses "
            f"excite the terms; larger is better (Sun & Hollerbach 2008)",
        ]
        if self.start:
            lines.append(self.start)
        if self.prior:
            lines.append(f"maximum a posteriori estimate, std from the posterior — {self.prior}")
        if self.shared_std:
            lines.append(f"std includes the shared uncertainty of {', '.join(sorted(self.shared_std))} (type B)")
        if self.aliases:
            lines.append("not identifiable from these data (held fixed, not returned as values):")
            lines += [f"  - {a.message}" for a in self.aliases]
        if self.set_aside:
            lines.append(f"set aside as gross errors ({len(self.set_aside)}; kinid identify --no-robust keeps them):")
            lines += [f"  - {a.describe()}" for a in self.set_aside]
        if not self.success:
            lines.append(f"WARNING: {self.message}")
        elif "; " in self.message:  # converged, with a word more (the identifiable set changed at the solution)
            lines.append(f"WARNING: {self.message.split('; ', 1)[1]}")
        from ..model import warning_lines

        lines += warning_lines(self.implausible())
        return "\n".join(lines)

    def implausible(self) -> tuple:
        """The effects whose fitted size is beyond what a machine or a set-up could have
        (:mod:`~kinid.identification.model.plausibility`)."""
        from ..model import implausible_effects

        return implausible_effects(self)


@blas_single_threaded
def fit(
    machine: Machine,
    obs: Observations,
    effects=None,
    *,
    noise_um: float | Noise | None = None,
    bounds: dict | None = None,
    rank_tol: float = RANK_TOL,
    max_iter: int = 100,
    xtol: float = 1e-12,
    theta0=None,
    prior_std=None,
    frame_start: bool = True,
) -> FitResult:
    """Fit ``effects`` (default: the default model) to the observations.

    Parameters
    ----------
    machine : Machine
    obs : Observations
    effects : sequence of Effect, optional
    noise_um : float or Noise, optional
        σ of one residual coordinate, µm (a float is σ given by the user; a
        :class:`Noise` keeps its source). Default: estimated from the residuals.
    bounds : dict name -> (low, high), optional
        Box bounds on parameters, in their units.
    rank_tol : float
        See :mod:`identification.identifiability`.
    max_iter : int
        Levenberg–Marquardt iterations at most.
    xtol : float
        Stop when the scaled step is below ``xtol`` × (1 + ‖scaled θ‖).
    theta0 : array (P,), optional
        Starting values (default zero).
    prior_std : array (P,), optional
        A prior on each parameter's size: zero mean, this standard deviation in the parameter's unit
        (inf: none). The fit is then the maximum a posteriori estimate with the noise σ (``noise_um``,
        required) and its standard deviations the posterior's (:mod:`~kinid.identification.fitting.prior`).
    frame_start : bool
        Fit the measurement frame (the six ``E?0W`` joints) and the point on the tool in closed form first, where
        the frame turns by more than :data:`~kinid.identification.fitting.start.TURN_RAD` from ``theta0`` and the
        start costs less (:mod:`~kinid.identification.fitting.start`). False: iterate from ``theta0`` as given.

    Returns
    -------
    FitResult
    """
    noise = noise_um if isinstance(noise_um, Noise) else (
        None if noise_um is None else Noise(check_positive("noise_um", noise_um), "given"))
    noise_um = None if noise is None else noise.value_um
    check_machine(machine)
    check_observations(obs)
    effects = tuple(default_model(machine)) if effects is None else check_effects(machine, effects)
    d_full = design(machine, effects, obs)
    names = d_full.param_names()
    mr, d = reduced(machine, d_full)  # the passes' machine: the error joints in use only (fit_pass)
    P = d.n_params
    theta = np.zeros(P) if theta0 is None else np.asarray(theta0, float).copy()
    # the prior as extra residual rows w·θ (µm, like the data's): w = σ / s, 0 where there is none
    w_prior = np.zeros(P)
    if prior_std is not None:
        if noise_um is None:
            raise DataError("a prior needs the noise σ (noise_um) to weigh it against the data", parameter="noise_um")
        s = np.asarray(prior_std, float)
        if s.shape != (P,) or np.any(np.isnan(s)) or np.any(s <= 0):
            raise DataError(f"must be {P} positive standard deviations (inf for none)", parameter="prior_std")
        w_prior = noise_um / s
    # the Jacobian is only ever held as the R factor of its QR (fit_pass): memory flat in the alignments
    ps = model_pass_qr(mr, d, obs, theta)
    r = ps.r
    M = r.size
    rows = M + int(np.sum(w_prior > 0))  # the analysis's per-row figures count the data's rows and the prior's
    sigma0 = noise_um or 1.0
    ident = analyse(_with_prior(ps.R, w_prior) / sigma0, names, tol=rank_tol, rows=rows)
    free = ident.identifiable
    if np.any(theta[~free] != 0.0):
        # a warm start that gives values to parameters these data cannot identify (another subset of the
        # data held others) is no start for these data: its aliased pairs would lose their sums. From zero.
        theta[:] = 0.0
        ps = model_pass_qr(mr, d, obs, theta)
        r = ps.r
        ident = analyse(_with_prior(ps.R, w_prior) / sigma0, names, tol=rank_tol, rows=rows)
        free = ident.identifiable
    r_zero = None if np.any(theta) else ps.R
    lo = np.full(P, -np.inf)
    hi = np.full(P, np.inf)
    for name, (a, b) in (bounds or {}).items():
        if name not in names:
            raise DataError(f"bound on unknown parameter {name!r}")
        lo[names.index(name)], hi[names.index(name)] = a, b
    prior_cost = lambda th: 0.5 * float(np.sum((w_prior * th) ** 2))  # noqa: E731
    cost = 0.5 * float(np.sum(r**2)) + prior_cost(theta)
    # the measurement frame in closed form first, where it turns far (start.py); kept only if it costs less
    started = _frame_start(mr, d, obs, theta, ps, ident, lo, hi, prior_cost) if frame_start else None
    start = None
    if started is not None:
        start, ps = started
        theta, r = start.theta, ps.r
        cost = 0.5 * float(np.sum(r**2)) + prior_cost(theta)
    D = np.linalg.norm(_with_prior(ps.R, w_prior)[:, free], axis=0)
    wf = w_prior[free]
    lam = LAMBDA_START
    success, message, it = False, "", 0
    for it in range(1, max_iter + 1):
        Js = ps.R[:, free] / D  # ‖r + Jδ‖² = rest + ‖Qᵀr + Rδ‖²
        xs = theta[free] * D
        if wf.any():  # the prior's rows: w·(θ + δ/D)
            Js = np.vstack([Js, np.diag(wf / D)])
            r_all = np.concatenate([ps.qtr, wf * theta[free]])
        else:
            r_all = ps.qtr
        delta = _lm_step(Js, r_all, lam, lo[free] * D - xs, hi[free] * D - xs)
        predicted = cost - 0.5 * (ps.rest + float(np.sum((r_all + Js @ delta) ** 2)))
        if predicted <= 1e-13 * cost:  # the linearised model promises nothing more: converged
            success, message = True, f"converged in {it} iterations"
            break
        trial = theta.copy()
        trial[free] += delta / D
        if lam <= LAMBDA_START and below_noise(predicted, cost, noise_um, rows - int(free.sum())):
            # a Gauss–Newton step the noise cannot tell from zero: taken where it lowers the cost (the residuals
            # checked, no Jacobian more: the covariance is the last pass's, a step of < 1 % σ away), and done
            r_new = residuals_chunked(mr, d, obs, trial)
            cost_new = 0.5 * float(np.sum(r_new**2)) + prior_cost(trial)
            if cost_new <= cost:
                theta, cost, r = trial, cost_new, r_new
            success, message = True, f"converged in {it} iterations"
            break
        # the residuals and the Jacobian at the trial point in one pass: most steps are taken, and the
        # Jacobian then is the next step's (a step not taken costs the Jacobian's share of one pass)
        ps_new = model_pass_qr(mr, d, obs, trial)
        cost_new = 0.5 * float(np.sum(ps_new.r**2)) + prior_cost(trial)
        if cost_new <= cost:
            small = np.linalg.norm(delta) <= xtol * (1 + np.linalg.norm(xs))
            flat = cost - cost_new <= 1e-13 * cost
            theta, cost = trial, cost_new
            lam = max(lam / 10, 1e-12)
            ps = ps_new
            r = ps.r
            if small or flat:
                success, message = True, f"converged in {it} iterations"
                break
        else:
            lam *= 10
            if lam > 1e12:
                success, message = True, f"converged in {it} iterations (no further decrease)"
                break
    else:
        message = f"did not converge in {max_iter} iterations"

    # uncertainty at the solution
    rms = float(np.sqrt(np.mean(r**2)))
    rank = int(free.sum())
    dof = M - rank
    if noise is None:
        if dof <= 0:
            raise DataError(f"is needed: {len(obs)} observation row(s) of {obs.source} give {M} residuals for {rank} "
                            "free parameters, too few to take σ from the residuals (or measure more rows)",
                            parameter="noise_um")
        noise = Noise(float(np.sqrt(np.sum(r**2) / dof)), "residuals")
    sigma = noise.value_um
    Jf = ps.R[:, free] / sigma
    if wf.any():  # the posterior: the prior's rows 1/s in whitened units
        Jf = np.vstack([Jf, np.diag(wf / noise_um)])
    Df = np.linalg.norm(Jf, axis=0)
    _, s, Vt = np.linalg.svd(Jf / Df, full_matrices=False)
    cov_scaled = (Vt.T / s**2) @ Vt
    std = np.full(P, np.nan)
    std[free] = np.sqrt(np.diag(cov_scaled)) / Df
    correlation = np.full((P, P), np.nan)
    correlation[np.ix_(free, free)] = cov_scaled / np.outer(std[free] * Df, std[free] * Df)
    shared = shared_std(mr, d, obs, theta, free)
    std = np.sqrt(std**2 + sum((v**2 for v in shared.values()), np.zeros(P)))
    # observability at the solution: the singular values just computed are those of the unit-column Jacobian of
    # the fitted parameters, as long as the rank test at the solution keeps them all (a held one it would now take,
    # a tool axis's tilt once the marker is off it, changes nothing fitted: 12 of 12 far-frame arms, no better held out)
    if identifiable_columns(_with_prior(ps.R, w_prior)[:, free] / sigma, tol=rank_tol).all():
        condition_number, o1, o3 = observability(s, rows)
        singular_values = s
    else:
        message += "; the identifiable set changed at the solution (nonlinear aliasing): check the held parameters"
        condition_number, o1, o3, singular_values = ident.condition_number, ident.o1, ident.o3, ident.singular_values
    values = np.where(free, theta, np.nan)
    units = tuple(u for e in effects for u in e.param_units(machine))
    return FitResult(
        machine=machine, effects=effects, param_names=tuple(names), units=units, values=values, std=std,
        identifiable=free.copy(), aliases=ident.aliases, rank=rank, condition_number=condition_number,
        o1=o1, o3=o3, residuals_um=r, n_observations=int(r.shape[0]), rms_um=rms, noise=noise, dof=dof,
        iterations=it, success=success, message=message, singular_values=singular_values,
        axis_ranges=_axis_ranges(machine, obs), axis_readings=axis_readings(machine, obs), shared_std=shared,
        prior_std=None if prior_std is None else np.asarray(prior_std, float), correlation=correlation,
        start="" if start is None else start.describe(), jacobian_r=ps.R,
        jacobian_r_zero=r_zero,
    )


def evaluated_fit(machine: Machine, obs: Observations, effects, theta, residuals_um, identifiable, *,
                  noise_um: float | None = None) -> FitResult:
    """The model ``effects`` at the values ``theta`` on ``obs``, as a FitResult, from its residuals there (N, 3)
    and the parameters the data identify — both already evaluated: no pass, no iteration. For code that reads a
    model's values, residuals and identifiable set at a point known to be its optimum (the held-out check's turns,
    Gauss–Newton steps from the whole data's fit); no standard deviations (NaN) or observability."""
    effects = tuple(effects)
    free = np.asarray(identifiable, bool)
    r = np.asarray(residuals_um, float)
    rank = int(free.sum())
    dof = r.size - rank
    noise = (Noise(float(np.sqrt(np.sum(r**2) / dof)) if dof > 0 else float("nan"), "residuals")
             if noise_um is None else Noise(noise_um, "given"))
    P = len(free)
    return FitResult(
        machine=machine, effects=effects, param_names=tuple(n for e in effects for n in e.param_names()),
        units=tuple(u for e in effects for u in e.param_units(machine)), values=np.where(free, theta, np.nan),
        std=np.full(P, np.nan), identifiable=free.copy(), aliases=(), rank=rank, condition_number=float("nan"),
        o1=float("nan"), o3=float("nan"), residuals_um=r, n_observations=int(r.shape[0]),
        rms_um=float(np.sqrt(np.mean(r**2))), noise=noise, dof=dof, iterations=0, success=True,
        message="evaluated at the values given", axis_ranges=_axis_ranges(machine, obs),
        axis_readings=axis_readings(machine, obs))


def _frame_start(machine: Machine, d, obs: Observations, theta, ps, ident, lo, hi, prior_cost):
    """(Start, its pass) where the measurement frame turns by more than TURN_RAD from ``theta`` (judged from the
    residuals at hand first: a set-up turned less, a machine tool's, costs no pass more), the start lies within
    the bounds and costs less than ``theta``; None otherwise. The parameters held are those ``ident`` holds at
    ``theta``: at the start a marker off the last joint's axis would trade the joint's zero for the marker's place
    about it, and the start puts its values on the parameters free here."""
    if not frame_turn_rad(obs, ps.r) > TURN_RAD:
        return None
    start = closed_form_start(machine, d, obs, theta, free=ident.identifiable, aliases=ident.aliases)
    if start is None or not start.turn_rad > TURN_RAD or not np.all((start.theta >= lo) & (start.theta <= hi)):
        return None
    ps_start = model_pass_qr(machine, d, obs, start.theta)
    cost = 0.5 * float(np.sum(ps.r**2)) + prior_cost(theta)
    return (start, ps_start) if 0.5 * float(np.sum(ps_start.r**2)) + prior_cost(start.theta) < cost else None


def _with_prior(J, w_prior):
    """The Jacobian with the prior's rows (a parameter with a prior is identified by it where the data cannot)."""
    return np.vstack([J, np.diag(w_prior)[w_prior > 0]]) if np.any(w_prior > 0) else J


#: Decimals (of mm / deg) to which :func:`axis_readings` tells readings apart: 0.1 µm, 0.0001°.
READING_DIGITS = 4


def axis_readings(machine: Machine, obs: Observations) -> dict:
    """Axis name -> the distinct readings of that axis in ``obs``, ascending, to :data:`READING_DIGITS` decimals
    (axes with readings only)."""
    out = {}
    for j, a in enumerate(machine.axes):
        q = obs.axes[:, j]
        q = q[np.isfinite(q)]
        if q.size:
            out[a.name] = np.unique(np.round(q, READING_DIGITS))
    return out


def _axis_ranges(machine: Machine, obs: Observations) -> dict:
    """Axis name -> (min, max) of the readings in ``obs`` (axes with readings only)."""
    out = {}
    for j, a in enumerate(machine.axes):
        q = obs.axes[:, j]
        q = q[np.isfinite(q)]
        if q.size:
            out[a.name] = (float(q.min()), float(q.max()))
    return out
