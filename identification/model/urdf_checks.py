"""Reading a machine URDF safely and checking it against docs/machines.md, before and after Pinocchio.

Size limits checked before parsing (file size, joints, chain depth, no DOCTYPE or entities); the
origins as written in the file (Pinocchio folds fixed joints into the next placement); the short axis
names of the motion joints; the kind and axis of a 1-DOF joint; the placement rules of error joints.
Used by :func:`~kinid.identification.model.machine.machine_from_urdf`.
"""
from __future__ import annotations

import re

import numpy as np
import pinocchio as pin

from kinid.errors import MachineError

__all__ = ["check_urdf_limits", "joint_kind", "MAX_URDF_BYTES", "MAX_URDF_JOINTS", "MAX_CHAIN_DEPTH"]


_ERROR_CODE = re.compile(r"^E([XYZABC])(0?)([A-Z][A-Z0-9]*)$")


_AXIS_NAME = re.compile(r"^[A-Z][A-Z0-9]*$", re.IGNORECASE)


_LOOKS_LIKE_CODE = re.compile(r"^E([A-Z])(0?)([A-Z][A-Z0-9]*)$")


def joint_kind(jmodel) -> tuple[str | None, np.ndarray | None]:
    """(kind, unit axis in the joint frame) of a 1-DOF joint, else (None, None)."""
    short = jmodel.shortname()
    m = re.fullmatch(r"JointModel(P|R|RUB)([XYZ])", short)
    if m:
        axis = np.zeros(3)
        axis["XYZ".index(m.group(2))] = 1.0
        return ("prismatic" if m.group(1) == "P" else "revolute"), axis
    if short in ("JointModelPrismaticUnaligned", "JointModelRevoluteUnaligned", "JointModelRevoluteUnboundedUnaligned"):
        kind = "prismatic" if "Prismatic" in short else "revolute"
        concrete = jmodel.extract() if hasattr(jmodel, "extract") else jmodel  # the generic wrapper has no axis
        if hasattr(concrete, "axis"):
            axis = np.asarray(concrete.axis, dtype=float).reshape(3)
        else:  # the unbounded unaligned joint's binding has no axis: read it from the motion subspace
            jdata = jmodel.createData()
            jmodel.calc(jdata, np.array([1.0, 0.0]))
            S = np.asarray(jdata.S, dtype=float).reshape(6)
            axis = S[:3] if kind == "prismatic" else S[3:]
        norm = float(np.linalg.norm(axis))
        return (kind, axis / norm) if norm > 1e-12 else (None, None)
    return None, None


def _ancestors(model: pin.Model, joint_id: int) -> list[int]:
    """Joint ids from the root (exclusive) to ``joint_id`` (inclusive)."""
    chain = []
    j = joint_id
    while j != 0:
        chain.append(j)
        j = model.parents[j]
    return chain[::-1]


#: Limits on a URDF before any parser sees it (a machine has tens of joints; a robot a few hundred).
MAX_URDF_BYTES = 8 * 1024 * 1024


MAX_URDF_JOINTS = 2000


MAX_CHAIN_DEPTH = 200


def check_urdf_limits(text: str, path):
    """Refuse URDF text that is too large, declares entities, or nests its links deeper than a machine could;
    return its parsed XML root (the one parse of the text that the other checks share).

    Pinocchio recurses along the kinematic tree, so a file of thousands of
    nested links would crash the process; the depth is checked here first.
    """
    import xml.etree.ElementTree as ET

    if len(text) > MAX_URDF_BYTES:
        raise MachineError(f"URDF is larger than {MAX_URDF_BYTES:,} characters", path=path)
    upper = text.upper()
    if "<!DOCTYPE" in upper or "<!ENTITY" in upper:
        raise MachineError("URDF declares a DOCTYPE or entities; kinid reads plain URDF only", path=path)
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        line, column = getattr(exc, "position", (None, None))
        hint = "; a xacro file: run xacro first (xacro robot.urdf.xacro > robot.urdf)" if "xacro:" in text else ""
        raise MachineError(f"not valid XML ({str(exc).split(':')[0]} at column {column + 1}){hint}", path=path,
                           line=line) from None
    xacro = next((el.tag for el in root.iter() if isinstance(el.tag, str) and "xacro" in el.tag.partition("}")[0]),
                 None)
    if xacro is not None:
        raise MachineError(f"holds xacro macros (<xacro:{xacro.rsplit('}', 1)[-1]}>), which kinid does not expand; "
                           f"run xacro first (xacro robot.urdf.xacro > robot.urdf)", path=path)
    if root.tag != "robot":
        raise MachineError(f"not a URDF: the root element is <{root.tag}>, expected <robot>", path=path)
    joints = root.findall("joint")
    if len(joints) > MAX_URDF_JOINTS:
        raise MachineError(f"URDF has {len(joints)} joints, more than the limit of {MAX_URDF_JOINTS}", path=path)
    parent_of = {}
    for j in joints:
        parent, child = j.find("parent"), j.find("child")
        if parent is not None and child is not None:
            parent_of[child.get("link")] = parent.get("link")
        if j.get("type") in ("prismatic", "revolute", "continuous"):
            axis = j.find("axis")
            raw = axis.get("xyz", "1 0 0") if axis is not None else "1 0 0"
            try:
                v = [float(x) for x in raw.split()]
            except ValueError:
                v = []
            if len(v) != 3 or not all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
                raise MachineError(f"joint {j.get('name')!r}: axis xyz={raw!r} is not a non-zero direction", path=path)
    for link in parent_of:
        depth, seen = 0, set()
        while link in parent_of:
            if link in seen:
                raise MachineError(f"link {link!r} is its own ancestor (a loop in the joints)", path=path)
            seen.add(link)
            link = parent_of[link]
            depth += 1
            if depth > MAX_CHAIN_DEPTH:
                raise MachineError(f"a chain of more than {MAX_CHAIN_DEPTH} joints; a machine's chains are short",
                                   path=path)
    return root


