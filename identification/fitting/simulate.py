"""Synthetic machines: measurement plans, known error sets, simulated alignment readings.

A plan lists poses: a mark on the board and the readings of the preset axes
(the rotary axes); :func:`simulate` solves the remaining axes with the true
errors (:func:`identification.alignment.solve_axes`) and adds reading noise.

The patent's plan: the camera is aligned over each of 4 marks at
every combination of 7 tilt angles and 12 table angles — 336 alignments.
"""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from kinid.errors import DataError
from kinid.files import read_json
from kinid.schema import Either, Items, Number, Table, validate

from ..model import Machine, basis_of, evaluate, parse_effect, tool_rotation_in_workpiece
from ..data import Observations, read_observations
from .alignment import solve_axes
from .residuals import design, joint_values

__all__ = ["patent_plan", "load_plan", "load_errors", "simulate", "approach_directions", "mark_offsets_mm", "PATENT_MARKS_MM"]

#: The four marks of the built-in plan, workpiece frame, mm.
PATENT_MARKS_MM = ((40.0, 40.0, 0.0), (-40.0, 40.0, 0.0), (-40.0, -40.0, 0.0), (40.0, -40.0, 0.0))
TILT_DEG = tuple(np.linspace(-60.0, 60.0, 7))
TURN_DEG = tuple(np.arange(0.0, 360.0, 30.0))
SECONDS_PER_ALIGNMENT = 15.0


def _is_table_axis(machine: Machine, axis) -> bool:
    """A rotary axis about z at home (a turntable): it gets full turns in the plan."""
    import pinocchio as pin

    data = machine.model.createData()
    q = pin.neutral(machine.model)
    pin.forwardKinematics(machine.model, data, q)
    jid = machine.model.getJointId(axis.joint)
    from ..model import joint_kind

    _, local = joint_kind(machine.model.joints[jid])
    world = data.oMi[jid].rotation @ local
    return abs(abs(world[2]) - 1.0) < 1e-6


def patent_plan(machine: Machine, marks_mm=PATENT_MARKS_MM, *, tilt_deg=TILT_DEG, turn_deg=TURN_DEG) -> Observations:
    """The patent's grid: every mark at every (tilt, table) angle combination.

    Rotary axes about z at home get ``turn_deg`` (12 angles), the others
    ``tilt_deg`` (7 angles). Order: tilt outermost, then table angle, then mark,
    as a machine would run it; ``t_s`` advances 15 s per alignment.
    """
    rotary = [a for a in machine.axes if a.kind == "revolute"]
    grids = [turn_deg if _is_table_axis(machine, a) else tilt_deg for a in rotary]
    combos = np.array(np.meshgrid(*grids, indexing="ij")).reshape(len(rotary), -1).T if rotary else np.zeros((1, 0))
    rows, marks, w = [], [], []
    names = machine.axis_names
    for combo in combos:
        for k, m in enumerate(marks_mm):
            a = np.full(len(names), np.nan)
            for ax, v in zip(rotary, combo):
                a[names.index(ax.name)] = v
            rows.append(a)
            marks.append(f"M{k + 1}")
            w.append(m)
    n = len(rows)
    return Observations(tuple(marks), np.array(w, float), np.array(rows), np.arange(n) * SECONDS_PER_ALIGNMENT, {}, tuple(range(1, n + 1)), "<patent plan>")


def load_plan(spec: str, machine: Machine, solve=None) -> Observations:
    """``"patent"`` for the built-in plan, else a CSV of poses (observation columns without the solved axes)."""
    if spec == "patent":
        return patent_plan(machine)
    if not Path(spec).is_file():
        raise DataError(f"plan {spec!r} is neither 'patent' nor an existing CSV file")
    solve = tuple(a.name for a in machine.axes if a.kind == "prismatic") if solve is None else tuple(solve)
    return read_observations(spec, machine, optional_axes=solve)


def load_errors(path, machine: Machine):
    """Read an error set: JSON object effect name -> value or list of values (effect units).

    Returns
    -------
    effects : list of Effect
    theta : array (P,)

    Examples
    --------
    ``{"EX0C": 12.0, "EA0B": -25.0, "EXX:periodic:10": [1.5, -0.8], "EXX:poly2": [0.01, 2e-5]}``
    """
    path = Path(path)
    data = read_json(path, what="error-set file")
    if not isinstance(data, dict):
        raise DataError("an error set is a JSON object: effect name -> value or list of values", path=path)
    validate(data, ERROR_SET_SCHEMA, path=path)
    return errors_from_mapping(data, machine, source=str(path))


_SIZE = Number(low=-1e7, high=1e7)
#: What an error-set file holds: effect name -> its value, or its list of values, each in its unit (µm, µrad, ...)
#: and within ±10⁷ of it (10 m in µm): a larger one is no machine's error.
ERROR_SET_SCHEMA = Table(Either((_SIZE, Items(_SIZE, min_length=1))))


def errors_from_mapping(data: dict, machine: Machine, *, source="<errors>"):
    """Effects and parameter vector from a mapping effect name -> value(s)."""
    effects, theta = [], []
    for name, value in data.items():
        try:
            e = parse_effect(name, machine)
        except DataError as exc:
            raise DataError(exc.message, path=source) from None
        values = np.atleast_1d(np.asarray(value, dtype=float)) if _numeric(value) else None
        if values is None or values.ndim != 1 or values.size != e.n_params or not np.all(np.isfinite(values)):
            raise DataError(f"effect {name!r} needs {e.n_params} finite number(s), got {value!r}", path=source)
        effects.append(e)
        theta.extend(values)
    return effects, np.array(theta, float)


