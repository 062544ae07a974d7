"""Residuals of alignment observations and their Jacobian with respect to effect parameters.

The model's claim for a row (docs/formats.md, "Observation CSV"): the tool point (plus the row's
measured offset in the tool frame, if any), expressed in the workpiece frame, equals the mark. The
residual is the difference in µm.
An effect's Jacobian column is its error joint's column (from Pinocchio) times
the basis value, so every effect, and the whole candidate library, is scored
from one kinematic pass.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..model import Machine, basis_values, evaluate
from ..data import Observations

__all__ = ["Design", "design", "joint_values", "residuals", "effect_columns"]


@dataclass(frozen=True)
class Design:
    """Basis values of a list of effects on a set of observations.

    Attributes
    ----------
    effects : tuple of Effect
    joint_index : array (P,)
        Error-joint index (in ``machine.error_joints``) of each parameter.
    basis : array (N, P)
        Basis value of each parameter at each observation.
    """

    effects: tuple
    joint_index: np.ndarray
    basis: np.ndarray

    @property
    def n_params(self) -> int:
        return self.basis.shape[1]

    def param_names(self) -> list[str]:
        return [n for e in self.effects for n in e.param_names()]

    @functools.cached_property  # every pass of a fit asks; the fields are frozen
    def joints(self) -> tuple:
        """(used, column, first, more): the error joints the parameters sit on (sorted), each parameter's place
        among them, each used joint's first parameter and the parameters after a joint's first."""
        used, first, column = np.unique(self.joint_index, return_index=True, return_inverse=True)
        more = np.ones(len(self.joint_index), dtype=bool)
        more[first] = False
        return used, column, first, np.flatnonzero(more)


def design(machine: Machine, effects, obs: Observations, axes_user: np.ndarray | None = None) -> Design:
    """Basis values of ``effects`` at the poses of ``obs`` (axes from ``axes_user`` if given)."""
    axes_user = obs.axes if axes_user is None else axes_user
    codes = machine.error_codes
    blocks, index = [], []
    for e in effects:
        b = basis_values(e, machine, axes_user, t_s=obs.t_s, directions=obs.directions, marks=obs.marks)
        blocks.append(b)
        index += [codes.index(e.code)] * b.shape[1]
    basis = np.concatenate(blocks, axis=1) if blocks else np.zeros((len(obs), 0))
    return Design(tuple(effects), np.asarray(index, dtype=int), basis)


def joint_values(machine: Machine, d: Design, theta: np.ndarray) -> np.ndarray:
    """Error-joint values (N, n_errors) in µm / µrad for parameters ``theta`` (P,)."""
    values = np.zeros((d.basis.shape[0], len(machine.error_joints)))
    if d.n_params == 0:
        return values
    bt = d.basis * theta
    index = d.joint_index
    used, _, first, more = d.joints
    values[:, used] = bt[:, first]
    for k in more:  # the joint's further parameters, added in order
        values[:, index[k]] += bt[:, k]
    return values


def residuals(machine: Machine, d: Design, obs: Observations, theta, *, jacobian: bool = True, axes_user=None):
    """Residuals (tool point + offset − mark, µm) and their Jacobian.

    Parameters
    ----------
    machine, d, obs
    theta : array (P,)
        Effect parameters in their units.
    jacobian : bool
    axes_user : array (N, n_axes), optional
        Axis readings to use instead of ``obs.axes``.

    Returns
    -------
    r_um : array (N, 3)
    J : array (N, 3, P)
        ∂r/∂θ, µm per parameter unit (only with ``jacobian=True``).
    d_errors : array (N, 3, n_errors)
        ∂r/∂(error joint value), for scoring further effects (only with ``jacobian=True``).
    """
    axes_user = obs.axes if axes_user is None else axes_user
    values = joint_values(machine, d, np.asarray(theta, float))
    if not jacobian:
        p = evaluate(machine, axes_user, values, jacobian=False, offsets_mm=obs.offsets_mm)
        return (p - obs.w_mm) * 1e3
    p, d_err, _ = evaluate(machine, axes_user, values, offsets_mm=obs.offsets_mm)
    return (p - obs.w_mm) * 1e3, effect_columns(d_err, d), d_err


def effect_columns(d_errors: np.ndarray, d: Design) -> np.ndarray:
    """Jacobian (N, 3, P) of effects from the error-joint Jacobian (N, 3, n_errors)."""
    return d_errors[:, :, d.joint_index] * d.basis[:, None, :]
