"""The tool point and its derivatives from Pinocchio's joint placements, for a chunk of poses
(the inside of :func:`~kinid.identification.model.machine.evaluate`); the rows that share every turning joint's
value grouped (:func:`_affine_plan`, for :func:`~kinid.identification.model.machine.evaluate_blocks`).

Per pose, one ``forwardKinematics`` and one copy of the joint placements (:func:`_read_placements`); the rest for
all poses at once, in numpy. Units: SI (m, rad) inside, the tool point in mm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .derived import derived

__all__ = []


@dataclass(frozen=True)
class _Columns:
    """What :func:`_evaluate_chunk` needs to know about the velocity columns asked for, worked out once per
    machine and set of columns (:func:`_columns`).

    Attributes
    ----------
    first, last : int
        The joints whose placements are read: the frames' parents and the columns' joints.
    workpiece, tool : slice
        The parent joint's 12 numbers in a pose's row of placements (R column-major, then p).
    workpiece_placement, tool_placement : array (12, 12)
        The frame's placement in its joint, as the matrix that maps a joint's 12 numbers to the frame's.
    take : array (6k,)
        Each column's axis R_k e_c (3 components, component-major) and then its joint's position, as places in a
        pose's row of placements (c: :func:`_joint_geometry`'s; 0 where the axis is along none of e_c).
    sliding : array of int
        The columns whose joint slides along ±e_c.
    other, other_joints, other_subspace, other_turning
        The columns whose joint's axis is along none of its frame's axes, their joints, motion subspaces (lin, ang)
        and whether they turn.
    signs : array (k,)
        ± of each column: its chain's (+ tool, − workpiece) times its axis's (±e_c).
    """

    first: int
    last: int
    workpiece: slice
    tool: slice
    workpiece_placement: np.ndarray
    tool_placement: np.ndarray
    take: np.ndarray
    sliding: np.ndarray
    other: np.ndarray
    other_joints: np.ndarray
    other_subspace: np.ndarray
    other_turning: np.ndarray
    signs: np.ndarray


def _columns(machine, columns: np.ndarray) -> _Columns:
    """The :class:`_Columns` of ``columns`` (velocity indices), kept on the machine: a fit asks the same each pass."""
    def make():
        model = machine.model
        wf, tf = model.frames[machine.workpiece_frame], model.frames[machine.tool_frame]
        jw, jt = wf.parentJoint, tf.parentJoint
        joint_of, axis, sign, subspace = _joint_geometry(machine)
        joints, ax = joint_of[columns], axis[columns]
        first, last = min(jw, jt, *joints), max(jw, jt, *joints)
        at, comp = (joints - first) * 12, np.arange(3)[:, None]
        other = np.flatnonzero(ax < 0)
        s = subspace[columns[other]]
        return _Columns(
            first, last, slice((jw - first) * 12, (jw - first + 1) * 12), slice((jt - first) * 12, (jt - first + 1) * 12),
            _placement_matrix(wf.placement), _placement_matrix(tf.placement),
            np.concatenate([(at + 3 * (np.maximum(ax, 0) % 3) + comp).ravel(), (at + 9 + comp).ravel()]),
            np.flatnonzero(ax >= 3), other, joints[other], s, np.any(s[:, 3:] != 0, axis=1),
            _chain_signs(machine, jw, jt)[columns] * sign[columns])
    return derived(machine, ("columns", columns.tobytes()), make)


def _placement_matrix(placement: pin.SE3) -> np.ndarray:
    """(12, 12) T such that the 12 numbers (R column-major, then p) of oMi · ``placement`` are those of oMi times T:
    composing every pose's placement with a constant one is then one matrix product."""
    T = np.zeros((12, 12))
    T[:9, :9] = np.kron(placement.rotation, np.eye(3))  # (R M)[r, d] = Σ_c R[r, c] M[c, d]
    T[:9, 9:] = np.kron(placement.translation[:, None], np.eye(3))  # R t + p
    T[9:, 9:] = np.eye(3)
    return T


