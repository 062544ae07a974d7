"""The candidate alignments a plan chooses from, and what each one teaches at the nominal machine.

Every mark at every combination of the preset axes' values, the solved axes at the nominal machine; or, on a
machine without three linear axes to align with (a robot arm), joint configurations drawn within the ranges and
the nominal tool point as the mark.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from kinid.errors import DataError
from ..model import Machine, axis_limits
from ..data import Observations

__all__ = ["solved_axes", "candidate_poses", "candidate_jacobian", "axis_motion", "MAX_CANDIDATES"]

#: Largest candidate pool.
MAX_CANDIDATES = 200_000


def solved_axes(machine: Machine, solve):
    if solve is not None:
        return tuple(solve)
    linear = tuple(a.name for a in machine.axes if a.kind == "prismatic")
    return linear if len(linear) == 3 else ()


def candidate_poses(machine: Machine, marks_mm, presets: dict, *, solve=None, samples: int = 0, rng=None) -> Observations:
    """Every mark at every combination of the preset axes' values, the solved axes at the nominal machine.

    Parameters
    ----------
    marks_mm : array (K, 3)
        Mark positions on the workpiece, mm.
    presets : dict axis -> sequence of readings (mm / deg)
        The grid of each preset axis (every axis but the solved ones needs one).
    solve : sequence of str, optional
        The axes that align the tool point with the mark (default: the three linear axes; none on a machine
        without three, whose candidates are then joint configurations).
    samples : int
        With no solved axes: draw this many configurations uniformly within ``presets``' ranges (each
        preset's min and max) instead of the grid.
    """
    from ..fitting import solve_axes
    from ..model import evaluate

    names = machine.axis_names
    solve = solved_axes(machine, solve)
    need = [a for a in names if a not in solve]
    missing = [a for a in need if a not in presets]
    if missing:
        raise DataError(f"the candidates need values of axis {', '.join(missing)} (--range {missing[0]}=START:STOP:STEP)")
    marks = np.atleast_2d(np.asarray(marks_mm, float))
    # counted before anything is built: a grid of 10 000 values on each of five axes is 1e20 rows
    n_combos = samples if samples and not solve else math.prod(np.asarray(presets[a]).size for a in need)
    total = n_combos * (len(marks) if solve else 1)
    if total > MAX_CANDIDATES:
        raise DataError(f"{total:,} candidate alignments; at most {MAX_CANDIDATES:,}: use coarser --range steps or "
                        f"fewer marks", parameter="range")
    if samples and not solve:
        rng = np.random.default_rng(0) if rng is None else rng
        combos = np.column_stack([rng.uniform(np.min(presets[a]), np.max(presets[a]), samples) for a in need])
    else:
        combos = np.array(list(itertools.product(*[np.asarray(presets[a], float) for a in need])), float)
        combos = combos.reshape(max(len(combos), 1), len(need))
    axes = np.full((total, len(names)), np.nan)
    if solve:
        rows = [(c, k) for c in range(len(combos)) for k in range(len(marks))]
        for j, a in enumerate(need):
            axes[:, names.index(a)] = [combos[c, j] for c, _ in rows]
        w = marks[[k for _, k in rows]]
        labels = tuple(f"M{k + 1}" for _, k in rows)
    else:
        for j, a in enumerate(need):
            axes[:, names.index(a)] = combos[:, j]
        w = evaluate(machine, axes, np.zeros((total, len(machine.error_joints))), jacobian=False)
        labels = tuple("P" for _ in range(total))
    obs = Observations(labels, w, axes, None, {}, (), "<candidates>")
    if solve:
        obs = solve_axes(machine, [], np.zeros(0), obs, solve)
        limits = axis_limits(machine)
        inside = np.all((obs.axes >= limits[:, 0] - 1e-9) & (obs.axes <= limits[:, 1] + 1e-9), axis=1)
        if not inside.any():
            raise DataError("no candidate alignment lies within the axes' travel (the URDF limits): check the marks "
                            "and the ranges", parameter="range")
        obs = obs.subset(np.flatnonzero(inside))
    return obs


def candidate_jacobian(machine: Machine, effects, obs: Observations, noise_um: float):
    """Whitened Jacobian (N, 3, P) of ``effects`` at the nominal machine, the parameter names and the held ones."""
    from ..fitting import analyse
    from ..fitting import design, residuals

    d = design(machine, effects, obs)
    _, J, _ = residuals(machine, d, obs, np.zeros(d.n_params))
    names = d.param_names()
    ident = analyse(J.reshape(-1, len(names)) / noise_um, names)
    free = ident.identifiable
    return J[:, :, free] / noise_um, tuple(n for n, f in zip(names, free) if f), ident.aliases


def axis_motion(machine: Machine):
    """(linear, wraps) per axis: linear axes; rotary axes that take the shorter way round (no limits, or a turn)."""
    limits = axis_limits(machine)
    linear = np.array([a.kind == "prismatic" for a in machine.axes])
    span = limits[:, 1] - limits[:, 0]
    wraps = ~linear & ~(np.isfinite(span) & (span < 359.999))
    return linear, wraps
