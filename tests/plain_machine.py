"""A machine in plain Pinocchio, error joints set from kinid's compensation tables (tests' independent side).

What a URDF consumer does with ``kinid compensate``'s files: load calibrated.urdf, set every motion
joint to its reading and every error joint to the value its axis table gives (linear
interpolation, the column of the approach direction, end values held beyond a table), and apply
the work and tool offsets of setup.json to the workpiece and tool frames. No kinid code is used.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pinocchio as pin


def _tables(folder):
    out = {}
    for f in folder.glob("*.csv"):
        rows = list(csv.reader(open(f)))
        header, data = rows[0], np.array(rows[1:], float)
        out[f.stem] = (data[:, 0], {h: data[:, k] for k, h in enumerate(header) if k})
    return out


class PlainMachine:
    """calibrated.urdf (or any URDF) in plain Pinocchio, error joints from the tables (or at zero)."""

    def __init__(self, folder=None, urdf=None, setup=None):
        folder = None if folder is None else Path(folder)
        self.model = pin.buildModelFromUrdf(str(urdf if urdf is not None else folder / "calibrated.urdf"))
        self.data = self.model.createData()
        self.tables = _tables(folder) if folder is not None else {}
        self.work_offset = self.tool_offset = pin.SE3.Identity()
        setup = Path(setup) if setup is not None else None if folder is None else folder / "setup.json"
        if setup is not None and setup.exists():
            data = json.loads(setup.read_text())
            for key, attr in (("workpiece", "work_offset"), ("tool", "tool_offset")):
                if key in data:
                    T = np.array(data[key]["transform_mm"], float)
                    setattr(self, attr, pin.SE3(T[:3, :3], T[:3, 3] * 1e-3))

    def joint_values(self, readings: dict, directions: dict) -> dict:
        """Error joint -> value (m or rad): the table column of the approach direction, interpolated."""
        values = {}
        for axis, (grid, cols) in self.tables.items():
            backwards = directions.get(axis, 1) < 0
            for name, col in cols.items():
                code, unit = name.split("_")[0], name.split("_")[-1]
                reverse = name.endswith(f"_rev_{unit}")
                wanted = backwards and f"{code}_rev_{unit}" in cols
                if reverse == wanted:
                    values[code] = np.interp(readings[axis], grid, col) * 1e-6  # µm -> m, µrad -> rad
        return values

    def tool_in_workpiece_mm(self, readings: dict, directions: dict | None = None) -> np.ndarray:
        directions = directions or {}
        q = pin.neutral(self.model)
        values = {**{k: v * (1e-3 if k in "XYZ" else np.pi / 180) for k, v in readings.items()},
                  **self.joint_values(readings, directions)}
        for name, v in values.items():
            jid = self.model.getJointId(name)
            i = self.model.idx_qs[jid]
            if self.model.nqs[jid] == 2:
                q[i:i + 2] = np.cos(v), np.sin(v)
            else:
                q[i] = v
        pin.framesForwardKinematics(self.model, self.data, q)
        oMw = self.data.oMf[self.model.getFrameId("workpiece")] * self.work_offset
        oMt = self.data.oMf[self.model.getFrameId("tool")] * self.tool_offset
        return oMw.actInv(oMt.translation) * 1e3



    def solve(self, mark_mm, fixed: dict, solve=("X", "Y", "Z"), directions=None, start=None) -> dict:
        """Readings of the ``solve`` axes (mm) that put the tool point on ``mark_mm``: Newton, central differences."""
        r = dict(fixed)
        x = np.zeros(len(solve)) if start is None else np.asarray(start, float)
        for _ in range(30):
            r.update(zip(solve, x))
            f = self.tool_in_workpiece_mm(r, directions) - mark_mm
            J = np.empty((3, len(solve)))
            for k, a in enumerate(solve):
                h = 1e-4
                rp, rm = dict(r), dict(r)
                rp[a] += h
                rm[a] -= h
                J[:, k] = (self.tool_in_workpiece_mm(rp, directions) - self.tool_in_workpiece_mm(rm, directions)) / (2 * h)
            step = np.linalg.solve(J, f)
            x = x - step
            if np.abs(step).max() < 1e-10:
                break
        r.update(zip(solve, x))
        return r