def _evaluate_chunk(machine, data, qs: np.ndarray, jacobian: bool, offsets_m=None, columns=None):
    """Tool point (n, 3) mm and, with ``jacobian``, G (n, 3, len(columns)) m per SI unit (velocity ``columns``,
    default all), at configurations ``qs``; with ``offsets_m`` (n, 3), of the point that far from it (tool frame, m).

    A 1-DOF joint k's world-frame Jacobian column (``data.J``'s) is ang = R_k s, lin = p_k × ang (revolute, s its
    axis) or lin = R_k s (prismatic): only the columns asked for are formed. The point p_t is on the tool chain,
    the workpiece frame on the other, so d/dq_k of R_wᵀ (p_t − p_w) is ±R_wᵀ (lin_k − p_t × ang_k): + on the tool
    chain, − on the workpiece's (its frame turns about the same point)."""
    model, n = machine.model, qs.shape[0]
    columns = np.arange(model.nv) if columns is None else np.asarray(columns, dtype=int)
    c = _columns(machine, columns if jacobian else columns[:0])
    B = _read_placements(machine, data, qs, c.first, c.last).reshape(n, -1)  # a pose's placements in a row
    # frame placements oMf = oMi · (frame placement in its joint); a rotation's column-major 9 are its transpose's rows
    Fw, Ft = B[:, c.workpiece] @ c.workpiece_placement, B[:, c.tool] @ c.tool_placement
    # R_w held row by row and R_wᵀ as its transposed view: the products with R_wᵀ then round the same as before
    # this layout was chosen (matmul's kernel depends on the strides)
    RwT = Fw[:, :9].reshape(n, 3, 3).transpose(0, 2, 1).copy().transpose(0, 2, 1)
    pw, pt = Fw[:, 9:], Ft[:, 9:]
    if offsets_m is not None:  # a point fixed to the tool: p_t + R_t d (dᵀ R_tᵀ, R_tᵀ's rows: Ft's first 9)
        pt = pt + (offsets_m[:, None, :] @ Ft[:, :9].reshape(n, 3, 3))[:, 0]
    p = (RwT @ (pt - pw)[:, :, None])[:, :, 0] * 1e3  # R_wᵀ (p_t − p_w), mm
    if not jacobian:
        return p
    k = len(columns)
    # component-major (2, 3, k, n): the arithmetic below runs along all poses at once, not k at a time
    W, X = B.T[c.take].reshape(2, 3, k, n)  # R_k e_c, p_k (a copy)
    X -= pt.T[:, None, :]  # p_k − p_t
    D = np.empty((3, k, n))  # velocity of p_t: R_k e_c × (p_t − p_k) (= p_k × ω − p_t × ω) or R_k e_c (sliding)
    D[0] = X[1] * W[2] - X[2] * W[1]
    D[1] = X[2] * W[0] - X[0] * W[2]
    D[2] = X[0] * W[1] - X[1] * W[0]
    D[:, c.sliding] = W[:, c.sliding]
    if len(c.other):  # a joint axis along none of its frame's axes: R_k s (s: the lin or the ang part, the other 0)
        R = B.reshape(n, -1, 12)[:, c.other_joints - c.first, :9].reshape(n, len(c.other), 3, 3)
        Wo = np.einsum("nkcr,kc->rkn", R, c.other_subspace[:, :3] + c.other_subspace[:, 3:])
        D[:, c.other] = np.where(c.other_turning[:, None], np.cross(X[:, c.other], Wo, axis=0), Wo)
    D *= c.signs[:, None]
    return p, RwT @ D.transpose(2, 0, 1)


