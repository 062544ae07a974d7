"""From a fit to what a controller loads: axis error tables, constants, a calibrated URDF (docs/compensation.md).

- :func:`axis_error_columns` — the value of every position-dependent error joint of one axis over a
  grid of that axis (direction + and, where the model has a reversal, direction −);
- :func:`constant_errors` — every constant (location and set-up) error with its standard deviation;
- :func:`calibrated_urdf` — the machine's URDF with every identified constant folded into the fixed
  geometry, the error joints kept at zero;
- :func:`write_compensation` — all of it into one folder, plus the controller files of
  :mod:`kinid.axis_tables`.

Values are the fitted model's own: the same effect bases as the fit, at the identified parameters
(a held, unidentifiable parameter counts as 0, as in the fit's predictions).
"""
from __future__ import annotations

import hashlib
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinid.axis_tables import FORMATS, AxisErrorTable, format_text, neutral_csv_text, points_for
from kinid.errors import DataError
from .effects import basis_values
from .fit import FitResult
from .machine import axis_limits

__all__ = ["AxisColumns", "axis_error_columns", "axis_grid", "constant_errors", "calibrated_urdf",
           "write_compensation", "positioning_table", "CompensationFiles"]

#: Fraction of the fitted data's span added on each side where the URDF gives an axis no travel.
DATA_MARGIN = 0.05


@dataclass(frozen=True)
class AxisColumns:
    """The error joints of one axis tabulated over its travel.

    Attributes
    ----------
    axis : str
    column : str
        The position column's name (``x_mm``, ``c_deg``).
    positions : array (n,)
    columns : dict name -> array (n,)
        ``EXX_um`` …, ``ECX_urad``; with a reversal effect also ``EXX_rev_um`` (direction −).
    source : str
        Where the grid's range comes from: "URDF limits" or "fitted data".
    """

    axis: str
    column: str
    positions: np.ndarray
    columns: dict
    source: str


def _effects_by_axis(result: FitResult):
    """Axis -> list of (effect, its parameter values), for bases driven by that axis's position or direction."""
    out, k = {}, 0
    theta = result.theta
    for e in result.effects:
        if e.basis in ("poly", "periodic", "map", "local", "reversal"):
            out.setdefault(e.axis, []).append((e, theta[k:k + e.n_params]))
        k += e.n_params
    return out


def axis_grid(result: FitResult, axis: str, step: float) -> tuple:
    """(positions, source) covering the axis's travel: the URDF limits, else the fitted data with a margin."""
    machine = result.machine
    j = machine.axis_names.index(axis)
    lo, hi = axis_limits(machine)[j]
    if np.isfinite(lo) and np.isfinite(hi):
        return points_for(step, lo, hi), "URDF limits"
    a = machine.axes[j]
    if a.kind == "revolute" and a.nq == 2:  # a continuous turntable: one turn
        return points_for(step, 0.0, 360.0), "one turn (continuous axis)"
    if axis not in result.axis_ranges:
        raise DataError(f"axis {axis} has no limits in the URDF and the fit does not record the range of its "
                        f"readings; add <limit> to the joint or refit", parameter="fit")
    d_lo, d_hi = result.axis_ranges[axis]
    margin = DATA_MARGIN * max(d_hi - d_lo, step)
    return points_for(step, d_lo - margin, d_hi + margin), "fitted data"


def axis_error_columns(result: FitResult, axis: str, positions) -> dict:
    """Value of each error joint of ``axis`` at ``positions`` (n,): name -> array (n,).

    Columns: every position-dependent error joint of the axis (``EXX_um`` …), and any other joint
    whose fitted effects are driven by this axis; ``<code>_rev_<unit>`` for direction − where the
    model has a reversal effect on the axis.
    """
    machine = result.machine
    q = np.asarray(positions, float)
    n = q.size
    axes = np.zeros((n, len(machine.axes)))
    axes[:, machine.axis_names.index(axis)] = q
    effects = _effects_by_axis(result).get(axis, [])
    codes = [e.code for e in machine.error_joints if e.axis == axis and not e.location]
    codes += [e.code for e, _ in effects if e.code not in codes]
    has_reversal = any(e.basis == "reversal" for e, _ in effects)
    out = {}
    for direction, suffix in ((1.0, ""), (-1.0, "_rev")) if has_reversal else ((1.0, ""),):
        dirs = {axis: np.full(n, direction)}
        for code in codes:
            joint = machine.error_joint(code)
            v = np.zeros(n)
            for e, th in effects:
                if e.code == code:
                    v += basis_values(e, machine, axes, directions=dirs) @ th
            out[f"{code}{suffix}_{joint.unit}"] = v
    return out


