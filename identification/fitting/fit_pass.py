"""One pass of the model over the alignments, a chunk at a time: the residuals, and the Jacobian compressed to the
R factor of its QR decomposition.

A least-squares step needs only JᵀJ and Jᵀr, and the identifiability analysis and the covariance only R: with
``J = Q R``, ``‖r + Jδ‖² = ‖r‖² − ‖Qᵀr‖² + ‖Qᵀr + Rδ‖²``. So the (3N × P) Jacobian is never held whole: each chunk
of :data:`CHUNK_ROWS` alignments is evaluated (Pinocchio) and folded into R by a QR of the stacked rows (TSQR), and
memory stays flat in the number of alignments (the residuals, 3N numbers, and the error joints' values are kept).
Rows that share every turning joint's value (the same table and head angles, the linear axes anywhere) are
evaluated once per group and its slopes along the linear axes
(:func:`~kinid.identification.model.evaluate_blocks`): a million alignments of a plan's 84 angle pairs cost 84 × 4
poses of Pinocchio, not a million.

Only the error joints the model's parameters sit on are in the pass: the others, at zero, are locked into the
placements of their neighbours (Pinocchio's ``buildReducedModel``, :func:`reduced`), so each ``forwardKinematics``
walks 28 joints instead of 58 for the default model of the B/C five-axis machine (1.68x faster, 336 poses in 0.47
against 0.80 ms); and the chunks are views of the design and of the observations' arrays.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pinocchio as pin

from ..model import Machine, evaluate, evaluate_blocks
from ..data import Observations
from .residuals import Design, joint_values, put_rotation_rows

__all__ = ["Pass", "model_pass_qr", "reduced", "residuals_chunked", "jacobian_chunks", "chunks", "CHUNK_ROWS"]

#: Alignments evaluated at a time.
CHUNK_ROWS = 10_000
#: Alignments evaluated and folded into R at a time by :func:`model_pass_qr`: a block's Jacobian is still in the
#: processor's cache when it is factorised (one QR of all rows at once runs at a third of the speed).
BLOCK_ROWS = 512


@dataclass(frozen=True)
class Pass:
    """Residuals and the compressed Jacobian at one parameter vector.

    Attributes
    ----------
    r : array (N, 3)
        Residuals, µm.
    R : array (P, P)
        ``J = Q R`` (J: the (3N × P) Jacobian, µm per parameter unit; Q with orthonormal columns).
    qtr : array (P,)
        ``Qᵀ r``.
    rest : float
        ``‖r‖² − ‖Qᵀr‖²``: the part of the residual no step can reach.
    """

    r: np.ndarray
    R: np.ndarray
    qtr: np.ndarray
    rest: float


def chunks(d: Design, obs: Observations, chunk: int):
    """(design, observations) of consecutive chunks of at most ``chunk`` alignments."""
    n = len(obs)
    for first in range(0, n, chunk):
        rows = np.arange(first, min(first + chunk, n))
        if len(rows) == n:
            yield d, obs
        else:
            yield replace(d, basis=d.basis[rows]), obs.subset(rows)


def _slices(d: Design, obs: Observations, chunk: int):
    """(design, axes, marks, offsets, orientation rows) of consecutive chunks of at most ``chunk`` alignments: views,
    not copies; the orientation rows (measured rotations, their weights) None without them."""
    n = len(obs)
    for lo in range(0, n, chunk):
        hi = min(lo + chunk, n)
        dc = d if (lo, hi) == (0, n) else replace(d, basis=d.basis[lo:hi])
        turned = None if obs.rotations is None else (obs.rotations[lo:hi], obs.rotation_um_per_urad[lo:hi])
        yield dc, obs.axes[lo:hi], obs.w_mm[lo:hi], None if obs.offsets_mm is None else obs.offsets_mm[lo:hi], turned


def _evaluated(machine, d: Design, obs: Observations, theta, chunk: int, **kw):
    """(design, observed points, :func:`~kinid.identification.model.evaluate`'s outputs with the orientation rows put
    in) of consecutive chunks of at most ``chunk`` alignments: the error joints' values of all rows first (one row
    for all where every basis is constant), then the chunks through
    :func:`~kinid.identification.model.evaluate_blocks` (rows that share the turning joints' values evaluated
    once)."""
    n, shape, basis = len(obs), (len(obs), len(machine.error_joints)), d.basis
    if n and (basis.strides[0] == 0 or (basis == basis[0]).all()):  # every basis constant: one row for all
        values = np.broadcast_to(joint_values(machine, d, theta, rows=slice(0, 1))[0], shape)
    else:
        values = np.empty(shape)
        for lo in range(0, n, chunk):  # a chunk's basis times θ at a time: no (N, P) product held
            values[lo: lo + chunk] = joint_values(machine, d, theta, rows=slice(lo, lo + chunk))
    parts = _slices(d, obs, chunk)
    # the rows' grouping by their turning axes' values is the same at every θ: made once per observations (which
    # are frozen), kept with them
    groups = obs.__dict__.setdefault("_turning_groups", {})
    blocks = evaluate_blocks(machine, obs.axes, values, block=chunk, offsets_mm=obs.offsets_mm, groups=groups, **kw)
    for (lo, hi, out), (dc, axes, w, _, turned) in zip(blocks, parts):
        if turned is not None:
            p, G = (out, None) if kw.get("jacobian", True) is False else out[:2]
            put_rotation_rows(machine, axes, values[lo:hi], w, *turned, p, G, error_columns=kw.get("error_columns"))
        yield dc, w, out


#: Reduced machines kept per machine (one per set of error joints in use), at most.
REDUCED_KEPT = 64


def reduced(machine: Machine, d: Design) -> tuple:
    """(machine, design) with only the error joints ``d``'s parameters sit on: the others, which a pass holds at
    zero, locked at zero into the placements around them (``pinocchio.buildReducedModel``). The pair gives the
    same tool points and Jacobian columns as the full one (to rounding: a locked joint's zero placement is folded
    into its neighbours' once); the design's joint indices are the reduced machine's. A machine whose every
    error joint is in use is returned as it is (a reduced one, again)."""
    used, column = d.joints[:2]
    if len(used) == len(machine.error_joints):
        return machine, d
    store = machine.__dict__.setdefault("_reduced", {})
    key = tuple(int(u) for u in used)
    small = store.get(key)  # one look-up: another thread may clear the store between two
    if small is None:  # made once per set of joints: 3-4 ms (the model, its data and geometry), 0.3 ms saved a pass
        if len(store) >= REDUCED_KEPT:  # the models of a selection past
            store.clear()
        small = store[key] = _reduced_machine(machine, key)
    return small, replace(d, joint_index=column)


def _reduced_machine(machine: Machine, used: tuple) -> Machine:
    """The machine with the error joints not in ``used`` (indices into ``machine.error_joints``) locked at zero."""
    model = machine.model
    keep = set(used)
    locked = [model.getJointId(e.code) for i, e in enumerate(machine.error_joints) if i not in keep]
    small = pin.buildReducedModel(model, locked, machine.configuration_parts[0])

    def moved(item, name):  # the same joint, at its places in the reduced model
        jid = small.getJointId(name)
        return replace(item, q_index=small.idx_qs[jid], v_index=small.idx_vs[jid])

    return replace(machine, model=small, axes=tuple(moved(a, a.joint) for a in machine.axes),
                   error_joints=tuple(moved(machine.error_joints[i], machine.error_joints[i].code) for i in used),
                   workpiece_frame=small.getFrameId(model.frames[machine.workpiece_frame].name),
                   tool_frame=small.getFrameId(model.frames[machine.tool_frame].name))


def residuals_chunked(machine: Machine, d: Design, obs: Observations, theta, *, chunk: int = CHUNK_ROWS) -> np.ndarray:
    """Residuals (N, 3), µm, evaluated a chunk at a time."""
    theta = np.asarray(theta, float)
    machine, d = reduced(machine, d)
    parts = [(p - w) * 1e3 for _, w, p in _evaluated(machine, d, obs, theta, chunk, jacobian=False)]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def jacobian_chunks(machine: Machine, d: Design, obs: Observations, theta, *, chunk: int = CHUNK_ROWS):
    """The Jacobian (n, 3, P) of ``d``'s parameters at ``theta``, µm per parameter unit, for consecutive chunks of at
    most ``chunk`` alignments: the pass of :func:`model_pass_qr` (the reduced machine, only the error joints in use),
    the rows given instead of folded into R."""
    theta = np.asarray(theta, float)
    machine, d = reduced(machine, d)
    used, column = d.joints[:2]
    one_each = np.array_equal(column, np.arange(d.n_params))
    for dc, _, (_, G, _) in _evaluated(machine, d, obs, theta, chunk, error_columns=used, axes_jacobian=False):
        yield (G if one_each else G[:, :, column]) * dc.basis[:, None, :]


def model_pass_qr(machine: Machine, d: Design, obs: Observations, theta, *, chunk: int = CHUNK_ROWS) -> Pass:
    """Residuals and the R factor of the Jacobian of ``d``'s parameters at ``theta``, chunk by chunk."""
    theta = np.asarray(theta, float)
    machine, d = reduced(machine, d)
    P = d.n_params
    used, column = d.joints[:2]  # the joints the parameters sit on
    one_each = np.array_equal(column, np.arange(P))  # each parameter on its own joint, in order: no gather
    parts = []
    top = np.zeros((0, P + 1))
    for dc, w, (p, G, _) in _evaluated(machine, d, obs, theta, min(chunk, BLOCK_ROWS), error_columns=used,
                                       axes_jacobian=False):
        n = len(p)
        stacked = np.empty((top.shape[0] + 3 * n, P + 1), order="F")  # LAPACK's order: qr's copy is a plain one
        stacked[: top.shape[0]] = top
        rows = stacked[top.shape[0]:].reshape(n, 3, P + 1)  # a view (the rows of an F-ordered block split in 3)
        # ∂r/∂θ_p = ∂p/∂(its joint) × basis_p, µm per parameter unit; the residual in the last column
        np.multiply(G if one_each else G[:, :, column], dc.basis[:, None, :], out=rows[:, :, :P])
        r = rows[:, :, P]
        np.subtract(p, w, out=r)
        r *= 1e3
        parts.append(r.copy())
        top = np.linalg.qr(stacked, mode="r")[: P + 1]
    if top.shape[0] < P + 1:
        top = np.vstack([top, np.zeros((P + 1 - top.shape[0], P + 1))])
    return Pass(np.concatenate(parts) if parts else np.zeros((0, 3)), top[:P, :P], top[:P, P], float(top[P, P] ** 2))
