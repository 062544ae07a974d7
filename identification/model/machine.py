"""Machines: a URDF with ISO 230-1 error joints, loaded into Pinocchio (docs/machines.md).

:func:`load_machine` discovers the motion axes and error joints and checks the
naming and placement convention. :func:`evaluate` gives the tool point in the
workpiece frame and its derivatives with respect to every joint, from
Pinocchio's forward kinematics (the joint placements).

Units: axis readings in mm (prismatic) and degrees (revolute) at this
module's boundary; error-joint values in µm (prismatic) and µrad (revolute);
Pinocchio works in metres and radians inside.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import numpy as np
import pinocchio as pin

from kinid.checks import check_array
from kinid.errors import DataError, MachineError
from kinid.files import captured_stderr, read_limited_text
from .placements import _affine_plan, _evaluate_chunk
from .urdf_checks import (_ERROR_CODE, MAX_URDF_BYTES, _ancestors, _axis_names, _check_placement,  # noqa: F401
                          joint_kind, _urdf_origins, check_urdf_limits)

__all__ = ["axis_limits", "check_machine", "Axis", "ErrorJoint", "Machine", "load_machine", "machine_from_urdf",
           "evaluate", "evaluate_blocks", "tool_in_workpiece_mm", "tool_rotation_in_workpiece"]

_UNIT = {"prismatic": "mm", "revolute": "deg"}


@dataclass(frozen=True)
class Axis:
    """A motion axis of the machine.

    Attributes
    ----------
    name : str
        Short axis name (``X``, ``B``, ``J1`` ...): the URDF joint's name where that is letters and
        digits, else the name the URDF's ``<kinid><axis joint=... name=.../></kinid>`` gives it, else
        ``J<n>`` (its place among the motion joints, in URDF order). Used in CSV columns and error codes.
    kind : {"prismatic", "revolute"}
    chain : {"workpiece", "tool"}
    column : str
        Its column in observation files: ``x_mm``, ``b_deg`` ...
    q_index, v_index : int
        Position in Pinocchio's configuration / velocity vector.
    nq : int
        1, or 2 for a continuous (unbounded revolute) joint stored as (cos, sin).
    joint : str
        The joint's name in the URDF (``shoulder_pan_joint``); the short name if empty.
    """

    name: str
    kind: str
    chain: str
    column: str
    q_index: int
    v_index: int
    nq: int = 1
    joint: str = ""

    def __post_init__(self):
        if not self.joint:
            object.__setattr__(self, "joint", self.name)


@dataclass(frozen=True)
class ErrorJoint:
    """An error joint named by its ISO 230-1 code.

    Attributes
    ----------
    code : str
        ``EXX``, ``EC0Y``, ``EX0W`` ...
    direction : str
        Error direction letter ``X Y Z`` (translation) or ``A B C`` (rotation).
    axis : str
        The axis it belongs to (``W``/``T`` for set-up).
    location : bool
        True for a location (position-independent) error ``E<d>0<k>``.
    kind : {"prismatic", "revolute"}
    unit : {"um", "urad"}
        Unit of its value at kinid's boundary.
    q_index, v_index : int
    """

    code: str
    direction: str
    axis: str
    location: bool
    kind: str
    unit: str
    q_index: int
    v_index: int


@dataclass(frozen=True)
class Machine:
    """A loaded machine: Pinocchio model plus the discovered axes and error joints."""

    path: str
    urdf: str
    model: pin.Model
    axes: tuple
    error_joints: tuple
    workpiece_frame: int
    tool_frame: int

    def __repr__(self) -> str:
        return f"Machine({self.path!r}: axes {', '.join(self.axis_names)}; {len(self.error_joints)} error joints)"

    def axis(self, name: str) -> Axis:
        for a in self.axes:
            if a.name == name:
                return a
        raise KeyError(name)

    def error_joint(self, code: str) -> ErrorJoint:
        for e in self.error_joints:
            if e.code == code:
                return e
        raise KeyError(code)

    @functools.cached_property
    def axis_names(self) -> tuple:
        return tuple(a.name for a in self.axes)

    @functools.cached_property  # read thousands of times per diagnosis; the fields are frozen
    def error_codes(self) -> tuple:
        return tuple(e.code for e in self.error_joints)

    @functools.cached_property
    def urdf_sha256(self) -> str:
        """SHA-256 of the machine's URDF text: what tells two results of the same machine (a fit, a verification,
        a calibration in the history) from results of different ones."""
        import hashlib

        return hashlib.sha256(self.urdf.encode()).hexdigest()

    @functools.cached_property  # every pass of a fit asks
    def velocity_columns(self) -> tuple:
        """(error joints' velocity indices, axes' velocity indices, the axes' scale from the SI derivative (m per m,
        m per rad) to µm per mm or µm per deg)."""
        parts = (np.array([e.v_index for e in self.error_joints], dtype=int),
                 np.array([a.v_index for a in self.axes], dtype=int),
                 np.array([1e3 if a.kind == "prismatic" else 1e6 * np.pi / 180.0 for a in self.axes]))
        for a in parts:
            a.flags.writeable = False
        return parts

    @functools.cached_property  # every pass of a fit asks
    def configuration_parts(self) -> tuple:
        """(Pinocchio's neutral configuration, the error joints' places in a configuration)."""
        neutral = pin.neutral(self.model)
        neutral.flags.writeable = False
        return neutral, np.array([e.q_index for e in self.error_joints], dtype=int)

    @functools.cached_property
    def parsed_effects(self) -> dict:
        """Effect names parsed against this machine (:func:`~kinid.identification.model.effects.parse_effect`), by
        name: a diagnosis parses the names of its ~800 candidates again in each of its tests."""
        return {}


def load_machine(path) -> Machine:
    """Load a machine URDF and check it against docs/machines.md.

    Parameters
    ----------
    path : str or Path
        URDF file.

    Returns
    -------
    Machine

    Raises
    ------
    MachineError
        If the file cannot be read or parsed, a ``workpiece`` or ``tool`` link
        is missing, or an error joint breaks the naming/placement convention
        (the message names the joint and what is wrong).
    """
    path = Path(path)
    text = read_limited_text(path, what="machine file", max_bytes=MAX_URDF_BYTES, error=MachineError)
    return machine_from_urdf(text, path)


def machine_from_urdf(text: str, path="<urdf>") -> Machine:
    """Build a :class:`Machine` from URDF text; ``path`` names it in messages."""
    root = check_urdf_limits(text, path)
    origins = _urdf_origins(root, path)
    with captured_stderr() as said:
        try:
            model = pin.buildModelFromXML(text)
        except Exception as exc:  # Pinocchio raises ValueError/RuntimeError for malformed URDF
            first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
            model, failure = None, first
    if model is None:
        extra = said.text.strip().splitlines()
        detail = failure if not extra else f"{failure}; the URDF parser said: {extra[0][:200]}"
        raise MachineError(f"not a valid URDF ({detail})", path=path)

    frames = {}
    for name in ("workpiece", "tool"):
        if not model.existFrame(name):
            raise MachineError(f"no link named {name!r}; the {name} chain must end at a link named {name!r} (a URDF "
                               f"without kinid's error joints, a ROS robot or a machine drawn elsewhere, becomes one "
                               f"with kinid model --urdf FILE --tool LINK --out MACHINE.urdf: docs/machines.md)",
                               path=path)
        frames[name] = model.getFrameId(name)
    chains = {c: set(_ancestors(model, model.frames[frames[c]].parentJoint)) for c in frames}

    short = _axis_names(model, root, path)
    axes, errors, pending = [], [], []
    for jid in range(1, model.njoints):
        name = model.names[jid]
        jmodel = model.joints[jid]
        kind, direction = joint_kind(jmodel)
        in_chain = [c for c in ("workpiece", "tool") if jid in chains[c]]
        where = f"joint {name!r}"
        if kind is None:
            raise MachineError(f"{where} has type {jmodel.shortname()}; only 1-DOF prismatic/revolute joints are supported", path=path)
        if len(in_chain) != 1:
            raise MachineError(f"{where} is on neither the workpiece nor the tool chain" if not in_chain else f"{where} is on both chains", path=path)
        m = _ERROR_CODE.match(name)
        if m:
            d, zero, k = m.group(1), m.group(2) == "0", m.group(3)
            want_kind = "prismatic" if d in "XYZ" else "revolute"
            if kind != want_kind:
                raise MachineError(f"{where}: direction {d} needs a {want_kind} joint, found {kind}", path=path)
            want_axis = np.eye(3)["XYZ".index(d) if d in "XYZ" else "ABC".index(d)]
            if not np.allclose(direction, want_axis, atol=1e-9):
                raise MachineError(f"{where}: axis must be {want_axis.astype(int).tolist()} (direction {d}), found {np.round(direction, 6).tolist()}", path=path)
            origin = origins.get(name, ((0.0,) * 3, (0.0,) * 3))
            if not np.allclose(np.r_[origin[0], origin[1]], 0.0, atol=1e-12):
                raise MachineError(f"{where}: an error joint must have a zero origin (xyz and rpy 0), found xyz={list(origin[0])} rpy={list(origin[1])}", path=path)
            pending.append((jid, name, d, zero, k, in_chain[0]))
            errors.append(
                ErrorJoint(name, d, k, zero, kind, "um" if kind == "prismatic" else "urad", model.idx_qs[jid], model.idx_vs[jid])
            )
        else:
            axis_name = short[name]
            axes.append(Axis(axis_name, kind, in_chain[0], f"{axis_name.lower()}_{_UNIT[kind]}", model.idx_qs[jid],
                             model.idx_vs[jid], model.nqs[jid], name))
    axis_ids = {a.name: model.getJointId(a.joint) for a in axes}
    for jid, name, d, zero, k, chain in pending:
        _check_placement(model, jid, name, zero, k, chain, axis_ids, frames, path)
    if not axes:
        raise MachineError("no motion axes (prismatic/revolute joints whose names are not error codes)", path=path)
    return Machine(str(path), text, model, tuple(axes), tuple(errors), frames["workpiece"], frames["tool"])


def _configurations(machine: Machine, axes_si: np.ndarray, errors_si: np.ndarray) -> np.ndarray:
    """Pinocchio configurations (N, nq) for N poses at once (SI, machine order)."""
    neutral, error_q = machine.configuration_parts
    q = np.empty((axes_si.shape[0], len(neutral)))
    q[:] = neutral
    for j, a in enumerate(machine.axes):
        if a.nq == 2:
            q[:, a.q_index] = np.cos(axes_si[:, j])
            q[:, a.q_index + 1] = np.sin(axes_si[:, j])
        else:
            q[:, a.q_index] = axes_si[:, j]
    if len(error_q):
        q[:, error_q] = errors_si
    return q


def axis_limits(machine: Machine) -> np.ndarray:
    """(n_axes, 2) travel of each axis from the URDF joint limits, mm / deg; ±inf where the URDF gives none."""
    from .derived import derived

    def read():  # every periodic effect parsed asks: the model is read once
        out = np.full((len(machine.axes), 2), [-np.inf, np.inf])
        for j, a in enumerate(machine.axes):  # a continuous joint (nq 2) has no limits
            lo, hi = (machine.model.lowerPositionLimit[a.q_index], machine.model.upperPositionLimit[a.q_index]) \
                if a.nq == 1 else (np.nan, np.nan)
            if np.isfinite(lo) and np.isfinite(hi) and hi > lo and abs(hi) < 1e10:
                out[j] = np.array([lo, hi]) * (1e3 if a.kind == "prismatic" else 180.0 / np.pi)
        return out
    return derived(machine, "axis_limits", read).copy()


def axes_to_si(machine: Machine, axes_user: np.ndarray) -> np.ndarray:
    """Axis readings (..., n_axes) in mm / deg to m / rad."""
    scale = np.array([1e-3 if a.kind == "prismatic" else np.pi / 180.0 for a in machine.axes])
    return np.asarray(axes_user, dtype=float) * scale


def errors_to_si(machine: Machine, errors_user: np.ndarray) -> np.ndarray:
    """Error-joint values (..., n_errors) in µm / µrad to m / rad."""
    return np.asarray(errors_user, dtype=float) * 1e-6


def check_machine(machine, name: str = "machine") -> "Machine":
    """``machine`` if it is a :class:`Machine`; DataError naming the argument otherwise."""
    if not isinstance(machine, Machine):
        hint = " (load it with kinid.identification.load_machine(path))" if isinstance(machine, (str, Path)) else ""
        raise DataError(f"must be a Machine{hint}, got {type(machine).__name__}", parameter=name)
    return machine


def evaluate(machine: Machine, axes_user, errors_user, *, jacobian: bool = True, offsets_mm=None, error_columns=None,
             axes_jacobian: bool = True):
    """Tool point (or a point at an offset from it) in the workpiece frame and its derivatives, for a batch of poses.

    Parameters
    ----------
    machine : Machine
    axes_user : array (N, n_axes)
        Axis readings in machine-axis order (``machine.axes``), mm or deg.
    errors_user : array (N, n_errors) or (n_errors,)
        Error-joint values in ``machine.error_joints`` order, µm or µrad.
    jacobian : bool
        Also return the derivatives.
    offsets_mm : array (N, 3) or (3,), optional
        A point fixed to the tool, given in the ``tool`` frame relative to the tool point, mm
        (where the camera and laser saw the mark); default the tool point itself.
    error_columns : sequence of int, optional
        Indices into ``machine.error_joints``: ``d_errors`` has only these joints, in this order (default all).
    axes_jacobian : bool
        Compute ``d_axes`` (None in its place otherwise).

    Returns
    -------
    p_mm : array (N, 3)
        Tool point (plus ``offsets_mm`` in the tool frame) expressed in the workpiece frame, mm.
    d_errors : array (N, 3, n_errors)
        ∂p/∂(error joint value) in µm per µm (prismatic) or µm per µrad (revolute).
    d_axes : array (N, 3, n_axes)
        ∂p/∂(axis reading) in µm per mm (prismatic) or µm per deg (revolute).
    """
    check_machine(machine)
    axes_user = check_array("axes_user", np.atleast_2d(np.asarray(axes_user, dtype=float)), shape=(None, len(machine.axes)))
    errors_user = np.asarray(errors_user, dtype=float)
    if errors_user.shape not in ((len(machine.error_joints),), (axes_user.shape[0], len(machine.error_joints))):
        raise DataError(f"must have shape ({len(machine.error_joints)},) or ({axes_user.shape[0]}, "
                        f"{len(machine.error_joints)}), got {errors_user.shape}", parameter="errors_user")
    check_array("errors_user", errors_user)
    if offsets_mm is not None:
        offsets_mm = np.asarray(offsets_mm, dtype=float)
        if offsets_mm.shape not in ((3,), (axes_user.shape[0], 3)):
            raise DataError(f"must have shape (3,) or ({axes_user.shape[0]}, 3), got {offsets_mm.shape}", parameter="offsets_mm")
        check_array("offsets_mm", offsets_mm)
        offsets_mm = np.broadcast_to(offsets_mm, (axes_user.shape[0], 3))
    data = _pinocchio_data(machine)
    n = axes_user.shape[0]
    errors_user = np.broadcast_to(errors_user, (n, len(machine.error_joints)))
    ev_all, av, axis_scale = machine.velocity_columns
    ev = ev_all if error_columns is None else ev_all[np.asarray(error_columns, dtype=int)]
    av = av if axes_jacobian else av[:0]
    p = np.empty((n, 3))
    d_err = np.empty((n, 3, len(ev))) if jacobian else None
    d_ax = np.empty((n, 3, len(av))) if jacobian and axes_jacobian else None
    for lo in range(0, n, EVALUATE_CHUNK):  # chunks keep the Pinocchio copies small (in the cache) whatever N is
        hi = min(lo + EVALUATE_CHUNK, n)
        qs = _configurations(machine, axes_to_si(machine, axes_user[lo:hi]), errors_to_si(machine, errors_user[lo:hi]))
        out = _evaluate_chunk(machine, data, qs, jacobian, None if offsets_mm is None else offsets_mm[lo:hi] * 1e-3,
                              np.concatenate([ev, av]))
        if not jacobian:
            p[lo:hi] = out
            continue
        p[lo:hi], G = out
        d_err[lo:hi] = G[:, :, : len(ev)]
        if d_ax is not None:
            d_ax[lo:hi] = G[:, :, len(ev):] * axis_scale
    return (p, d_err, d_ax) if jacobian else p


#: Poses per chunk of :func:`evaluate`.
EVALUATE_CHUNK = 512


#: Rows :func:`evaluate_blocks` makes at once on the affine route (their gathered slopes, 1.7 MB for the B/C
#: machine's 23 error joints, stay in the processor's cache: a pass over 10⁶ rows 0.1-0.2 s faster than at 4096).
AFFINE_ROWS = 1024


def evaluate_blocks(machine: Machine, axes_user, errors_user, *, block: int, offsets_mm=None, groups=None, **kw):
    """``(lo, hi, evaluate(rows lo..hi))`` for consecutive blocks of at most ``block`` rows: :func:`evaluate`'s
    outputs, computed once per group of rows that share every turning joint's value where that pays.

    With the turning joints (revolute axes and error joints) held, every placement turns the same, so the tool point
    and each Jacobian column are affine in the sliding joints' values. The rows are grouped by the turning values
    that vary; each group is evaluated at its first row and at that row moved by one metre along each sliding value
    that varies; a row is its group's value plus the slopes times its moves (the same to rounding). With too many
    groups (``placements.AFFINE_SHARE``) or offsets that vary, every block is evaluated pose by pose. Same
    arguments as :func:`evaluate`, over all N rows (``errors_user`` (N, n_errors)); ``groups``: a dict kept by the
    caller for these rows (``axes_user`` and ``offsets_mm`` unchanged), where the rows' grouping is kept from one
    call to the next when ``errors_user`` is one row broadcast (the passes of a fit: the grouping follows from the
    axes alone)."""
    n = len(axes_user)
    plan = _affine_plan(machine, axes_user, errors_user, offsets_mm, groups)
    if plan is None:
        for lo in range(0, n, block):
            off = None if offsets_mm is None else np.broadcast_to(offsets_mm, (n, 3))[lo:lo + block]
            yield lo, min(lo + block, n), evaluate(machine, axes_user[lo:lo + block], errors_user[lo:lo + block],
                                                   offsets_mm=off, **kw)
        return
    base, slopes, places = _affine_coefficients(machine, plan, kw)
    span = block * max(1, AFFINE_ROWS // block)  # rows yielded from one array, a block at a time
    for first in range(0, n, span):
        last = min(first + span, n)
        flat = np.empty((last - first, base.shape[1]))
        for a in range(first, last, AFFINE_ROWS):  # made AFFINE_ROWS at a time: the gathered slopes stay in cache
            b = min(a + AFFINE_ROWS, last)
            g = plan["group"][a:b]
            np.add(base[g], np.einsum("nm,nmf->nf", plan["moves"][a:b] - plan["at"][g], slopes[g]),
                   out=flat[a - first:b - first])
        for lo in range(first, last, block):
            rows = flat[lo - first:lo - first + block]
            out = tuple(None if p is None else rows[:, p[1]:p[2]].reshape((len(rows), *p[0])) for p in places)
            yield lo, lo + len(rows), out if kw.get("jacobian", True) else out[0]


def _affine_coefficients(machine, plan, kw):
    """(value at each group's first row (G, f), slopes per unit move (G, m, f), each output's (shape per row, first
    and last column + 1 in f) or None)."""
    G, m = len(plan["axes"]), len(plan["moving"])
    axes, errors = np.tile(plan["axes"], (1 + m, 1)), np.tile(plan["errors"], (1 + m, 1))
    for k, (which, i) in enumerate(plan["moving"]):  # one metre: 1000 mm, 1e6 µm
        (axes if which == 0 else errors)[(k + 1) * G:(k + 2) * G, i] += 1e3 if which == 0 else 1e6
    out = evaluate(machine, axes, errors, offsets_mm=plan["offsets"], **kw)
    out = out if isinstance(out, tuple) else (out,)
    flat = np.concatenate([o.reshape(len(axes), -1) for o in out if o is not None], axis=1).reshape(1 + m, G, -1)
    steps = np.array([1e3 if which == 0 else 1e6 for which, _ in plan["moving"]])[:, None, None]
    ends = np.cumsum([0] + [o[0].size for o in out if o is not None])
    places = iter(zip(ends[:-1], ends[1:]))  # each output's columns in a row of flat
    return (flat[0], ((flat[1:] - flat[0]) / steps).transpose(1, 0, 2),
            [None if o is None else (o.shape[1:], *next(places)) for o in out])


def tool_rotation_in_workpiece(machine: Machine, axes_user, errors_user) -> np.ndarray:
    """Rotation (N, 3, 3) of the ``tool`` frame in the workpiece frame: its columns are the tool
    frame's x, y, z axes expressed in the workpiece frame."""
    p0 = evaluate(machine, axes_user, errors_user, jacobian=False)
    # the offset point is affine in the offset: p(d) = p0 + R d
    return np.stack([evaluate(machine, axes_user, errors_user, jacobian=False, offsets_mm=e) - p0
                     for e in np.eye(3)], axis=2)