def positioning_table(result: FitResult, axis: str, positions) -> AxisErrorTable:
    """The axis's own positioning error (``E<a><a>``: EXX for X, ECC for C) as a controller table."""
    machine = result.machine
    code = f"E{axis}{axis}" if len(axis) == 1 else None
    cols = axis_error_columns(result, axis, positions)
    rotary = machine.axis(axis).kind == "revolute"
    unit = "urad" if rotary else "um"
    if code is None or f"{code}_{unit}" not in cols:
        raise DataError(f"axis {axis} has no positioning error joint E{axis}{axis} in the URDF; a controller's "
                        f"axis table holds only that error", parameter="axis")
    fwd = cols[f"{code}_{unit}"]
    rev = cols.get(f"{code}_rev_{unit}")
    return AxisErrorTable(axis, rotary, np.asarray(positions, float), fwd, rev)


def constant_errors(result: FitResult) -> list:
    """Every constant effect: dicts with name, value, std (None where held), unit, identified."""
    out, k = [], 0
    for e in result.effects:
        if e.basis == "constant":
            ok = bool(result.identifiable[k])
            out.append({"name": e.name, "value": float(result.values[k]) if ok else None,
                        "std": float(result.std[k]) if ok and np.isfinite(result.std[k]) else None,
                        "unit": "µm" if e.unit == "um" else "µrad", "identified": ok})
        k += e.n_params
    return out


# --- the calibrated URDF -----------------------------------------------------------------------

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


def calibrated_urdf(result: FitResult) -> str:
    """The machine's URDF with every identified constant error folded into the fixed geometry.

    An error joint's constant value is a fixed transform right after that joint; it is moved into
    the origin of the next joint down the chain that is not an error joint (error joints must keep
    a zero origin), or, at the end of a chain, into a fixed joint added for it. Error joints stay,
    at zero: with every joint of the file at the axis readings and the error joints at 0 (or at the
    values of the axis tables), any URDF consumer reproduces the fitted kinematics.
    """
    machine = result.machine
    root = ET.fromstring(machine.urdf)
    joints = {j.get("name"): j for j in root.findall("joint")}
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

    values = {}
    for c in constant_errors(result):
        if c["identified"] and c["value"] and c["name"] in joints:
            values[c["name"]] = c["value"]
    added = 0
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
            else:  # end of a chain: a fixed joint between the error joint and its child link
                child = j.find("child")
                link_name = f"{j.get('name')}_calibration_link"
                ET.SubElement(root, "link", {"name": link_name})
                fixed = ET.SubElement(root, "joint", {"name": f"{j.get('name')}_calibration", "type": "fixed"})
                ET.SubElement(fixed, "parent", {"link": link_name})
                ET.SubElement(fixed, "child", {"link": child.get("link")})
                _set_origin(fixed, T)
                child.set("link", link_name)
                added += 1
    header = (f"\n  Calibrated by kinid: identified constant errors folded into the joint origins\n"
              f"  ({', '.join(f'{n} = {v:.4g}' for n, v in values.items()) or 'none'});\n"
              f"  error joints kept, at zero.\n")
    root.insert(0, ET.Comment(header))
    return ET.tostring(root, encoding="unicode") + "\n"


# --- the compensation folder -------------------------------------------------------------------

def _interpolation_error(result: FitResult, table: AxisErrorTable, unit: str) -> float:
    """Largest difference (µm or µrad) between the table's linear interpolation and the model, both directions."""
    q = table.positions
    fine = np.linspace(q[0], q[-1], 20 * (q.size - 1) + 1)
    model = positioning_table(result, table.axis, fine)
    worst = 0.0
    for coarse, exact in ((table.forward, model.forward), (table.backward, model.backward)):
        worst = max(worst, float(np.max(np.abs(np.interp(fine, q, coarse) - exact))))
    return worst


@dataclass(frozen=True)
class CompensationFiles:
    """What :func:`write_compensation` wrote.

    Attributes
    ----------
    files : tuple of str
        File names in the folder.
    notes : tuple of str
        One line per controller file that cannot follow the model closely (too few points for
        the fitted effects), and per effect that no table holds (drift).
    """

    files: tuple
    notes: tuple


