"""Controller compensation files read as their controllers read them (tests' and benchmarks' independent side).

Each reader parses one file format with its controller's documented rules — units, signs, which
points, modulo tables, end values held beyond the table — and returns ``reads(x, forward=True)``:
the compensation the controller applies at commanded positions ``x`` (mm or degrees), in mm or
degrees. No kinid code is used.

- LinuxCNC ``COMP_FILE_TYPE 0``: "nominal forward reverse"; the trim is actual − nominal; the loader's
  end entries have zero slope (the end values are held).
- Beckhoff TwinCAT CNC ``kw.ssfk``: setpoints and values in 0.1 µm (0.0001°), explicit points,
  ``kw_nr_max`` below ``max_points`` (1500), ``modulo`` wraps the table.
- Siemens SINUMERIK ``%_N_AX_EEC_INI``: ``$AA_ENC_COMP[0,N,AX]`` from N = 0 to (MAX − MIN)/STEP at equal
  steps, in mm (degrees), one table for both directions, ends held, ``IS_MODULO`` wraps.
"""
from __future__ import annotations

import re

import numpy as np


def _hold_interp(x, xp, fp, modulo=False):
    if modulo:
        x = xp[0] + np.mod(x - xp[0], xp[-1] - xp[0])
    return np.interp(x, xp, fp)  # numpy holds the end values, as the controllers do


def linuxcnc_reads(text):
    """LinuxCNC COMP_FILE_TYPE 0: 'nominal forward reverse' in machine units; the trim is actual − nominal."""
    rows = np.array([line.split() for line in text.splitlines() if line.strip()], float)
    assert np.all(np.diff(rows[:, 0]) > 0), "LinuxCNC: compensation values must increase"
    assert rows.shape[0] <= 256
    nominal = rows[:, 0]
    return lambda x, forward=True: _hold_interp(x, nominal, rows[:, 1 if forward else 2] - nominal)


def twincat_reads(text, rotary):
    kv = dict(line.split(None, 1) for line in text.splitlines() if line.strip() and not line.startswith("#"))
    n = int(kv["kw.ssfk.kw_nr_max"])
    assert n < 1500 and kv["kw.ssfk.interval"].strip() == "0" and kv["kw.ssfk.unit"].strip() == "1"
    setpoint = np.array([int(kv[f"kw.ssfk.table[{i}].setpoint"]) for i in range(n)]) * 1e-4  # mm or deg
    scale = 1e-4 if rotary else 1e-4  # 0.0001° or 0.1 µm (= 1e-4 mm)
    pos = np.array([int(kv[f"kw.ssfk.table[{i}].pos"]) for i in range(n)]) * scale
    neg = np.array([int(kv[f"kw.ssfk.table[{i}].neg"]) for i in range(n)]) * scale
    modulo = kv.get("kw.ssfk.modulo", "0").strip() == "1"
    return lambda x, forward=True: _hold_interp(x, setpoint, pos if forward else neg, modulo)


def sinumerik_reads(text):
    lines = text.splitlines()
    assert lines[0] == "%_N_AX_EEC_INI" and lines[1] == "CHANDATA(1)" and lines[-1] == "M17"
    values = {int(m.group(1)): float(m.group(2)) for m in
              (re.match(r"\$AA_ENC_COMP\[0,(\d+),AX\d+\]=(\S+)", line) for line in lines) if m}
    get = lambda key: float(re.search(rf"\${key}\[0,AX\d+\]=(\S+)", text).group(1))  # noqa: E731
    step, lo, hi = get("AA_ENC_COMP_STEP"), get("AA_ENC_COMP_MIN"), get("AA_ENC_COMP_MAX")
    k = round((hi - lo) / step)
    assert sorted(values) == list(range(k + 1)), "every point from 0 to (MAX - MIN) / STEP"
    x_pts = lo + step * np.arange(k + 1)
    v = np.array([values[i] for i in range(k + 1)])
    modulo = get("AA_ENC_COMP_IS_MODULO") == 1
    return lambda x, forward=True: _hold_interp(x, x_pts, v, modulo)


READERS = {"linuxcnc": lambda text, rotary: linuxcnc_reads(text), "twincat": twincat_reads,
           "sinumerik": lambda text, rotary: sinumerik_reads(text)}
