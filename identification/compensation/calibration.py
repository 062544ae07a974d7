"""A fit's constant errors as geometry: the calibrated URDF and the set-up offsets (docs/compensation.md).

- :func:`constant_errors` — every constant (location and set-up) error with its standard deviation
  and expanded uncertainty;
- :func:`setup_offsets` — the board's and the sensor's set-up as the transforms a work offset and a
  tool offset apply;
- :func:`calibrated_urdf` — the machine's URDF with every constant of a fit folded into the fixed
  geometry, the error joints kept at zero.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from kinid.stats import K_EXPANDED
from ..model import basis_of
from ..fitting import FitResult

__all__ = ["constant_errors", "setup_offsets", "calibrated_urdf"]




def constant_errors(result: FitResult, compensated=None) -> list:
    """Every constant effect: dicts with name, value, std, expanded uncertainty (k = 2), unit, identified.

    ``compensated`` (a :class:`Compensation`) adds whether each is compensated, and why not.
    """
    why = dict(compensated.left_out) if compensated is not None else {}
    out, k = [], 0
    for e in result.effects:
        if basis_of(e).constant:
            ok = bool(result.identifiable[k])
            std = float(result.std[k]) if ok and np.isfinite(result.std[k]) else None
            row = {"name": e.name, "value": float(result.values[k]) if ok else None, "std": std,
                   "expanded_uncertainty_k2": None if std is None else K_EXPANDED * std,
                   "unit": "µm" if e.unit == "um" else "µrad", "identified": ok}
            if compensated is not None:
                row["compensated"] = e.name not in why
                if e.name in why:
                    row["left_out_because"] = why[e.name]
            out.append(row)
        k += e.n_params
    return out


def _origin(joint) -> np.ndarray:
    import pinocchio as pin

    el = joint.find("origin")
    xyz = np.zeros(3) if el is None else np.array([float(v) for v in el.get("xyz", "0 0 0").split()])
    rpy = np.zeros(3) if el is None else np.array([float(v) for v in el.get("rpy", "0 0 0").split()])
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(*rpy)
    T[:3, 3] = xyz
    return T


def _set_origin(joint, T: np.ndarray) -> None:
    import pinocchio as pin

    el = joint.find("origin")
    if el is None:
        el = ET.SubElement(joint, "origin")
    rpy = pin.rpy.matrixToRpy(T[:3, :3])
    el.set("xyz", " ".join(f"{v:.17g}" for v in T[:3, 3]))
    el.set("rpy", " ".join(f"{v:.17g}" for v in rpy))


def _motion(joint, value_si: float) -> np.ndarray:
    """Transform of a 1-DOF joint at ``value_si`` (m or rad) in its own frame."""
    axis_el = joint.find("axis")
    axis = np.array([1.0, 0.0, 0.0]) if axis_el is None else np.array([float(v) for v in axis_el.get("xyz").split()])
    axis = axis / np.linalg.norm(axis)
    T = np.eye(4)
    if joint.get("type") == "prismatic":
        T[:3, 3] = axis * value_si
    else:
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        T[:3, :3] = np.eye(3) + math.sin(value_si) * K + (1 - math.cos(value_si)) * K @ K
    return T


def _constant_values(result: FitResult) -> dict:
    """Error joint -> identified constant value (µm / µrad), non-zero ones only."""
    return {c["name"]: c["value"] for c in constant_errors(result) if c["identified"] and c["value"]}


def setup_offsets(result: FitResult, written_as_zero=None) -> dict:
    """The set-up of the workpiece (W) and the sensor (T) as a work offset and a tool offset.

    For each end: the transform ``S`` that takes the nominal end frame to the identified one,
    expressed in the nominal end frame (where the board, or the sensor, really is:
    ``oMw_actual = oMw_nominal · S_W``, ``oMt_actual = oMt_nominal · S_T``), as a translation in mm,
    fixed-axis roll/pitch/yaw in degrees and the 4×4 matrix (mm); and each set-up joint's value with
    its expanded uncertainty (k = 2).

    ``written_as_zero`` (set-up joint -> reason) names joints that count as 0 in the transforms (a term
    within its expanded uncertainty); their entry keeps the fitted value as ``fitted_value`` and the reason.
    """
    import pinocchio as pin

    machine = result.machine
    root = ET.fromstring(machine.urdf)
    parent_of = {j.find("child").get("link"): j for j in root.findall("joint")}
    constants = {c["name"]: c for c in constant_errors(result)}
    zero = dict(written_as_zero or {})
    out = {}
    for pseudo, end in (("W", "workpiece"), ("T", "tool")):
        codes = {e.code for e in machine.error_joints if e.axis == pseudo}
        if not codes:
            continue
        chain, link, seen_setup = [], end, False
        while link in parent_of:  # from the end link up to the first joint above the set-up joints
            j = parent_of[link]
            is_setup = j.get("name") in codes
            if seen_setup and not is_setup:
                break
            seen_setup = seen_setup or is_setup
            chain.append(j)
            link = j.find("parent").get("link")
        chain.reverse()
        S, nominal = np.eye(4), np.eye(4)
        for j in chain:  # root -> end: the set-up joints at their values, the fixed origins after them
            c = constants.get(j.get("name"))
            value = c["value"] if c and c["identified"] and c["value"] and j.get("name") not in zero else 0.0
            S = S @ _origin(j) @ _motion(j, value * 1e-6) if j.get("name") in codes else S @ _origin(j)
            nominal = nominal @ _origin(j)
        S_end = np.linalg.inv(nominal) @ S

        joints = {}
        for code in sorted(codes):
            c = constants.get(code)
            if c is None:
                continue
            joints[code] = {"value": 0.0 if code in zero else c["value"],
                            "expanded_uncertainty_k2": c["expanded_uncertainty_k2"],
                            "unit": c["unit"], "identified": c["identified"]}
            if code in zero:
                joints[code].update(fitted_value=c["value"], written_as_zero=zero[code])
        T_mm = S_end.copy()
        T_mm[:3, 3] *= 1e3
        out["workpiece" if pseudo == "W" else "tool"] = {
            "frame": end,
            "offset_mm": [float(v) for v in T_mm[:3, 3]],
            "rotation_rpy_deg": [float(v) for v in np.degrees(pin.rpy.matrixToRpy(S_end[:3, :3]))],
            "transform_mm": [[float(v) for v in row] for row in T_mm],
            "joints": joints,
        }
    targets = _target_points(result, zero)
    if targets:
        out["targets"] = targets
    return out


def _target_points(result: FitResult, zero: dict) -> dict:
    """Each target's own point on the tool when several were fitted together (``E?0T:target:<mark>``): mark ->
    its offset in the tool frame, mm (a term within its U, or one the data cannot see, at 0), and each term with its
    value and U, µm. A coordinate held for one target (seen only with a machine term) makes the others' relative."""
    out, k = {}, 0
    for e in result.effects:
        if basis_of(e).driver == "mark":  # one target of several measured at each pose
            mark, ok = e.args[0], bool(result.identifiable[k])
            std = float(result.std[k]) if ok and np.isfinite(result.std[k]) else None
            value = float(result.values[k]) if ok else None
            t = out.setdefault(mark, {"offset_mm": [0.0, 0.0, 0.0], "joints": {}})
            if e.code[1] in "XYZ" and ok and e.name not in zero:
                t["offset_mm"]["XYZ".index(e.code[1])] = value * 1e-3
            t["joints"][e.code] = {"value": 0.0 if e.name in zero else value, "unit": "µm", "identified": ok,
                                   "expanded_uncertainty_k2": None if std is None else K_EXPANDED * std}
            if e.name in zero:
                t["joints"][e.code].update(fitted_value=value, written_as_zero=zero[e.name])
            elif not ok:
                t["joints"][e.code]["held"] = ("not identifiable from these data: held at 0, and this coordinate of "
                                               "the other targets is given relative to it")
        k += e.n_params
    return out