def write_compensation(result: FitResult, folder, *, step_mm: float = 1.0, step_deg: float = 1.0,
                       formats=("linuxcnc", "twincat"), fit_path=None) -> CompensationFiles:
    """Write the compensation of ``result`` into ``folder``.

    Files: ``<AXIS>.csv`` per motion axis with error joints, ``constants.json``, ``calibrated.urdf``,
    ``compensation.json`` (provenance, grids, sign convention, how closely each controller file
    follows the model) and, per controller format, one file per axis with a positioning error joint
    (on the same grid, or on the finest grid the format holds).
    """
    from kinid import __version__
    from kinid.files import write_json, write_text

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    machine = result.machine
    written, tables, skipped, controller, notes = [], {}, [], [], []
    for a in machine.axes:
        step = step_mm if a.kind == "prismatic" else step_deg
        grid, source = axis_grid(result, a.name, step)
        cols = axis_error_columns(result, a.name, grid)
        if not cols:
            skipped.append(a.name)
            continue
        write_text(folder / f"{a.name}.csv", neutral_csv_text(a.column, grid, cols))
        written.append(f"{a.name}.csv")
        tables[a.name] = {"file": f"{a.name}.csv", "column": a.column, "from": float(grid[0]), "to": float(grid[-1]),
                          "points": int(grid.size), "range_from": source, "columns": list(cols)}
        span = result.axis_ranges.get(a.name)
        if span and source == "URDF limits" and any(cols[c].any() for c in cols) and \
                (span[1] - span[0]) < 0.9 * (grid[-1] - grid[0]):
            unit_q = "deg" if a.kind == "revolute" else "mm"
            notes.append(f"{a.name}.csv: the fitted data span {span[0]:.4g} .. {span[1]:.4g} {unit_q} of the travel "
                         f"{grid[0]:.4g} .. {grid[-1]:.4g} {unit_q}; beyond them the table is the model's extrapolation")
        if f"E{a.name}{a.name}" not in machine.error_codes:
            continue
        unit = "µrad" if a.kind == "revolute" else "µm"
        for fmt in formats:
            pattern, _, most = FORMATS[fmt]
            fgrid = grid if grid.size <= most else points_for(step, grid[0], grid[-1], most)
            table = positioning_table(result, a.name, fgrid)
            options = {"axis_number": machine.axis_names.index(a.name) + 1} if fmt == "twincat" else {}
            name = pattern.format(axis=a.name)
            write_text(folder / name, format_text(fmt, table, **options))
            written.append(name)
            worst = _interpolation_error(result, table, unit)
            controller.append({"file": name, "format": fmt, "axis": a.name, "points": int(fgrid.size),
                               "step": float(fgrid[1] - fgrid[0]), "max_interpolation_error": worst, "unit": unit})
            if worst > 0.1:
                notes.append(f"{name}: {fmt} holds {most} points, a step of {fgrid[1] - fgrid[0]:.3g} "
                             f"{'deg' if a.kind == 'revolute' else 'mm'} over the travel; its linear interpolation "
                             f"departs from the model by up to {worst:.3g} {unit}")
    write_json(folder / "constants.json", {"errors": constant_errors(result)})
    write_text(folder / "calibrated.urdf", calibrated_urdf(result))
    written += ["constants.json", "calibrated.urdf"]
    not_tabulated = [e.name for e in result.effects if e.basis == "drift"]
    notes += [f"{n}: a drift with time, in no table" for n in not_tabulated]
    info = {
        "kinid_version": __version__,
        "fit": None if fit_path is None else {"file": str(fit_path),
                                              "sha256": hashlib.sha256(Path(fit_path).read_bytes()).hexdigest()},
        "machine": machine.path,
        "sign_convention": "error = actual - commanded, µm (linear) or µrad (rotary); direction + unless _rev",
        "fitted_ranges": {k: list(v) for k, v in result.axis_ranges.items()},
        "tables": tables,
        "controller_files": controller,
        "axes_without_error_joints": skipped,
        "not_tabulated": not_tabulated,
    }
    write_json(folder / "compensation.json", info)
    written.append("compensation.json")
    return CompensationFiles(tuple(written), tuple(notes))
