"""The fit's start: the measurement frame (and the measured point on the tool) in closed form.

The set-up of the measurement frame (the six joints ``E?0W``) is the one part of a model whose values may be
large: a laser tracker stands metres from a robot and is turned any way. From zero, the Levenberg–Marquardt
iterations then start metres and tens of degrees away, where the linearised model is far from the true one,
and may end on a non-physical solution. Here the frame is estimated first, in closed form:

1. the points the model predicts at the current values (``p``, the tool point in the frame the model has now)
   are matched to the measured points ``w`` by the rigid transform ``w ≈ R p + t`` of least squares (Kabsch
   1976, Umeyama 1991: the SVD of the cross-covariance, with the sign of the smallest singular direction
   turned where a reflection would fit better); rows whose distance after it is beyond :data:`TRIM_MADS`
   median absolute deviations above the median are left out and the transform fitted once more (gross
   errors must not turn the frame);
2. the transform is put into the six set-up joints: with ``S`` the set-up's placement (translations, then
   rotations, in the chain's order), the model's point is ``S⁻¹ p₀``, so ``S ← S · [R, t]⁻¹``, its rotation
   split into the set-up's three angles in their chain order;
3. where the tool point's set-up translations ``E[XYZ]0T`` are in the model (one constant each, or one per
   target where several are measured at each pose, ``EX0T:target:T2``), the frame and the point(s) on the
   tool are first solved at once (:func:`frame_and_tool`: ``Rᵀ (w − t) = p + G s`` is linear in ``Rᵀ`` taken as
   any matrix, ``Rᵀ t`` and the point's move ``s``; the matrix then turned into the nearest rotation), and then
   alternately: the point on the tool by linear least squares in the frame of 1.–2. (the point is affine in
   them), and 1.–2. again, :data:`ROUNDS` rounds at most, ending with the frame (alternating alone converges
   slowly where the poses span little: 11 mm left after 4 rounds on 25 poses within ±30°, 0.25 mm with the
   joint solve first).

The model's own forward kinematics then checks the start: the points it predicts at the start must be the
rigid transform's (within :data:`AGREE_MM`), or there is no start (a URDF whose set-up joints are in
another order than this module reads). The fit uses the start only where the frame turns by more than
:data:`TURN_RAD` (a smaller turn the iterations take from zero as they always did: set-ups of machine tools
fit as before) and where the start's cost is below the current one (measured, not assumed).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, replace

import numpy as np

from ..model import Machine, evaluate, rigid_transform
from ..data import Observations
from .residuals import Design, joint_values

__all__ = ["Start", "closed_form_start", "frame_and_tool", "frame_turn_rad", "rigid_transform", "robust_rigid_transform", "turn_rad",
           "TRIM_MADS", "ROUNDS", "TURN_RAD", "AGREE_MM"]

#: Rows farther from the rigid transform than the median distance plus this many scaled median absolute
#: deviations (1.4826 × MAD: σ for normal data) are left out of the refit: gross errors, not noise (for 3-D
#: normal residuals the bound is about 6 σ, which clean data do not reach).
TRIM_MADS = 5.0
#: Rounds of frame, then point on the tool, at most.
ROUNDS = 4
#: A tool point moving less than this in a round ends the rounds, mm.
TOOL_STEP_MM = 1e-4
#: The start is used where the measurement frame turns by more than this, rad (0.01 rad: the linearised
#: model's error at 1 m is then below 50 µm, which the iterations take from zero).
TURN_RAD = 0.01
#: The model's points at the start must be the rigid transform's within this, mm.
AGREE_MM = 1e-4
#: A point cloud whose second singular value is below this share of its first is a line: it does not fix a turn.
FLAT_SHARE = 1e-6


@dataclass(frozen=True)
class Start:
    """A start of the fit with the measurement frame (and the point on the tool) in closed form.

    Attributes
    ----------
    theta : array (P,)
        The parameters at the start: the set-up's estimated, the others as they were.
    rotation : array (3, 3)
        ``R`` of the last rigid transform ``w = R p + t`` (the measured points from the model's).
    translation_mm : array (3,)
        ``t``, mm.
    turn_rad : float
        The angle of the measurement frame's turn from where it was, rad (over all rounds).
    shift_mm : float
        How far the frame's origin moved from where it was, mm (over all rounds).
    rms_um : float
        RMS of the residual components at ``theta``, µm: the rigid transform's over all rows.
    trimmed : int
        Rows left out of the last rigid fit as gross errors.
    rounds : int
        Rounds of frame and point on the tool.
    tool_moved_mm : float
        How far the point on the tool moved from where it was, mm (0 without ``E[XYZ]0T`` in the model).
    """

    theta: np.ndarray
    rotation: np.ndarray
    translation_mm: np.ndarray
    turn_rad: float
    shift_mm: float
    rms_um: float
    trimmed: int
    rounds: int
    tool_moved_mm: float = 0.0

    def describe(self) -> str:
        """One line: what the start estimated."""
        tool = f", the point on the tool moved {self.tool_moved_mm:.4g} mm" if self.tool_moved_mm > 0 else ""
        trimmed = f", {self.trimmed} rows left out as gross errors" if self.trimmed else ""
        return (f"started from the measurement frame fitted as a rigid transform (turned "
                f"{np.degrees(self.turn_rad):.4g}°, moved {self.shift_mm:.4g} mm{tool}{trimmed}; residual RMS "
                f"{self.rms_um:.4g} µm)")


def robust_rigid_transform(p_mm, w_mm, *, trim_mads: float = TRIM_MADS) -> tuple:
    """:func:`rigid_transform`, refitted once without the rows farther than the median distance plus
    ``trim_mads`` scaled MADs.

    Returns
    -------
    R, t_mm
    keep : array (N,) of bool
        The rows of the last fit.
    """
    p, w = np.asarray(p_mm, float), np.asarray(w_mm, float)
    R, t = rigid_transform(p, w)
    dist = np.linalg.norm(p @ R.T + t - w, axis=1)
    med = np.median(dist)
    keep = dist <= med + trim_mads * 1.4826 * np.median(np.abs(dist - med))
    if keep.all() or keep.sum() < 3 or _flat(p[keep]):
        return R, t, np.ones(len(p), bool)
    R, t = rigid_transform(p[keep], w[keep])
    return R, t, keep


def turn_rad(p_mm, w_mm) -> float:
    """The angle of :func:`robust_rigid_transform`'s rotation from ``p_mm`` to ``w_mm``, rad (0 where the points
    do not fix a turn): how far the measured points' frame is turned from the model's."""
    p = np.asarray(p_mm, float)
    if _flat(p) or not np.all(np.isfinite(p)):
        return 0.0
    R = robust_rigid_transform(p, w_mm)[0]
    return float(np.arccos(np.clip((np.trace(R) - 1) / 2, -1.0, 1.0)))


def frame_turn_rad(obs: Observations, r_um) -> float:
    """:func:`turn_rad` of the points of ``obs`` (its orientation rows left out) from where the model puts them (the
    residuals ``r_um`` (N, 3) away) to where they were measured."""
    points = ~obs.rotation_rows
    return turn_rad(obs.w_mm[points] + r_um[points] * 1e-3, obs.w_mm[points])


def frame_and_tool(p_mm, G, w_mm) -> tuple | None:
    """The rigid transform ``w ≈ R p' + t`` and the move ``s`` of the point on the tool that make the model's
    points ``p' = p + G s`` the measured ones, at once: ``Rᵀ (w − t) = p + G s`` is linear in ``Q = Rᵀ`` (taken as
    any 3 × 3 matrix), ``q = −Rᵀ t`` and ``s`` (``Q w + q − G s = p``); ``Q`` is then turned into the nearest
    rotation and ``t`` and ``s`` solved again with it.

    Parameters
    ----------
    p_mm : array (N, 3)
        The model's points, mm.
    G : array (N, 3, k)
        Their derivatives with respect to the point on the tool's translations (mm per mm).
    w_mm : array (N, 3)
        The measured points, mm.

    Returns
    -------
    (R, t_mm, s_mm) or None
        None where the measured points lie in a plane (Q is then not determined).
    """
    p, w = np.asarray(p_mm, float), np.asarray(w_mm, float)
    n, k = len(p), G.shape[2]
    wc = w - w.mean(axis=0)
    sv = np.linalg.svd(wc, compute_uv=False)
    if n < 5 or not sv[2] > FLAT_SHARE * sv[0]:
        return None
    A = np.zeros((n, 3, 12 + k))
    for r in range(3):
        A[:, r, 3 * r:3 * r + 3] = wc
        A[:, r, 9 + r] = 1.0
    A[:, :, 12:] = -G
    x = np.linalg.lstsq(A.reshape(3 * n, -1), p.ravel(), rcond=None)[0]
    U, _, Vt = np.linalg.svd(x[:9].reshape(3, 3))
    R = (U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0]) @ Vt).T
    # with R: w − R G s − t = R p, linear in t and s
    B = np.zeros((n, 3, 3 + k))
    B[:, :, :3] = np.eye(3)
    B[:, :, 3:] = np.einsum("ij,njk->nik", R, G)
    y = np.linalg.lstsq(B.reshape(3 * n, -1), (w - p @ R.T).ravel(), rcond=None)[0]
    return R, y[:3], y[3:]


def _flat(p) -> bool:
    """The points lie on a line (or a point): a rigid transform's turn about it is not determined."""
    if len(p) < 3:
        return True
    s = np.linalg.svd(p - p.mean(axis=0), compute_uv=False)
    return not s[1] > FLAT_SHARE * s[0]


