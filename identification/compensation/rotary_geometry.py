"""The rotary axes' geometry from a fit, and the controller kinematics files that hold it (docs/compensation.md).

- :func:`rotary_geometry` — where each rotary axis turns at the home position (its pivot point and its
  direction in the machine frame), nominal and with the significant location errors the compensation
  keeps (the same filter as the constants), from the sensor's point as the fit finds it (its set-up T
  included: the data fix the pivots relative to the sensor that measured them); the board's set-up W
  is no part of it;
- :func:`carried_points_mm` — the tool point carried back by the table's motions into the machine frame
  at home (what a controller's kinematics computes from the axis readings), for a machine with
  given location errors;
- :func:`kinematics_files` — the geometry in every kinematics format of :mod:`kinid.kinematics_formats`
  that applies, with what each leaves out.

Frame: the URDF's base with every axis at 0, its origin moved to the tool point (mm).
"""
from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from kinid.kinematics_formats import (LinearAxisMapping, RotaryAxisGeometry, RotaryGeometry,
                                      default_kinematics_formats, kinematics_format)
from ..model import basis_of

__all__ = ["rotary_geometry", "location_errors", "carried_points_mm", "kinematics_files", "kinematics_note",
           "KinematicsFiles", "geometry_lines"]

_KIND = {(0, 2): "table-table", (2, 0): "head-head", (1, 1): "head-table", (0, 1): "table", (1, 0): "head"}


def location_errors(comp, *, sensor: bool = False) -> dict:
    """Error code -> value (µm / µrad) of the location errors a compensation keeps (a :class:`Compensation`):
    identified, significant (or every term, as the compensation was made), not the set-up (W, T); with
    ``sensor`` also the sensor's set-up (T) as ``setup.json`` holds it (a term within its uncertainty as 0)."""
    result, left = comp.fit, dict(comp.left_out)
    zero = dict(comp.setup_left_out)
    machine = result.machine
    out, k = {}, 0
    for e in result.effects:
        joint = machine.error_joint(e.code)
        keep = (e.name not in left) if joint.axis not in ("W", "T") else (sensor and joint.axis == "T"
                                                                            and e.name not in zero)
        if basis_of(e).constant and joint.location and keep and bool(result.identifiable[k]) and result.values[k]:
            out[e.code] = out.get(e.code, 0.0) + float(result.values[k])
        k += e.n_params
    return out


def _configuration(machine, errors: dict, axes_user=None) -> np.ndarray:
    import pinocchio as pin

    q = pin.neutral(machine.model)
    for code, value in errors.items():
        q[machine.error_joint(code).q_index] = value * 1e-6
    if axes_user is not None:
        for a, v in zip(machine.axes, axes_user):
            if a.nq == 2:
                q[a.q_index:a.q_index + 2] = np.cos(np.radians(v)), np.sin(np.radians(v))
            else:
                q[a.q_index] = v * (1e-3 if a.kind == "prismatic" else np.pi / 180.0)
    return q


def _home(machine, errors: dict):
    """(pinocchio data at home, tool point at home in m)."""
    import pinocchio as pin

    data = machine.model.createData()
    pin.forwardKinematics(machine.model, data, _configuration(machine, errors))
    pin.updateFramePlacements(machine.model, data)
    return data, data.oMf[machine.tool_frame].translation.copy()


def _joint_axes(machine) -> dict:
    """URDF joint name -> its axis (unit, in the joint's frame)."""
    out = {}
    for j in ET.fromstring(machine.urdf).findall("joint"):
        el = j.find("axis")
        v = np.array([1.0, 0.0, 0.0]) if el is None else np.array([float(x) for x in el.get("xyz").split()])
        out[j.get("name")] = v / np.linalg.norm(v)
    return out


