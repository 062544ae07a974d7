"""Truth for the diagnosis proving ground, in plain numpy: it shares no code with kinid.

A machine is read from its URDF text with ``xml.etree`` (joints, origins, axes, limits); its forward
kinematics is the product of the joint transforms from the root link to the ``workpiece`` and ``tool``
links. Motion joints take the readings (mm, deg); error joints (names ``E`` + an ISO 230-1 code)
take hidden error values (µm, µrad) that are plain functions of the readings and of time.
"""
from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field

import numpy as np

ERROR_NAME = re.compile(r"E[XYZABC][0XYZABCUVW][A-Z0-9]*")


@dataclass(frozen=True)
class Joint:
    name: str
    kind: str  # fixed, prismatic, revolute, continuous
    parent: str
    child: str
    xyz: np.ndarray
    rpy: np.ndarray
    axis: np.ndarray
    limit: tuple | None  # (low, high) in m / rad


@dataclass(frozen=True)
class TrueMachine:
    """Joints by child link, and the names of motion and error joints."""

    joints: dict
    motion: tuple
    errors: tuple
    limits: dict = field(default_factory=dict)  # motion joint -> (low, high) in mm / deg

    def kind(self, name: str) -> str:
        return next(j.kind for j in self.joints.values() if j.name == name)


def _floats(text, default):
    return np.array([float(v) for v in text.split()]) if text else np.array(default, float)


def read_urdf(text: str) -> TrueMachine:
    root = ET.fromstring(text)
    joints = {}
    for j in root.findall("joint"):  # (a transmission also has <joint> elements)
        origin = j.find("origin")
        axis = j.find("axis")
        lim = j.find("limit")
        kind = j.get("type")
        joints[j.find("child").get("link")] = Joint(
            j.get("name"), kind, j.find("parent").get("link"), j.find("child").get("link"),
            _floats(origin.get("xyz") if origin is not None else None, (0, 0, 0)),
            _floats(origin.get("rpy") if origin is not None else None, (0, 0, 0)),
            _floats(axis.get("xyz") if axis is not None else None, (1, 0, 0)),
            None if lim is None or kind == "continuous" else (float(lim.get("lower")), float(lim.get("upper"))))
    movable = [j for j in joints.values() if j.kind != "fixed"]
    motion = tuple(j.name for j in movable if not ERROR_NAME.fullmatch(j.name))
    errors = tuple(j.name for j in movable if ERROR_NAME.fullmatch(j.name))
    limits = {}
    for j in movable:
        if j.name in motion:
            scale = 1e3 if j.kind == "prismatic" else 180.0 / np.pi
            limits[j.name] = (-np.inf, np.inf) if j.limit is None else (j.limit[0] * scale, j.limit[1] * scale)
    return TrueMachine(joints, motion, errors, limits)


def _rot_axis(axis, angle):
    """(N, 3, 3) rotations by ``angle`` (N,) about unit ``axis`` (Rodrigues)."""
    a = axis / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


def _rpy(rpy):
    r, p, y = rpy
    Rx = np.array([[1, 0, 0], [0, np.cos(r), -np.sin(r)], [0, np.sin(r), np.cos(r)]])
    Ry = np.array([[np.cos(p), 0, np.sin(p)], [0, 1, 0], [-np.sin(p), 0, np.cos(p)]])
    Rz = np.array([[np.cos(y), -np.sin(y), 0], [np.sin(y), np.cos(y), 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def _chain(m: TrueMachine, link: str) -> list:
    out = []
    while link in m.joints:
        j = m.joints[link]
        out.append(j)
        link = j.parent
    return out[::-1]


def _pose(m: TrueMachine, link: str, values: dict, n: int):
    """Rotation (N, 3, 3) and position (N, 3), metres, of ``link`` in the root frame."""
    R = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    p = np.zeros((n, 3))
    for j in _chain(m, link):
        Ro = _rpy(j.rpy)
        p = p + R @ j.xyz
        R = R @ Ro
        if j.kind == "fixed":
            continue
        q = values.get(j.name)
        if q is None:
            continue
        q = np.broadcast_to(np.asarray(q, float), (n,))
        if j.kind == "prismatic":
            p = p + (R @ (j.axis / np.linalg.norm(j.axis))) * q[:, None]
        else:
            R = R @ _rot_axis(j.axis, q)
    return R, p


def joint_values(m: TrueMachine, readings: dict, errors: dict) -> dict:
    """Readings (mm / deg) and error values (µm / µrad) as joint values in metres / radians."""
    out = {}
    for name, v in readings.items():
        out[name] = np.asarray(v, float) * (1e-3 if m.kind(name) == "prismatic" else np.pi / 180.0)
    for name, v in errors.items():
        out[name] = out.get(name, 0.0) + np.asarray(v, float) * 1e-6
    return out


def tool_point_mm(m: TrueMachine, readings: dict, errors: dict, n: int) -> np.ndarray:
    """The tool point in the workpiece frame, mm (N, 3)."""
    return tool_pose_mm(m, readings, errors, n)[1]


def tool_pose_mm(m: TrueMachine, readings: dict, errors: dict, n: int):
    """The tool frame in the workpiece frame: its rotation (N, 3, 3) and its origin, mm (N, 3)."""
    values = joint_values(m, readings, errors)
    Rw, pw = _pose(m, "workpiece", values, n)
    Rt, pt = _pose(m, "tool", values, n)
    return np.einsum("nji,njk->nik", Rw, Rt), np.einsum("nji,nj->ni", Rw, pt - pw) * 1e3


def align_linear(m: TrueMachine, presets: dict, marks_mm: np.ndarray, pull: float = 1e-3, iterations: int = 30) -> dict:
    """Readings that put the nominal tool point on each mark: the linear axes moved from their presets
    (Gauss–Newton with a small pull towards the preset where the axes are redundant)."""
    n = len(marks_mm)
    linear = [a for a in m.motion if m.kind(a) == "prismatic"]
    r = {k: np.asarray(v, float).copy() for k, v in presets.items()}
    for _ in range(iterations):
        p = tool_point_mm(m, r, {}, n)
        J = np.empty((n, 3, len(linear)))
        for k, a in enumerate(linear):
            shifted = dict(r)
            shifted[a] = r[a] + 1e-3
            J[:, :, k] = (tool_point_mm(m, shifted, {}, n) - p) / 1e-3
        e = marks_mm - p
        A = np.einsum("nik,nil->nkl", J, J) + pull * np.eye(len(linear))
        b = np.einsum("nik,ni->nk", J, e) - pull * np.column_stack([r[a] - presets[a] for a in linear])
        step = np.linalg.solve(A, b[:, :, None])[:, :, 0]
        for k, a in enumerate(linear):
            r[a] = r[a] + step[:, k]
        if np.max(np.abs(step)) < 1e-9:
            break
    return r