@dataclass(frozen=True)
class _Setup:
    """The set-up's parameters in ``theta``: per joint in chain order, its parameter and the basis value."""

    translations: tuple  # (parameter, basis value, unit axis index) of E[XYZ]0W in chain order
    rotations: tuple  # (parameter, basis value, axis letter) of E[ABC]0W in chain order


def _single_constants(machine: Machine, d: Design, axis: str, letters: str, free) -> dict:
    """Error-joint code -> (parameter, basis value, joint) for the location joints ``E<letter>0<axis>`` that carry
    exactly one parameter of ``d``, constant over the rows and free."""
    out = {}
    for j in np.unique(d.joint_index):
        joint = machine.error_joints[j]
        if joint.axis != axis or not joint.location or joint.direction not in letters:
            continue
        params = np.flatnonzero(d.joint_index == j)
        column = d.basis[:, params[0]] if len(params) == 1 else None
        if column is None or not free[params[0]] or not column.size or not column[0] != 0:
            continue
        if np.all(column == column[0]):
            out[joint.code] = (int(params[0]), float(column[0]), joint)
    return out


def _frame_setup(machine: Machine, d: Design, free) -> _Setup | None:
    """The measurement frame's six set-up parameters, translations before rotations in the chain; None if the
    model lacks one (or holds one) or the chain puts a rotation before a translation."""
    found = _single_constants(machine, d, "W", "XYZABC", free)
    if len(found) != 6:
        return None
    ordered = sorted(found.values(), key=lambda f: f[2].q_index)
    if any(f[2].kind != "prismatic" for f in ordered[:3]):
        return None
    return _Setup(tuple((k, b, "XYZ".index(jt.direction)) for k, b, jt in ordered[:3]),
                  tuple((k, b, "XYZ"["ABC".index(jt.direction)]) for k, b, jt in ordered[3:]))


