"""Pinhole camera with lens distortion; calibration by Zhang's method.

The model is OpenCV's: a point ``(X, Y, Z)`` in the camera frame (x right,
y down, z along the optical axis, mm) has normalised coordinates
``x = X / Z, y = Y / Z``; the lens moves them to

    x' = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
    y' = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

with ``r^2 = x^2 + y^2``, and the camera matrix ``K`` maps ``(x', y', 1)`` to
pixels (x right, y down, centre of the top-left pixel at (0, 0)).

:func:`calibrate_camera` finds a chessboard or a circle grid in every image
(``cv2.findChessboardCornersSB`` / ``cv2.findChessboardCorners`` with
``cv2.cornerSubPix``, or ``cv2.findCirclesGrid``) and runs
``cv2.calibrateCameraExtended`` (Zhang 2000) for ``K`` and
``(k1, k2, p1, p2, k3)``.

References
----------
Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11), 2000.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinid.files import read_json, write_json
from kinid.errors import DataError, ImageError
from kinid.schema import Fields, Items, Number, Row, validate

__all__ = [
    "CameraModel",
    "CalibrationResult",
    "circle_centre_bias",
    "calibrate_camera",
    "detect_pattern",
    "load_camera",
    "save_camera",
    "camera_from_dict",
]

#: Newton iterations and tolerance (normalised units) of the distortion inverse.
UNDISTORT_MAX_ITER = 50
UNDISTORT_TOL = 1e-14
#: Largest half-window of ``cv2.cornerSubPix`` and its stopping rule.
CORNER_WINDOW_MAX_PX = 10
CORNER_CRITERIA = (3, 100, 1e-4)  # cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER


def _distort_normalised(xy, dist):
    """Distorted normalised coordinates and their 2x2 Jacobians."""
    k1, k2, p1, p2, k3 = dist
    x, y = xy[:, 0], xy[:, 1]
    r2 = x * x + y * y
    radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dradial = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # d radial / d r2
    xd = x * radial + 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
    yd = y * radial + p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
    jac = np.empty((len(x), 2, 2))
    jac[:, 0, 0] = radial + x * dradial * 2 * x + 2 * p1 * y + p2 * 6 * x
    jac[:, 0, 1] = x * dradial * 2 * y + 2 * p1 * x + p2 * 2 * y
    jac[:, 1, 0] = y * dradial * 2 * x + p1 * 2 * x + 2 * p2 * y
    jac[:, 1, 1] = radial + y * dradial * 2 * y + p1 * 6 * y + 2 * p2 * x
    return np.column_stack([xd, yd]), jac


@dataclass(frozen=True, eq=False)
class CameraModel:
    """Intrinsics and distortion of a camera (OpenCV model, see module docstring).

    Attributes
    ----------
    camera_matrix : ndarray, shape (3, 3)
        ``[[fx, s, cx], [0, fy, cy], [0, 0, 1]]`` in pixels.
    dist_coeffs : ndarray, shape (5,)
        ``(k1, k2, p1, p2, k3)``.
    image_size : (int, int)
        ``(width, height)`` in pixels.
    rms_px : float
        Reprojection RMS of the calibration (nan if unknown).
    """

    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    image_size: tuple
    rms_px: float = math.nan

    def __post_init__(self):
        from kinid.checks import check_array

        k = np.array(check_array("camera_matrix", self.camera_matrix, finite=False), dtype=float)
        d = np.array(check_array("dist_coeffs", self.dist_coeffs, finite=False), dtype=float).ravel()
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise DataError(f"camera_matrix must be a finite 3x3 matrix, got shape {k.shape}")
        if k[0, 0] <= 0 or k[1, 1] <= 0 or not np.allclose(k[2], [0, 0, 1]) or k[1, 0] != 0:
            raise DataError("camera_matrix must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0")
        if d.size == 4:
            d = np.append(d, 0.0)
        if d.size != 5 or not np.all(np.isfinite(d)):
            raise DataError(f"dist_coeffs must be 5 finite numbers (k1, k2, p1, p2, k3), got {d.size}")
        size = tuple(int(v) for v in self.image_size)
        if len(size) != 2 or min(size) <= 0:
            raise DataError(f"image_size must be (width, height) > 0, got {self.image_size!r}")
        k.setflags(write=False)
        d.setflags(write=False)
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "dist_coeffs", d)
        object.__setattr__(self, "image_size", size)
        object.__setattr__(self, "rms_px", float(self.rms_px))

    # -- pixel <-> normalised -------------------------------------------------
    def _to_normalised(self, pts_px):
        k = self.camera_matrix
        y = (pts_px[:, 1] - k[1, 2]) / k[1, 1]
        x = (pts_px[:, 0] - k[0, 2] - k[0, 1] * y) / k[0, 0]
        return np.column_stack([x, y])

    def _to_pixels(self, xy):
        k = self.camera_matrix
        return np.column_stack([k[0, 0] * xy[:, 0] + k[0, 1] * xy[:, 1] + k[0, 2], k[1, 1] * xy[:, 1] + k[1, 2]])

    def project(self, xyz_cam):
        """Pixels of points given in the camera frame.

        Parameters
        ----------
        xyz_cam : array_like, shape (N, 3)
            Points in the camera frame (any length unit), z > 0.

        Returns
        -------
        ndarray, shape (N, 2)
            Distorted pixel coordinates.
        """
        p = np.asarray(xyz_cam, dtype=float).reshape(-1, 3)
        if np.any(p[:, 2] <= 0):
            raise DataError("project: every point needs z > 0 (in front of the camera)")
        xy = p[:, :2] / p[:, 2:3]
        return self._to_pixels(_distort_normalised(xy, self.dist_coeffs)[0])

    def distort_points(self, pts_ideal_px):
        """Where the lens images points that an ideal pinhole camera puts at ``pts_ideal_px``.

        Parameters
        ----------
        pts_ideal_px : array_like, shape (N, 2)
            Ideal (undistorted) pinhole pixel coordinates.

        Returns
        -------
        ndarray, shape (N, 2)
            Distorted (observed) pixel coordinates.
        """
        pts = np.asarray(pts_ideal_px, dtype=float).reshape(-1, 2)
        return self._to_pixels(_distort_normalised(self._to_normalised(pts), self.dist_coeffs)[0])

    def undistort_points(self, pts_px):
        """Ideal pinhole pixels of observed pixels (inverse of :meth:`distort_points`).

        Newton's method on the distortion, to 1e-14 in normalised units
        (round trip 1e-13 px), where ``cv2.undistortPoints`` with its default 5
        fixed-point iterations leaves 4e-4 px near the corners of the test
        camera of ``benchmarks/bench_camera.py`` (k1 = -0.25), more for
        stronger distortion.

        Parameters
        ----------
        pts_px : array_like, shape (N, 2)
            Observed pixel coordinates.

        Returns
        -------
        ndarray, shape (N, 2)
            Ideal pinhole pixel coordinates (same camera matrix).
        """
        pts = np.asarray(pts_px, dtype=float).reshape(-1, 2)
        target = self._to_normalised(pts)
        xy = target.copy()
        if np.any(self.dist_coeffs != 0):
            for _ in range(UNDISTORT_MAX_ITER):
                value, jac = _distort_normalised(xy, self.dist_coeffs)
                res = target - value
                det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
                step = np.column_stack([jac[:, 1, 1] * res[:, 0] - jac[:, 0, 1] * res[:, 1],
                                        jac[:, 0, 0] * res[:, 1] - jac[:, 1, 0] * res[:, 0]]) / det[:, None]
                xy += step
                if np.max(np.abs(step), initial=0.0) < UNDISTORT_TOL:
                    break
        return self._to_pixels(xy)

    def to_dict(self):
        """The JSON form (see :func:`save_camera`)."""
        return {
            "camera_matrix": self.camera_matrix.tolist(),
            "dist_coeffs": self.dist_coeffs.tolist(),
            "image_size": list(self.image_size),
            "rms_px": None if math.isnan(self.rms_px) else self.rms_px,
        }


def circle_centre_bias(centre, normal, radius):
    """How far a pinhole camera images a circle's ellipse centre from its centre's image.

    A circle seen obliquely through a pinhole is an ellipse whose centre is not the image of the
    circle's centre (perspective is not affine); a locator finds the ellipse's centre. The bias is
    about ``r² sinθ cosθ / D`` (radius r, tilt θ, distance D): 26 µm on the board for a Ø5 mm
    circle tilted 40° at 120 mm. Exact for an ideal pinhole: the circle's conic ``a² + b² = r²``
    in its plane is mapped by the homography ``[u v C]`` and the ellipse's centre solved for.

    Parameters
    ----------
    centre : array_like, shape (N, 3)
        Circle centres in the camera frame (z > 0), any length unit.
    normal : array_like, shape (N, 3) or (3,)
        Normals of the circles' planes in the camera frame (either sign).
    radius : float
        Circle radius, same unit as ``centre``.

    Returns
    -------
    ndarray, shape (N, 2)
        Ellipse centre minus the centre's projection, normalised image coordinates (x / z, y / z).
    """
    c = np.atleast_2d(np.asarray(centre, dtype=float))
    n = np.broadcast_to(np.asarray(normal, dtype=float), c.shape)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    # two unit vectors spanning each plane: start from the camera axis least aligned with the normal
    helper = np.eye(3)[np.argmin(np.abs(n), axis=1)]
    u = np.cross(n, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(n, u)
    H = np.stack([u, v, c], axis=2)  # plane (a, b, 1) -> homogeneous image point
    Hinv = np.linalg.inv(H)
    Q = np.diag([1.0, 1.0, -float(radius) ** 2])
    conic = np.einsum("nji,jk,nkl->nil", Hinv, Q, Hinv)  # H^-T Q H^-1
    ellipse_centre = np.linalg.solve(conic[:, :2, :2], -conic[:, :2, 2:3])[:, :, 0]
    return ellipse_centre - c[:, :2] / c[:, 2:3]


@dataclass(frozen=True, eq=False)
class CalibrationResult:
    """Result of :func:`calibrate_camera`.

    Attributes
    ----------
    success : bool
        Calibration ran on enough views.
    message : str
        What happened (views used, views without a pattern).
    camera : CameraModel or None
        The calibrated camera.
    rms_px : float
        Reprojection RMS over all points of all used views, px.
    per_view_rms_px : ndarray, shape (n_used,)
        Reprojection RMS of each used view, px.
    n_views : int
        Images given.
    used_views : tuple of int
        Indices of the images in which the pattern was found.
    rvecs, tvecs : list of ndarray, shape (3,)
        Pose of the board in each used view (Rodrigues rad; mm).
    std_intrinsics : ndarray, shape (9,)
        Standard deviations of ``fx, fy, cx, cy, k1, k2, p1, p2, k3``.
    """

    success: bool
    message: str
    camera: CameraModel | None
    rms_px: float
    per_view_rms_px: np.ndarray
    n_views: int
    used_views: tuple
    rvecs: list = field(default_factory=list)
    tvecs: list = field(default_factory=list)
    std_intrinsics: np.ndarray = field(default_factory=lambda: np.full(9, np.nan))


def _read_gray(image, index):
    import cv2

    if isinstance(image, (str, Path)):
        from kinid.files import read_image

        arr = read_image(image)  # header-checked, limited, errors name the file
    else:
        arr = np.asarray(image)
    if arr.ndim == 3 and arr.shape[2] in (3, 4):
        arr = cv2.cvtColor(arr.astype(np.uint8), cv2.COLOR_BGR2GRAY if arr.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    if arr.ndim != 2 or arr.size == 0:
        raise ImageError(f"images[{index}] must be a 2-D grey image, got shape {arr.shape}")
    if arr.dtype != np.uint8:
        if not np.all(np.isfinite(arr)):
            raise ImageError(f"images[{index}] has non-finite pixels")
        arr = np.clip(np.rint(arr), 0, 255).astype(np.uint8)
    return arr


def detect_pattern(gray, pattern="chessboard", pattern_size=(9, 6)):
    """Image points of a calibration pattern, or ``None`` if not found.

    Parameters
    ----------
    gray : ndarray, shape (H, W), uint8
        Grey image.
    pattern : {"chessboard", "circles", "acircles"}
        Chessboard (inner corners), symmetric or asymmetric circle grid.
    pattern_size : (int, int)
        ``(cols, rows)`` of inner corners or circles.

    Returns
    -------
    ndarray, shape (cols * rows, 2) or None
        Points in OpenCV's order, px.
    """
    import cv2

    size = tuple(int(v) for v in pattern_size)
    if pattern == "chessboard":
        found, corners = cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_EXHAUSTIVE)
        if not found:
            found, corners = cv2.findChessboardCorners(gray, size, flags=cv2.CALIB_CB_ADAPTIVE_THRESH)
            if not found:
                return None
        corners = np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2)
        # refine with the gradient-orthogonality corner model; the window stays
        # within a third of the nearest corner distance
        grid = corners.reshape(size[1], size[0], 2)
        spacing = min(np.linalg.norm(np.diff(grid, axis=0), axis=2).min(),
                      np.linalg.norm(np.diff(grid, axis=1), axis=2).min())
        half = int(np.clip(spacing / 3.0, 2, CORNER_WINDOW_MAX_PX))
        corners = cv2.cornerSubPix(gray, corners, (half, half), (-1, -1), CORNER_CRITERIA)
        return np.asarray(corners, dtype=float).reshape(-1, 2)
    if pattern in ("circles", "acircles"):
        flags = cv2.CALIB_CB_ASYMMETRIC_GRID if pattern == "acircles" else cv2.CALIB_CB_SYMMETRIC_GRID
        found, centres = cv2.findCirclesGrid(gray, size, flags=flags)
        if not found:
            return None
        return np.asarray(centres, dtype=float).reshape(-1, 2)
    raise DataError(f"pattern must be 'chessboard', 'circles' or 'acircles', got {pattern!r}")


def calibrate_camera(images, pattern="chessboard", pattern_size=(9, 6), square_mm=1.0, *, min_views=3,
                     fix_k3=False):
    """Calibrate a camera from views of a planar pattern (Zhang's method).

    Parameters
    ----------
    images : sequence of ndarray (H, W) or path
        Grey (or BGR) images, or image files, all the same size.
    pattern : {"chessboard", "circles", "acircles"}
        Pattern type (see :func:`detect_pattern`).
    pattern_size : (int, int)
        ``(cols, rows)``: inner corners of a chessboard, or circles.
    square_mm : float
        Chessboard square side or circle spacing, mm (sets the unit of ``tvecs``).
    min_views : int
        Fewest views with a detected pattern needed (at least 3).
    fix_k3 : bool
        Hold k3 at zero (for lenses with little distortion or narrow views).

    Returns
    -------
    CalibrationResult

    Raises
    ------
    ImageError
        An image cannot be read, images differ in size, or the pattern was
        found in fewer than ``min_views`` images.
    DataError
        Bad ``pattern``, ``pattern_size`` or ``square_mm``.
    """
    import cv2

    from .calibration_targets import chessboard_object_points, circle_grid_object_points

    if pattern not in ("chessboard", "circles", "acircles"):
        raise DataError(f"pattern must be 'chessboard', 'circles' or 'acircles', got {pattern!r}")
    if pattern == "chessboard":
        object_points = chessboard_object_points(pattern_size, square_mm)
    else:
        object_points = circle_grid_object_points(pattern_size, square_mm, asymmetric=pattern == "acircles")
    images = list(images)
    if int(min_views) < 3:
        raise DataError(f"min_views must be at least 3, got {min_views!r}")
    size = None
    obj, img, used = [], [], []
    for index, image in enumerate(images):
        gray = _read_gray(image, index)
        if size is None:
            size = (gray.shape[1], gray.shape[0])
        elif (gray.shape[1], gray.shape[0]) != size:
            raise ImageError(f"images[{index}] is {gray.shape[1]}x{gray.shape[0]} px, the first is {size[0]}x{size[1]}")
        points = detect_pattern(gray, pattern, pattern_size)
        if points is not None:
            obj.append(object_points.astype(np.float32))
            img.append(points.astype(np.float32).reshape(-1, 1, 2))
            used.append(index)
    if len(used) < int(min_views):
        raise ImageError(
            f"{pattern} {tuple(pattern_size)} found in {len(used)} of {len(images)} images, "
            f"need at least {min_views}; check pattern_size (inner corners for a chessboard)"
        )
    flags = cv2.CALIB_FIX_K3 if fix_k3 else 0
    criteria = (cv2.TERM_CRITERIA_COUNT + cv2.TERM_CRITERIA_EPS, 200, 1e-12)
    rms, k, dist, rvecs, tvecs, std_in, _std_ex, per_view = cv2.calibrateCameraExtended(
        obj, img, size, None, None, flags=flags, criteria=criteria
    )
    dist = np.asarray(dist, dtype=float).ravel()[:5]
    camera = CameraModel(k, dist, size, float(rms))
    std = np.asarray(std_in, dtype=float).ravel()
    std_intrinsics = std[:9] if std.size >= 9 else np.full(9, np.nan)  # fx fy cx cy k1 k2 p1 p2 k3
    missing = [i for i in range(len(images)) if i not in used]
    message = f"calibrated from {len(used)} of {len(images)} views, reprojection RMS {rms:.4f} px"
    if missing:
        message += f"; pattern not found in images {missing}"
    return CalibrationResult(
        success=True,
        message=message,
        camera=camera,
        rms_px=float(rms),
        per_view_rms_px=np.asarray(per_view, dtype=float).ravel(),
        n_views=len(images),
        used_views=tuple(used),
        rvecs=[np.asarray(r, dtype=float).ravel() for r in rvecs],
        tvecs=[np.asarray(t, dtype=float).ravel() for t in tvecs],
        std_intrinsics=std_intrinsics,
    )


def save_camera(camera, path):
    """Write a camera as JSON (whole or not at all).

    The file is ``{"camera_matrix": [[..],[..],[..]], "dist_coeffs": [k1, k2,
    p1, p2, k3], "image_size": [w, h], "rms_px": x}``; ``rms_px`` is null when it is not known (NaN or
    infinite).

    Raises
    ------
    DataError
        Naming the file, if the camera matrix or the distortion holds a NaN or infinity (a failed
        calibration: nothing is written).
    """
    data = camera.to_dict()
    if data.get("rms_px") is not None and not math.isfinite(data["rms_px"]):
        data["rms_px"] = None
    write_json(path, data, indent=2)


_ENTRY = Number(low=-1e7, high=1e7)
#: What a camera file holds (:func:`save_camera`): a 3x3 matrix in pixels (focal lengths up to 10^7 px),
#: the 5 distortion coefficients of OpenCV's model (a lens whose coefficients pass 1000 is no lens OpenCV
#: can undo), the image size in pixels and the calibration's RMS reprojection error.
CAMERA_SCHEMA = Fields({
    "camera_matrix": Row((Row((_ENTRY,) * 3),) * 3),
    "dist_coeffs": Items(Number(low=-1000, high=1000), length=5),
    "image_size": Row((Number(low=1, high=100000, integer=True),) * 2),
}, optional={"rms_px": Number(low=0, high=1000, null=True)}, other=True)


def load_camera(path):
    """Read a camera written by :func:`save_camera`.

    Raises
    ------
    DataError
        Missing file, invalid JSON, a missing key or a malformed value (the
        message names the key).
    """
    path = Path(path)
    return camera_from_dict(read_json(path, what="camera file"), path=path)


def camera_from_dict(data, *, path=None) -> CameraModel:
    """The camera a camera file's object describes (:data:`CAMERA_SCHEMA`); a DataError naming ``path`` and the key."""
    if not isinstance(data, dict):
        raise DataError("expected a JSON object with camera_matrix, dist_coeffs, image_size", path=path)
    validate(data, CAMERA_SCHEMA, path=path)
    rms = math.nan if data.get("rms_px") is None else data["rms_px"]
    try:
        return CameraModel(np.array(data["camera_matrix"], dtype=float), np.array(data["dist_coeffs"], dtype=float),
                           tuple(data["image_size"]), float(rms))
    except DataError as exc:
        column = "camera_matrix" if "camera_matrix" in exc.message else "dist_coeffs"
        raise DataError(exc.message, path=path, column=column) from None
