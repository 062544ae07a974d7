"""Errors of the instrument, not of the machine: does the residual follow the offsets read?

Rows with the offset columns (``mark_dx_mm``, ``mark_dy_mm``, ``mark_dz_mm``) place the mark at the tool point
plus the offset in the tool frame. A camera whose pixel size is 1.5 % off reads every offset 1.5 % too long, one
turned by 2 mrad reads it turned; a laser whose scale is off reads the stand-off too long. The residual is then
the tool frame's rotation R times ``s·(dx, dy, 0)`` (scale), ``θ·(−dy, dx, 0)`` (rotation) or ``s·(0, 0, dz)``
(laser), a shape no error joint of the machine has: the selection would add machine errors that mimic it and
predict the machine worse. The three columns are scored together against the residual, projected off the model
(the score test of :mod:`.scoring`, at the same σ), and their sizes are estimated to first order.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from kinid.stats import chi2_logsf

from ..model import Machine
from ..data import Observations
from ..fitting import FitResult, design, residuals
from .scoring import fit_side

__all__ = ["InstrumentError", "instrument_errors", "INSTRUMENT_TERMS", "ABSORBED"]

#: A term whose column keeps less than this share of its norm off the model is the model's own (not scored).
ABSORBED = 1e-6

#: The instrument's errors scored: name, what it is, its unit in words.
INSTRUMENT_TERMS = (("camera-scale", "the camera's scale (pixel size) on mark_dx_mm and mark_dy_mm"),
                    ("camera-rotation", "the camera's rotation about the tool axis on mark_dx_mm and mark_dy_mm"),
                    ("laser-scale", "the laser's scale on mark_dz_mm"))


@dataclass(frozen=True)
class InstrumentError:
    """The score test of the instrument's errors at a fit.

    Attributes
    ----------
    statistic : float
        Predicted drop of the whitened sum of squares (χ² units) of the three terms together.
    k : int
        Terms the offsets read can show (a term whose offsets are all zero, or that the model holds, is left out).
    p_value : float
    sizes : dict name -> (size, standard deviation)
        Each term's size to first order: a scale as a fraction (0.015 is 1.5 % too long), a rotation in rad.
    """

    statistic: float
    k: int
    p_value: float
    sizes: dict

    @property
    def named(self) -> tuple:
        """The terms more than three standard deviations from zero, largest first."""
        big = [(abs(v / s), n) for n, (v, s) in self.sizes.items() if s > 0 and abs(v) > 3 * s]
        return tuple(n for _, n in sorted(big, reverse=True))

    def describe(self) -> str:
        words = []
        for n in self.named or tuple(self.sizes):
            v, s = self.sizes[n]
            what = dict(INSTRUMENT_TERMS)[n]
            amount = f"{v * 1e3:+.2f} ± {s * 1e3:.2f} mrad" if n == "camera-rotation" else f"{v:+.2%} ± {s:.2%}"
            words.append(f"{what}: {amount}")
        return "; ".join(words)


def instrument_errors(machine: Machine, obs: Observations, result: FitResult, sigma: float):
    """The score test of the instrument's errors at ``result`` (:class:`InstrumentError`); None for rows without
    offsets (alignments), where the instrument reads nothing."""
    if obs.offsets_mm is None or not np.any(obs.offsets_mm):
        return None
    d = design(machine, result.effects, obs)
    base = residuals(machine, d, obs, result.theta, jacobian=False)
    R = np.empty((len(obs), 3, 3))  # the tool frame's axes in the workpiece frame, per row (the offset's lever)
    for k in range(3):
        moved = obs.offsets_mm + np.eye(3)[k]
        R[:, :, k] = (residuals(machine, d, replace(obs, offsets_mm=moved), result.theta, jacobian=False) - base) * 1e-3
    dx, dy, dz = obs.offsets_mm.T
    zero = np.zeros(len(obs))
    local = {"camera-scale": np.column_stack([dx, dy, zero]), "camera-rotation": np.column_stack([-dy, dx, zero]),
             "laser-scale": np.column_stack([zero, zero, dz])}
    names = [n for n, _ in INSTRUMENT_TERMS if np.any(local[n])]
    # µm of residual per unit of the term (a fraction, a radian), whitened like the residual
    C = np.column_stack([np.einsum("nij,nj->ni", R, local[n]).ravel() * 1e3 / sigma for n in names])
    side = fit_side(machine, obs, result, sigma)
    before = np.linalg.norm(C, axis=0)
    C = C - side.q0 @ (side.q0.T @ C)
    # a term the model already holds is no error of the instrument it could see: the camera's rotation about the
    # tool axis is the tool set-up's own rotation (EC0T) where the model has it
    seen = np.linalg.norm(C, axis=0) > ABSORBED * before
    names, C = [n for n, ok in zip(names, seen) if ok], C[:, seen]
    if not names:
        return None
    u, s, vt = np.linalg.svd(C, full_matrices=False)
    keep = s > 1e-9 * max(float(s.max()), 1e-300)
    if not keep.any():
        return None
    proj = u[:, keep].T @ side.r
    statistic = float(proj @ proj)
    coef = vt[keep].T @ (proj / s[keep])
    cov = vt[keep].T @ np.diag(1.0 / s[keep] ** 2) @ vt[keep]
    k = int(keep.sum())
    p = math.exp(chi2_logsf(statistic, k))
    sizes = {n: (float(c), float(math.sqrt(max(cov[i, i], 0.0)))) for i, (n, c) in enumerate(zip(names, coef))}
    return InstrumentError(statistic, k, p, sizes)
