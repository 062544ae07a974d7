"""Units the data can tell: mark coordinates in metres or inches, ``_mm`` readings in metres or inches,
``_deg`` readings in radians.

The nominal machine (every error zero) puts the tool point near each mark: the marks and the nominal
tool points are one cloud of points up to the set-up (a rigid placement of the board) and the machine's
errors, micrometres to a millimetre. A column in the wrong unit bends the tool points' cloud out of that
shape by tens of millimetres. :func:`unit_hints` measures the misfit of the two clouds after the best
rigid placement (Kabsch), then again with each likely unit mistake undone (the marks, one column or all
columns of a kind times 1000, 25.4 or 180/π); a mistake whose undoing leaves a fraction
(:data:`HINT_GAIN`) of the misfit is what the data point to. Data in the right units have no such
mistake: undoing one that was not made bends the cloud further.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..model import Machine, evaluate, rigid_transform
from .axis_columns import warn_if_metres

__all__ = ["UnitHint", "unit_hints", "warn_units", "HINT_GAIN", "HINT_MIN_MM", "HINT_ROWS"]

#: A unit mistake is named when undoing it leaves at most this share of the misfit (measured: the shipped
#: examples' misfit is not lowered by any; a mistake made and undone lowers it 100- to 10 000-fold).
HINT_GAIN = 0.05
#: ... and the misfit is at least this, mm (below it the data are right to the machine's errors).
HINT_MIN_MM = 0.5
#: The clouds are compared on at most this many rows, evenly spread over the file (a unit mistake bends every
#: row alike; a million rows are judged in the time of 2000).
HINT_ROWS = 2000

# (what was written, factor to mm or deg): the mistakes a newcomer makes
_LENGTHS = (("metres", 1000.0), ("inches", 25.4))
_ANGLES = (("radians", 180.0 / math.pi),)


@dataclass(frozen=True)
class UnitHint:
    """A unit mistake the data point to.

    Attributes
    ----------
    columns : tuple of str
        The columns concerned (``wx_mm``, ``wy_mm``, ``wz_mm`` for the marks).
    unit : str
        What they look like: ``metres``, ``inches`` or ``radians``.
    factor : float
        What they must be multiplied by (1000, 25.4, 57.2958).
    misfit_mm, undone_mm : float
        RMS distance of the nominal tool points from the marks after the best rigid placement, mm, as read
        and with the mistake undone.
    """

    columns: tuple
    unit: str
    factor: float
    misfit_mm: float
    undone_mm: float

    def describe(self) -> str:
        """One clause: ``x_mm looks like inches, not mm: multiplied by 25.4 the nominal machine meets the marks
        within 0.0121 mm instead of 35.8 mm``."""
        cols = ", ".join(self.columns)
        verb = "looks" if len(self.columns) == 1 else "look"
        target = "degrees" if self.unit == "radians" else "mm"
        return (f"{cols} {verb} like {self.unit}, not {target}: multiplied by {self.factor:.6g} the nominal "
                f"machine meets the marks within {self.undone_mm:.3g} mm instead of {self.misfit_mm:.3g} mm")


def _rigid_misfit_mm(p: np.ndarray, w: np.ndarray) -> float:
    """RMS distance of the points ``p`` (N, 3) from ``w`` (N, 3) after the best rotation and translation of ``p``."""
    R, t = rigid_transform(p, w)
    return float(np.sqrt(np.mean(np.sum((p @ R.T + t - w) ** 2, axis=1))))


def _tool_points(machine: Machine, axes: np.ndarray, offsets_mm) -> np.ndarray:
    return evaluate(machine, axes, np.zeros(len(machine.error_joints)), jacobian=False, offsets_mm=offsets_mm)


def _candidates(machine: Machine, obs):
    """(columns, unit, factor, axes, w_mm) for every unit mistake tried."""
    mark_cols = ("wx_mm", "wy_mm", "wz_mm")
    for unit, k in _LENGTHS:
        yield mark_cols, unit, k, obs.axes, obs.w_mm * k
    for kind, units in (("prismatic", _LENGTHS), ("revolute", _ANGLES)):
        idx = [j for j, a in enumerate(machine.axes) if a.kind == kind and np.ptp(obs.axes[:, j]) > 0]
        groups = [[j] for j in idx] + ([idx] if len(idx) > 1 else [])
        for unit, k in units:
            for g in groups:
                axes = obs.axes.copy()
                axes[:, g] *= k
                yield tuple(sorted(machine.axes[j].column for j in g)), unit, k, axes, obs.w_mm


def unit_hints(machine: Machine, obs) -> tuple:
    """The unit mistake the data point to, if any: a tuple of one :class:`UnitHint` or empty.

    ``obs`` is :class:`~.observations.Observations` (this module sits below the reader, which calls it).

    Rows with an axis not given (NaN, poses for ``predict``) are not judged.
    """
    if len(obs) < 3 or not np.all(np.isfinite(obs.axes)):
        return ()
    if len(obs) > HINT_ROWS:
        obs = obs.subset(np.unique(np.linspace(0, len(obs) - 1, HINT_ROWS).round().astype(int)))
    base = _rigid_misfit_mm(_tool_points(machine, obs.axes, obs.offsets_mm), obs.w_mm)
    if base < HINT_MIN_MM:
        return ()
    best = None
    for columns, unit, k, axes, w in _candidates(machine, obs):
        misfit = _rigid_misfit_mm(_tool_points(machine, axes, obs.offsets_mm), w)
        if misfit <= HINT_GAIN * base and (best is None or misfit < best.undone_mm):
            best = UnitHint(columns, unit, k, base, misfit)
    return () if best is None else (best,)


def warn_units(machine: Machine, obs) -> tuple:
    """A warning for each reading column that looks like metres (:func:`~.axis_columns.warn_if_metres`) and for
    the mistake of :func:`unit_hints` (unless it is the same), each naming the file; returns the hints."""
    import warnings

    warned = warn_if_metres(machine, obs.axes, obs.source)
    hints = unit_hints(machine, obs)
    for h in hints:
        if not (h.unit == "metres" and set(h.columns) <= set(warned)):
            warnings.warn(f"{obs.source}: {h.describe()}", stacklevel=3)
    return hints