def _read_placements(machine, data, qs: np.ndarray, first: int, last: int) -> np.ndarray:
    """(n, last − first + 1, 12): ``data.oMi[first..last]`` (R column-major, then p) after ``forwardKinematics``
    at each configuration of ``qs``, through a live view of Pinocchio's array of placements (one copy per pose).

    The view's layout (SE3 after SE3: rotation, then translation) is checked once per ``data`` against the
    addresses of Pinocchio's own views and the values after a call; without it, the placements are read one by one."""
    model, cache = machine.model, machine.__dict__.setdefault("_placements_view_cache", {})
    if id(data) not in cache or cache[id(data)][0] is not data:
        live = [(data.oMi[j].rotation, data.oMi[j].translation) for j in range(model.njoints)]
        addr = [(R.__array_interface__["data"][0], t.__array_interface__["data"][0]) for R, t in live]
        step, view = (addr[1][0] - addr[0][0] if len(addr) > 1 else 96), None
        if step >= 96 and all(R.strides == (8, 24) and t.strides == (8,) and R.dtype == t.dtype == np.float64 and
                              a == (addr[0][0] + j * step, addr[0][0] + j * step + 72) for j, ((R, t), a) in
                              enumerate(zip(live, addr))):
            view = np.lib.stride_tricks.as_strided(live[0][0], (model.njoints, 12), (step, 8), writeable=False)
            q = pin.neutral(model)
            q[-1] += 0.25  # any configuration: not all placements the identity
            pin.forwardKinematics(model, data, q)
            view = view if np.array_equal(view, [np.r_[R.ravel(order="F"), t] for R, t in live]) else None
        cache[id(data)] = (data, view)  # the data, kept alive with the view into its memory
    view, out, kinematics = cache[id(data)][1], np.empty((qs.shape[0], last - first + 1, 12)), pin.forwardKinematics
    rows = view[first : last + 1] if view is not None else None  # live: refreshed by every call
    for i in range(qs.shape[0]):
        kinematics(model, data, qs[i])
        out[i] = rows if rows is not None else [np.r_[data.oMi[j].rotation.ravel(order="F"), data.oMi[j].translation]
                                                for j in range(first, last + 1)]
    return out


def _joint_geometry(machine):
    """Per velocity column: its joint, c and the sign where its motion is ±e_c of the joint's frame (c 0-2
    turning, 3-5 sliding along e_(c−3); c −1 otherwise), and its motion subspace (lin, ang) in that frame."""
    def make():
        model, data = machine.model, machine.model.createData()
        pin.computeJointJacobians(model, data, pin.neutral(model))
        joint_of, S = np.zeros(model.nv, dtype=int), np.zeros((model.nv, 6))
        for j in range(1, model.njoints):
            for v in range(model.idx_vs[j], model.idx_vs[j] + model.nvs[j]):
                joint_of[v], S[v] = j, pin.getJointJacobian(model, data, j, pin.ReferenceFrame.LOCAL)[:, v]
        unit, c = (np.count_nonzero(S, axis=1) == 1) & (np.abs(S).max(axis=1) == 1.0), np.argmax(np.abs(S), axis=1)
        return joint_of, np.where(unit, (c + 3) % 6, -1), np.where(unit, S[np.arange(model.nv), c], 1.0), S
    return derived(machine, "joint_geometry", make)


def _chain_signs(machine, jw: int, jt: int) -> np.ndarray:
    """(nv,) +1 on the velocity columns of the tool chain, −1 on the workpiece chain's, 0 elsewhere."""
    def make():
        model, signs = machine.model, np.zeros(machine.model.nv)
        for joint, sign in ((jt, 1.0), (jw, -1.0)):  # the joints that carry it (its support, itself included)
            signs[[v for j in model.supports[joint] if j > 0
                   for v in range(model.idx_vs[j], model.idx_vs[j] + model.nvs[j])]] = sign
        return signs
    return derived(machine, ("chain_signs", jw, jt), make)


#: Groups × (1 + the sliding values that vary) at most this share of the rows for
#: :func:`~kinid.identification.model.evaluate_blocks` to take the affine route (a group costs 1 + m evaluations of
#: a pose; a row, a gather and a small product).
AFFINE_SHARE = 0.25


