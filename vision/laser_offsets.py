"""Offsets between the camera and the laser displacement sensor on Z.

The five-axis method aligns the camera's optical centre over a mark for x and
y, and uses the laser, read at a preset height, for z. Both sit on the Z axis,
parallel to it, a few millimetres apart. Their offsets, in machine
coordinates, are

    offset = (machine position with the laser on the feature)
             - (machine position with the camera on the same feature),

the move that takes the machine from the camera-aligned to the laser-aligned
position (the patent's "first alignment coordinate" = camera coordinate +
offset). Radial (x, y) offsets come from one of three features, the axial (z)
offset from the camera's focus height and the laser reading:

- :func:`radial_offset_from_hole`: laser spot dropped into a small hole vs the
  camera centred on it;
- :func:`~kinid.vision.laser_shapes.radial_offset_from_sphere`: least-squares sphere through the machine
  positions at which the laser reads its stand-off on a ball, vs the camera
  centred on the ball's image;
- :func:`~kinid.vision.laser_shapes.radial_offset_from_edges`: two straight edges scanned by the laser;
  the intersection of the two fitted lines vs the camera centred on the corner;
- :func:`axial_offset`: camera focus height vs the height at which the laser
  reads the preset value on the same mark (:func:`focus_height` finds the
  focus height from a focus sweep).

Every result carries standard deviations propagated from the fit covariance
(or the scatter of repeated readings) and the fit's residual RMS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kinid.errors import DataError

__all__ = [
    "OffsetResult",
    "FocusResult",
    "radial_offset_from_hole",
    "axial_offset",
    "focus_height",
    "focus_measure",
]

_NAN3 = (math.nan, math.nan, math.nan)


@dataclass(frozen=True)
class OffsetResult:
    """Camera-to-laser offset (laser position minus camera position, machine frame).

    Attributes
    ----------
    dx_mm, dy_mm, dz_mm : float
        Offset components, mm; nan for those the method does not measure.
    sigma : tuple of float
        Standard deviations of ``(dx_mm, dy_mm, dz_mm)``, mm (nan where not
        measured, or where nothing tells the repeatability of single readings).
    residual_rms_mm : float
        RMS of the fit residuals (or of the readings about their means), mm.
    n_points : int
        Number of readings used.
    method : str
        ``"hole"``, ``"sphere"``, ``"edges"`` or ``"axial"``.
    feature_mm : tuple of float
        Where the laser found the feature: mean hole position (x, y), sphere
        centre (x, y, z of the surface points), edge intersection (x, y), or
        the laser height at the preset reading (z,).
    radius_mm : float
        Fitted (or given) sphere radius; nan for other methods.
    covariance_mm2 : ndarray
        Covariance of the measured components (2 x 2 for radial, 1 x 1 for axial), mm^2.
    """

    dx_mm: float
    dy_mm: float
    dz_mm: float
    sigma: tuple
    residual_rms_mm: float
    n_points: int
    method: str
    feature_mm: tuple = ()
    radius_mm: float = math.nan
    covariance_mm2: np.ndarray = field(default_factory=lambda: np.full((2, 2), np.nan), compare=False)


@dataclass(frozen=True)
class FocusResult:
    """Peak of a focus sweep (:func:`focus_height`).

    Attributes
    ----------
    found : bool
        A peak inside the sweep was fitted.
    z_mm : float
        Height of best focus, mm (nan if not found).
    sigma_mm : float
        Its standard deviation from the fit, mm.
    reason : str
        Empty when found, otherwise why not.
    """

    found: bool
    z_mm: float
    sigma_mm: float
    reason: str = ""


def _points(value, name, dim):
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"{name} must be numbers of shape ({dim},) or (N, {dim}), got {value!r}") from None
    if arr.ndim == 1 and arr.size == dim:
        arr = arr.reshape(1, dim)
    if arr.ndim != 2 or arr.shape[1] != dim or len(arr) == 0:
        raise DataError(f"{name} must have shape ({dim},) or (N, {dim}) in mm, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{name} holds a non-finite value")
    return arr


def _scalars(value, name):
    try:
        arr = np.atleast_1d(np.asarray(value, dtype=float)).ravel()
    except (TypeError, ValueError):
        raise DataError(f"{name} must be a number or a list of numbers (mm), got {value!r}") from None
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        raise DataError(f"{name} must be one or more finite numbers (mm), got {value!r}")
    return arr


def _mean_and_cov(arr, sigma_each):
    """Mean of repeated readings and the covariance of that mean.

    A single reading without ``sigma_each`` counts as exact (zero covariance).
    """
    n, dim = arr.shape
    mean = arr.mean(axis=0)
    if sigma_each is not None:
        cov = np.eye(dim) * sigma_each ** 2 / n
    elif n >= 2:
        cov = np.cov(arr, rowvar=False, ddof=1).reshape(dim, dim) / n
    else:
        cov = np.zeros((dim, dim))
    return mean, cov


def _check_sigma(sigma_mm):
    if sigma_mm is None:
        return None
    try:
        value = float(sigma_mm)
    except (TypeError, ValueError):
        raise DataError(f"sigma_mm must be a non-negative number or None, got {sigma_mm!r}") from None
    if not np.isfinite(value) or value < 0:
        raise DataError(f"sigma_mm must be a non-negative number or None, got {sigma_mm!r}")
    return value


def _radial(delta, cov, rms, n, method, feature, radius=math.nan):
    sx, sy = np.sqrt(np.diag(cov))
    return OffsetResult(float(delta[0]), float(delta[1]), math.nan, (float(sx), float(sy), math.nan), float(rms), n,
                        method, tuple(float(v) for v in feature), float(radius), cov)


def radial_offset_from_hole(laser_xy_mm, camera_xy_mm, *, sigma_mm=None):
    """Radial offset from a hole the size of the laser spot.

    Parameters
    ----------
    laser_xy_mm : array_like, shape (2,) or (N, 2)
        Machine (x, y) with the laser spot dropped into the hole, mm; repeated
        alignments average.
    camera_xy_mm : array_like, shape (2,) or (M, 2)
        Machine (x, y) with the camera's optical centre on the hole, mm.
    sigma_mm : float or None
        Repeatability of one alignment, mm. ``None``: the scatter of repeated
        readings gives the uncertainty (a side with one reading counts as
        exact; with one reading on both sides ``sigma`` is nan).

    Returns
    -------
    OffsetResult
        ``dx_mm, dy_mm`` = mean laser position - mean camera position.

    Examples
    --------
    >>> r = radial_offset_from_hole([[52.1, 10.3], [52.1, 10.3]], [[40.0, 12.0], [40.0, 12.0]])
    >>> round(r.dx_mm, 3), round(r.dy_mm, 3)
    (12.1, -1.7)
    """
    sigma_mm = _check_sigma(sigma_mm)
    laser = _points(laser_xy_mm, "laser_xy_mm", 2)
    camera = _points(camera_xy_mm, "camera_xy_mm", 2)
    lm, lc = _mean_and_cov(laser, sigma_mm)
    cm, cc = _mean_and_cov(camera, sigma_mm)
    dev = np.concatenate([laser - lm, camera - cm])
    n_free = max(len(laser) - 1, 0) + max(len(camera) - 1, 0)
    rms = math.sqrt((dev ** 2).sum() / (2 * n_free)) if n_free else math.nan
    cov = lc + cc
    if sigma_mm is None and len(laser) == 1 and len(camera) == 1:
        cov = np.full((2, 2), np.nan)  # one reading each and no repeatability: unknown
    return _radial(lm - cm, cov, rms, len(laser) + len(camera), "hole", lm)


def _covariance(rr, s2):
    """``s2 * (J^T J)^-1`` from the R factor of J, without forming the normal matrix."""
    rinv = np.linalg.solve(rr, np.eye(rr.shape[0]))
    return s2 * (rinv @ rinv.T)


def axial_offset(camera_focus_z_mm, laser_reading_mm, *, laser_z_mm, laser_height_mm, sigma_mm=None):
    """Axial (z) offset: camera focus height vs the laser at its preset reading.

    Parameters
    ----------
    camera_focus_z_mm : float or array_like (N,)
        Machine z with the camera in focus on the mark, mm (repeated readings
        average; :func:`focus_height` gives one from a focus sweep).
    laser_reading_mm : float or array_like (M,)
        Laser readings on the same mark, mm, taken at machine heights ``laser_z_mm``.
    laser_z_mm : float or array_like (M,)
        Machine z at each laser reading, mm.
    laser_height_mm : float
        The preset laser reading ("preset laser height"), mm. A reading off
        the preset is moved to it: the laser would read ``laser_height_mm`` at
        ``laser_z_mm + laser_height_mm - laser_reading_mm`` (the reading grows
        with z, the laser looks down).
    sigma_mm : float or None
        Repeatability of one reading, mm. ``None``: the scatter of repeated
        readings (a side with one reading counts as exact; with one reading
        on both sides ``sigma`` is nan).

    Returns
    -------
    OffsetResult
        ``dz_mm`` = laser height at the preset reading - camera focus height;
        ``dx_mm, dy_mm`` nan.
    """
    sigma_mm = _check_sigma(sigma_mm)
    focus = _scalars(camera_focus_z_mm, "camera_focus_z_mm")
    reading = _scalars(laser_reading_mm, "laser_reading_mm")
    z = _scalars(laser_z_mm, "laser_z_mm")
    if len(z) != len(reading):
        raise DataError(f"laser_z_mm has {len(z)} values but laser_reading_mm has {len(reading)}; "
                        "give one machine z per laser reading")
    height = _scalars(laser_height_mm, "laser_height_mm")
    if height.size != 1:
        raise DataError(f"laser_height_mm must be one number, got {laser_height_mm!r}")
    at_preset = z + float(height[0]) - reading
    fm, fc = _mean_and_cov(focus[:, None], sigma_mm)
    lm, lc = _mean_and_cov(at_preset[:, None], sigma_mm)
    cov = fc + lc
    if sigma_mm is None and len(focus) == 1 and len(at_preset) == 1:
        cov = np.full((1, 1), np.nan)  # one reading each and no repeatability: unknown
    dev = np.concatenate([focus - fm[0], at_preset - lm[0]])
    n_free = max(len(focus) - 1, 0) + max(len(at_preset) - 1, 0)
    rms = math.sqrt((dev ** 2).sum() / n_free) if n_free else math.nan
    return OffsetResult(math.nan, math.nan, float(lm[0] - fm[0]), (math.nan, math.nan, float(math.sqrt(cov[0, 0]))),
                        rms, len(focus) + len(reading), "axial", (float(lm[0]),), math.nan, cov)


def focus_measure(image):
    """Sharpness of a grey image: variance of its Laplacian (larger = sharper).

    Parameters
    ----------
    image : ndarray, shape (H, W)

    Returns
    -------
    float
    """
    import cv2

    arr = np.asarray(image)
    if arr.ndim != 2:
        raise DataError(f"image must be a 2-D grey image, got shape {arr.shape}")
    return float(cv2.Laplacian(arr.astype(np.float64), cv2.CV_64F).var())


def focus_height(z_mm, sharpness, *, n_fit=5):
    """Height of best focus from a focus sweep.

    Fits a parabola to the logarithm of the sharpness (a Gaussian focus
    curve) at the ``n_fit`` heights around the sharpest, and returns its vertex
    with the standard deviation from the fit.

    Parameters
    ----------
    z_mm : array_like (N,)
        Machine heights of the sweep, mm.
    sharpness : array_like (N,)
        Focus measure at each height (positive; :func:`focus_measure`).
    n_fit : int
        Points around the maximum used for the fit (at least 4 for an
        uncertainty).

    Returns
    -------
    FocusResult
    """
    z = _scalars(z_mm, "z_mm")
    s = _scalars(sharpness, "sharpness")
    if len(z) != len(s):
        raise DataError(f"z_mm has {len(z)} values but sharpness has {len(s)}")
    if np.any(s <= 0):
        raise DataError("sharpness must be positive (a focus measure such as focus_measure(image))")
    if int(n_fit) < 4 or len(z) < int(n_fit):
        raise DataError(f"need n_fit >= 4 and at least n_fit sweep points, got n_fit={n_fit}, {len(z)} points")
    order = np.argsort(z)
    z, s = z[order], s[order]
    k = int(np.argmax(s))
    half = int(n_fit) // 2
    lo = min(max(k - half, 0), len(z) - int(n_fit))
    zz, ls = z[lo:lo + int(n_fit)], np.log(s[lo:lo + int(n_fit)])
    zc = zz.mean()
    a = np.column_stack([(zz - zc) ** 2, zz - zc, np.ones(len(zz))])
    coef, *_ = np.linalg.lstsq(a, ls, rcond=None)
    if coef[0] >= 0:
        return FocusResult(False, math.nan, math.nan, "the sharpness has no maximum inside the sweep")
    vertex = -coef[1] / (2 * coef[0])
    if not (zz[0] <= zc + vertex <= zz[-1]):
        return FocusResult(False, math.nan, math.nan, "the sharpest height lies at the end of the sweep; extend it")
    res = ls - a @ coef
    dof = len(zz) - 3
    s2 = (res @ res) / dof if dof > 0 else math.nan
    cov = _covariance(np.linalg.qr(a, mode="r"), s2)
    grad = np.array([coef[1] / (2 * coef[0] ** 2), -1 / (2 * coef[0]), 0.0])
    sigma = math.sqrt(max(grad @ cov @ grad, 0.0))
    return FocusResult(True, float(zc + vertex), sigma, "")
