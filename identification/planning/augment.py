"""A sequential design: the alignments to add to those already measured so that the target holds for the model the
fit of them found.

A plan is made for a model chosen before any data: the default model plus the effects named with ``--add``. The
fit may find more (``identify --auto``: a scale error, a two-per-turn error of a turntable), and the promise of the
plan was not for that model. Here the measured rows' information ``M₀ = Σ J_mᵀJ_m`` (their Jacobian at their own
readings, the fitted model's parameters) is a fixed part of the design and the candidates' information adds to
it: the greedy choice, the exchange and the trim of :mod:`~kinid.identification.planning.design` run with the
measured rows kept, and the bound is the relaxation's with ``M₀`` fixed (:func:`~.design.added_bound`).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from kinid.errors import DataError
from ..model import Machine, parse_effect
from ..data import Observations
from .order import TravelModel, order_for_time, with_checks
from .plan import Candidates, Plan, _terms, tool_point_u_um, volume_weight
from .pool import axis_motion, candidate_jacobian

__all__ = ["Augmented", "augment_plan", "planned_effects"]


@dataclass(frozen=True)
class Augmented:
    """The alignments to add (:func:`augment_plan`).

    Attributes
    ----------
    plan : Plan
        The added alignments in visiting order; its figures (``u_tool_um``, ``u_params``, ``bound_count``,
        ``efficiency``) are those of the measured and the added together, ``bound_count`` counting added
        alignments only.
    measured : int
        Alignments already measured.
    u_measured_um : float
        The tool point's U (k = 2, per coordinate, RMS over the candidates' poses) of the measured alignments
        alone for the same model (inf where they leave a parameter the candidates determine undetermined).
    effects : tuple of str
        The model planned for.
    settled : tuple of str
        Effects of the fit driven by time or by the approach direction: settled by the order, not planned for.
    """

    plan: Plan
    measured: int
    u_measured_um: float
    effects: tuple
    settled: tuple

    def __repr__(self) -> str:
        return (f"Augmented({self.measured} measured + {len(self.plan.obs)} added, U {self.plan.u_tool_um:.3g} µm "
                f"(k=2))")


def planned_effects(effects):
    """(effects a plan chooses poses for, names of those the order settles: driven by time or direction)."""
    from ..model import basis_of

    kept = tuple(e for e in effects if basis_of(e).driver not in ("time", "direction"))
    return kept, tuple(e.name for e in effects if basis_of(e).driver in ("time", "direction"))


def _nominal(obs: Observations, source: str) -> Observations:
    """The rows' marks and readings only (what the Jacobian at the nominal machine needs)."""
    return Observations(tuple(obs.marks), np.asarray(obs.w_mm, float), np.asarray(obs.axes, float), None, {}, (),
                        source)