def _affine_plan(machine, axes_user, errors_user, offsets_mm, groups=None):
    """The groups (rows with the same values of every turning joint, axis or error) and the sliding values that
    vary, of :func:`~kinid.identification.model.evaluate_blocks`; None where the groups are too many (or the rows
    carry offsets of their own). ``groups``: a store (a dict the caller keeps for the same rows, ``axes_user`` and
    ``offsets_mm`` unchanged) where the grouping of rows whose error values are one row for all is kept and taken
    from: it follows from the axes alone, and the passes of a fit ask for it at every parameter vector."""
    n = len(axes_user)
    constant = n > 0 and groups is not None and errors_user.strides[0] == 0  # a broadcast row: no error varies
    key = ("turning groups", AFFINE_SHARE, tuple(a.kind for a in machine.axes), errors_user.shape[1])
    if constant and key in groups:
        rows = groups[key]
    else:
        rows = _turning_groups(machine, axes_user, errors_user, offsets_mm)
        if constant:
            groups[key] = rows
    if rows is None:
        return None
    first, offsets = rows["first"], rows["offsets"]
    return dict(axes=axes_user[first], errors=errors_user[first], offsets=None if offsets is None else offsets[0],
                moving=rows["moving"], moves=rows["moves"], at=rows["at"], group=rows["group"])


def _turning_groups(machine, axes_user, errors_user, offsets_mm):
    """:func:`_affine_plan`'s grouping of the rows: their groups, each group's first row, the sliding values that
    vary and their values (each row's, each group's first row's); None where the groups are too many (or the rows
    carry offsets of their own)."""
    n, both = len(axes_user), (axes_user, errors_user)
    joints = [(0, j, a.kind) for j, a in enumerate(machine.axes)]
    joints += [(1, k, e.kind) for k, e in enumerate(machine.error_joints)]
    offsets = None if offsets_mm is None else np.broadcast_to(np.asarray(offsets_mm, float), (n, 3))
    if n == 0 or (offsets is not None and offsets.strides[0] != 0 and not (offsets == offsets[0]).all()):
        return None  # rows with offsets of their own (a camera beside a laser) are few
    varies = np.r_[(axes_user != axes_user[0]).any(axis=0),  # a broadcast row of error values: none varies
                   np.zeros(errors_user.shape[1], bool) if errors_user.strides[0] == 0
                   else (errors_user != errors_user[0]).any(axis=0)]
    turning = [both[w][:, i] for (w, i, kind), col in zip(joints, varies) if kind != "prismatic" and col]
    # Rows in runs of the same turning values (a plan's poses repeated) are grouped by the first row of each run:
    # the same values, groups and first rows as over every row, with sorts of the runs only.
    starts = np.ones(n, bool)
    starts[1:] = np.logical_or.reduce([t[1:] != t[:-1] for t in turning]) if turning else False
    heads = np.flatnonzero(starts)
    codes = np.zeros(len(heads), dtype=np.int64)
    for column in turning:
        values, inverse = np.unique(column[heads], return_inverse=True)
        if len(values) > AFFINE_SHARE * n or codes.max() >= (1 << 62) // len(values):
            return None
        codes = codes * len(values) + inverse.ravel()
    moving = [(w, i) for (w, i, kind), col in zip(joints, varies) if kind == "prismatic" and col]
    _, first, group = np.unique(codes, return_index=True, return_inverse=True)
    if len(first) * (1 + len(moving)) > AFFINE_SHARE * n:
        return None
    first, group = heads[first], group.ravel()[np.cumsum(starts) - 1]
    moves = np.column_stack([both[w][:, i] for w, i in moving]) if moving else np.zeros((n, 0))
    return dict(first=first, offsets=offsets, moving=moving, moves=moves, at=moves[first], group=group)
