"""Residuals of alignment observations and their Jacobian with respect to effect parameters.

The model's claim for a row (docs/formats.md, "Observation CSV"): the tool point (plus the row's
measured offset in the tool frame, if any), expressed in the workpiece frame, equals the mark. The
residual is the difference in µm. A row of a measured orientation (``obs.rotations``) claims the tool's orientation
instead: its residual is the small-angle vector of the model's against it, weighted to µm (:func:`put_rotation_rows`).
An effect's Jacobian column is its error joint's column (from Pinocchio) times
the basis value, so every effect, and the whole candidate library, is scored
from one kinematic pass.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..model import Machine, basis_values, evaluate, param_codes
from ..data import Observations

__all__ = ["Design", "design", "joint_values", "residuals", "effect_columns", "put_rotation_rows", "tool_rotations",
           "rotation_residual_urad"]

#: The lever of the points on the tool that give its orientation, mm (the point is affine in it: any length will do).
LEVER_MM = 1000.0


@dataclass(frozen=True)
class Design:
    """Basis values of a list of effects on a set of observations.

    Attributes
    ----------
    effects : tuple of Effect
    joint_index : array (P,)
        Error-joint index (in ``machine.error_joints``) of each parameter.
    basis : array (N, P)
        Basis value of each parameter at each observation (a read-only broadcast of one row where every basis is
        constant).
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
        index += [codes.index(c) for c in param_codes(e, machine)]
    if blocks and all((b == b[:1]).all() for b in blocks):  # every basis constant (location errors): one row for
        # all, read-only (a broadcast: no N × P array made, and nothing can write into it)
        basis = np.broadcast_to(np.concatenate([b[0] for b in blocks]), (len(obs), len(index)))
    else:  # column after column (Fortran order): the columns are copied whole, not a number at a time (0.9 ->
        # 0.1 s for 23 columns of a million alignments); every use of the basis is elementwise
        basis = np.concatenate([b.T for b in blocks]).T if blocks else np.zeros((len(obs), 0))
    return Design(tuple(effects), np.asarray(index, dtype=int), basis)


def joint_values(machine: Machine, d: Design, theta: np.ndarray, rows=slice(None)) -> np.ndarray:
    """Error-joint values (N, n_errors) in µm / µrad for parameters ``theta`` (P,) (of the ``rows`` of ``d``)."""
    basis = d.basis[rows]
    values = np.zeros((basis.shape[0], len(machine.error_joints)))
    if d.n_params == 0:
        return values
    bt = basis * theta
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
        put_rotation_rows(machine, axes_user, values, obs.w_mm, obs.rotations, obs.rotation_um_per_urad, p)
        return (p - obs.w_mm) * 1e3
    p, d_err, _ = evaluate(machine, axes_user, values, offsets_mm=obs.offsets_mm)
    put_rotation_rows(machine, axes_user, values, obs.w_mm, obs.rotations, obs.rotation_um_per_urad, p, d_err)
    return (p - obs.w_mm) * 1e3, effect_columns(d_err, d), d_err


def effect_columns(d_errors: np.ndarray, d: Design) -> np.ndarray:
    """Jacobian (N, 3, P) of effects from the error-joint Jacobian (N, 3, n_errors)."""
    return d_errors[:, :, d.joint_index] * d.basis[:, None, :]


def tool_rotations(machine: Machine, axes_user, errors_user, *, jacobian: bool = False, error_columns=None):
    """The tool frame's orientation in the workpiece frame (N, 3, 3) and, with ``jacobian``, the error joints'
    angular velocity columns (N, 3, n) in the workpiece frame, µrad per µrad (zero for a translation joint).

    From the tool point at ``LEVER_MM`` along each tool axis (:func:`~kinid.identification.model.evaluate`): the
    columns of R are the points' moves over the lever; a joint's column of a point at ``d`` is the tool point's plus
    ``a × R d``, so ``a = ½ Σₖ rₖ × cₖ`` with ``cₖ`` the difference per lever of axis k (rₖ ⊥ and unit)."""
    kw = dict(error_columns=error_columns, axes_jacobian=False) if jacobian else dict(jacobian=False)
    base = evaluate(machine, axes_user, errors_user, **kw)
    p0, G0 = (base[0], base[1]) if jacobian else (base, None)
    R = np.empty(p0.shape + (3,))
    A = None if G0 is None else np.zeros(G0.shape)
    for k, e in enumerate(np.eye(3) * LEVER_MM):
        out = evaluate(machine, axes_user, errors_user, offsets_mm=e, **kw)
        p, G = (out[0], out[1]) if jacobian else (out, None)
        R[:, :, k] = (p - p0) / LEVER_MM
        if A is not None:  # G in µm per µrad, the lever in mm: (G − G0)·1e3/lever = a × rₖ
            A += 0.5 * np.cross(R[:, :, k][:, :, None], (G - G0) * 1e3 / LEVER_MM, axis=1)
    return (R, A) if jacobian else R


def rotation_residual_urad(R_model, R_measured) -> np.ndarray:
    """ω (N, 3), µrad: ``R_model = exp([ω]×) R_measured``, in the frame both are expressed in."""
    from scipy.spatial.transform import Rotation  # here: a fit without orientation rows does not import scipy

    return Rotation.from_matrix(np.einsum("nij,nkj->nik", R_model, R_measured)).as_rotvec() * 1e6


def put_rotation_rows(machine: Machine, axes_user, errors_user, w_mm, rotations, um_per_urad, p_mm, G=None,
                      error_columns=None) -> None:
    """On the rows of a measured orientation (``um_per_urad`` > 0), put into ``p_mm`` (and ``G``) what makes
    ``(p − w)·1e3`` the row's residual, ω times its weight (µm), and ``G`` its Jacobian: in place, a chunk of an
    :func:`~kinid.identification.model.evaluate` pass at a time (``errors_user`` its error-joint values)."""
    if um_per_urad is None:
        return
    rows = np.flatnonzero(um_per_urad > 0)
    if not len(rows):
        return
    errors = np.asarray(errors_user, float)
    errors = errors[rows] if errors.ndim == 2 else errors
    out = tool_rotations(machine, axes_user[rows], errors, jacobian=G is not None, error_columns=error_columns)
    R, A = out if G is not None else (out, None)
    s = um_per_urad[rows]
    p_mm[rows] = w_mm[rows] + rotation_residual_urad(R, rotations[rows]) * s[:, None] * 1e-3
    if G is not None:
        G[rows] = A * s[:, None, None]