def _placement(setup: _Setup, theta) -> tuple:
    """(rotation, translation mm) of the set-up at ``theta``."""
    from scipy.spatial.transform import Rotation

    e = np.zeros(3)
    for k, b, i in setup.translations:
        e[i] = theta[k] * b * 1e-3
    seq = "".join(letter for _, _, letter in setup.rotations)
    angles = [theta[k] * b * 1e-6 for k, b, _ in setup.rotations]
    return Rotation.from_euler(seq, angles).as_matrix(), e


def _with_placement(setup: _Setup, theta, R_s, e_mm) -> np.ndarray:
    """``theta`` with the set-up's parameters at the placement (R_s, e_mm)."""
    from scipy.spatial.transform import Rotation

    theta = theta.copy()
    for k, b, i in setup.translations:
        theta[k] = e_mm[i] * 1e3 / b
    seq = "".join(letter for _, _, letter in setup.rotations)
    with warnings.catch_warnings():  # a gimbal lock still gives angles of this placement
        warnings.simplefilter("ignore", UserWarning)
        angles = Rotation.from_matrix(R_s).as_euler(seq)  # upper case: about the turned axes, as a chain turns
    for (k, b, _), a in zip(setup.rotations, angles):
        theta[k] = a * 1e6 / b
    return theta


