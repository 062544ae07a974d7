"""Contour error of a measured track against a programmed path; ISO 230-4 circular-test figures.

All coordinates are in the camera frame of the track (x right, y down in the
image, mm, relative to the first frame). Errors are normal to the path, µm:

* circle: radial deviation ``|p - centre| - radius``, positive outward;
* line / polyline: signed distance to the nearest segment, positive to the
  right of the direction of travel as seen in the image (the segment direction
  turned by +90 degrees in x-right / y-down axes).

ISO 230-4:2005 figures for a circular test (:func:`circular_test`), all about
the least-squares circle's centre:

* G, circular deviation: ``max(r) - min(r)`` (one direction at a time; the
  larger one when both directions were run);
* F, radial deviation: ``max(r - R0)`` and ``min(r - R0)`` against the nominal
  radius ``R0`` (the fitted radius when none is given);
* H, circular hysteresis: largest radial difference between the paths run
  clockwise and counter-clockwise at the same angle.

References
----------
ISO 230-4:2005, Test code for machine tools - Part 4: Circular tests for
numerically controlled machine tools.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError

__all__ = ["CirclePath", "LinePath", "PolylinePath", "ContourError", "CircularTest", "fit_circle", "fit_line",
           "contour_error", "circular_test", "travel_direction", "load_polyline"]

#: Gauss-Newton iterations and step tolerance (mm) of the geometric circle fit.
CIRCLE_FIT_MAX_ITER = 50
CIRCLE_FIT_TOL_MM = 1e-12
#: Angular bins (over 360 degrees) on which the two directions are compared for H.
HYSTERESIS_BINS = 720
#: Points whose spread across their best line is below this fraction of the spread along it are collinear.
COLLINEAR_REL = 1e-9


@dataclass(frozen=True)
class CirclePath:
    """A programmed circle; ``None`` fields are fitted (least squares) to the track.

    Attributes
    ----------
    centre_mm : tuple of float or None
        Centre in track coordinates, mm.
    radius_mm : float or None
        Radius, mm.
    """

    centre_mm: tuple | None = None
    radius_mm: float | None = None

    def __post_init__(self):
        from kinid.checks import check_array, check_positive

        if self.radius_mm is not None:
            object.__setattr__(self, "radius_mm", check_positive("radius_mm", self.radius_mm))
        if self.centre_mm is not None:
            object.__setattr__(self, "centre_mm", tuple(check_array("centre_mm", self.centre_mm, shape=(2,))))


@dataclass(frozen=True)
class LinePath:
    """A programmed straight line through ``start_mm`` and ``end_mm`` (fitted when None)."""

    start_mm: tuple | None = None
    end_mm: tuple | None = None


@dataclass(frozen=True)
class PolylinePath:
    """A programmed path given by its vertices, mm (track coordinates), shape (M, 2), M >= 2."""

    vertices_mm: tuple


@dataclass(frozen=True)
class ContourError:
    """Contour error of a track.

    Attributes
    ----------
    error_um : ndarray, shape (N,)
        Error normal to the path per point, µm (NaN where the point is NaN).
    path : CirclePath or LinePath or PolylinePath
        The path with every fitted quantity filled in.
    rms_um, max_um : float
        RMS and largest absolute error over the finite points, µm.
    """

    error_um: np.ndarray
    path: object
    rms_um: float
    max_um: float


@dataclass(frozen=True)
class CircularTest:
    """ISO 230-4 figures of a circular test, µm.

    Attributes
    ----------
    G_um : float
        Circular deviation (largest over the directions run).
    F_max_um, F_min_um : float
        Radial deviation: largest and smallest ``r - R0``.
    H_um : float
        Circular hysteresis; NaN unless both directions cover a common arc.
    centre_mm : tuple of float
        Least-squares centre.
    radius_mm : float
        Least-squares radius.
    nominal_radius_mm : float
        ``R0`` used for F.
    G_by_direction_um : dict
        ``{"+": G, "-": G}`` for the directions present (``+``: angle
        increasing in x-right / y-down axes, i.e. clockwise as seen in the image).
    """

    G_um: float
    F_max_um: float
    F_min_um: float
    H_um: float
    centre_mm: tuple
    radius_mm: float
    nominal_radius_mm: float
    G_by_direction_um: dict


def _finite_points(xy):
    xy = np.asarray(xy, float).reshape(-1, 2)
    ok = np.all(np.isfinite(xy), axis=1)
    return xy, ok


def fit_circle(xy_mm):
    """Least-squares (geometric) circle through points.

    Algebraic (Kåsa) start, then Gauss-Newton on the radial distances.

    Parameters
    ----------
    xy_mm : array_like, shape (N, 2)
        Points, mm; rows with NaN are ignored.

    Returns
    -------
    tuple
        ``((cx, cy), r)`` in mm.

    Raises
    ------
    DataError
        Fewer than 3 finite points, or all on a line.
    """
    xy, ok = _finite_points(xy_mm)
    p = xy[ok]
    if len(p) < 3:
        raise DataError(f"a circle needs at least 3 located points, got {len(p)}", column="path")
    m = p.mean(axis=0)
    q = p - m
    sv = np.linalg.svd(q, compute_uv=False)
    if not sv[1] > COLLINEAR_REL * sv[0]:
        raise DataError("the located points lie on a line; no circle can be fitted (try --path line)",
                        column="path")
    A = np.column_stack([2 * q, np.ones(len(q))])
    rhs = (q ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(A, rhs, rcond=None)
    c = sol[:2]
    r2 = sol[2] + c @ c
    span = float(np.ptp(q, axis=0).max())
    if not (r2 > 0 and math.isfinite(r2)) or math.sqrt(r2) > 1e6 * max(span, 1e-12):
        raise DataError("the located points lie on a line; no circle can be fitted (try --path line)",
                        column="path")
    r = math.sqrt(r2)
    for _ in range(CIRCLE_FIT_MAX_ITER):
        d = q - c
        rho = np.hypot(d[:, 0], d[:, 1])
        res = rho - r
        J = np.column_stack([-d[:, 0] / rho, -d[:, 1] / rho, -np.ones(len(rho))])
        step, *_ = np.linalg.lstsq(J, -res, rcond=None)
        c = c + step[:2]
        r = r + step[2]
        if np.max(np.abs(step)) < CIRCLE_FIT_TOL_MM:
            break
    return (float(c[0] + m[0]), float(c[1] + m[1])), float(abs(r))


def fit_line(xy_mm):
    """Total-least-squares line: ``(start, end)``, the extreme projections of the points on it, mm."""
    xy, ok = _finite_points(xy_mm)
    p = xy[ok]
    if len(p) < 2:
        raise DataError(f"a line needs at least 2 located points, got {len(p)}", column="path")
    m = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - m, full_matrices=False)
    u = vt[0]
    if u @ (p[-1] - p[0]) < 0:  # direction of travel
        u = -u
    s = (p - m) @ u
    return tuple(map(float, m + s.min() * u)), tuple(map(float, m + s.max() * u))


def _segment_errors(xy, verts):
    """Signed distance of every point to the nearest segment of a polyline (mm)."""
    a = verts[:-1][None, :, :]
    d = (verts[1:] - verts[:-1])[None, :, :]
    L2 = (d ** 2).sum(-1)
    if np.any(L2 == 0):
        raise DataError("path has two equal consecutive vertices", column="path")
    q = xy[:, None, :] - a
    t = np.clip((q * d).sum(-1) / L2, 0.0, 1.0)
    foot = a + t[..., None] * d
    dist = np.hypot(*(xy[:, None, :] - foot).transpose(2, 0, 1))
    j = np.argmin(dist, axis=1)
    i = np.arange(len(xy))
    dj = d[0, j]
    side = np.sign(dj[:, 0] * q[i, j, 1] - dj[:, 1] * q[i, j, 0])  # +: right of travel in y-down axes
    side[side == 0] = 1.0
    return dist[i, j] * side


def contour_error(track_xy_mm, path) -> ContourError:
    """Error of a track normal to a programmed path.

    Parameters
    ----------
    track_xy_mm : array_like, shape (N, 2)
        Track, mm (NaN rows allowed: their error is NaN).
    path : CirclePath or LinePath or PolylinePath

    Returns
    -------
    ContourError
    """
    from kinid.checks import check_array, check_instance

    check_array("track_xy_mm", track_xy_mm, finite=False)
    check_instance("path", path, (CirclePath, LinePath, PolylinePath))
    xy, ok = _finite_points(track_xy_mm)
    err = np.full(len(xy), np.nan)
    p = xy[ok]
    if isinstance(path, CirclePath):
        centre, radius = path.centre_mm, path.radius_mm
        if centre is None:
            centre, r_fit = fit_circle(p)
            if radius is None:
                radius = r_fit
            else:
                # centre fitted with the radius held at the given value
                centre = _fit_centre_fixed_radius(p, centre, float(radius))
        centre = (float(centre[0]), float(centre[1]))
        rho = np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1])
        if radius is None:
            radius = float(rho.mean())
        err[ok] = (rho - float(radius)) * 1e3
        path = CirclePath(centre, float(radius))
    elif isinstance(path, LinePath):
        start, end = path.start_mm, path.end_mm
        if start is None or end is None:
            start, end = fit_line(p)
        verts = np.array([start, end], float)
        err[ok] = _segment_line(p, verts) * 1e3
        path = LinePath(tuple(map(float, verts[0])), tuple(map(float, verts[1])))
    elif isinstance(path, PolylinePath):
        verts = np.asarray(path.vertices_mm, float).reshape(-1, 2)
        if len(verts) < 2:
            raise DataError(f"a polyline needs at least 2 vertices, got {len(verts)}", column="path")
        err[ok] = _segment_errors(p, verts) * 1e3
    else:
        raise DataError(f"unknown path {path!r}; expected CirclePath, LinePath or PolylinePath", column="path")
    fin = err[np.isfinite(err)]
    rms = float(np.sqrt(np.mean(fin ** 2))) if fin.size else float("nan")
    mx = float(np.max(np.abs(fin))) if fin.size else float("nan")
    return ContourError(err, path, rms, mx)


def _segment_line(p, verts):
    """Signed distance to the infinite line through two vertices (mm)."""
    d = verts[1] - verts[0]
    L = float(np.hypot(*d))
    if L == 0:
        raise DataError("line start and end are the same point", column="path")
    q = p - verts[0]
    return (d[0] * q[:, 1] - d[1] * q[:, 0]) / L


def _fit_centre_fixed_radius(p, centre0, radius):
    c = np.asarray(centre0, float)
    for _ in range(CIRCLE_FIT_MAX_ITER):
        d = p - c
        rho = np.hypot(d[:, 0], d[:, 1])
        J = np.column_stack([-d[:, 0] / rho, -d[:, 1] / rho])
        step, *_ = np.linalg.lstsq(J, -(rho - radius), rcond=None)
        c = c + step
        if np.max(np.abs(step)) < CIRCLE_FIT_TOL_MM:
            break
    return float(c[0]), float(c[1])


def travel_direction(track_xy_mm, centre_mm):
    """Direction of travel round ``centre_mm`` per point: +1, -1 (0 where unknown).

    ``+1``: polar angle ``atan2(y, x)`` increasing in x-right / y-down axes
    (clockwise as seen in the image). Each point takes the sign of the angle
    step to the next located point (the last one that of the step before).
    """
    xy, ok = _finite_points(track_xy_mm)
    out = np.zeros(len(xy), int)
    idx = np.flatnonzero(ok)
    if len(idx) < 2:
        return out
    ang = np.unwrap(np.arctan2(xy[idx, 1] - centre_mm[1], xy[idx, 0] - centre_mm[0]))
    s = np.sign(np.diff(ang)).astype(int)
    out[idx[:-1]] = s
    out[idx[-1]] = s[-1]
    return out


def circular_test(track_xy_mm, *, nominal_radius_mm=None, centre_mm=None) -> CircularTest:
    """ISO 230-4 circular deviation G, radial deviation F and hysteresis H of a circle track.

    Parameters
    ----------
    track_xy_mm : array_like, shape (N, 2)
        Track, mm; NaN rows ignored. A run in both directions (e.g. a full
        turn one way, then back) gives H.
    nominal_radius_mm : float or None
        ``R0`` for F; default the least-squares radius.
    centre_mm : tuple of float or None
        Centre to use instead of the least-squares centre.

    Returns
    -------
    CircularTest
    """
    xy, ok = _finite_points(track_xy_mm)
    c_fit, r_fit = fit_circle(xy[ok])
    centre = c_fit if centre_mm is None else (float(centre_mm[0]), float(centre_mm[1]))
    r0 = r_fit if nominal_radius_mm is None else float(nominal_radius_mm)
    rho = np.hypot(xy[:, 0] - centre[0], xy[:, 1] - centre[1])
    direction = travel_direction(xy, centre)
    G_dir = {}
    for s, key in ((1, "+"), (-1, "-")):
        sel = ok & (direction == s)
        if sel.sum() >= 3:
            G_dir[key] = float((rho[sel].max() - rho[sel].min()) * 1e3)
    G = max(G_dir.values()) if G_dir else float((rho[ok].max() - rho[ok].min()) * 1e3)
    dev = (rho[ok] - r0) * 1e3
    H = float("nan")
    if len(G_dir) == 2:
        ang = np.mod(np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]), 2 * np.pi)
        grid = (np.arange(HYSTERESIS_BINS) + 0.5) * (2 * np.pi / HYSTERESIS_BINS)
        curves = []
        for s in (1, -1):
            sel = ok & (direction == s)
            a, r = ang[sel], rho[sel]
            order = np.argsort(a)
            a, r = a[order], r[order]
            # covered bins: within one mean angular step of a sample
            step = 2 * np.pi / max(len(a), 1)
            gap = np.abs(((grid[:, None] - a[None, :]) + np.pi) % (2 * np.pi) - np.pi).min(axis=1)
            covered = gap <= 1.5 * max(step, np.median(np.diff(a)) if len(a) > 1 else step)
            val = np.interp(grid, np.concatenate([a - 2 * np.pi, a, a + 2 * np.pi]), np.tile(r, 3))
            curves.append((val, covered))
        both = curves[0][1] & curves[1][1]
        if both.any():
            H = float(np.max(np.abs(curves[0][0][both] - curves[1][0][both])) * 1e3)
    return CircularTest(G, float(dev.max()), float(dev.min()), H, centre, r_fit, r0, G_dir)


def load_polyline(path):
    """Vertices from a CSV file with columns ``x_mm,y_mm`` (header row required; ``#`` comments).

    Raises
    ------
    DataError
        Missing file or columns, a cell that is not a number, fewer than 2 rows.
    """
    from kinid.files import csv_number, read_csv_rows

    lines = read_csv_rows(path, what="path file")
    if not lines:
        raise DataError("empty path file; expected a header x_mm,y_mm and at least 2 rows", path=path)
    rows = [cells for _, cells in lines]
    header = [h.strip() for h in rows[0]]
    for col in ("x_mm", "y_mm"):
        if col not in header:
            raise DataError(f"missing column {col} (header is {','.join(header)})", path=path, line=lines[0][0],
                            column=col)
    ix, iy = header.index("x_mm"), header.index("y_mm")
    verts = []
    for (lineno, _), row in zip(lines[1:], rows[1:]):
        verts.append([csv_number(row, i, path=path, line=lineno, column=col) for i, col in ((ix, "x_mm"), (iy, "y_mm"))])
    if len(verts) < 2:
        raise DataError(f"a polyline needs at least 2 vertices, got {len(verts)}", path=path)
    return tuple(tuple(v) for v in verts)
