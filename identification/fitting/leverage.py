"""Residual diagnostics at a fit: one Pinocchio pass, leverages and studentized residuals, replicate
noise, and the residuals as axis readings.

Below the fit and the diagnosis: the fit's set-aside of gross errors
(:mod:`~kinid.identification.fitting.outliers`) and the diagnosis both use them.
"""
from __future__ import annotations

import numpy as np

from ..model import Machine, evaluate
from ..data import Observations, exact_duplicates, row_groups
from .residuals import design, effect_columns, joint_values, put_rotation_rows

__all__ = ["model_pass", "hat_diagonal", "studentized", "noise_from_replicates", "axis_residuals"]


def noise_from_replicates(machine: Machine, obs: Observations, r_um: np.ndarray):
    """Pooled σ (µm per coordinate) from alignments repeated at the same pose, or None.

    Rows are replicates when they have the same mark, the same readings of the
    preset (non-prismatic) axes and the same approach directions. Rows that
    repeat another row exactly (every reading equal) are one measurement
    copied, not replicates, and are left out.
    """
    preset = [j for j, a in enumerate(machine.axes) if a.kind != "prismatic"]
    kept = np.ones(len(obs), bool)
    kept[[i for i, _ in exact_duplicates(obs)]] = False  # an exact copy is the same measurement, not a replicate
    rows = np.flatnonzero(kept)
    if rows.size == 0:
        return None
    readings = np.round(obs.axes[rows][:, preset], 9)
    # a pose with a reading missing is nobody's replicate: a group of its own
    alone = np.where(np.any(np.isnan(readings), axis=1), np.arange(1, rows.size + 1), 0)
    group, first = row_groups(np.asarray(obs.marks)[rows], readings, alone,
                              *(np.asarray(obs.directions[a])[rows] for a in sorted(obs.directions)))
    count = np.bincount(group, minlength=first.size)
    r = r_um[rows]
    sums = np.stack([np.bincount(group, weights=r[:, k], minlength=first.size) for k in range(3)], axis=1)
    mean = sums / count[:, None]
    dof = int(3 * np.sum(count - 1))
    return (np.sqrt(float(np.sum((r - mean[group]) ** 2)) / dof), dof) if dof else None


def model_pass(machine: Machine, obs: Observations, result, d_errors=None):
    """One Pinocchio pass at the fit: error-joint and axis Jacobians, and an orthonormal basis
    ``Q0`` (3N, rank) of the identifiable model columns — shared by the score test, the
    leverages and the axis residuals. Given ``d_errors`` (N, 3, n_errors), no pass: the basis from them (the axis
    Jacobian is then None)."""
    d0 = design(machine, result.effects, obs)
    d_axes = None
    if d_errors is None:
        values = joint_values(machine, d0, result.theta)
        p, d_errors, d_axes = evaluate(machine, obs.axes, values, offsets_mm=obs.offsets_mm)
        put_rotation_rows(machine, obs.axes, values, obs.w_mm, obs.rotations, obs.rotation_um_per_urad, p, d_errors)
        d_axes[obs.rotation_rows] = 0.0  # an orientation row's axis columns are not its point's: none given
    J0 = effect_columns(d_errors, d0).reshape(3 * len(obs), -1)[:, result.identifiable]
    Q0 = np.linalg.qr(J0, mode="reduced")[0] if J0.shape[1] else np.zeros((J0.shape[0], 0))
    return d_errors, d_axes, Q0


def hat_diagonal(q) -> np.ndarray:
    """The hat matrix's diagonal (N, 3) from an orthonormal basis ``q`` (3N, rank) of the identifiable columns."""
    return np.sum(q**2, axis=1).reshape(-1, 3)


def studentized(result, q0, sigma, *, h=None):
    """Per-alignment studentized residual norm and leverage (hat matrix Q0 Q0ᵀ of the identifiable Jacobian;
    ``h`` (N, 3) instead of ``q0``: its diagonal, from :func:`leverages`)."""
    r = result.residuals_um
    N = r.shape[0]
    h = hat_diagonal(q0) if h is None else h
    stud = np.sqrt(np.sum(r**2 / np.maximum(1 - h, 1e-12), axis=1)) / sigma
    return stud, h.sum(axis=1)


#: Alignments whose Jacobian rows :func:`leverages` holds at a time (a chunk's rows, not the data's: memory flat).
LEVERAGE_CHUNK = 4096


def leverages(machine: Machine, obs: Observations, result) -> np.ndarray:
    """The hat matrix's diagonal (N, 3) of the identifiable Jacobian at the fit: each row's ‖J_i R⁻¹‖² (R of
    J = QR). R is the fit's own (``result.jacobian_r``, from its last pass), else one pass more makes it; then one
    pass gives the rows, a chunk of :data:`LEVERAGE_CHUNK` alignments at a time, each a triangular solve: memory
    flat in the alignments."""
    from .fit_pass import jacobian_chunks, model_pass_qr

    d0 = design(machine, result.effects, obs)
    free = result.identifiable
    if not free.any():
        return np.zeros((len(obs), 3))
    R = getattr(result, "jacobian_r", None)
    if R is None or R.shape != (d0.n_params, d0.n_params) or result.n_observations != len(obs):
        R = model_pass_qr(machine, d0, obs, result.theta).R  # a fit loaded from its file, or of other rows
    Rf = np.linalg.qr(R[:, free], mode="r")[: int(free.sum())]
    # R⁻¹ of the small triangle once (no scipy import: 0.5 s), then each chunk's J_i R⁻¹ one matrix product: a
    # general solve per chunk (an LU of Rᵀ and two triangular solves of every row) took 0.9 s of 10⁶ alignments
    R_inv = np.linalg.solve(Rf, np.eye(len(Rf)))
    out = []
    for J in jacobian_chunks(machine, d0, obs, result.theta, chunk=LEVERAGE_CHUNK):
        rows = J.reshape(-1, d0.n_params)[:, free] @ R_inv  # J_i R⁻¹
        out.append(np.einsum("ij,ij->i", rows, rows).reshape(-1, 3))
    return np.concatenate(out) if out else np.zeros((0, 3))


def axis_residuals(machine: Machine, obs: Observations, result, *, d_axes=None):
    """Residuals as readings of the prismatic axes (measured − model), µm; and the axes' names.

    To first order, the readings at which the model puts the tool point on the
    mark differ from the measured ones by A⁻¹ r, with A the Jacobian of the
    tool point with respect to those axes (``d_axes``: from :func:`evaluate`
    at the fit, computed if not given).
    """
    cols = [j for j, a in enumerate(machine.axes) if a.kind == "prismatic"]
    names = tuple(machine.axes[j].name for j in cols)
    if len(cols) != 3:
        return np.full((len(obs), 3), np.nan), names
    if d_axes is None:
        _, d_axes, _ = model_pass(machine, obs, result)
    A = d_axes[:, :, cols]  # µm per mm
    out = np.full((len(obs), 3), np.nan)
    # axes that do not span the three directions at a pose (two parallel rails of a gantry, a tool point
    # that never moves in z) have no unique readings there
    ok = np.linalg.cond(A) < 1e8
    out[ok] = np.linalg.solve(A[ok], result.residuals_um[ok, :, None])[:, :, 0] * 1e3
    return out, names