def _frame_round(machine, d, obs, setup: _Setup, theta, tool_columns):
    """One rigid fit of the frame at ``theta``: (theta with the frame, p, G, R, t, keep), or None where the
    points do not fix a turn. ``G`` (N, 3, k): the points' columns of ``tool_columns`` (None without them)."""
    values = joint_values(machine, d, theta)
    G = None
    if tool_columns:
        p, G, _ = evaluate(machine, obs.axes, values, offsets_mm=obs.offsets_mm, error_columns=tool_columns,
                           axes_jacobian=False)
    else:
        p = evaluate(machine, obs.axes, values, jacobian=False, offsets_mm=obs.offsets_mm)
    if _flat(p):
        return None
    R, t, keep = robust_rigid_transform(p, obs.w_mm)
    R_s, e_s = _placement(setup, theta)
    # the model's point is S⁻¹ p₀; the measured one R S⁻¹ p₀ + t = (S [R, t]⁻¹)⁻¹ p₀
    return _with_placement(setup, theta, R_s @ R.T, e_s - R_s @ R.T @ t), p, G, R, t, keep


def _tool_setup(machine: Machine, d: Design, free, aliases) -> tuple:
    """The point on the tool's set-up translations ``E[XYZ]0T`` the start estimates, in chain order, as
    (parameter, basis value, joint): a joint's parameters each one value on the rows it is on and 0 elsewhere
    (one constant; or one per target, ``EX0T:target:T2``, where several targets are measured at each pose);
    and, for those held, where their value goes: parameter -> ((the free parameter it aliases with, c), …), the
    data seeing ``partner + c · held`` (a held ``EZ0T`` beside ``EZ0J6``, the same line: its value is the
    partner's; a held ``EZ0T:target:T3``'s goes to ``EZ0J6``, the other targets' ``EZ0T:target:…`` moving back by
    as much: their rows unmoved)."""
    names = d.param_names()
    tool, moves = [], {}
    for j in np.unique(d.joint_index):
        joint = machine.error_joints[j]
        if joint.axis != "T" or not joint.location or joint.direction not in "XYZ":
            continue
        params = np.flatnonzero(d.joint_index == j)
        levels = [np.unique(d.basis[:, k][d.basis[:, k] != 0]) for k in params]
        if any(v.size != 1 for v in levels):
            continue
        shares = d.basis[:, params] / np.array([v[0] for v in levels])
        if len(params) > 1 and not np.all(shares.sum(axis=1) == 1.0):
            continue  # several, and not one per row (each target's rows): no move of a held one is exact
        for k, v in zip(params, levels):
            k, b = int(k), float(v[0])
            if free[k]:
                tool.append((k, b, joint))
                continue
            alias = next((a for a in aliases if a.name == names[k]), None)
            # one partner; or, of several targets' (the other targets' points move back), all of them free
            if alias is not None and alias.kind == "aliased" and (len(alias.partners) == 1 or len(params) > 1):
                partners = tuple((names.index(n), c) for n, c in alias.partners)
                if all(free[p] for p, _ in partners):
                    tool.append((k, b, joint))
                    moves[k] = partners
    return sorted(tool, key=lambda f: f[2].q_index), moves


def _tool_columns(machine: Machine, d: Design, tool) -> tuple:
    """(the error joints of ``tool``, once each; f(G) the points' derivatives (N, 3, len(tool)) with respect to
    each parameter's move in mm, from G (N, 3, joints) of the joints')."""
    columns = sorted({machine.error_joints.index(jt) for _, _, jt in tool})
    at = [columns.index(machine.error_joints.index(jt)) for _, _, jt in tool]
    share = d.basis[:, [k for k, _, _ in tool]] / np.array([b for _, b, _ in tool])  # 1 on a parameter's rows

    def per_parameter(G):
        return G[:, :, at] * share[:, None, :]
    return columns, per_parameter


