"""A simulated UVW stage with known actuator errors (for tests and the demo).

Each actuator is a lead screw driven to a commanded position ``c`` (µm from
home). The nut sits at ``n(c) = c + scale·c + Σ_h (s_h sin(2πhc/L) + c_h cos(2πhc/L))``
(scale error and periodic lead error of lead ``L``); the table follows the nut
through a play of width ``B`` (backlash): it only moves once the nut has taken
up the play in the new direction. The vision system reports the table
position relative to where it was at home (approached forward), plus Gaussian
noise.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinid.errors import StageError

from .kinematics import ACTUATORS, check_actuator

__all__ = ["ActuatorTruth", "SimulatedUVWStage", "default_truth"]


@dataclass(frozen=True)
class ActuatorTruth:
    """True position errors of one actuator.

    Parameters
    ----------
    lead_um : float
        Screw lead L, µm (period of the lead error).
    scale_ppm : float
        Scale (cumulative lead) error, µm per m of travel; the nut moves
        ``(1 + scale_ppm·1e-6)`` per commanded µm.
    backlash_um : float
        Width of the play between nut and table, µm (≥ 0).
    periodic_um : tuple of (float, float)
        ``(sin, cos)`` amplitudes of the periodic lead error for harmonics
        1, 2, …, µm.
    poly_um : tuple of float
        Bow of the cumulative lead error: coefficients of (c / 1 mm)^2,
        (c / 1 mm)^3, …, µm.
    """

    lead_um: float = 2000.0
    scale_ppm: float = 0.0
    backlash_um: float = 0.0
    periodic_um: tuple = ()
    poly_um: tuple = ()

    def nut_um(self, command_um):
        """Nut position for a commanded position (µm), before the play (µm)."""
        c = np.asarray(command_um, dtype=float)
        n = c * (1.0 + 1e-6 * self.scale_ppm)
        for p, q in enumerate(self.poly_um, start=2):
            n = n + q * (1e-3 * c) ** p
        for h, (s, k) in enumerate(self.periodic_um, start=1):
            phase = 2.0 * np.pi * h * c / self.lead_um
            n = n + s * np.sin(phase) + k * np.cos(phase)
        return n


def default_truth(lead_um: float = 2000.0) -> dict:
    """The demo stage: a ±4 µm-class UVW stage with a periodic lead error.

    Errors of each actuator over ±4 mm reach about ±4 µm: scale errors of
    250–450 ppm, 1.6–2.3 µm backlash and a 0.6–0.7 µm periodic lead error
    (with a small second harmonic). Each actuator has its own values. On this
    stage the patent's method roughly halves the error, as the patent reports.
    """
    return {
        "X1": ActuatorTruth(lead_um, scale_ppm=-300.0, backlash_um=2.0, periodic_um=((0.2, -0.7), (0.1, 0.05))),
        "X2": ActuatorTruth(lead_um, scale_ppm=-450.0, backlash_um=1.6, periodic_um=((-0.15, -0.6), (0.05, 0.1))),
        "Y": ActuatorTruth(lead_um, scale_ppm=250.0, backlash_um=2.3, periodic_um=((0.25, -0.6), (-0.1, 0.05))),
    }


class SimulatedUVWStage:
    """UVW stage implementing the ``move(actuator, target_um) -> measured_um`` protocol.

    Parameters
    ----------
    truth : dict or None
        ``{"X1": ActuatorTruth, "X2": ..., "Y": ...}``; ``None`` for
        :func:`default_truth`.
    noise_um : float
        Standard deviation of the vision measurement, µm.
    travel_um : float
        Each actuator may be commanded within ± this from home, µm.
    rng : numpy.random.Generator or None
        Source of measurement noise (``np.random.default_rng(0)`` if None).

    Attributes
    ----------
    moves : int
        Number of moves made so far.
    """

    def __init__(self, truth=None, *, noise_um: float = 0.1, travel_um: float = 5000.0, rng=None):
        self.truth = default_truth() if truth is None else dict(truth)
        missing = [a for a in ACTUATORS if a not in self.truth]
        if missing:
            raise StageError(f"SimulatedUVWStage truth lacks actuator(s) {missing}; expected keys X1, X2, Y")
        if not (noise_um >= 0 and math.isfinite(noise_um)):
            raise StageError(f"noise_um must be a finite number >= 0, got {noise_um!r}")
        if not (travel_um > 0 and math.isfinite(travel_um)):
            raise StageError(f"travel_um must be a positive number, got {travel_um!r}")
        self.noise_um = float(noise_um)
        self.travel_um = float(travel_um)
        self.rng = np.random.default_rng(0) if rng is None else rng
        self.moves = 0
        self._command = {a: 0.0 for a in ACTUATORS}
        # Home approached forward: the table trails the nut by half the play.
        self._table = {a: float(self.truth[a].nut_um(0.0)) - 0.5 * self.truth[a].backlash_um for a in ACTUATORS}
        self._home = dict(self._table)

    def move(self, actuator: str, target_um: float) -> float:
        """Drive ``actuator`` to the commanded ``target_um`` (µm from home); return the measured position, µm."""
        check_actuator(actuator)
        try:
            target = float(target_um)
        except (TypeError, ValueError):
            raise StageError(f"target_um for {actuator} must be a number, got {target_um!r}") from None
        if not math.isfinite(target) or abs(target) > self.travel_um:
            raise StageError(f"move of {actuator} to {target:g} µm is outside the travel ±{self.travel_um:g} µm")
        self.moves += 1
        self._command[actuator] = target
        t = self.truth[actuator]
        nut = float(t.nut_um(target))
        half = 0.5 * t.backlash_um
        table = self._table[actuator]
        if nut - table > half:
            table = nut - half
        elif table - nut > half:
            table = nut + half
        self._table[actuator] = table
        return self.true_um(actuator) + self.noise_um * float(self.rng.standard_normal())

    def true_um(self, actuator: str) -> float:
        """True (noise-free) table position of ``actuator`` relative to home, µm."""
        check_actuator(actuator)
        return self._table[actuator] - self._home[actuator]

    def command_um(self, actuator: str) -> float:
        """Last commanded position of ``actuator``, µm."""
        check_actuator(actuator)
        return self._command[actuator]
