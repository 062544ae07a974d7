"""Controllers' kinematics applied to their own files, in plain numpy (the tests' independent side).

Each consumer reads the file ``kinid compensate`` wrote as that controller reads it and applies the
controller's kinematic transform as its documentation states it, to the controller's coordinates:
``J`` (N, 3) the tool point's linear coordinates relative to the part, mm, and the rotary readings in
degrees. It returns the point of the part under the tool in the part's frame at home (N, 3), mm. No
kinid code is used.
"""
from __future__ import annotations

import re

import numpy as np


def rotation(axis, angle_rad) -> np.ndarray:
    """Right-handed rotation by ``angle_rad`` about the unit vector ``axis`` (Rodrigues)."""
    a = np.asarray(axis, float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle_rad) * K + (1 - np.cos(angle_rad)) * K @ K


# --- SINUMERIK: a swivel data record ($TC_CARR) as CYCLE800 applies it -------------------------------

def read_carr(text: str) -> dict:
    """``$TC_CARRk[n]=value`` assignments of one record: k -> value (numbers as float, the rest as text)."""
    out = {}
    for line in text.splitlines():
        m = re.fullmatch(r"\$TC_CARR(\d+)\[(\d+)\]=(.+)", line.strip())
        if m:
            value = m.group(3).strip()
            try:
                out[int(m.group(1))] = float(value)
            except ValueError:
                out[int(m.group(1))] = value.strip('"')
    return out


def cycle800_points(text: str, J_mm, first_deg, second_deg=None) -> np.ndarray:
    """The part's point under the tool by the swivel data's chain.

    Type T: tool = J + l1 + R(v1, α1)(l2 + R(v2, α2) l3). Type P: a table point p is at
    l2 + R(v1, α1)(l3 + R(v2, α2)(l4 + p)). Type M: tool = J + l1 + R(v1, α1) l2, a table point at
    l3 + R(v2, α2)(l4 + p). Rotations right-handed about the axis vectors.
    """
    c = read_carr(text)
    vec = lambda k: np.array([c.get(k, 0.0), c.get(k + 1, 0.0), c.get(k + 2, 0.0)])  # noqa: E731
    l1, l2, v1, v2, l3, l4 = vec(1), vec(4), vec(7), vec(10), vec(15), vec(18)
    kind = c[23]
    J = np.atleast_2d(np.asarray(J_mm, float))
    a1 = np.radians(np.asarray(first_deg, float))
    a2 = np.zeros(len(J)) if second_deg is None else np.radians(np.asarray(second_deg, float))
    out = []
    for j, t1, t2 in zip(J, a1, a2):
        R1 = rotation(v1, t1) if np.any(v1) else np.eye(3)
        R2 = rotation(v2, t2) if np.any(v2) else np.eye(3)
        if kind == "T":
            out.append(j + l1 + R1 @ (l2 + R2 @ l3))
        elif kind == "P":  # the machine point j is the table point p with l2 + R1(l3 + R2(l4 + p)) = j
            out.append(R2.T @ (R1.T @ (j - l2) - l3) - l4)
        else:  # M: the head's chain, then the table's inverted
            tool = j + l1 + R1 @ l2
            out.append(R2.T @ (tool - l3) - l4)
    return np.array(out)


# --- LinuxCNC: the trunnion kinematics' forward transform --------------------------------------------

def read_setp(text: str) -> dict:
    """``setp <module>.<pin> value`` lines: pin -> value, and ``module``."""
    out = {}
    for line in text.splitlines():
        m = re.fullmatch(r"setp\s+([\w-]+)\.([\w-]+)\s+(\S+)", line.strip())
        if m:
            out["module"] = m.group(1)
            out[m.group(2)] = float(m.group(3))
    return out


def trt_points(text: str, J_mm, tilt_deg, c_deg) -> np.ndarray:
    """xyzac-trt-kins / xyzbc-trt-kins forward kinematics as its source writes them (tool-offset 0)."""
    p = read_setp(text)
    xr, yr, zr = p.get("x-rot-point", 0.0), p.get("y-rot-point", 0.0), p.get("z-rot-point", 0.0)
    dt = p.get("tool-offset", 0.0)
    J = np.atleast_2d(np.asarray(J_mm, float))
    x, y, z = J[:, 0], J[:, 1], J[:, 2]
    t, c = np.radians(np.asarray(tilt_deg, float)), np.radians(np.asarray(c_deg, float))
    if p["module"] == "xyzac-trt-kins":
        dy, dz = p.get("y-offset", 0.0), p.get("z-offset", 0.0) + dt
        a = t
        px = np.cos(c) * (x - xr) + np.sin(c) * np.cos(a) * (y - dy - yr) + np.sin(c) * np.sin(a) * (z - dz - zr) \
            + np.sin(c) * dy + xr
        py = -np.sin(c) * (x - xr) + np.cos(c) * np.cos(a) * (y - dy - yr) + np.cos(c) * np.sin(a) * (z - dz - zr) \
            + np.cos(c) * dy + yr
        pz = -np.sin(a) * (y - dy - yr) + np.cos(a) * (z - dz - zr) + dz + zr
    elif p["module"] == "xyzbc-trt-kins":
        dx, dz = p.get("x-offset", 0.0), p.get("z-offset", 0.0) + dt
        b = t
        px = np.cos(c) * np.cos(b) * (x - dx - xr) + np.sin(c) * (y - yr) - np.cos(c) * np.sin(b) * (z - dz - zr) \
            + np.cos(c) * dx + xr
        py = -np.sin(c) * np.cos(b) * (x - dx - xr) + np.cos(c) * (y - yr) + np.sin(c) * np.sin(b) * (z - dz - zr) \
            - np.sin(c) * dx + yr
        pz = np.sin(b) * (x - dx - xr) + np.cos(b) * (z - dz - zr) + dz + zr
    else:
        raise ValueError(f"unknown module {p['module']}")
    return np.stack([px, py, pz], axis=1)