def rotary_geometry(comp) -> RotaryGeometry | None:
    """The rotary axes' geometry of a :class:`Compensation`.

    None where the machine has no rotary axis, or more than two (:func:`kinematics_note` says why).
    """
    from pathlib import Path

    machine = comp.result.machine
    rotary = [a for a in machine.axes if a.kind == "revolute"]
    if not rotary:
        return None
    heads = sorted((a for a in rotary if a.chain == "tool"), key=lambda a: machine.model.getJointId(a.joint))
    tables = sorted((a for a in rotary if a.chain != "tool"), key=lambda a: machine.model.getJointId(a.joint))
    kind = _KIND.get((len(heads), len(tables)))
    if kind is None:
        return None
    errors = location_errors(comp)
    cal, t_cal = _home(machine, location_errors(comp, sensor=True))
    nom, t_nom = _home(machine, {})
    local = _joint_axes(machine)
    axes = []
    for a in heads + tables:
        jid = machine.model.getJointId(a.joint)
        d_cal = cal.oMi[jid].rotation @ local[a.joint]
        d_nom = nom.oMi[jid].rotation @ local[a.joint]
        c = (cal.oMi[jid].translation - t_cal) * 1e3
        n = (nom.oMi[jid].translation - t_nom) * 1e3
        c = c + np.dot(n - c, d_cal) * d_cal  # the calibrated line's point nearest the nominal pivot
        axes.append(RotaryAxisGeometry(a.name, "head" if a.chain == "tool" else "table", tuple(map(float, c)),
                                       tuple(map(float, d_cal)), tuple(map(float, n)), tuple(map(float, d_nom))))
    linear = []
    for a in machine.axes:
        if a.kind != "prismatic":
            continue
        d = nom.oMi[machine.model.getJointId(a.joint)].rotation @ local[a.joint]
        k = int(np.argmax(np.abs(d)))
        linear.append(LinearAxisMapping(a.name, "XYZ"[k], int(np.sign(d[k])) * (1 if a.chain == "tool" else -1)))
    left = []
    for code, value in errors.items():
        axis = machine.error_joint(code).axis
        if machine.axis(axis).kind == "prismatic":
            unit = {"um": "µm", "urad": "µrad"}[machine.error_joint(code).unit]
            left.append((code, f"{value:.4g} {unit}: the orientation of linear axis "
                               f"{axis} — in the geometry of the axes it carries, but its own squareness is for the "
                               f"controller's squareness compensation"))
    if any(e.axis in ("W", "T") for e in machine.error_joints):
        left.append(("set-up", "the board's set-up (W): the work offset (setup.json); the vectors start from the "
                               "sensor's point with its set-up (T)"))
    units = {code: machine.error_joint(code).unit for code in errors}
    return RotaryGeometry(Path(machine.path).stem, kind, tuple(axes), tuple(linear),
                          tuple((code, v, units[code]) for code, v in errors.items()), tuple(left))


def carried_points_mm(machine, errors: dict, axes_user) -> np.ndarray:
    """The tool point carried back by the table's motions (N, 3), mm.

    For readings ``q``: ``F(0)·F(q)⁻¹·t(q) − t(0)`` with ``F`` the workpiece end's placement and ``t`` the
    tool point in the base, at the location ``errors`` (code -> µm / µrad; every other error joint and
    the set-up at 0, or the sensor's included in ``errors``): the point of the table under the tool, in the machine frame at home, from the tool
    point at home — what a controller's kinematics computes from the readings.
    """
    import pinocchio as pin

    model = machine.model
    data = model.createData()
    home, t0 = _home(machine, errors)
    F0 = home.oMf[machine.workpiece_frame]
    out = []
    for row in np.atleast_2d(np.asarray(axes_user, float)):
        pin.forwardKinematics(model, data, _configuration(machine, errors, row))
        pin.updateFramePlacements(model, data)
        F = data.oMf[machine.workpiece_frame]
        p = F0.act(F.actInv(data.oMf[machine.tool_frame].translation))
        out.append((p - t0) * 1e3)
    return np.array(out)


def kinematics_note(machine) -> str | None:
    """Why a machine with rotary axes gets no kinematics files (more than two of them), or None."""
    rotary = [a.name for a in machine.axes if a.kind == "revolute"]
    if len(rotary) <= 2:
        return None
    return (f"no kinematics files: {len(rotary)} rotary axes ({', '.join(rotary)}); a controller's five-axis "
            f"kinematics holds one or two")


