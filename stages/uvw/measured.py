"""The UVW actuator model from measured moves (``kinid uvw --data MOVES.csv``, docs/uvw.md).

The moves file holds, per actuator, the test plan a user ran on the stage: each commanded position, the
direction it was approached from, and the position the vision system measured (µm from home). Each
actuator's error model (:mod:`~kinid.stages.uvw.model`) is chosen by BIC and fitted to them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from kinid.errors import DataError
from kinid.files import csv_number, read_csv_table

from .kinematics import ACTUATORS
from .model import select_actuator_model

__all__ = ["read_moves", "fit_moves", "models_json", "actuator_tables", "MOVES_COLUMNS"]

MOVES_COLUMNS = ("actuator", "command_um", "direction", "measured_um")


def read_moves(path) -> dict:
    """actuator -> (commands_um, directions, measured_um) from a moves CSV.

    Raises
    ------
    DataError
        Naming the file, line and column of the first problem.
    """
    path = Path(path)
    header_line, header, rows = read_csv_table(path, what="moves file", required=MOVES_COLUMNS)
    data = {}
    for line, cells in rows:
        actuator = cells[header.index("actuator")].strip()
        if actuator not in ACTUATORS:
            raise DataError(f"unknown actuator {actuator!r}; expected {', '.join(ACTUATORS)}", path=path, line=line,
                            column="actuator")
        num = lambda c: csv_number(cells, header.index(c), path=path, line=line, column=c)  # noqa: E731
        d = num("direction")
        if d not in (1.0, -1.0):
            raise DataError(f"direction must be +1 or -1, found {cells[header.index('direction')].strip()!r}",
                            path=path, line=line, column="direction")
        data.setdefault(actuator, []).append((num("command_um"), d, num("measured_um")))
    if not data:
        raise DataError("no data rows after the header", path=path, line=header_line)
    out = {}
    for a, rows_a in data.items():
        arr = np.array(rows_a)
        if len(set(arr[:, 1])) < 2:
            raise DataError(f"actuator {a}: every move approaches from one side; the backlash needs both", path=path)
        out[a] = (arr[:, 0], arr[:, 1], arr[:, 2])
    return out


def fit_moves(moves: dict, lead_um: float, *, noise_um=None) -> dict:
    """actuator -> ActuatorModel chosen by BIC (degree 1-3, 1-4 harmonics of the lead)."""
    return {a: select_actuator_model(c, d, m, lead_um, noise_um=noise_um) for a, (c, d, m) in moves.items()}


def models_json(models: dict, source: str) -> dict:
    """The fitted models for a file: parameters with standard deviations, units in the names."""
    out = {"source": source, "model": "measured = command + offset + scale·c − d·B/2 + bow + lead harmonics (docs/uvw.md)",
           "actuators": {}}
    for a, m in models.items():
        out["actuators"][a] = {
            "lead_um": m.lead_um, "degree": m.degree, "harmonics": m.harmonics,
            "parameters": {n: {"value": float(v), "std": float(s)} for n, v, s in zip(m.names, m.values, m.std)},
            "rms_um": m.rms_um, "noise_um": m.sigma_um, "span_um": list(m.span_um),
        }
    return out


def actuator_tables(models: dict, step_um: float = 50.0) -> dict:
    """actuator -> AxisErrorTable over its fitted span (positions mm, errors µm, both directions)."""
    from kinid.axis_tables import AxisErrorTable, points_for

    out = {}
    for a, m in models.items():
        c = points_for(step_um, *m.span_um)
        out[a] = AxisErrorTable(a, False, c * 1e-3, np.asarray(m.error_um(c, 1.0), float),
                                np.asarray(m.error_um(c, -1.0), float))
    return out