def _pinocchio_data(machine: Machine):
    """A Pinocchio ``Data`` for ``machine``, made once per thread (making one costs milliseconds)."""
    import threading

    cache = machine.__dict__.setdefault("_data_cache", {})
    key = threading.get_ident()
    if key not in cache:
        cache[key] = machine.model.createData()
    return cache[key]


def tool_in_workpiece_mm(machine: Machine, axes: Mapping[str, float], joint_errors: Mapping[str, float] | None = None) -> np.ndarray:
    """Tool point in the workpiece frame (mm) at one pose.

    Parameters
    ----------
    machine : Machine
    axes : mapping
        Axis name -> reading (mm or deg); missing axes are 0.
    joint_errors : mapping, optional
        Error code -> value (µm or µrad); missing joints are 0.

    Returns
    -------
    array (3,)
        mm.

    Examples
    --------
    >>> from kinid.urdf import path
    >>> m = load_machine(path("five_axis_bc"))
    >>> tool_in_workpiece_mm(m, {"X": 10.0}).round(6).tolist()
    [10.0, 0.0, 0.0]
    """
    joint_errors = joint_errors or {}
    unknown = set(axes) - set(machine.axis_names)
    if unknown:
        raise MachineError(f"unknown axes {sorted(unknown)}; this machine has {list(machine.axis_names)}", path=machine.path)
    unknown = set(joint_errors) - set(machine.error_codes)
    if unknown:
        raise MachineError(f"unknown error joints {sorted(unknown)}", path=machine.path)
    a = np.array([[axes.get(n, 0.0) for n in machine.axis_names]])
    e = np.array([joint_errors.get(c, 0.0) for c in machine.error_codes])
    return evaluate(machine, a, e, jacobian=False)[0]