@dataclass(frozen=True)
class KinematicsFiles:
    """The kinematics files of one geometry.

    Attributes
    ----------
    files : dict
        File name -> text.
    notes : tuple of str
        What a format leaves out, or why it writes nothing for this machine.
    info : dict
        For compensation.json: the geometry, each file with its format and sha256.
    geometry : RotaryGeometry or None
        None where the machine has more than two rotary axes (no file, a note).
    """

    files: dict
    notes: tuple
    info: dict
    geometry: RotaryGeometry | None = None


def kinematics_files(comp, formats=None, comment: str = "") -> KinematicsFiles | None:
    """The rotary axes' geometry of a :class:`Compensation` in every kinematics format that applies (``formats``:
    names asked for; default: every default one); None where the machine has no rotary axis and no format was
    named."""
    machine = comp.result.machine
    if not any(a.kind == "revolute" for a in machine.axes):  # asked for by name: say why there is none
        why = "no kinematics files: the machine has no rotary axis"
        return None if formats is None else KinematicsFiles({}, (why,), {"not_written": why})
    why = kinematics_note(machine)
    if why is not None:
        return KinematicsFiles({}, (why,), {"not_written": why})
    geometry = rotary_geometry(comp)
    fmts = [kinematics_format(f) for f in (default_kinematics_formats() if formats is None else formats)]
    files, notes, entries = {}, [], []
    for fmt in fmts:
        fit = fmt.fit(geometry)
        if not fit.writable:
            if formats is not None:
                notes += [f"{fmt.title}: not written, {line}" for line in fit.notes]
            continue
        text = fmt.write(geometry, comment)
        files[fmt.file_name] = text
        notes += [f"{fmt.file_name}: {line}" for line in fit.notes]
        entries.append({"file": fmt.file_name, "format": fmt.name, "title": fmt.title,
                        "sha256": hashlib.sha256(text.encode()).hexdigest(), "left_out": list(fit.notes)})
    notes += [f"{code}: not in the kinematics files ({why})" for code, why in geometry.left_out if code != "set-up"]
    info = {"kind": geometry.kind, "frame": "the machine frame with every axis at 0, origin at the tool point, mm",
            "axes": [{"axis": a.name, "carrier": a.carrier, "pivot_mm": list(a.pivot_mm),
                      "direction": list(a.direction), "nominal_pivot_mm": list(a.nominal_pivot_mm),
                      "nominal_direction": list(a.nominal_direction), "pivot_shift_um": list(a.pivot_shift_um),
                      "tilt_urad": a.tilt_urad} for a in geometry.axes],
            "linear_axes": [{"axis": m.axis, "coordinate": m.coordinate, "sign": m.sign} for m in geometry.linear],
            "location_errors": [{"effect": c, "value": v, "unit": u} for c, v, u in geometry.location_errors],
            "not_in_the_kinematics": [{"what": c, "why": w} for c, w in geometry.left_out],
            "files": entries}
    return KinematicsFiles(files, tuple(notes), info, geometry)


def geometry_lines(geometry: RotaryGeometry) -> list:
    """The geometry in plain words, one line per rotary axis and one for the linear axes' mapping."""
    lines = [f"rotary axes ({geometry.kind}), at home in the machine frame, from the sensor's point:"]
    for a in geometry.axes:
        s = a.pivot_shift_um
        lines.append(f"  {a.name} ({a.carrier}): pivot moved by {np.linalg.norm(s):.3g} µm (x {s[0]:+.3g}, y "
                     f"{s[1]:+.3g}, z {s[2]:+.3g}), axis tilted by {a.tilt_urad:.3g} µrad; direction "
                     f"({', '.join(f'{v:.7f}' for v in a.direction)})")
    lines.append(f"  linear axes as the tool's coordinates relative to the part: {geometry.mapping_words()}")
    return lines