def _urdf_origins(root, path) -> dict:
    """Joint name -> (xyz, rpy) of its ``<origin>`` as written in the URDF (``root``: its parsed XML).

    Pinocchio folds fixed joints into the next joint's placement, so the
    "zero origin" rule of error joints is checked on the file itself.
    """
    origins = {}
    for joint in root.iter("joint"):
        o = joint.find("origin")

        def vec(key):
            raw = o.get(key, "0 0 0") if o is not None else "0 0 0"
            try:
                values = tuple(float(v) for v in raw.split())
            except ValueError:
                values = ()
            if len(values) != 3:
                raise MachineError(f"joint {joint.get('name')!r}: origin {key}={raw!r} is not three numbers", path=path)
            return values

        origins[joint.get("name")] = (vec("xyz"), vec("rpy"))
    return origins


def _axis_names(model, root, path) -> dict:
    """URDF joint name -> short axis name, for every motion joint (see :class:`Axis`).

    ``<kinid><axis joint="shoulder_pan_joint" name="J1"/></kinid>`` in the URDF names a joint;
    a joint whose own name is letters and digits keeps it; any other gets ``J<n>``.
    """
    motion = [model.names[j] for j in range(1, model.njoints) if not _ERROR_CODE.match(model.names[j])]
    given = {}
    for el in root.iter("kinid"):
        for a in el.iter("axis"):
            joint, name = a.get("joint"), a.get("name")
            if joint not in motion:
                raise MachineError(f"<kinid><axis joint={joint!r}>: no motion joint of that name", path=path)
            if not name or not _AXIS_NAME.match(name) or _ERROR_CODE.match(name):
                raise MachineError(f"<kinid><axis joint={joint!r} name={name!r}>: an axis name is letters and digits, "
                                   f"not an error code (e.g. J1, X, B)", path=path)
            given[joint] = name
    out = {}
    for n, joint in enumerate(motion, start=1):
        out[joint] = given.get(joint) or (joint if _AXIS_NAME.match(joint) else f"J{n}")
    # an error code with a slip of the pen would silently become a motion axis
    others = lambda joint: {v for k, v in out.items() if k != joint} | {"W", "T"}  # noqa: E731
    for joint in motion:
        typo = _LOOKS_LIKE_CODE.match(joint)
        if typo and joint not in given and (typo.group(3) in others(joint)
                                            or typo.group(3) in {f"J{n}" for n in range(1, len(motion) + 1)}):
            raise MachineError(f"joint {joint!r}: looks like an error joint of axis {typo.group(3)}, but "
                               f"{typo.group(1)!r} is not an error direction; an ISO 230-1 error code is E<d><k> "
                               f"or E<d>0<k> with d in XYZABC (e.g. EXX, EC0Y)", path=path)
    seen = {}
    for joint, name in out.items():
        if name.upper() in seen:
            raise MachineError(f"joints {seen[name.upper()]!r} and {joint!r} both get the axis name {name!r}; name them "
                               f"in <kinid><axis joint=... name=.../></kinid>", path=path)
        seen[name.upper()] = joint
    return out


def _check_placement(model, jid, name, zero, k, chain, axis_ids, frames, path):
    """Check that error joint ``name`` sits where docs/machines.md says for axis ``k``."""
    is_error = lambda j: _ERROR_CODE.match(model.names[j])  # noqa: E731
    where = f"joint {name!r}"
    if k in ("W", "T"):
        if not zero:
            raise MachineError(f"{where}: set-up joints are location errors, named E<d>0{k}", path=path)
        end = "workpiece" if k == "W" else "tool"
        if chain != end:
            raise MachineError(f"{where}: set-up joints of {k} belong on the {end} chain", path=path)
        # every joint between it and the end link must be an E?0k joint
        j_end = model.frames[frames[end]].parentJoint
        j = j_end
        while j != jid:
            if not (is_error(j) and model.names[j][2:] == f"0{k}"):
                raise MachineError(f"{where}: set-up joints must sit directly before link {end!r}; joint {model.names[j]!r} is in between", path=path)
            j = model.parents[j]
        return
    if k not in axis_ids:
        raise MachineError(f"{where}: refers to axis {k!r}, which is not a motion axis of this machine", path=path)
    kid = axis_ids[k]
    if zero:  # directly before joint k: walk down to k through location errors of k only
        # the child of jid on the way to k
        path_to_k = _ancestors(model, kid)
        if jid not in path_to_k:
            raise MachineError(f"{where}: a location error of {k} must sit directly before joint {k!r} (it is not on its chain)", path=path)
        for j in path_to_k[path_to_k.index(jid) + 1 : -1]:
            if not (is_error(j) and model.names[j][2:] == f"0{k}"):
                raise MachineError(f"{where}: a location error of {k} must sit directly before joint {k!r}; joint {model.names[j]!r} is in between", path=path)
    else:  # directly after joint k, only PDGE joints of k in between
        j = model.parents[jid]
        while j != kid:
            if j == 0 or not (is_error(j) and _ERROR_CODE.match(model.names[j]).group(2) == "" and model.names[j][2:] == k):
                raise MachineError(f"{where}: a position-dependent error of {k} must sit directly after joint {k!r}", path=path)
            j = model.parents[j]
