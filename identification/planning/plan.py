"""Plan a measurement: the fewest alignments, in the order that costs least machine time, for the accuracy asked.

The candidates are every mark at every combination of the preset axes' angles (or, on a machine without
three linear axes to solve — a robot arm — joint configurations drawn over the travel). At the nominal
machine each candidate's Jacobian says what it teaches about the model's parameters; the plan picks the
candidates that bring the target within reach (:mod:`~kinid.identification.planning.design`), keeps named
effects detectable, orders them for machine time with time following no axis
(:mod:`~kinid.identification.planning.order`), and names the parameters no candidate can determine, with
the poses that would (:mod:`~kinid.identification.planning.advice`).

The tool-point target is an expanded uncertainty (k = 2) per coordinate of the predicted tool point,
RMS over the work volume — the candidates' poses: ``U = 2·sqrt(mean_v trace(Cov_v) / 3)``, where
``Cov_v`` is the covariance of the fitted model's tool point at pose ``v`` for reading noise σ. The
held-out 3-D RMS a simulation measures is ``√3·U/2``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from kinid.errors import DataError
from ..model import Machine
from ..data import Observations
from .order import Order, TravelModel, order_for_time
from .pool import axis_motion, candidate_jacobian

__all__ = ["Plan", "Candidates", "plan_measurement", "volume_weight", "tool_point_u_um", "detect_power"]

#: Reading noise assumed when the user gives none, µm.
NOISE_UM = 1.0
#: Significance of the diagnosis's test of one candidate effect (before Bonferroni over the library).
ALPHA = 0.01


@dataclass(frozen=True)
class Candidates:
    """The pool: poses (nominal readings of every axis) and what each one teaches.

    Attributes
    ----------
    obs : Observations
        Marks and the nominal readings of every axis.
    J : array (N, 3, P)
        Residual (µm) per parameter unit of the model's free parameters, at the nominal machine.
    names : tuple of str
        The free parameters (the model's identifiable ones over the whole pool).
    held : tuple of Alias
        The model's parameters no candidate determines.
    description : str
    """

    obs: Observations
    J: np.ndarray
    names: tuple
    held: tuple
    description: str


@dataclass(frozen=True)
class Plan:
    """A planned measurement (:func:`plan_measurement`).

    Attributes
    ----------
    obs : Observations
        The alignments in visiting order (``t_s``: when each is made), nominal readings of every axis.
    chosen : array of int
        Candidate indices chosen (no repeats; ``obs`` adds the reference repeats).
    candidates : Candidates
    u_tool_um : float
        Expanded uncertainty (k = 2) per coordinate of the tool point, RMS over the volume.
    u_tool_worst_um : float
        The same at the worst pose of the volume.
    u_params : dict name -> (U k=2, target)
    bound_count : int
        No plan from these candidates with fewer alignments meets the target (the convex relaxation's
        bound; 0 without a target).
    efficiency : float
        The relaxation's bound on φ for this count over this plan's φ (1: provably optimal).
    powers : dict effect -> (size, power)
    order : Order
    held : tuple of Alias
        Parameters this plan leaves undetermined.
    advice : tuple of Advice
    target_um : float or None
    noise_um : float
    travel : TravelModel
    reach : Reach or None
        What the plan detects, with ``detect_um`` (:mod:`~kinid.identification.planning.reach`).
    checks : DriftChecks or None
        The reference alignment's readings over the run (:mod:`~kinid.identification.planning.drift`); None without.
    """

    obs: Observations
    chosen: np.ndarray
    candidates: Candidates
    u_tool_um: float
    u_tool_worst_um: float
    u_params: dict
    bound_count: int
    efficiency: float
    powers: dict
    order: Order
    held: tuple
    advice: tuple
    target_um: float | None
    noise_um: float
    travel: TravelModel
    seconds: dict = field(default_factory=dict)
    reach: object = None
    checks: object = None

    def __repr__(self) -> str:
        return (f"Plan({len(self.obs)} alignments of {len(self.candidates.obs)} candidates, U {self.u_tool_um:.3g} µm "
                f"(k=2), {self.order.total_s / 60:.1f} min)")


def volume_weight(J_volume_um: np.ndarray) -> np.ndarray:
    """``W`` of the tool-point target: mean of J_vᵀJ_v over the volume's poses (J unwhitened, µm per unit)."""
    X = J_volume_um.reshape(-1, J_volume_um.shape[2])
    return X.T @ X / len(J_volume_um)


def tool_point_u_um(J: np.ndarray, W: np.ndarray, index, noise_um: float, volume=None) -> tuple[float, float]:
    """(U k=2 per coordinate RMS over the volume, the same at the worst volume pose), µm, for the plan ``index``
    (``J`` whitened, ``W`` from :func:`volume_weight` of the unwhitened volume Jacobian ``J·σ``; the volume's
    whitened Jacobian is ``volume``, default ``J``)."""
    X = J[index].reshape(-1, J.shape[2])
    try:
        Minv = np.linalg.inv(X.T @ X)
    except np.linalg.LinAlgError:
        return float("inf"), float("inf")
    mean = float(np.trace(Minv @ W))
    Jv = (J if volume is None else volume) * noise_um
    per_pose = ((Jv.reshape(-1, Jv.shape[2]) @ Minv) * Jv.reshape(-1, Jv.shape[2])).reshape(len(Jv), -1).sum(axis=1)
    return 2.0 * np.sqrt(max(mean, 0.0) / 3.0), 2.0 * np.sqrt(max(float(per_pose.max()), 0.0) / 3.0)


def detect_power(J_model: np.ndarray, J_effect: np.ndarray, size: float, alpha: float) -> float:
    """Power of the diagnosis's test (its F test, σ estimated from the residuals) to detect an effect of
    parameter-vector norm ``size`` (its unit) at its least detectable phase, given the model (both Jacobians
    whitened, rows of the plan only)."""
    from scipy.special import fdtri, ncfdtr

    A = np.concatenate([J_model, J_effect], axis=2).reshape(-1, J_model.shape[2] + J_effect.shape[2])
    M = A.T @ A
    k = J_effect.shape[2]
    dof = A.shape[0] - A.shape[1]
    if dof < 1:
        return 0.0
    try:
        inv_ee = np.linalg.inv(M)[-k:, -k:]
    except np.linalg.LinAlgError:
        return 0.0
    lam = size**2 / max(float(np.linalg.eigvalsh(inv_ee).max()), 1e-300)
    return float(1.0 - ncfdtr(k, dof, lam, fdtri(k, dof, 1.0 - alpha)))


def covariance_if_added(A: np.ndarray, index, k: int) -> np.ndarray:
    """The covariance (candidates, k, k) of the last ``k`` columns of ``A`` (candidates, 3, P) fitted over the rows
    ``index``, were each candidate's three rows added to them (a rank-3 update of the information, whitened rows)."""
    X = A[index].reshape(-1, A.shape[2])
    Minv = np.linalg.pinv(X.T @ X)
    B = A @ Minv  # (N, 3, P)
    G = A @ B.transpose(0, 2, 1) + np.eye(3)
    Be = B[:, :, -k:]
    return Minv[-k:, -k:] - Be.transpose(0, 2, 1) @ np.linalg.solve(G, Be)


def _terms(J, names, noise_um, target_um, param_targets):
    """(weight matrix, φ target, label) of each target, φ ≤ target meaning met."""
    terms = []
    if target_um is not None:
        terms.append((volume_weight(J * noise_um), 3.0 * (target_um / 2.0) ** 2, "tool point"))
    for name, u in (param_targets or {}).items():
        if name not in names:
            raise DataError(f"parameter {name!r} is not one the candidates can determine ({', '.join(names)})",
                            parameter="param")
        E = np.zeros((len(names), len(names)))
        j = names.index(name)
        E[j, j] = 1.0
        terms.append((E, (u / 2.0) ** 2, name))
    return terms


#: Singular values below this share of the largest leave a direction undetermined (a plan of too few alignments).
DETERMINED_TOL = 1e-9


def _check_determined(X, count: int, names) -> None:
    """Refuse a plan of ``count`` alignments (rows ``X`` of the scaled Jacobian) that leaves any of the model's
    parameters ``names`` undetermined: its promise would be a number only the prior could keep."""
    s = np.linalg.svd(X, compute_uv=False) if X.size else np.zeros(0)
    rank = int(np.sum(s > DETERMINED_TOL * s.max())) if s.size and s.max() > 0 else 0
    if rank < len(names):
        need = -(-len(names) // 3)
        raise DataError(f"{count} alignment{'s' if count != 1 else ''} cannot determine the model's {len(names)} "
                        f"parameters (rank {rank} of {len(names)}); a plan needs at least {need} alignments of 3 "
                        f"readings each, usually more: give a larger --count or a --target-um", parameter="count")


def plan_measurement(machine: Machine, candidates: Observations, *, effects=None, noise_um: float = NOISE_UM,
                     target_um: float | None = None, param_targets: dict | None = None, count: int | None = None,
                     detect: dict | None = None, detect_um: float | None = None, power: float = 0.9, travel: TravelModel = TravelModel(),
                     blocks: int | None = None, reference: bool = True, drift_checks: int | None = None,
                     advice_pool: Observations | None = None, max_count: int = 2000) -> Plan:
    """The fewest candidates that meet the targets, ordered for machine time (module docstring).

    Parameters
    ----------
    machine : Machine
    candidates : Observations
        From :func:`candidate_poses`.
    effects : sequence of Effect, optional
        The model to identify (default: the default model). Effects driven by time or by the approach
        direction are for the order, not the choice of poses, and are refused.
    noise_um : float
        σ of one reading, µm.
    target_um : float, optional
        Tool point: expanded uncertainty (k = 2) per coordinate, RMS over the volume, µm.
    param_targets : dict name -> U (k = 2, the parameter's unit), optional
    count : int, optional
        A fixed number of alignments instead of targets.
    detect : dict effect name -> size, optional
        Effects the diagnosis must detect at this size (norm of the parameter vector) with ``power``.
    detect_um : float, optional
        Every error the model lacks (the diagnosis's candidates) that leaves this much at the tool (2·RMS per
        coordinate over the candidates' poses of what the model cannot absorb, µm, the target's scale) detected
        with ``power`` (:mod:`~kinid.identification.planning.reach`): the plan of a model that may grow.
    travel : TravelModel
    blocks, reference
        See :func:`~kinid.identification.planning.order.order_for_time`.
    drift_checks : int, optional
        Readings of the reference alignment (the run's first) over the run (0: only the blocks' references; default:
        the fewest that detect, with ``power``, a time effect that would move the cold machine's prediction by
        ``detect_um``, else twice ``target_um``: :mod:`~kinid.identification.planning.drift`).
    advice_pool : Observations, optional
        Poses beyond the candidates to advise from for parameters the candidates cannot determine.
    """
    import time as _time

    from ..model import basis_of
    from ..model import check_effects, default_model
    from .advice import pose_advice
    from .design import criterion, relaxation_bound, select, trim

    started = _time.perf_counter()
    effects = tuple(default_model(machine)) if effects is None else check_effects(machine, effects)
    timed = [e.name for e in effects if basis_of(e).driver in ("time", "direction")]
    if timed:
        raise DataError(f"{', '.join(timed)} depend on time or on the approach direction, which the order settles, "
                        f"not the choice of poses: plan without them (the order keeps time apart from the axes)",
                        parameter="add")
    if count is None and target_um is None and not param_targets:
        raise DataError("give a target (--target-um or --param NAME=U) or a --count", parameter="target_um")
    J, names, held = candidate_jacobian(machine, effects, candidates, noise_um)
    terms = _terms(J, names, noise_um, target_um, param_targets)
    W = sum(Wi / ti for Wi, ti, _ in terms) if terms else volume_weight(J * noise_um)

    def enough(index):
        return all(criterion(J, Wi, index) <= ti for Wi, ti, _ in terms)

    sel = select(J, W, count=count, enough=enough if terms else None, max_count=max_count)
    index = sel.index
    if count is None:
        if not enough(index):
            raise DataError(f"the targets are out of reach with {len(index)} of the {len(candidates)} candidates: "
                            f"ask less, give more candidates, or a lower --noise-um", parameter="target_um")
        index = trim(J, W, index, enough)
    else:
        _check_determined(J[index].reshape(-1, J.shape[2]), len(index), names)
    t_design = _time.perf_counter() - started
    powers = {}
    if detect:
        index, powers = _keep_detectable(machine, effects, candidates, J, index, detect, noise_um, power)
    reach = None
    if detect_um is not None:
        from .reach import keep_reach, probes_of

        probes, library = probes_of(machine, effects, candidates, J, noise_um)
        index, reach = keep_reach(J, index, probes, library, detect_um, power, ALPHA, max(max_count - len(index), 0))
    bound_W = relaxation_bound(J, W)[0]  # with one target, W is its weight over its φ target
    bounds = [bound_W] if len(terms) == 1 else [relaxation_bound(J, Wi)[0] / ti for Wi, ti, _ in terms]
    bound_count = int(np.ceil(max(bounds) - 1e-9)) if bounds and count is None else 0
    linear, wraps = axis_motion(machine)
    chosen = candidates.subset(index)
    order = order_for_time(chosen.axes, machine.axis_names, linear, wraps, travel, blocks=blocks, reference=reference)
    checks = None
    if reference and drift_checks != 0:
        from .drift import drift_checks as keep_checks

        size = detect_um if detect_um is not None else (2.0 * target_um if target_um is not None else None)
        order, checks = keep_checks(machine, effects, chosen, J[index], J, order, chosen.axes, linear, wraps, travel,
                                    machine.axis_names, noise_um=noise_um, size_um=size, power=power,
                                    alpha_total=ALPHA, count=drift_checks)
    efficiency = bound_W / len(order.index) / criterion(J, W, index[order.index])
    obs = replace(chosen.subset(order.index), t_s=order.t_s, lines=(), source="<plan>")
    rows = index[order.index]  # the reference repeats teach too
    u, worst = tool_point_u_um(J, volume_weight(J * noise_um), rows, noise_um)
    X = J[rows].reshape(-1, J.shape[2])
    Minv = np.linalg.inv(X.T @ X)
    u_params = {n: (2.0 * float(np.sqrt(Minv[names.index(n), names.index(n)])), t) for n, t in (param_targets or {}).items()}
    advice = pose_advice(machine, effects, chosen, advice_pool, held, noise_um, travel) if advice_pool is not None else ()
    seconds = {"design": t_design, "total": _time.perf_counter() - started}
    pool = Candidates(candidates, J, names, held, f"{len(candidates)} candidate alignments")
    return Plan(obs, index, pool, u, worst, u_params, bound_count, float(efficiency), powers, order, held, advice,
                target_um, noise_um, travel, seconds, reach, checks)


def _keep_detectable(machine, effects, candidates, J, index, detect, noise_um, power):
    """Add candidates until every effect of ``detect`` reaches ``power`` at its size (weakest effect first)."""
    from ..model import candidate_library, parse_effect
    from ..fitting import design, residuals

    library = len(candidate_library(machine, effects, has_directions=False, has_time=True))
    alpha = ALPHA / max(library, 1)
    blocks = {}
    have = {e.name for e in effects}
    for name, size in detect.items():
        e = parse_effect(name, machine, source="--detect")
        if e.name in have:
            raise DataError(f"{e.name} is in the model: it is identified, not detected", parameter="detect")
        d = design(machine, [e], candidates)
        _, Je, _ = residuals(machine, d, candidates, np.zeros(d.n_params))
        blocks[name] = (Je / noise_um, float(size))
        best = detect_power(J, blocks[name][0], float(size), alpha)
        if best < power:
            raise DataError(f"{name} at size {size:g}: even all {len(candidates)} candidates detect it with probability "
                            f"{best:.2f} only (below {power:g}); ask a larger size, more candidates or a lower "
                            f"--noise-um", parameter="detect")
    index = list(index)
    for _ in range(len(candidates)):
        powers = {n: detect_power(J[index], Je[index], s, alpha) for n, (Je, s) in blocks.items()}
        weakest = min(powers, key=powers.get)
        if powers[weakest] >= power:
            return np.array(index, int), {n: (blocks[n][1], p) for n, p in powers.items()}
        Je, s = blocks[weakest]
        new_ee = covariance_if_added(np.concatenate([J, Je], axis=2), index, Je.shape[2])
        score = -np.linalg.eigvalsh(new_ee)[:, -1]
        score[index] = -np.inf
        index.append(int(np.argmax(score)))
    raise DataError("the effects asked for cannot be made detectable with these candidates", parameter="detect")
