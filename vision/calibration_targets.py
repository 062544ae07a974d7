"""Coverage functions of calibration targets and textured plates, for rendering.

A *coverage function* maps points of a plane, ``xy_mm`` of shape (N, 2) in
millimetres, to the ink coverage at those points, shape (N,), in [0, 1]
(1 = ink, 0 = bare paper). :func:`vision.render.render_pattern` turns one into
an anti-aliased image through an ``image_to_plane`` map; this module also
provides that map for a pinhole camera with lens distortion looking at a
plane (:func:`pinhole_image_to_plane`).

Targets:

- :func:`chessboard_coverage` -- the board that ``cv2.findChessboardCorners``
  finds; inner corner (0, 0) at the plane origin, x along a row of corners.
- :func:`circle_grid_coverage` -- symmetric or asymmetric grid of dark discs,
  as ``cv2.findCirclesGrid`` finds it.
- :func:`smooth_texture_coverage` -- a random smooth (band-limited) texture,
  a stand-in for a machined or printed plate (template matching, 003).
- :func:`printed_features_coverage` -- random printed discs and bars.
"""
from __future__ import annotations

import numpy as np

from kinid.errors import DataError

__all__ = [
    "chessboard_coverage",
    "chessboard_object_points",
    "circle_grid_coverage",
    "circle_grid_object_points",
    "smooth_texture_coverage",
    "printed_features_coverage",
    "pinhole_image_to_plane",
]


def _check_pattern_size(pattern_size, minimum=2):
    try:
        cols, rows = (int(v) for v in pattern_size)
    except (TypeError, ValueError):
        raise DataError(f"pattern_size must be two integers (cols, rows), got {pattern_size!r}") from None
    if cols < minimum or rows < minimum or (cols, rows) != tuple(pattern_size):
        raise DataError(f"pattern_size must be two integers >= {minimum} (cols, rows), got {pattern_size!r}")
    return cols, rows


def _check_positive(value, name):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise DataError(f"{name} must be a positive number, got {value!r}") from None
    if not np.isfinite(value) or value <= 0:
        raise DataError(f"{name} must be a positive number, got {value!r}")
    return value


def _as_points(xy_mm):
    xy = np.asarray(xy_mm, dtype=float)
    return xy.reshape(-1, 2)


def chessboard_object_points(pattern_size, square_mm):
    """Board coordinates of the inner corners in OpenCV's order.

    Parameters
    ----------
    pattern_size : (int, int)
        Inner corners per row and per column, ``(cols, rows)``.
    square_mm : float
        Side of a square, mm.

    Returns
    -------
    ndarray, shape (cols * rows, 3)
        ``(i * square_mm, j * square_mm, 0)`` row by row (j), i fastest.
    """
    cols, rows = _check_pattern_size(pattern_size)
    square_mm = _check_positive(square_mm, "square_mm")
    j, i = np.mgrid[0:rows, 0:cols]
    return np.column_stack([i.ravel() * square_mm, j.ravel() * square_mm, np.zeros(cols * rows)])


def chessboard_coverage(pattern_size, square_mm):
    """Coverage function of a chessboard with ``pattern_size`` inner corners.

    The board has ``(cols + 1) x (rows + 1)`` squares; inner corner ``(i, j)``
    is at ``(i * square_mm, j * square_mm)``, the square whose top-left corner
    is the plane origin is white, so the corner square at
    ``(-square_mm, -square_mm)`` is black. Outside the board is paper (0).

    Parameters
    ----------
    pattern_size : (int, int)
        Inner corners ``(cols, rows)``.
    square_mm : float
        Side of a square, mm.

    Returns
    -------
    callable
        ``coverage(xy_mm (N, 2)) -> (N,)`` with values 0 or 1.
    """
    cols, rows = _check_pattern_size(pattern_size)
    square_mm = _check_positive(square_mm, "square_mm")

    def coverage(xy_mm):
        xy = _as_points(xy_mm)
        i = np.floor(xy[:, 0] / square_mm)
        j = np.floor(xy[:, 1] / square_mm)
        inside = (i >= -1) & (i <= cols - 1) & (j >= -1) & (j <= rows - 1)
        black = ((i + j).astype(np.int64) % 2) == 0
        return (inside & black).astype(float)

    return coverage