def calibrated_urdf(result: FitResult) -> str:
    """The machine's URDF with every identified constant error folded into the fixed geometry.

    An error joint's constant value is a fixed transform right after that joint; it is moved into
    the origin of the next joint down the chain that is not an error joint (error joints must keep
    a zero origin), or, at the end of a chain, into one fixed joint added between the chain's last
    joint and its link. Error joints stay, at zero: with every joint of the file at the axis
    readings and the error joints at 0 (or at the values of the axis tables), any URDF consumer
    reproduces the model of ``result``. Names added are unique in the file.
    """
    machine = result.machine
    root = ET.fromstring(machine.urdf)
    joints = {j.get("name"): j for j in root.findall("joint")}
    names = set(joints) | {link.get("name") for link in root.findall("link")}
    by_parent = {}
    for j in root.findall("joint"):
        by_parent.setdefault(j.find("parent").get("link"), []).append(j)
    parent_of = {j.find("child").get("link"): j for j in root.findall("joint")}
    codes = set(machine.error_codes)

    def depth(joint):
        d, link = 0, joint.find("parent").get("link")
        while link in parent_of:
            d += 1
            link = parent_of[link].find("parent").get("link")
        return d

    def unique(stem):
        name, k = stem, 1
        while name in names:
            k += 1
            name = f"{stem}_{k}"
        names.add(name)
        return name

    values = {n: v for n, v in _constant_values(result).items() if n in joints}
    leaf_joints = {}  # error joint at a chain's end -> the fixed joint added after it
    # deepest first: a transform pushed down a chain of error joints keeps the chain's order
    for name in sorted(values, key=lambda n: -depth(joints[n])):
        T = _motion(joints[name], values[name] * 1e-6)
        targets, frontier = [], [joints[name]]
        while frontier:
            j = frontier.pop()
            children = by_parent.get(j.find("child").get("link"), [])
            if not children:
                targets.append(("leaf", j))
            for c in children:
                if c.get("name") in codes:
                    frontier.append(c)
                else:
                    targets.append(("joint", c))
        for kind, j in targets:
            if kind == "joint":
                _set_origin(j, T @ _origin(j))
                continue
            fixed = leaf_joints.get(j.get("name"))
            if fixed is None:  # end of a chain: one fixed joint between the error joint and its child link
                child = j.find("child")
                link_name = unique(f"{j.get('name')}_calibration_link")
                ET.SubElement(root, "link", {"name": link_name})
                fixed = ET.SubElement(root, "joint", {"name": unique(f"{j.get('name')}_calibration"), "type": "fixed"})
                ET.SubElement(fixed, "parent", {"link": link_name})
                ET.SubElement(fixed, "child", {"link": child.get("link")})
                child.set("link", link_name)
                leaf_joints[j.get("name")] = fixed
                _set_origin(fixed, T)
            else:
                _set_origin(fixed, T @ _origin(fixed))
    header = (f"\n  Calibrated by kinid: identified constant errors folded into the joint origins\n"
              f"  ({', '.join(f'{n} = {v:.4g}' for n, v in values.items()) or 'none'});\n"
              f"  error joints kept, at zero.\n")
    root.insert(0, ET.Comment(header))
    return ET.tostring(root, encoding="unicode") + "\n"
