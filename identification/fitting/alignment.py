"""Solve axis readings at which a (fitted or true) machine aligns the tool point with a mark.

Used by ``kinid predict`` (readings of the fitted machine at new poses) and by
``kinid simulate`` (readings of a machine with known errors). Newton's method
on the solved axes with Pinocchio's axis Jacobian; the basis values of
position-dependent effects are refreshed every iteration, so the fixed point
includes them.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from kinid.threads import blas_single_threaded
from kinid.errors import DataError
from ..model import Machine, evaluate
from ..data import Observations
from .residuals import design, joint_values

__all__ = ["solve_axes"]


@blas_single_threaded
def solve_axes(machine: Machine, effects, theta, obs: Observations, solve=None, *, tol_mm: float = 1e-10, max_iter: int = 50) -> Observations:
    """Readings of the axes ``solve`` that put the tool point on each mark.

    Parameters
    ----------
    machine : Machine
    effects : sequence of Effect
    theta : array (P,)
        Effect parameters.
    obs : Observations
        Poses: marks and the readings of the other axes (solved ones may be NaN;
        non-NaN values are the starting guess). With offsets, the readings put the
        point at that offset from the tool point on the mark (where the camera
        would see the mark there).
    solve : sequence of str, optional
        Axes to solve; default the prismatic axes. Needs as many axes as the
        3 coordinates of a point.
    tol_mm : float
        Convergence threshold on the largest axis update (mm or deg).
    max_iter : int

    Returns
    -------
    Observations
        ``obs`` with the solved readings filled in.

    Raises
    ------
    DataError
        If the axes cannot be solved (unknown axis, not three, singular
        geometry at a row, no convergence).
    """
    names = machine.axis_names
    solve = tuple(a.name for a in machine.axes if a.kind == "prismatic") if solve is None else tuple(solve)
    unknown = [s for s in solve if s not in names]
    if unknown:
        raise DataError(f"cannot solve unknown axes {unknown}; this machine has {', '.join(names)}")
    if len(solve) != 3:
        raise DataError(f"solve exactly three axes (one per coordinate of the mark), got {', '.join(solve) or 'none'}")
    cols = [names.index(s) for s in solve]
    axes = obs.axes.copy()
    others = [j for j in range(len(names)) if j not in cols]
    missing = np.isnan(axes[:, others])
    if missing.any():
        i, j = np.argwhere(missing)[0]
        line = obs.lines[i] if obs.lines else None
        raise DataError(f"reading of axis {names[others[j]]} is needed", path=obs.source, line=line, column=machine.axes[others[j]].column)
    axes[:, cols] = np.nan_to_num(axes[:, cols])
    theta = np.asarray(theta, float)
    for _ in range(max_iter):
        d = design(machine, effects, obs, axes)
        p, _, d_ax = evaluate(machine, axes, joint_values(machine, d, theta), offsets_mm=obs.offsets_mm)
        r_um = (p - obs.w_mm) * 1e3
        A = d_ax[:, :, cols]  # µm per (mm|deg)
        det = np.linalg.det(A)
        bad = np.abs(det) < 1e-9 * np.max(np.abs(A), axis=(1, 2)) ** 3
        if bad.any():
            i = int(np.argmax(bad))
            line = obs.lines[i] if obs.lines else None
            raise DataError(f"axes {', '.join(solve)} cannot move the tool point in all three directions at this pose (singular)", path=obs.source, line=line)
        step = np.linalg.solve(A, r_um[:, :, None])[:, :, 0]
        axes[:, cols] -= step
        if np.max(np.abs(step)) < tol_mm:
            return replace(obs, axes=axes)
    i = int(np.argmax(np.max(np.abs(step), axis=1)))
    line = obs.lines[i] if obs.lines else None
    raise DataError(f"no readings of {', '.join(solve)} align the tool point with mark {obs.marks[i]!r} "
                    f"(largest update {np.max(np.abs(step[i])):.3g} after {max_iter} iterations); give readings of "
                    f"{', '.join(machine.axis(a).column for a in solve)} near the solution in this row as the "
                    f"starting guess", path=obs.source, line=line)