def _numeric(value) -> bool:
    try:
        np.asarray(value, dtype=float)
        return True
    except (TypeError, ValueError):
        return False


def approach_directions(axes: np.ndarray, names) -> dict:
    """Approach direction of each axis from the order of the readings: sign of the last change (first: +1)."""
    out = {}
    for j, name in enumerate(names):
        s = np.empty(axes.shape[0])
        current = 1.0
        prev = axes[0, j]
        for i in range(axes.shape[0]):
            delta = axes[i, j] - prev
            if abs(delta) > 1e-9:
                current = 1.0 if delta > 0 else -1.0
            s[i] = current
            prev = axes[i, j]
        out[name] = s
    return out


def simulate(machine: Machine, plan: Observations, effects, theta, *, noise_um: float = 0.0, rng=None, solve=None,
             directions: bool = True, stop_scatter_um: float = 0.0) -> Observations:
    """Readings at which the machine with the true errors aligns the tool point with each mark.

    Parameters
    ----------
    machine : Machine
    plan : Observations
        Poses; the solved axes may be NaN.
    effects, theta
        The true error set.
    noise_um : float
        σ of Gaussian noise added to each solved reading: µm on a linear axis
        (a revolute solved axis gets the same number in millidegrees).
    rng : numpy Generator
    solve : axes to solve (default the prismatic axes)
    directions : bool
        Add ``dir_<axis>`` columns from the order of the readings (and use them
        for reversal effects).
    stop_scatter_um : float
        If > 0, the operator stops near each alignment instead of on it: the solved
        readings are scattered by this σ (µm, or millidegrees on a revolute axis), and
        the rows record where the true machine then shows the mark relative to the tool
        point, in the tool frame (``offsets_mm``, the ``mark_d*_mm`` columns).
    """
    rng = np.random.default_rng() if rng is None else rng
    names = machine.axis_names
    solve = tuple(a.name for a in machine.axes if a.kind == "prismatic") if solve is None else tuple(solve)
    if not solve or (len(solve) != 3 and not any(a.kind == "prismatic" for a in machine.axes)):
        return _measured_points(machine, plan, effects, theta, noise_um, rng)
    obs = plan
    if directions and not plan.directions:
        # directions depend on the solved readings: solve, derive, solve again
        first = solve_axes(machine, [e for e in effects if basis_of(e).driver != "direction"],
                           _drop_reversal(effects, theta), plan, solve)
        obs = replace(plan, directions=approach_directions(first.axes, names))
    out = solve_axes(machine, effects, theta, obs, solve)
    cols = [names.index(s) for s in solve]
    if stop_scatter_um:
        stopped = out.axes.copy()
        stopped[:, cols] += rng.normal(0.0, stop_scatter_um, size=(len(out), len(cols))) * 1e-3
        out = replace(out, axes=stopped, offsets_mm=mark_offsets_mm(machine, effects, theta, replace(out, axes=stopped)))
    if noise_um:
        noisy = out.axes.copy()
        noisy[:, cols] += rng.normal(0.0, noise_um, size=(len(out), len(cols))) * 1e-3
        out = replace(out, axes=noisy)
    return replace(out, source="<simulated>")


def _measured_points(machine: Machine, plan: Observations, effects, theta, noise_um, rng) -> Observations:
    """A machine without three axes to align with (a robot arm): every axis is set as the plan says and the mark
    columns are where an external measurement sees the tool point, with the noise on each coordinate."""
    if np.isnan(plan.axes).any():
        i, j = np.argwhere(np.isnan(plan.axes))[0]
        raise DataError(f"reading of axis {machine.axes[j].name} is needed (this machine has no three axes to align the "
                        f"tool point with a mark: every axis is set, the point is measured)", path=plan.source,
                        line=plan.lines[i] if plan.lines else None, column=machine.axes[j].column)
    values = joint_values(machine, design(machine, effects, plan), np.asarray(theta, float))
    p = evaluate(machine, plan.axes, values, jacobian=False, offsets_mm=plan.offsets_mm)
    if noise_um:
        p = p + rng.normal(0.0, noise_um, size=p.shape) * 1e-3
    return replace(plan, w_mm=p, source="<simulated>")


def mark_offsets_mm(machine: Machine, effects, theta, obs: Observations) -> np.ndarray:
    """Where the machine with errors ``effects``/``theta`` shows each mark relative to the tool point
    at the readings of ``obs``, in the tool frame, mm (N, 3)."""
    values = joint_values(machine, design(machine, effects, obs), np.asarray(theta, float))
    p0 = evaluate(machine, obs.axes, values, jacobian=False)
    R = tool_rotation_in_workpiece(machine, obs.axes, values)
    return np.einsum("nji,nj->ni", R, obs.w_mm - p0)


def _drop_reversal(effects, theta):
    keep = []
    k = 0
    for e in effects:
        if basis_of(e).driver != "direction":
            keep.extend(theta[k : k + e.n_params])
        k += e.n_params
    return np.array(keep)
