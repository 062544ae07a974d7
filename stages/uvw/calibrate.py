"""Calibrate a UVW stage with the model of :mod:`stages.uvw.model` (docs/hardware.md).

Test plan (per actuator, ISO 230-2 style): ``points`` positions evenly spread
over ``span_um`` (default ± max(1.5 leads, 2000 µm), so the positions fall on many phases of
the lead), visited in a forward sweep and a reverse sweep, each sweep entered
with an overrun so that every position is approached with the play taken up;
``repeats`` times. The fitted model is inverted by the compensator.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from kinid.checks import check_int, check_positive
from kinid.errors import DataError, StageError
from kinid.progress import Progress

from .compensator import DirectionTrackingCompensator
from .kinematics import ACTUATORS, Strokes, check_actuator, check_lead, forward_kinematics, inverse_kinematics
from .model import fit_actuator_model, select_actuator_model

__all__ = ["UVWCompensator", "plan_positions", "measure_plan", "calibrate", "alignment_targets",
           "run_moves", "run_stage_moves", "home_forward"]


def _check_span(span_um, lead):
    half = max(1.5 * lead, 2000.0)
    lo, hi = (-half, half) if span_um is None else (float(span_um[0]), float(span_um[1]))
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise DataError(f"span_um must be (low, high) with high > low, µm, got {span_um!r}")
    if hi - lo < lead:
        raise DataError(f"span_um {lo:g}..{hi:g} µm is shorter than one lead ({lead:g} µm); "
                         "the periodic lead error cannot be separated")
    return lo, hi


def plan_positions(lead_um: float, span_um=None, points: int = 37):
    """Commanded positions of the test plan, µm.

    Parameters
    ----------
    lead_um : float
        Screw lead, µm.
    span_um : (float, float) or None
        Range to cover, µm (default ± max(1.5 leads, 2000 µm)).
    points : int
        Number of positions (default 37: over ±1.5 leads, 12 phases per lead);
        raised if the positions would fall on fewer than 8 phases of the lead.

    Returns
    -------
    numpy.ndarray, shape (points,)
    """
    lead = check_lead(lead_um)
    lo, hi = _check_span(span_um, lead)
    n = check_int("points", points, minimum=8)
    # Positions must fall on many phases of the lead; add points until they do (no aliasing).
    for _ in range(64):
        positions = np.linspace(lo, hi, n)
        phases = np.unique(np.round(np.mod(positions / lead, 1.0) * 100.0) % 100.0)
        if phases.size >= min(8, n):
            break
        n += 1
    return positions


def measure_plan(move, actuator: str, positions_um, *, repeats: int = 3, overrun_um: float = 100.0,
                 progress=None):
    """Run the bidirectional test plan on one actuator.

    Parameters
    ----------
    move : callable
        ``move(actuator, target_um) -> measured_um``.
    actuator : str
        ``"X1"``, ``"X2"`` or ``"Y"``.
    positions_um : array_like
        Positions to visit (ascending), µm.
    repeats : int
        Bidirectional sweeps.
    overrun_um : float
        Distance beyond the first position of each sweep from which it is
        entered, µm; must exceed the backlash.
    progress : Progress or None
        Updated once per measurement.

    Returns
    -------
    commands_um, directions, measured_um : numpy.ndarray
        One entry per measurement. The actuator ends at home, approached forward.
    """
    check_actuator(actuator)
    p = np.sort(np.asarray(positions_um, dtype=float))
    repeats = check_int("repeats", repeats, minimum=1)
    overrun_um = check_positive("overrun_um", overrun_um)
    cmds, dirs, meas = [], [], []
    for _ in range(repeats):
        for direction, seq in ((1, p), (-1, p[::-1])):
            move(actuator, seq[0] - direction * overrun_um)
            for c in seq:
                cmds.append(c)
                dirs.append(direction)
                meas.append(move(actuator, c))
                if progress is not None:
                    progress.update()
    home_forward(move, actuator, overrun_um)
    return np.array(cmds), np.array(dirs, dtype=float), np.array(meas, dtype=float)


def home_forward(move, actuator: str, overrun_um: float = 100.0) -> float:
    """Bring ``actuator`` to home approached forward (the compensators' start state); return the reading, µm."""
    move(actuator, -overrun_um)
    return move(actuator, 0.0)


class UVWCompensator(DirectionTrackingCompensator):
    """Inverts the fitted actuator models: ``command(actuator, target_um) -> command_um``.

    Parameters
    ----------
    models : dict
        ``{"X1": ActuatorModel, ...}``.
    tol_um : float
        Newton tolerance of the inversion, µm.
    max_iter : int
        Newton iterations at most.

    Attributes
    ----------
    models : dict
        The fitted models (values, standard deviations, residuals).
    moves : int
        Moves the calibration made (0 if built directly).
    """

    def __init__(self, models: dict, *, tol_um: float = 1e-9, max_iter: int = 50, moves: int = 0):
        self.models = dict(models)
        for name in self.models:
            check_actuator(name)
        self.tol_um = tol_um
        self.max_iter = max_iter
        self.moves = moves
        super().__init__(tuple(self.models))

    def _command_for(self, actuator, target_um, direction):
        m = self.models[actuator]
        lo, hi = m.span_um
        margin = 0.5 * m.lead_um
        if not (lo - margin <= target_um <= hi + margin):
            warnings.warn(f"target {target_um:g} µm of {actuator} is outside the calibrated span "
                          f"{lo:g}..{hi:g} µm; the compensation is extrapolated", stacklevel=3)
        return m.command_for(target_um, direction, tol_um=self.tol_um, max_iter=self.max_iter)


def calibrate(stage, lead_um: float, *, span_um=None, points: int = 37, repeats: int = 3, harmonics=None,
              degree=None, overrun_um: float = 100.0, noise_um=None, actuators=ACTUATORS, progress: bool | None = None
              ) -> UVWCompensator:
    """Measure each actuator, fit its error model and return the compensator.

    Parameters
    ----------
    stage : ActuatorStage or callable
        An object with ``move(actuator, target_um) -> measured_um``
        (:class:`kinid.stages.protocols.ActuatorStage`, docs/hardware.md), or
        that ``move`` function itself.
    lead_um : float
        Screw lead of the actuators, µm (> 0).
    span_um : (float, float) or None
        Command range to calibrate, µm (default ± max(1.5 leads, 2000 µm));
        must lie within the stage's travel together with ``overrun_um``.
    points : int
        Positions per sweep.
    repeats : int
        Bidirectional sweeps per actuator.
    harmonics : int or None
        Harmonics of the periodic lead error in the model; None chooses 1 to 4
        by the Bayesian information criterion (:func:`select_actuator_model`).
    degree : int or None
        Polynomial degree of the cumulative lead error (1: scale only); None
        chooses 1 to 3 by the same criterion.
    overrun_um : float
        Reversal overrun before each sweep, µm (larger than the backlash).
    noise_um : float or None
        Known measurement noise for the parameter uncertainties, µm (None:
        estimated from the residuals).
    actuators : sequence of str
        Actuators to calibrate.
    progress : bool or None
        Show a progress line (default: when stderr is a terminal).

    Returns
    -------
    UVWCompensator
        Starts with every actuator at home approached forward, where
        :func:`measure_plan` leaves it.

    Examples
    --------
    >>> from kinid.stages.uvw import SimulatedUVWStage
    >>> stage = SimulatedUVWStage(rng=np.random.default_rng(1))
    >>> comp = calibrate(stage, lead_um=2000.0)                 # doctest: +SKIP
    >>> stage.move("X1", comp.command("X1", 1234.0))            # doctest: +SKIP
    1234.03...
    """
    move = getattr(stage, "move", stage)
    if not callable(move):
        raise StageError(f"stage must have a move(actuator, target_um) method or be such a function, "
                         f"got {type(stage).__name__}")
    lead = check_lead(lead_um)
    names = tuple(check_actuator(a) for a in actuators)
    if not names:
        raise StageError("actuators must name at least one of 'X1', 'X2', 'Y'")
    positions = plan_positions(lead, span_um, points)
    models = {}
    n_moves = 0
    bar = Progress(len(names) * 2 * len(positions) * repeats, "uvw calibration moves", enabled=progress)
    try:
        for name in names:
            counted = _Counting(move)
            try:
                c, d, y = measure_plan(counted, name, positions, repeats=repeats, overrun_um=overrun_um,
                                       progress=bar)
            except StageError as exc:
                raise StageError(f"{exc.message} (calibrating {name} over {positions[0]:g}..{positions[-1]:g} µm "
                                 f"with {overrun_um:g} µm overrun; pass a span_um within the stage's travel)"
                                 ) from exc
            n_moves += counted.n
            if harmonics is not None and degree is not None:
                models[name] = fit_actuator_model(c, d, y, lead, harmonics=harmonics, degree=degree,
                                                  noise_um=noise_um)
            else:
                models[name] = select_actuator_model(c, d, y, lead, harmonics=harmonics, degree=degree,
                                                     noise_um=noise_um)
    finally:
        bar.close()
    return UVWCompensator(models, moves=n_moves)


class _Counting:
    """Wrap a ``move`` callable and count its calls."""

    def __init__(self, move):
        self.move, self.n = move, 0

    def __call__(self, actuator, target_um):
        self.n += 1
        return self.move(actuator, target_um)


def alignment_targets(rng, n: int, *, start_um: float = 0.0, low_um: float = -3000.0, high_um: float = 3000.0,
                      min_move_um: float = 50.0, max_move_um: float = 2000.0):
    """A random sequence of alignment targets: each move 50–2000 µm, either sign, within the range.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    n : int
        Number of moves.
    start_um : float
        Position before the first move, µm.
    low_um, high_um : float
        Targets stay within this range, µm.
    min_move_um, max_move_um : float
        Size range of a move, µm.

    Returns
    -------
    numpy.ndarray, shape (n,)
        Target after each move, µm.
    """
    if not (0 < min_move_um <= max_move_um and high_um - low_um >= 2 * max_move_um and low_um <= start_um <= high_um):
        raise StageError(f"alignment_targets needs 0 < min_move_um <= max_move_um, a range {low_um:g}..{high_um:g} µm "
                         f"at least twice max_move_um ({max_move_um:g} µm) wide and the start inside it")
    out, pos = [], float(start_um)
    for _ in range(n):
        size = rng.uniform(min_move_um, max_move_um)
        sign = 1.0 if rng.random() < 0.5 else -1.0
        if not low_um <= pos + sign * size <= high_um:
            sign = -sign
        pos += sign * size
        out.append(pos)
    return np.array(out)


def run_moves(move, actuator: str, targets_um, compensator=None, *, truth=None, overrun_um: float = 100.0):
    """Drive ``actuator`` through ``targets_um`` from home and return the position errors.

    Parameters
    ----------
    move : callable
        ``move(actuator, target_um) -> measured_um``.
    actuator : str
        Actuator to move.
    targets_um : array_like
        Targets in order, µm.
    compensator : object or None
        Anything with ``command(actuator, target_um)`` and ``reset(actuator)``;
        None sends the targets uncompensated.
    truth : callable or None
        ``truth(actuator) -> true position µm`` (a simulated stage's
        ``true_um``); when given the errors are true, else measured.
    overrun_um : float
        Overrun of the initial homing move, µm.

    Returns
    -------
    numpy.ndarray
        Position minus target after each move, µm.
    """
    home_forward(move, actuator, overrun_um)
    if compensator is not None:
        compensator.reset(actuator)
    errors = []
    for t in np.asarray(targets_um, dtype=float):
        cmd = t if compensator is None else compensator.command(actuator, t)
        measured = move(actuator, cmd)
        pos = measured if truth is None else truth(actuator)
        errors.append(pos - t)
    return np.array(errors)


def run_stage_moves(move, geometry, poses, compensator=None, *, truth=None, overrun_um: float = 100.0):
    """Drive the stage through table poses from home and return the pose errors.

    Each pose is turned into actuator targets by the exact inverse kinematics
    (a rotation becomes two X moves and one Y move, as in the patent), each
    actuator is commanded (through ``compensator`` if given) and the reached
    pose is computed from the actuator positions by the forward kinematics.

    Parameters
    ----------
    move : callable
        ``move(actuator, target_um) -> measured_um``.
    geometry : UVWGeometry
        Pivot positions of the stage.
    poses : sequence of Pose
        Table poses to visit in order.
    compensator : object or None
        ``command(actuator, target_um)`` and ``reset(actuator)``, or None.
    truth : callable or None
        ``truth(actuator) -> true position µm``; when given the reached pose is
        the true one, else the measured one.
    overrun_um : float
        Overrun of the initial homing moves, µm.

    Returns
    -------
    numpy.ndarray, shape (len(poses), 3)
        Errors ``(x_um, y_um, theta_urad)`` of the reached pose.
    """
    for name in ACTUATORS:
        home_forward(move, name, overrun_um)
        if compensator is not None:
            compensator.reset(name)
    out = []
    for pose in poses:
        targets = inverse_kinematics(geometry, pose.x_um, pose.y_um, pose.theta_deg).as_dict()
        reached = {}
        for name, t in targets.items():
            cmd = t if compensator is None else compensator.command(name, t)
            measured = move(name, cmd)
            reached[name] = measured if truth is None else truth(name)
        got = forward_kinematics(geometry, Strokes(reached["X1"], reached["X2"], reached["Y"]))
        out.append((got.x_um - pose.x_um, got.y_um - pose.y_um, math.radians(got.theta_deg - pose.theta_deg) * 1e6))
    return np.array(out).reshape(-1, 3)
