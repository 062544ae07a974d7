"""Per-actuator position error model of a lead-screw actuator, fitted by linear least squares.

For a command ``c`` (µm from home) reached moving in direction ``d`` (+1
forward, −1 reverse) the measured position is ``c + e(c, d)`` with

    e(c, d) = offset + scale·c − d·B/2 + Σ_{p=2..degree} q_p (c / 1 mm)^p
              + Σ_h (s_h sin(2πhc/L) + k_h cos(2πhc/L))

(offset, scale, backlash B, an optional bow of the cumulative lead error and
the periodic lead error of lead L up to ``harmonics``). The model is linear in
its parameters; :func:`fit_actuator_model` returns values, standard deviations
and residuals; :func:`select_actuator_model` picks the degree and the number
of harmonics by the Bayesian information criterion; :func:`phase_residuals`
shows what a model without the periodic terms (the patent's: linear in stroke
plus a reversal) leaves behind as a function of position modulo the lead.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from kinid.checks import check_int
from kinid.errors import DataError, StageError

from .kinematics import check_lead

__all__ = ["ActuatorModel", "fit_actuator_model", "select_actuator_model", "phase_residuals", "parameter_names"]


def parameter_names(harmonics: int, degree: int = 1) -> tuple:
    """Names of the model parameters.

    ``offset_um``, ``scale_ppm``, ``backlash_um``, then ``poly2_um`` …
    ``poly<degree>_um`` (coefficient of (c / 1 mm)^p, µm), then ``s1_um``,
    ``k1_um``, ``s2_um``, … (sine and cosine amplitudes of each harmonic).
    """
    names = ["offset_um", "scale_ppm", "backlash_um"]
    names += [f"poly{p}_um" for p in range(2, degree + 1)]
    for h in range(1, harmonics + 1):
        names += [f"s{h}_um", f"k{h}_um"]
    return tuple(names)


def _design(commands_um, directions, lead_um, harmonics, degree=1):
    c = np.asarray(commands_um, dtype=float)
    d = np.asarray(directions, dtype=float)
    cols = [np.ones_like(c), 1e-6 * c, -0.5 * d]
    cols += [(1e-3 * c) ** p for p in range(2, degree + 1)]
    for h in range(1, harmonics + 1):
        phase = 2.0 * np.pi * h * c / lead_um
        cols += [np.sin(phase), np.cos(phase)]
    return np.column_stack(cols)


@dataclass(frozen=True, eq=False)
class ActuatorModel:
    """A fitted error model of one actuator.

    Attributes
    ----------
    lead_um : float
        Screw lead, µm.
    harmonics : int
        Number of harmonics of the periodic lead error.
    degree : int
        Polynomial degree of the cumulative lead error (1: scale only).
    names : tuple of str
        Parameter names (see :func:`parameter_names`).
    values, std : numpy.ndarray
        Parameter values and standard deviations (µm, ppm for ``scale_ppm``).
    sigma_um : float
        Measurement noise used for ``std`` (given, or estimated from the residuals).
    residuals_um : numpy.ndarray
        Measured minus modelled position for each calibration measurement, µm.
    commands_um, directions : numpy.ndarray
        The calibration commands and approach directions.
    span_um : tuple of float
        Range of commands the model was fitted on, µm.
    candidates : tuple
        ``(degree, harmonics, rms_um, bic)`` of every model compared by
        :func:`select_actuator_model` (empty when fitted directly).
    """

    lead_um: float
    harmonics: int
    names: tuple
    values: np.ndarray
    std: np.ndarray
    sigma_um: float
    residuals_um: np.ndarray
    commands_um: np.ndarray
    directions: np.ndarray
    span_um: tuple
    degree: int = 1
    candidates: tuple = ()

    def __getitem__(self, name: str) -> float:
        return float(self.values[self.names.index(name)])

    def std_of(self, name: str) -> float:
        """Standard deviation of parameter ``name``."""
        return float(self.std[self.names.index(name)])

    @property
    def rms_um(self) -> float:
        """RMS of the calibration residuals, µm."""
        return float(np.sqrt(np.mean(self.residuals_um ** 2)))

    @property
    def periodic_amplitude_um(self) -> float:
        """Amplitude of the first harmonic of the lead error, µm (0 without harmonics)."""
        if self.harmonics < 1:
            return 0.0
        return float(math.hypot(self["s1_um"], self["k1_um"]))

    def error_um(self, command_um, direction):
        """Modelled error ``e(c, d)`` (measured minus commanded position), µm (scalar or array like ``command_um``)."""
        c = np.asarray(command_um, dtype=float)
        d = np.broadcast_to(np.asarray(direction, dtype=float), c.shape)
        e = _design(c.ravel(), d.ravel(), self.lead_um, self.harmonics, self.degree) @ self.values
        return float(e[0]) if c.ndim == 0 else e.reshape(c.shape)

    def position_um(self, command_um, direction):
        """Modelled table position for a command reached in ``direction``, µm."""
        return command_um + self.error_um(command_um, direction)

    def _slope(self, command_um):
        """d(position)/d(command) at a command (dimensionless)."""
        g = 1.0 + 1e-6 * self["scale_ppm"]
        for p in range(2, self.degree + 1):
            g += 1e-3 * p * self[f"poly{p}_um"] * (1e-3 * command_um) ** (p - 1)
        for h in range(1, self.harmonics + 1):
            w = 2.0 * np.pi * h / self.lead_um
            g += w * (self[f"s{h}_um"] * math.cos(w * command_um) - self[f"k{h}_um"] * math.sin(w * command_um))
        return g

    def command_for(self, target_um: float, direction: int, *, tol_um: float = 1e-9, max_iter: int = 50) -> float:
        """Command whose modelled position, reached in ``direction``, is ``target_um`` (Newton), µm."""
        c = float(target_um)
        for _ in range(max_iter):
            f = self.position_um(c, direction) - target_um
            g = self._slope(c)
            if g <= 0:
                raise StageError("the fitted actuator model is not monotonic (periodic error slope above 1); "
                                 "check lead_um")
            c -= f / g
            if abs(f) < tol_um:
                break
        return c


def fit_actuator_model(commands_um, directions, measured_um, lead_um: float, *, harmonics: int = 2,
                       degree: int = 1, noise_um=None, rank_tol: float = 1e-10) -> ActuatorModel:
    """Fit the error model to calibration measurements by linear least squares.

    Parameters
    ----------
    commands_um : array_like, shape (k,)
        Commanded positions, µm from home.
    directions : array_like, shape (k,)
        Approach direction of each measurement, +1 or −1.
    measured_um : array_like, shape (k,)
        Measured table positions, µm from home.
    lead_um : float
        Screw lead, µm (> 0).
    harmonics : int
        Harmonics of the periodic lead error (0 gives the patent's kind of
        model: offset, scale and reversal only).
    degree : int
        Polynomial degree of the cumulative lead error (1: scale only).
    noise_um : float or None
        Known measurement noise, µm; if None it is estimated from the residuals.
    rank_tol : float
        Relative singular-value tolerance below which the plan is called unable
        to separate the parameters.

    Returns
    -------
    ActuatorModel

    Raises
    ------
    StageError
        Bad lead, mismatched arrays, directions other than ±1, or a plan that
        cannot separate the parameters (e.g. one approach direction only).
    """
    lead = check_lead(lead_um)
    harmonics = check_int("harmonics", harmonics, minimum=0)
    degree = check_int("degree", degree, minimum=1)
    c = np.asarray(commands_um, dtype=float)
    d = np.asarray(directions, dtype=float)
    y = np.asarray(measured_um, dtype=float)
    if not (c.ndim == 1 and c.shape == d.shape == y.shape):
        raise DataError(f"commands_um, directions and measured_um must be 1-D of one length, "
                         f"got {c.shape}, {d.shape}, {y.shape}")
    if not np.all(np.isin(d, (-1.0, 1.0))):
        raise DataError("directions must be +1 or -1")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(y))):
        raise DataError("commands_um and measured_um must be finite")
    names = parameter_names(harmonics, degree)
    A = _design(c, d, lead, harmonics, degree)
    if A.shape[0] <= A.shape[1]:
        raise StageError(f"{A.shape[0]} measurements cannot fit {A.shape[1]} parameters {list(names)}")
    u, s, vt = np.linalg.svd(A, full_matrices=False)
    if s[-1] <= rank_tol * s[0]:
        weak = names[int(np.argmax(np.abs(vt[-1])))]
        raise StageError(f"the test plan cannot separate the model parameters (weakest: {weak}); "
                         "measure both approach directions at positions spread over at least one lead")
    x = vt.T @ ((u.T @ (y - c)) / s)
    resid = (y - c) - A @ x
    dof = A.shape[0] - A.shape[1]
    sigma = float(np.sqrt(resid @ resid / dof)) if noise_um is None else float(noise_um)
    std = sigma * np.sqrt(np.sum((vt / s[:, None]) ** 2, axis=0))
    return ActuatorModel(lead_um=lead, harmonics=int(harmonics), names=names, values=x, std=std,
                         sigma_um=sigma, residuals_um=resid, commands_um=c, directions=d,
                         span_um=(float(c.min()), float(c.max())), degree=int(degree))


def select_actuator_model(commands_um, directions, measured_um, lead_um: float, *, max_harmonics: int = 4,
                          max_degree: int = 3, harmonics=None, degree=None, noise_um=None) -> ActuatorModel:
    """Fit every model up to ``max_degree`` and ``max_harmonics`` and keep the one of least BIC.

    The Bayesian information criterion ``n ln(RSS/n) + p ln n`` trades the
    residual against the number of parameters, so an effect is added only
    when the data show it (a bow of the lead error, a higher harmonic).

    Parameters
    ----------
    commands_um, directions, measured_um : array_like
        As for :func:`fit_actuator_model`.
    lead_um : float
        Screw lead, µm.
    max_harmonics : int
        Largest number of harmonics tried (1 … max_harmonics).
    max_degree : int
        Largest polynomial degree tried (1 … max_degree).
    harmonics, degree : int or None
        Fix the number of harmonics / the degree instead of choosing it.
    noise_um : float or None
        Known noise for the standard deviations of the chosen model, µm.

    Returns
    -------
    ActuatorModel
        The chosen model; ``candidates`` lists all fits compared.
    """
    max_harmonics = check_int("max_harmonics", max_harmonics, minimum=1)
    max_degree = check_int("max_degree", max_degree, minimum=1)
    n = np.asarray(commands_um).size
    best, best_bic, table = None, math.inf, []
    degrees = range(1, max_degree + 1) if degree is None else (degree,)
    harmonic_counts = range(1, max_harmonics + 1) if harmonics is None else (harmonics,)
    first_error = None
    for deg in degrees:
        for har in harmonic_counts:
            try:
                m = fit_actuator_model(commands_um, directions, measured_um, lead_um, harmonics=har,
                                       degree=deg, noise_um=noise_um)
            except StageError as exc:
                first_error = first_error or exc
                continue
            rss = max(float(m.residuals_um @ m.residuals_um), 1e-300)
            bic = n * math.log(rss / n) + len(m.names) * math.log(n)
            table.append((deg, har, m.rms_um, bic))
            if bic < best_bic - 1e-9:
                best, best_bic = m, bic
    if best is None:
        raise first_error
    return dataclasses.replace(best, candidates=tuple(table))


def phase_residuals(model: ActuatorModel):
    """What a model without periodic terms misses, against position modulo the lead.

    Refits the calibration data of ``model`` with offset, scale and reversal
    only (the patent's kind of model) and returns its residuals with the
    phase of each command.

    Parameters
    ----------
    model : ActuatorModel
        A fitted model (its calibration data are reused).

    Returns
    -------
    phase : numpy.ndarray
        Command modulo the lead, as a fraction of the lead in [0, 1).
    linear_residual_um : numpy.ndarray
        Residuals of the offset + scale + reversal fit, µm.
    full_residual_um : numpy.ndarray
        Residuals of ``model``, µm.
    """
    measured = model.commands_um + model.residuals_um + model.error_um(model.commands_um, model.directions)
    linear = fit_actuator_model(model.commands_um, model.directions, measured, model.lead_um, harmonics=0)
    phase = np.mod(model.commands_um / model.lead_um, 1.0)
    return phase, linear.residuals_um, model.residuals_um