def augment_plan(machine: Machine, measured: Observations, candidates: Observations, effects, *,
                 noise_um: float, target_um: float | None = None, param_targets: dict | None = None,
                 count: int | None = None, travel: TravelModel = TravelModel(), blocks: int | None = None,
                 reference: bool = True, drift_checks: int | None = None, max_count: int = 2000,
                 suspects=()) -> Augmented:
    """The fewest candidates to add to ``measured`` so that the targets hold for ``effects`` (module docstring).

    Parameters
    ----------
    machine : Machine
    measured : Observations
        The alignments already measured (their readings as read).
    candidates : Observations
        From :func:`~.pool.candidate_poses`: the poses to choose from, and the volume of the tool-point target.
    effects : sequence of Effect
        The model the fit found; those driven by time or the approach direction are left to the order.
    noise_um : float
        σ of one reading, µm.
    target_um, param_targets, count
        As :func:`~.plan.plan_measurement` (``count``: this many added alignments).
    travel, blocks, reference
        The order of the added alignments (:func:`~.order.order_for_time`).
    drift_checks : int, optional
        Read the added run's reference alignment (its first) this many times over it (:func:`~.order.with_checks`;
        default and 0: the blocks' references only — the measured run's checks already tell the drift).
    suspects : sequence of Suspect
        Effects the measured data hint at without establishing them (:func:`~.suspects.suspects_of`): the targets
        are planned for the model with them (the fit of all may add them), and the added alignments make each
        detectable at its estimated size with probability :data:`~.suspects.SUSPECT_POWER` (``plan.powers``), where
        the candidates can. Those driven by time or the approach direction are left out.

    Raises
    ------
    DataError
        No target and no count; the targets out of reach with every candidate added.
    """
    from .design import added_bound, criterion, select, trim

    if count is None and target_um is None and not param_targets:
        raise DataError("give a target (--target-um or --param NAME=U) or a --count", parameter="target_um")
    effects, settled = planned_effects(tuple(effects))
    suspects = _position_suspects(machine, suspects, effects)
    model = effects
    effects = effects + tuple(parse_effect(s.effect, machine) for s in suspects)
    m, n = len(measured), len(candidates)
    both = _nominal(candidates, "<candidates>")
    both = Observations(both.marks + tuple(measured.marks), np.vstack([both.w_mm, measured.w_mm]),
                        np.vstack([both.axes, measured.axes]), None, {}, (), "<candidates and measured>")
    J_all, names, held = candidate_jacobian(machine, effects, both, noise_um)
    J = np.concatenate([J_all[n:], J_all[:n]])  # the measured rows first: select's fixed start
    fixed = np.arange(m)
    terms = _terms(J_all[:n], names, noise_um, target_um, param_targets)
    W = sum(Wi / ti for Wi, ti, _ in terms) if terms else volume_weight(J_all[:n] * noise_um)

    def enough(index):
        return all(criterion(J, Wi, index) <= ti for Wi, ti, _ in terms)

    u_alone = float("inf")
    if np.isfinite(criterion(J, W, fixed)):
        u_alone = tool_point_u_um(J, volume_weight(J_all[:n] * noise_um), fixed, noise_um, volume=J_all[:n])[0]
    if count is None and enough(fixed):
        index = fixed
    else:
        sel = select(J, W, count=None if count is None else m + count, enough=enough if terms else None,
                     max_count=m + max_count, start=fixed)
        index = sel.index
        if count is None:
            if not enough(index):
                raise DataError(f"the targets are out of reach with {len(index) - m} of the {n} candidates added to "
                                f"the {m} measured: ask less, give more candidates, or a lower --noise-um",
                                parameter="target_um")
            index = trim(J, W, index, enough, keep=m)
    powers = {}
    if suspects:
        index, powers = _detect_suspects(machine, both, n, model, index, suspects, noise_um, max_count)
    added = index[m:] - m  # candidate indices
    if added.size == 0:
        order = None
    else:
        linear, wraps = axis_motion(machine)
        order = order_for_time(candidates.subset(added).axes, machine.axis_names, linear, wraps, travel,
                               blocks=blocks, reference=reference)
        if reference and drift_checks:
            order = with_checks(order, candidates.subset(added).axes, drift_checks, linear, wraps, travel,
                                machine.axis_names)
    rows = np.r_[fixed, m + added[order.index]] if order is not None else fixed  # the reference repeats teach too
    bound_count, efficiency = 0, 1.0
    if count is None and terms:
        bound_count = max(_bound_count(J, Wi / ti, fixed, len(rows) - m) for Wi, ti, _ in terms)
    if len(rows) > m:
        efficiency = added_bound(J, W, fixed, len(rows) - m) / criterion(J, W, rows)
    u, worst = tool_point_u_um(J, volume_weight(J_all[:n] * noise_um), rows, noise_um, volume=J_all[:n])
    X = J[rows].reshape(-1, J.shape[2])
    Minv = np.linalg.inv(X.T @ X)
    u_params = {k: (2.0 * float(np.sqrt(Minv[names.index(k), names.index(k)])), t)
                for k, t in (param_targets or {}).items()}
    if order is not None:
        chosen = candidates.subset(added)
        obs = replace(chosen.subset(order.index), t_s=order.t_s, lines=(), source="<added alignments>")
    else:
        obs = candidates.subset(np.zeros(0, int))
    pool = Candidates(candidates, J_all[:n], names, held, f"{n} candidate alignments")
    plan = Plan(obs, added, pool, u, worst, u_params, bound_count, float(efficiency), powers, order, held, (),
                target_um, noise_um, travel)
    return Augmented(plan, m, u_alone, tuple(e.name for e in effects), settled)


def _position_suspects(machine, suspects, effects) -> tuple:
    """The suspects a choice of poses can settle: not driven by time or the approach direction, not in ``effects``."""
    from ..model import basis_of

    have = {e.name for e in effects}
    return tuple(s for s in suspects if s.effect not in have
                 and basis_of(parse_effect(s.effect, machine)).driver not in ("time", "direction"))


