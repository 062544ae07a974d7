"""Cubic B-splines on knot grids: the basis of a local error (``CODE:local:<step>:<from>:<to>``), computed once per
grid for all the windows on it (the diagnosis scores hundreds of windows on the same readings); and a map's hat
functions (``CODE:map:<step>``)."""
from __future__ import annotations

import numpy as np

__all__ = ["local_grid", "local_columns", "local_column_index"]


def _bsplines(q, centres, step):
    """Cubic B-splines of knot spacing ``step`` centred at ``centres``, at readings ``q``: (N, len(centres))."""
    r = np.abs(q[:, None] - centres[None, :]) / step
    out = np.zeros_like(r)
    near, mid = r < 1, (r >= 1) & (r < 2)
    out[near] = 2 / 3 - r[near] ** 2 + r[near] ** 3 / 2
    out[mid] = (2 - r[mid]) ** 3 / 6
    return out


def local_grid(e) -> tuple:
    """(step, phase) of the knot grid of the local error ``e``: windows with the same pair share their B-splines."""
    knots = np.asarray(e.knots)
    step = float(knots[1] - knots[0])
    return step, round(float(knots[0] - step * np.round(knots[0] / step)), 9)


def _grid_span(q, step: float, phase: float) -> tuple:
    """(first centre, count) of the B-splines every ``step`` (at ``phase``) that reach readings ``q``."""
    first = phase + step * (np.floor((q.min() - phase) / step) - 2)
    return first, int(np.ceil((q.max() + 2 * step - first) / step)) + 1


def _grid_index(e, first: float, step: float, count: int) -> np.ndarray:
    """Columns of the grid (from ``first``, ``count`` B-splines) that are the local error ``e``'s; ``count`` for a
    B-spline off the grid (zero at every reading)."""
    index = np.round((np.asarray(e.knots)[2:-2] - first) / step).astype(int)
    return np.where((index >= 0) & (index < count), index, count)


def local_columns(effects, q, rows=slice(None)) -> np.ndarray:
    """The values (rows, c) at readings ``q[rows]`` of the B-splines of local errors ``effects`` on one knot grid
    (:func:`local_grid`), computed once for all of them; :func:`local_column_index` says which are whose.
    They are the numbers the local basis gives (:func:`_local_values`, each window's own B-splines), to rounding."""
    q = np.asarray(q, float)
    if q.size == 0 or not np.all(np.isfinite(q)):  # as _local_values: each effect's own B-splines
        return np.concatenate([_bsplines(q[rows], np.asarray(e.knots)[2:-2], local_grid(e)[0]) for e in effects],
                              axis=1)
    step, phase = local_grid(effects[0])
    first, count = _grid_span(q, step, phase)
    values = np.zeros((q[rows].size, count + 1))  # column ``count``: a B-spline off the grid, zero at every reading
    values[:, :count] = _bsplines(q[rows], first + step * np.arange(count), step)
    return values


def local_column_index(effects, q) -> list:
    """For each of the local errors ``effects`` on one knot grid, its columns among :func:`local_columns`."""
    q = np.asarray(q, float)
    if q.size == 0 or not np.all(np.isfinite(q)):
        edges = np.cumsum([0] + [e.n_params for e in effects])
        return [np.arange(a, b) for a, b in zip(edges[:-1], edges[1:])]
    step, phase = local_grid(effects[0])
    first, count = _grid_span(q, step, phase)
    return [_grid_index(e, first, step, count) for e in effects]


def _map_values(e, q, t, s):
    """Hat functions: linear between knots, constant beyond the ends."""
    knots = np.asarray(e.knots)
    n = q.shape[0]
    step = knots[1] - knots[0]
    x = np.clip((q - knots[0]) / step, 0.0, len(knots) - 1.0)
    i = np.minimum(np.floor(x).astype(int), len(knots) - 2)
    frac = x - i
    out = np.zeros((n, len(knots)))
    out[np.arange(n), i] = 1.0 - frac
    out[np.arange(n), i + 1] += frac
    return out


def _local_values(e, q, t, s):
    """Cubic B-splines whose support lies inside [from, to]: smooth, zero outside. (The diagnosis scores the windows
    of one knot grid from that grid's B-splines at once, :mod:`~kinid.identification.model.bsplines`.)"""
    knots = np.asarray(e.knots)
    return _bsplines(np.asarray(q, float), knots[2:-2], float(knots[1] - knots[0]))
