"""The patent's test plan and compensation for a UVW alignment stage.

Test step: for a screw lead of 2a, measure the error of strokes m₁ = 0.5a,
a and n₁ = 1.5a, 10–30 times each. ΔX is the mean error over all of them
(the patent calls it the mean return error), ΔXn the mean at m₁, ΔXm the mean
at n₁. Compensation step: a forward move of stroke X₁ gets the extra stroke
``x₁' = (ΔXm − ΔXn)/(n₁ − m₁) · X₁``, a reverse move of stroke X₂ gets
``x₂' = (ΔXm − ΔXn)/(n₁ − m₁) · X₂ + ΔX``.

Worked example of the patent: ΔXn = 2.02, ΔXm = 2.62, ΔX = 2.29 µm,
m₁ = 500, n₁ = 1500 µm, X₁ = X₂ = 1600 µm → x₁' = 0.96 µm, x₂' = 3.25 µm.

How the error of a stroke is measured is not spelled out; here each
measurement starts from home reached in reverse, moves forward by the stroke
and takes ``error = stroke − measured displacement`` (the shortfall), so every
error carries one backlash, which is what makes ΔX the "mean return error".

Applying the compensation: the patent gives extra strokes per move. The
:class:`PatentCompensator` applies them in absolute form, strokes counted
from home (``command = T + slope·T`` approaching forward, ``T + slope·T − ΔX``
approaching in reverse), which is the patent's formula for every move that
starts at home and, unlike a literal move-by-move reading, does not lose the
backlash on a forward move that follows a reverse one.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.checks import check_int, check_positive
from kinid.errors import StageError

from .compensator import DirectionTrackingCompensator
from .kinematics import ACTUATORS, check_actuator, check_lead

__all__ = ["PatentStatistics", "patent_strokes", "patent_statistics", "patent_compensation_um",
           "measure_patent", "PatentCompensator", "calibrate_patent"]


@dataclass(frozen=True)
class PatentStatistics:
    """The patent's numbers for one actuator (errors are shortfalls, µm).

    Attributes
    ----------
    mean_um : float
        ΔX, mean error over all measured strokes.
    at_m_um : float
        ΔXn, mean error at stroke m₁.
    at_n_um : float
        ΔXm, mean error at stroke n₁.
    m_um, n_um : float
        The strokes m₁ and n₁, µm.
    repeats : int
        Measurements per stroke.
    """

    mean_um: float
    at_m_um: float
    at_n_um: float
    m_um: float
    n_um: float
    repeats: int = 0

    @property
    def slope(self) -> float:
        """(ΔXm − ΔXn)/(n₁ − m₁), µm of extra stroke per µm of stroke."""
        return (self.at_n_um - self.at_m_um) / (self.n_um - self.m_um)


def patent_strokes(lead_um: float):
    """The patent's test strokes ``(m₁, mid, n₁) = (0.5a, a, 1.5a)`` for a lead of 2a, µm.

    Examples
    --------
    >>> patent_strokes(2000.0)
    (500.0, 1000.0, 1500.0)
    """
    a = 0.5 * check_lead(lead_um)
    return (0.5 * a, a, 1.5 * a)


def patent_statistics(strokes_um, errors_um, m_um: float, n_um: float) -> PatentStatistics:
    """ΔX, ΔXn, ΔXm from measured errors.

    Parameters
    ----------
    strokes_um : array_like, shape (k,)
        Stroke of each measurement, µm.
    errors_um : array_like, shape (k,)
        Measured error (shortfall) of each measurement, µm.
    m_um, n_um : float
        The strokes m₁ and n₁, µm; both must occur in ``strokes_um``.

    Returns
    -------
    PatentStatistics
    """
    s = np.asarray(strokes_um, dtype=float)
    e = np.asarray(errors_um, dtype=float)
    if s.shape != e.shape or s.ndim != 1 or s.size == 0:
        raise StageError(f"strokes_um and errors_um must be 1-D of the same length, got {s.shape} and {e.shape}")
    if not n_um > m_um:
        raise StageError(f"n_um must exceed m_um, got m_um={m_um!r}, n_um={n_um!r}")
    at_m, at_n = e[np.isclose(s, m_um)], e[np.isclose(s, n_um)]
    if at_m.size == 0 or at_n.size == 0:
        raise StageError(f"no measurement at stroke m_um={m_um:g} or n_um={n_um:g} µm")
    return PatentStatistics(mean_um=float(e.mean()), at_m_um=float(at_m.mean()), at_n_um=float(at_n.mean()),
                            m_um=float(m_um), n_um=float(n_um), repeats=int(at_m.size))


def patent_compensation_um(stats: PatentStatistics, stroke_um: float, forward: bool) -> float:
    """The patent's compensation stroke for a move, µm.

    Parameters
    ----------
    stats : PatentStatistics
        From the test step.
    stroke_um : float
        Preset stroke X₁ (forward) or X₂ (reverse), µm (magnitude).
    forward : bool
        True for a forward move, False for a reverse move.

    Returns
    -------
    float
        ``slope · X₁`` forward, ``slope · X₂ + ΔX`` reverse, µm.

    Examples
    --------
    >>> st = PatentStatistics(mean_um=2.29, at_m_um=2.02, at_n_um=2.62, m_um=500, n_um=1500)
    >>> round(patent_compensation_um(st, 1600, True), 6), round(patent_compensation_um(st, 1600, False), 6)
    (0.96, 3.25)
    """
    extra = stats.slope * float(stroke_um)
    return extra if forward else extra + stats.mean_um


def measure_patent(move, actuator: str, lead_um: float, *, repeats: int = 18, overrun_um: float = 100.0):
    """Run the patent's test step on one actuator.

    Each measurement: go to ``+overrun_um``, back to home (so home is reached
    in reverse), measure, move forward by the stroke, measure; the error is
    ``stroke − measured displacement``.

    Parameters
    ----------
    move : callable
        ``move(actuator, target_um) -> measured_um`` (docs/hardware.md).
    actuator : str
        ``"X1"``, ``"X2"`` or ``"Y"``.
    lead_um : float
        Screw lead 2a, µm.
    repeats : int
        Measurements per stroke (the patent: 10 to 30).
    overrun_um : float
        Reversal distance before each measurement, µm (larger than the backlash).

    Returns
    -------
    strokes_um, errors_um : numpy.ndarray
        One entry per measurement.
    """
    check_actuator(actuator)
    strokes = patent_strokes(lead_um)
    repeats = check_int("repeats", repeats, minimum=1)
    overrun_um = check_positive("overrun_um", overrun_um)
    s_out, e_out = [], []
    for _ in range(repeats):
        for s in strokes:
            move(actuator, overrun_um)
            p0 = move(actuator, 0.0)
            p1 = move(actuator, s)
            s_out.append(s)
            e_out.append(s - (p1 - p0))
    move(actuator, -overrun_um)
    move(actuator, 0.0)  # leave the actuator at home, approached forward
    return np.array(s_out), np.array(e_out)


class PatentCompensator(DirectionTrackingCompensator):
    """The patent's compensation with the ``command(actuator, target_um)`` protocol.

    Parameters
    ----------
    stats : dict
        ``{"X1": PatentStatistics, ...}``.
    """

    def __init__(self, stats: dict):
        self.stats = dict(stats)
        for name in self.stats:
            check_actuator(name)
        super().__init__(tuple(self.stats))

    def _command_for(self, actuator, target_um, direction):
        st = self.stats[actuator]
        cmd = target_um + st.slope * target_um
        return cmd if direction > 0 else cmd - st.mean_um


def calibrate_patent(move, lead_um: float, *, repeats: int = 18, actuators=ACTUATORS,
                     overrun_um: float = 100.0) -> PatentCompensator:
    """Run the patent's test step on each actuator and return its compensator.

    The actuators end at home, approached forward, which is the state the
    returned compensator starts from.
    """
    lead = check_lead(lead_um)
    m, _, n = patent_strokes(lead)
    stats = {}
    for name in actuators:
        s, e = measure_patent(move, name, lead, repeats=repeats, overrun_um=overrun_um)
        stats[name] = patent_statistics(s, e, m, n)
    return PatentCompensator(stats)
