"""Camera / laser radial offsets from a shape the laser scans: a ball (a least-squares sphere through the
machine positions at which the laser reads its stand-off) or two straight edges (the intersection of the
two fitted lines), each against the camera centred on the same feature. The hole, the axial offset and
the results are in :mod:`kinid.vision.laser_offsets`.
"""
from __future__ import annotations

import math

import numpy as np

from kinid.errors import DataError

from .laser_offsets import _check_sigma, _covariance, _mean_and_cov, _points, _radial

__all__ = ["radial_offset_from_sphere", "radial_offset_from_edges"]

#: Smallest angle between the two edges of :func:`radial_offset_from_edges`, degrees.
MIN_EDGE_ANGLE_DEG = 10.0
#: Gauss-Newton stopping rule of the sphere fit.
SPHERE_TOL_MM = 1e-12
SPHERE_MAX_ITER = 100
#: Largest condition number of the sphere fit's Jacobian before the points count as degenerate.
MAX_CONDITION = 1e10


def _fit_sphere(points, radius=None):
    """Geometric least-squares sphere: centre (3,), radius, covariance, residuals."""
    n = len(points)
    # algebraic start: |p|^2 = 2 c.p + (R^2 - |c|^2)
    a = np.column_stack([2 * points, np.ones(n)])
    rhs = (points ** 2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, rhs, rcond=None)
    centre = sol[:3]
    r = math.sqrt(max(sol[3] + centre @ centre, 0.0)) if radius is None else radius
    fit_radius = radius is None
    for _ in range(SPHERE_MAX_ITER):
        diff = points - centre
        dist = np.linalg.norm(diff, axis=1)
        if np.any(dist == 0):
            raise DataError("a laser point coincides with the sphere centre; the points do not describe a sphere")
        res = dist - r
        jac = -diff / dist[:, None]
        if fit_radius:
            jac = np.column_stack([jac, -np.ones(n)])
        step, *_ = np.linalg.lstsq(jac, -res, rcond=None)
        centre = centre + step[:3]
        if fit_radius:
            r += step[3]
        if np.max(np.abs(step)) < SPHERE_TOL_MM * max(1.0, abs(r)):
            break
    diff = points - centre
    dist = np.linalg.norm(diff, axis=1)
    res = dist - r
    jac = -diff / dist[:, None]
    if fit_radius:
        jac = np.column_stack([jac, -np.ones(n)])
    dof = n - jac.shape[1]
    s2 = (res @ res) / dof if dof > 0 else math.nan
    rr = np.linalg.qr(jac, mode="r")
    cond = np.linalg.cond(rr)
    if not np.isfinite(cond) or cond > MAX_CONDITION:
        raise DataError("the laser points do not fix a sphere (all on one plane or one line); "
                        "spread them over the ball's cap")
    return centre, r, _covariance(rr, s2), res


def radial_offset_from_sphere(laser_points_xyz_mm, standoff_mm, camera_centre_xy_mm, *, radius_mm=None,
                              sigma_mm=None):
    """Radial offset from a ball: sphere fit of laser points vs the camera on the ball's image.

    Parameters
    ----------
    laser_points_xyz_mm : array_like, shape (N, 3)
        Machine (x, y, z) at which the laser read ``standoff_mm`` on the
        ball's surface, mm. The surface point is ``(x, y, z - standoff_mm)``
        (the laser looks down, -z).
    standoff_mm : float
        The laser reading held on the surface, mm.
    camera_centre_xy_mm : array_like, shape (2,) or (M, 2)
        Machine (x, y) with the camera's optical centre on the centre of the
        ball's image (``vision.circles.locate_sphere``), mm.
    radius_mm : float or None
        Known ball radius, mm; ``None`` fits it (needs points well down the
        sides of the ball).
    sigma_mm : float or None
        Repeatability of one camera alignment, mm. ``None``: the scatter of
        repeated camera readings, or, for a single one, none (``sigma`` then
        covers the laser fit only).

    Returns
    -------
    OffsetResult
        ``dx_mm, dy_mm`` = fitted sphere centre - mean camera position;
        ``feature_mm`` = sphere centre (x, y, z) of the surface, ``radius_mm``.

    Raises
    ------
    DataError
        Too few points (4, or 3 with a known radius), points on one plane, bad
        arguments.
    """
    sigma_mm = _check_sigma(sigma_mm)
    pts = _points(laser_points_xyz_mm, "laser_points_xyz_mm", 3)
    try:
        standoff = float(standoff_mm)
    except (TypeError, ValueError):
        raise DataError(f"standoff_mm must be a number, got {standoff_mm!r}") from None
    if radius_mm is not None:
        radius_mm = float(radius_mm)
        if not radius_mm > 0:
            raise DataError(f"radius_mm must be positive or None, got {radius_mm!r}")
    need = 4 if radius_mm is None else 3
    if len(pts) < need + 1:
        raise DataError(f"laser_points_xyz_mm needs at least {need + 1} points to fit a sphere and its "
                        f"uncertainty, got {len(pts)}")
    surface = pts - np.array([0.0, 0.0, standoff])
    centre, radius, cov, res = _fit_sphere(surface, radius_mm)
    camera = _points(camera_centre_xy_mm, "camera_centre_xy_mm", 2)
    cm, cc = _mean_and_cov(camera, sigma_mm)
    rms = math.sqrt(np.mean(res ** 2))
    return _radial(centre[:2] - cm, cov[:2, :2] + cc, rms, len(pts), "sphere", centre, radius)