def _detect_suspects(machine, both, n, model, index, suspects, noise_um, limit):
    """``index`` (measured rows first) grown until each suspect is detectable, given the fit's ``model``
    (:func:`~.suspects.add_until_detected`); ``both`` holds the candidates' rows, then the measured ones (``n``
    candidates). Returns (index, {effect: (size, power)}), the size the norm of its estimated coefficients."""
    from ..fitting import design, residuals
    from .suspects import SUSPECT_POWER, SUSPECT_SHARE, add_until_detected, estimated_columns

    J_all = candidate_jacobian(machine, model, both, noise_um)[0]
    J = np.concatenate([J_all[n:], J_all[:n]])
    blocks = {}
    for s in suspects:
        d = design(machine, [parse_effect(s.effect, machine)], both)
        _, Je, _ = residuals(machine, d, both, np.zeros(d.n_params))
        Je = np.concatenate([Je[n:], Je[:n]]) / noise_um
        tested = estimated_columns(Je, s.coefficient_std)  # the others the diagnosis's model holds: nuisance, as there
        blocks[s.effect] = (np.concatenate([J, Je[:, :, ~tested]], axis=2), Je[:, :, tested],
                            np.asarray(s.coefficients)[tested], s.threshold)
    measured = len(both) - n
    index, reached = add_until_detected(index, blocks, SUSPECT_POWER, limit,
                                        each_at_most=int(np.ceil(SUSPECT_SHARE * measured)))
    return index, {s.effect: (float(np.linalg.norm(s.coefficients)), reached[s.effect]) for s in suspects}


def _bound_count(J, W, fixed, upper: int) -> int:
    """The fewest alignments to add that the relaxation does not rule out: adding fewer cannot reach φ ≤ 1 (W is
    the targets' weight over their φ targets)."""
    from .design import added_bound

    if added_bound(J, W, fixed, 0) <= 1.0:
        return 0
    lo, hi = 0, max(upper, 1)  # lo: ruled out; hi: not ruled out (the plan reaches it)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if added_bound(J, W, fixed, mid, stop_above=1.0) > 1.0:
            lo = mid
        else:
            hi = mid
    return hi


#: Largest volume rebuilt from the data's grid for :func:`fit_volume_u_um`; beyond it the measured poses are the volume.
MAX_VOLUME = 20_000


def data_volume(machine: Machine, obs: Observations) -> Observations:
    """The volume a measurement spans, as ``kinid plan`` builds its candidates: every mark measured (its mean
    position per label) at every
    combination of the values each preset axis was read at, the linear axes solved at the nominal machine, within
    the travel; the measured poses themselves on a machine without three linear axes, or where that grid exceeds
    :data:`MAX_VOLUME` alignments."""
    from .pool import candidate_poses, solved_axes

    solve = solved_axes(machine, None)
    if not solve:
        return _nominal(obs, "<measured poses>")
    presets = {a: np.unique(np.round(obs.axes[:, machine.axis_names.index(a)], 6))
               for a in machine.axis_names if a not in solve}
    labels = sorted(set(obs.marks))
    marks = np.array([np.asarray(obs.w_mm, float)[[m == k for m in obs.marks]].mean(axis=0) for k in labels])
    size = len(marks) * int(np.prod([len(v) for v in presets.values()]))
    if size > MAX_VOLUME:
        return _nominal(obs, "<measured poses>")
    try:
        return candidate_poses(machine, marks, presets, solve=solve)
    except DataError:
        return _nominal(obs, "<measured poses>")


def fit_volume_u_um(result, obs: Observations) -> tuple[float, int]:
    """The tool point's expanded uncertainty (k = 2, per coordinate, RMS over the volume ``obs`` spans:
    :func:`data_volume`) a fit promises, as ``kinid plan`` states it: ``U = 2·sqrt(mean_v trace(J_v C J_vᵀ) / 3)``,
    ``C`` the covariance of the fitted parameters (standard deviations and correlation of ``result``, a fresh fit).
    Effects driven by time or by the approach direction are left out (the volume is the cold machine). Returns
    (U in µm, the volume's poses); U is NaN without a correlation (a fit read from its file)."""
    from ..fitting import design, residuals

    machine = result.machine
    volume = data_volume(machine, obs)
    if result.correlation is None:
        return float("nan"), len(volume)
    kept, _ = planned_effects(result.effects)
    columns, start = [], 0
    for e in result.effects:
        if e in kept:
            columns += list(range(start, start + e.n_params))
        start += e.n_params
    columns = np.array(columns, int)
    d = design(machine, kept, volume)
    _, J, _ = residuals(machine, d, volume, result.theta[columns])
    ok = result.identifiable[columns]
    std = result.std[columns[ok]]
    C = result.correlation[np.ix_(columns[ok], columns[ok])] * np.outer(std, std)
    Jv = J[:, :, ok]
    per_pose = np.einsum("vip,pq,viq->v", Jv, C, Jv)
    return 2.0 * float(np.sqrt(max(float(per_pose.mean()), 0.0) / 3.0)), len(volume)