def circle_grid_object_points(pattern_size, spacing_mm, *, asymmetric=False):
    """Board coordinates of circle centres in ``cv2.findCirclesGrid`` order.

    Parameters
    ----------
    pattern_size : (int, int)
        Circles per row and per column, ``(cols, rows)``.
    spacing_mm : float
        Centre distance along a row (symmetric grid); for an asymmetric grid
        the distance between rows is ``spacing_mm`` and neighbours in a row
        are ``2 * spacing_mm`` apart, odd rows shifted by ``spacing_mm``.
    asymmetric : bool
        Asymmetric (staggered) grid, ``cv2.CALIB_CB_ASYMMETRIC_GRID``.

    Returns
    -------
    ndarray, shape (cols * rows, 3)
    """
    cols, rows = _check_pattern_size(pattern_size)
    spacing_mm = _check_positive(spacing_mm, "spacing_mm")
    j, i = np.mgrid[0:rows, 0:cols]
    i, j = i.ravel().astype(float), j.ravel().astype(float)
    if asymmetric:
        x = (2 * i + j % 2) * spacing_mm
    else:
        x = i * spacing_mm
    return np.column_stack([x, j * spacing_mm, np.zeros(cols * rows)])


def circle_grid_coverage(pattern_size, spacing_mm, diameter_mm, *, asymmetric=False):
    """Coverage function of a grid of dark discs (see :func:`circle_grid_object_points`).

    Parameters
    ----------
    pattern_size : (int, int)
        Circles ``(cols, rows)``.
    spacing_mm : float
        Grid spacing, mm.
    diameter_mm : float
        Disc diameter, mm; must be smaller than the nearest-neighbour distance.
    asymmetric : bool
        Staggered grid.

    Returns
    -------
    callable
        ``coverage(xy_mm (N, 2)) -> (N,)``.
    """
    centres = circle_grid_object_points(pattern_size, spacing_mm, asymmetric=asymmetric)[:, :2]
    diameter_mm = _check_positive(diameter_mm, "diameter_mm")
    nearest = spacing_mm * (np.sqrt(2.0) if asymmetric else 1.0)
    if diameter_mm >= nearest:
        raise DataError(f"diameter_mm must be below the neighbour distance {nearest:g} mm, got {diameter_mm:g}")
    r2 = (diameter_mm / 2.0) ** 2
    step = spacing_mm

    def coverage(xy_mm):
        xy = _as_points(xy_mm)
        out = np.zeros(len(xy))
        # the nearest centre on the (possibly staggered) lattice: try the row below/above
        for dj in (0.0, 1.0):
            j = np.floor(xy[:, 1] / step) + dj
            shift = (j % 2) * step if asymmetric else 0.0
            pitch = 2 * step if asymmetric else step
            i = np.round((xy[:, 0] - shift) / pitch)
            cx = i * pitch + shift
            cy = j * step
            valid = (j >= 0) & (j < pattern_size[1]) & (i >= 0) & (i < pattern_size[0])
            inside = ((xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2 <= r2) & valid
            out[inside] = 1.0
        return out

    coverage.centres_mm = centres
    return coverage


def smooth_texture_coverage(rng, *, wavelength_mm=1.0, n_waves=60, contrast=1.0):
    """A random, smooth, band-limited texture (a stand-in for a plate's surface).

    Sum of ``n_waves`` plane waves with random directions, random phases and
    wavelengths between ``wavelength_mm`` and ``4 * wavelength_mm``,
    mapped into [0, 1].

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the random texture.
    wavelength_mm : float
        Shortest wavelength, mm. Keep it at 3 pixels or more so the image is
        not aliased.
    n_waves : int
        Number of plane waves.
    contrast : float
        Standard deviation of the field before the squashing ``0.5 + 0.5 tanh``.

    Returns
    -------
    callable
        ``coverage(xy_mm (N, 2)) -> (N,)``.
    """
    wavelength_mm = _check_positive(wavelength_mm, "wavelength_mm")
    theta = rng.uniform(0, 2 * np.pi, n_waves)
    lam = wavelength_mm * rng.uniform(1.0, 4.0, n_waves)
    k = np.column_stack([np.cos(theta), np.sin(theta)]) * (2 * np.pi / lam)[:, None]
    phase = rng.uniform(0, 2 * np.pi, n_waves)
    amp = rng.normal(size=n_waves) * np.sqrt(2.0 / n_waves) * contrast

    def coverage(xy_mm):
        xy = _as_points(xy_mm)
        out = np.zeros(len(xy))
        for start in range(0, len(xy), 65536):
            part = xy[start:start + 65536]
            out[start:start + 65536] = np.cos(part @ k.T + phase) @ amp
        return 0.5 + 0.5 * np.tanh(out)

    return coverage


def printed_features_coverage(rng, extent_mm, *, n_features=40, size_mm=(0.3, 2.0)):
    """Random printed discs and bars on a plate (binary coverage).

    Parameters
    ----------
    rng : numpy.random.Generator
        Source of the random layout.
    extent_mm : (float, float, float, float)
        ``(x0, y0, x1, y1)`` area the features are scattered over, mm.
    n_features : int
        Number of features (half discs, half rotated bars).
    size_mm : (float, float)
        Range of disc diameters and bar lengths, mm.

    Returns
    -------
    callable
        ``coverage(xy_mm (N, 2)) -> (N,)`` with values 0 or 1.
    """
    x0, y0, x1, y1 = (float(v) for v in extent_mm)
    centre = np.column_stack([rng.uniform(x0, x1, n_features), rng.uniform(y0, y1, n_features)])
    size = rng.uniform(size_mm[0], size_mm[1], n_features)
    angle = rng.uniform(0, np.pi, n_features)
    kind = np.arange(n_features) % 2

    def coverage(xy_mm):
        xy = _as_points(xy_mm)
        out = np.zeros(len(xy), dtype=bool)
        for c, s, a, is_bar in zip(centre, size, angle, kind):
            d = xy - c
            if is_bar:
                u = d[:, 0] * np.cos(a) + d[:, 1] * np.sin(a)
                v = -d[:, 0] * np.sin(a) + d[:, 1] * np.cos(a)
                out |= (np.abs(u) <= s / 2) & (np.abs(v) <= s / 8)
            else:
                out |= (d ** 2).sum(axis=1) <= (s / 2) ** 2
        return out.astype(float)

    return coverage


def pinhole_image_to_plane(camera, rvec, tvec_mm):
    """Map from pixels to a plane seen by a pinhole camera with distortion.

    Parameters
    ----------
    camera : vision.camera.CameraModel
        Intrinsics and distortion (OpenCV model).
    rvec : array_like, shape (3,)
        Rotation vector (Rodrigues, rad) from plane to camera frame.
    tvec_mm : array_like, shape (3,)
        Plane origin in the camera frame, mm.

    Returns
    -------
    callable
        ``image_to_plane(pts_px (N, 2)) -> (N, 2)`` plane coordinates in mm
        of the point each pixel sees (the plane's z = 0 face).
    """
    import cv2

    rmat, _ = cv2.Rodrigues(np.asarray(rvec, dtype=float).reshape(3, 1))
    homography = np.column_stack([rmat[:, 0], rmat[:, 1], np.asarray(tvec_mm, dtype=float).ravel()])
    inverse = np.linalg.inv(homography)

    def image_to_plane(pts_px):
        ideal = camera.undistort_points(pts_px)
        k = camera.camera_matrix
        xn = (ideal[:, 0] - k[0, 2] - k[0, 1] * (ideal[:, 1] - k[1, 2]) / k[1, 1]) / k[0, 0]
        yn = (ideal[:, 1] - k[1, 2]) / k[1, 1]
        rays = np.column_stack([xn, yn, np.ones(len(xn))])
        uvw = rays @ inverse.T
        return uvw[:, :2] / uvw[:, 2:3]

    return image_to_plane