def _fit_line(points):
    """Total-least-squares line: centroid, unit direction, normal-offset variance, angle variance, residuals."""
    centroid = points.mean(axis=0)
    centred = points - centroid
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    direction = vt[0]
    normal = np.array([-direction[1], direction[0]])
    res = centred @ normal
    along = centred @ direction
    n = len(points)
    s2 = (res @ res) / (n - 2)
    spread = along @ along
    if spread <= 0:
        raise DataError("edge points coincide; they do not define a line")
    return centroid, direction, s2 / n, s2 / spread, res


def _line_intersection(c1, d1, c2, d2):
    a = np.column_stack([d1, -d2])
    t = np.linalg.solve(a, c2 - c1)
    return c1 + t[0] * d1


def radial_offset_from_edges(edge1_points_xy_mm, edge2_points_xy_mm, camera_corner_xy_mm, *, sigma_mm=None):
    """Radial offset from two straight edges scanned by the laser.

    Parameters
    ----------
    edge1_points_xy_mm, edge2_points_xy_mm : array_like, shape (N, 2)
        Machine (x, y) at which the laser reading jumped while crossing each
        edge (at least 3 per edge), mm.
    camera_corner_xy_mm : array_like, shape (2,) or (M, 2)
        Machine (x, y) with the camera's optical centre on the corner where
        the edges meet, mm.
    sigma_mm : float or None
        Repeatability of one camera alignment, mm. ``None``: the scatter of
        repeated camera readings, or, for a single one, none (``sigma`` then
        covers the laser fit only).

    Returns
    -------
    OffsetResult
        ``dx_mm, dy_mm`` = intersection of the two total-least-squares lines
        - mean camera position; ``feature_mm`` = the intersection.

    Raises
    ------
    DataError
        Fewer than 3 points on an edge, or edges closer to parallel than
        :data:`MIN_EDGE_ANGLE_DEG`.
    """
    sigma_mm = _check_sigma(sigma_mm)
    e1 = _points(edge1_points_xy_mm, "edge1_points_xy_mm", 2)
    e2 = _points(edge2_points_xy_mm, "edge2_points_xy_mm", 2)
    for name, e in (("edge1_points_xy_mm", e1), ("edge2_points_xy_mm", e2)):
        if len(e) < 3:
            raise DataError(f"{name} needs at least 3 points to fit a line and its uncertainty, got {len(e)}")
    c1, d1, var_off1, var_ang1, r1 = _fit_line(e1)
    c2, d2, var_off2, var_ang2, r2 = _fit_line(e2)
    angle = math.degrees(math.acos(min(1.0, abs(float(d1 @ d2)))))
    if angle < MIN_EDGE_ANGLE_DEG:
        raise DataError(f"the edges meet at {angle:.1f} deg; need at least {MIN_EDGE_ANGLE_DEG:g} deg "
                        "for a well-defined corner")
    corner = _line_intersection(c1, d1, c2, d2)

    # propagate: each line moves along its normal (variance s^2/N at the centroid) and turns
    # about its centroid (variance s^2/sum(u^2)); the four are independent
    def moved(p):
        rot1, rot2 = p[1], p[3]
        n1 = np.array([-d1[1], d1[0]])
        n2 = np.array([-d2[1], d2[0]])
        dd1 = d1 * math.cos(rot1) + n1 * math.sin(rot1)
        dd2 = d2 * math.cos(rot2) + n2 * math.sin(rot2)
        return _line_intersection(c1 + p[0] * n1, dd1, c2 + p[2] * n2, dd2)

    eps = 1e-7
    jac = np.column_stack([(moved(np.eye(4)[k] * eps) - moved(-np.eye(4)[k] * eps)) / (2 * eps) for k in range(4)])
    cov = jac @ np.diag([var_off1, var_ang1, var_off2, var_ang2]) @ jac.T
    camera = _points(camera_corner_xy_mm, "camera_corner_xy_mm", 2)
    cm, cc = _mean_and_cov(camera, sigma_mm)
    res = np.concatenate([r1, r2])
    return _radial(corner - cm, cov + cc, math.sqrt(np.mean(res ** 2)), len(e1) + len(e2), "edges", corner)