def closed_form_start(machine: Machine, d: Design, obs: Observations, theta, *, free=None,
                      aliases=()) -> Start | None:
    """The measurement frame (and the point on the tool) fitted in closed form from ``theta`` (module docstring).

    Parameters
    ----------
    machine : Machine
    d : Design
        The model's design on ``obs``.
    obs : Observations
        The measured points ``obs.w_mm`` (with their offsets on the tool, if any).
    theta : array (P,)
        The parameters to start from (the measured points are matched to the model's points at them).
    free : array (P,) of bool, optional
        The parameters the fit may move (default all): a held set-up parameter stays as it is.
    aliases : tuple of Alias
        What the held parameters alias with (:func:`~kinid.identification.fitting.identifiability.analyse`): a
        held translation of the point on the tool with one free partner is estimated and put on the partner.

    Returns
    -------
    Start or None
        None where the model has not the six set-up joints of the measurement frame, each with one constant
        free parameter; where the points do not fix a turn (fewer than 3, or on a line); or where the model's
        forward kinematics does not reproduce the rigid transform at the start.
    """
    theta = np.asarray(theta, float).copy()
    free = np.ones(len(theta), bool) if free is None else np.asarray(free, bool)
    setup = _frame_setup(machine, d, free)
    if obs.rotation_rows.any():  # the points' rows: the orientation's are no points (its check starts here)
        points = ~obs.rotation_rows
        d, obs = replace(d, basis=d.basis[points]), obs.subset(points)
    w = obs.w_mm
    if setup is None or len(obs) < 3 or not np.all(np.isfinite(obs.axes)):
        return None
    tool, moves = _tool_setup(machine, d, free, aliases)
    tool_columns, per_parameter = _tool_columns(machine, d, tool)
    R0, e0 = _placement(setup, theta)
    tool_moved_mm = np.zeros(len(tool))
    settled = not tool

    def move_tool(step_mm):
        for (k, b, _), s in zip(tool, step_mm):
            theta[k] += s * 1e3 / b
        for k, partners in moves.items():  # a held one's value onto the free parameters that carry it
            for partner, c in partners:
                theta[partner] += c * theta[k]
            theta[k] = 0.0
        tool_moved_mm[:] += step_mm

    if tool:  # frame and point on the tool at once, linear: the rounds then start near both
        p, G, _ = evaluate(machine, obs.axes, joint_values(machine, d, theta), offsets_mm=obs.offsets_mm,
                           error_columns=tool_columns, axes_jacobian=False)
        joint = frame_and_tool(p, per_parameter(G), w)
        if joint is not None:
            R, t, step_mm = joint
            R_s, e_s = _placement(setup, theta)
            theta = _with_placement(setup, theta, R_s @ R.T, e_s - R_s @ R.T @ t)
            move_tool(step_mm)
    for rounds in range(1, ROUNDS + 1):
        with_tool = not settled and rounds < ROUNDS
        step = _frame_round(machine, d, obs, setup, theta, tool_columns if with_tool else None)
        if step is None:
            return None
        theta, p, G, R, t, keep = step
        if not with_tool:
            break
        # the point on the tool in the new frame: the residual R p + t − w, its columns R G (mm per mm)
        r = p @ R.T + t - w
        J = np.einsum("ij,njk->nik", R, per_parameter(G))[keep].reshape(-1, len(tool))
        step_mm = np.linalg.lstsq(J, -r[keep].ravel(), rcond=None)[0]
        move_tool(step_mm)
        settled = bool(np.max(np.abs(step_mm)) < TOOL_STEP_MM)
    at_start = evaluate(machine, obs.axes, joint_values(machine, d, theta), jacobian=False, offsets_mm=obs.offsets_mm)
    if not np.all(np.abs(at_start - (p @ R.T + t)) <= AGREE_MM):
        return None  # the set-up joints are not in the order read here: no start
    R_s, e_s = _placement(setup, theta)
    turn = R0.T @ R_s
    return Start(theta=theta, rotation=R, translation_mm=t,
                 turn_rad=float(np.arccos(np.clip((np.trace(turn) - 1) / 2, -1.0, 1.0))),
                 shift_mm=float(np.linalg.norm(e_s - e0)),
                 rms_um=float(np.sqrt(np.mean((at_start - w) ** 2))) * 1e3, trimmed=int(np.sum(~keep)),
                 rounds=rounds, tool_moved_mm=float(np.linalg.norm(tool_moved_mm)))
