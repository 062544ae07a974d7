"""Render image sequences of a ring-coded board riding on a machine table (synthetic truth).

A fixed camera looks straight down on the table plane at ``distance_mm``. The
board lies on the table, rotated by ``board_angle_deg`` in the image, and moves
with the table along a programmed circle that the simulated machine follows with
known errors:

* **scale error** of each axis (``scale_x_ppm``, ``scale_y_ppm``),
* **servo mismatch**: the Y axis lags the X axis by ``lag_deg`` of the circle's
  phase, which turns the circle into an ellipse tilted at 45 degrees,
* **reversal spikes** (quadrant glitches): where an axis reverses, the path
  bulges outward by ``spike_um`` and recovers exponentially over
  ``spike_width_deg`` of travel.

Everything is expressed in the camera frame: x right, y down in the image, mm on
the table plane. The truth returned is the reference mark's displacement in that
frame relative to the first frame, i.e. exactly what :func:`stages.contour.track`
reconstructs.
"""
from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError

__all__ = ["MachineMotion", "SimulatedSequence", "circle_motion", "simulation_camera", "render_frame",
           "render_sequence"]


@dataclass(frozen=True)
class MachineMotion:
    """Table displacement per frame.

    Attributes
    ----------
    xy_mm : ndarray, shape (N, 2)
        Actual table (board) position in the camera frame, mm (x right, y down).
    nominal_xy_mm : ndarray, shape (N, 2)
        Programmed position, mm, same frame.
    t_s : ndarray, shape (N,)
        Time of each frame, seconds.
    """

    xy_mm: np.ndarray
    nominal_xy_mm: np.ndarray
    t_s: np.ndarray


def circle_motion(n_frames, radius_mm, *, fps=80.0, turns=1.0, start_deg=0.0, clockwise=False,
                  scale_x_ppm=0.0, scale_y_ppm=0.0, lag_deg=0.0, spike_um=0.0, spike_width_deg=5.0,
                  centre_mm=(0.0, 0.0)) -> MachineMotion:
    """Programmed circle plus known machine errors (see the module docstring).

    Parameters
    ----------
    n_frames : int
        Frames over the motion (the first at ``start_deg``; the last one step
        before ``start_deg + turns * 360``).
    radius_mm : float
        Programmed radius, mm.
    fps : float
        Frame rate, frames per second (sets ``t_s``).
    turns : float
        Revolutions over the sequence; a negative value is not allowed (use
        ``clockwise``).
    start_deg : float
        Start angle, degrees from the camera x axis towards y (clockwise as
        seen in the image, since y points down).
    clockwise : bool
        Direction of travel as seen in the image.
    scale_x_ppm, scale_y_ppm : float
        Scale error of each axis, parts per million.
    lag_deg : float
        Phase lag of the Y axis behind the X axis (servo gain mismatch), degrees.
    spike_um : float
        Outward bulge at each axis reversal, µm.
    spike_width_deg : float
        Decay length of the bulge, degrees of travel.
    centre_mm : tuple of float
        Programmed circle centre in the camera frame, mm.

    Returns
    -------
    MachineMotion
    """
    n = int(n_frames)
    if n < 2:
        raise DataError(f"n_frames must be >= 2, got {n_frames!r}", column="n_frames")
    if not radius_mm > 0:
        raise DataError(f"radius_mm must be positive, got {radius_mm!r}", column="radius_mm")
    sgn = -1.0 if clockwise else 1.0
    phi_deg = start_deg + sgn * float(turns) * 360.0 * np.arange(n) / n
    phi = np.deg2rad(phi_deg)
    cx, cy = (float(v) for v in centre_mm)
    nominal = np.column_stack([cx + radius_mm * np.cos(phi), cy + radius_mm * np.sin(phi)])
    lag = sgn * np.deg2rad(lag_deg)
    x = radius_mm * np.cos(phi) * (1 + scale_x_ppm * 1e-6)
    y = radius_mm * np.sin(phi - lag) * (1 + scale_y_ppm * 1e-6)
    # quadrant glitches: X reverses at 0 / 180 deg, Y at 90 / 270 deg; travelled angle since the reversal
    if spike_um:
        travelled = sgn * (phi_deg - start_deg)  # >= 0, increasing
        bump = np.zeros(n)
        for q in (0.0, 90.0, 180.0, 270.0):
            # travelled angle at which the path passes q (every turn)
            first = (sgn * (q - start_deg)) % 360.0
            for k in range(int(math.ceil(abs(turns))) + 1):
                since = travelled - (first + 360.0 * k)
                on = since >= 0
                bump[on] += spike_um * 1e-3 * np.exp(-since[on] / float(spike_width_deg))
        x = x + bump * np.cos(phi)
        y = y + bump * np.sin(phi)
    xy = np.column_stack([cx + x, cy + y])
    return MachineMotion(xy, nominal, np.arange(n) / float(fps))


def simulation_camera(image_size=(768, 768), pixel_mm=0.03, *, distance_mm=300.0, k1=-0.05, k2=0.0, p1=0.0,
                      p2=0.0):
    """A camera whose object-side pixel is ``pixel_mm`` on a plane ``distance_mm`` away.

    Parameters
    ----------
    image_size : tuple of int
        (width, height), pixels.
    pixel_mm : float
        Object-side pixel at the plane, mm.
    distance_mm : float
        Distance of the table plane from the projection centre, mm.
    k1, k2, p1, p2 : float
        Lens distortion (OpenCV model, normalised coordinates).

    Returns
    -------
    vision.camera.CameraModel
    """
    from kinid.vision import CameraModel

    w, h = (int(v) for v in image_size)
    f = distance_mm / pixel_mm
    K = np.array([[f, 0.0, (w - 1) / 2.0 + 3.3], [0.0, f, (h - 1) / 2.0 - 2.1], [0.0, 0.0, 1.0]])
    return CameraModel(K, np.array([k1, k2, p1, p2, 0.0]), (w, h))


class _PixelMap:
    """Normalised camera coordinates of any pixel position, by bilinear interpolation of a dense table.

    The camera does not move, so the (costly) inverse of the lens distortion is
    computed once per pixel centre; between centres the distortion is smooth
    and bilinear interpolation is exact to far below 1e-6 px.
    """

    def __init__(self, camera):
        w, h = camera.image_size
        ys, xs = np.mgrid[0:h, 0:w]
        pts = np.column_stack([xs.ravel(), ys.ravel()]).astype(float)
        ideal = camera.undistort_points(pts) if np.any(camera.dist_coeffs != 0) else pts
        K = camera.camera_matrix
        yn = (ideal[:, 1] - K[1, 2]) / K[1, 1]
        xn = (ideal[:, 0] - K[0, 2] - K[0, 1] * yn) / K[0, 0]
        self.w, self.h = w, h
        self.table = np.column_stack([xn, yn]).reshape(h, w, 2)

    def __call__(self, xy_px):
        xy = np.asarray(xy_px, float).reshape(-1, 2)
        x0 = np.clip(np.floor(xy[:, 0]).astype(np.int64), 0, self.w - 2)
        y0 = np.clip(np.floor(xy[:, 1]).astype(np.int64), 0, self.h - 2)
        fx = (xy[:, 0] - x0)[:, None]
        fy = (xy[:, 1] - y0)[:, None]
        t = self.table
        return ((1 - fy) * ((1 - fx) * t[y0, x0] + fx * t[y0, x0 + 1])
                + fy * ((1 - fx) * t[y0 + 1, x0] + fx * t[y0 + 1, x0 + 1]))


def render_frame(board, camera, distance_mm, board_origin_mm, board_angle_deg, *, noise_sigma=0.0, blur_px=0.7,
                 rng=None, supersample=3, low=30, high=220, pixel_map=None):
    """One image of ``board`` with its origin at ``board_origin_mm`` in the camera frame.

    Parameters
    ----------
    board : vision.board.Board
    camera : vision.camera.CameraModel
    distance_mm : float
        Distance of the board plane from the projection centre, mm.
    board_origin_mm : tuple of float
        Board-frame origin (mark row 0, column 0) on the plane, camera frame,
        mm from the optical axis.
    board_angle_deg : float
        Rotation of the board in the image, degrees (clockwise as seen, y down).
    noise_sigma, blur_px, rng, supersample, low, high
        As in :func:`vision.render.render_pattern`.
    pixel_map : object or None
        Cached pixel -> normalised-coordinate map of ``camera`` (reused across
        the frames of a sequence); built when None.

    Returns
    -------
    numpy.ndarray
        uint8 image (height, width).
    """
    from kinid.vision import board_coverage, render_pattern

    a = math.radians(board_angle_deg)
    c, s = math.cos(a), math.sin(a)
    ox, oy = (float(v) for v in board_origin_mm)
    if pixel_map is None:
        pixel_map = _PixelMap(camera)

    def image_to_plane(xy_px):
        p = pixel_map(xy_px) * distance_mm
        dx, dy = p[:, 0] - ox, p[:, 1] - oy
        return np.column_stack([c * dx + s * dy, -s * dx + c * dy])  # R(a)^T (p - o)

    w, h = camera.image_size
    return render_pattern(board_coverage(board), (h, w), image_to_plane, low=low, high=high,
                          supersample=supersample, blur_px=blur_px, noise_sigma=noise_sigma, rng=rng)


@dataclass(frozen=True)
class SimulatedSequence:
    """A rendered sequence and its truth.

    Attributes
    ----------
    paths : tuple of str
        Image files written, in frame order.
    track_mm : ndarray, shape (N, 2)
        True displacement of the reference mark in the camera frame relative to
        the first frame, mm.
    motion : MachineMotion
        The table motion that was rendered.
    reference_rc : tuple of int
        (row, column) of the mark nearest the image centre in the first frame.
    reference_start_mm : tuple of float
        That mark's position in the first frame, camera frame, mm from the
        optical axis (``+ track_mm[k]`` gives it in frame k).
    board_angle_deg : float
    distance_mm : float
    blank_frames : tuple of int
        Frames rendered without any mark (over-exposed).
    """

    paths: tuple
    track_mm: np.ndarray
    motion: MachineMotion
    reference_rc: tuple
    reference_start_mm: tuple
    board_angle_deg: float
    distance_mm: float
    blank_frames: tuple


def render_sequence(folder, board, camera, motion, *, distance_mm=300.0, board_angle_deg=0.7, start_rc=None,
                    start_offset_mm=(1.3, -0.8), noise_sigma=2.0, blur_px=0.7, blank_frames=(), rng=None,
                    supersample=3, prefix="frame_"):
    """Render ``motion`` as PNG files ``<prefix>0000.png``... in ``folder``.

    Parameters
    ----------
    folder : str or path
        Existing output folder.
    board : vision.board.Board
    camera : vision.camera.CameraModel
    motion : MachineMotion
        Table displacement per frame, camera frame, mm.
    distance_mm : float
        Plane distance used to build ``camera`` (see :func:`simulation_camera`).
    board_angle_deg : float
        Board rotation in the image, degrees.
    start_rc : tuple of int or None
        (row, column) of the mark placed near the optical axis in the first
        frame; default the board's middle mark.
    start_offset_mm : tuple of float
        Offset of that mark from the optical axis in the first frame, mm.
    noise_sigma, blur_px, supersample
        Image noise (grey levels), blur (px) and anti-aliasing.
    blank_frames : sequence of int
        Frames written as a uniform grey image (nothing decodes).
    rng : numpy.random.Generator or None
        Noise generator (``np.random.default_rng(0)`` when None).
    prefix : str
        File name prefix.

    Returns
    -------
    SimulatedSequence
    """
    import cv2

    from kinid.files import atomic_write

    if rng is None:
        rng = np.random.default_rng(0)
    if start_rc is None:
        start_rc = (board.rows // 2, board.cols // 2)
    r0, c0 = (int(v) for v in start_rc)
    a = math.radians(board_angle_deg)
    R = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    b_start = np.array(board.mark_mm(r0, c0))
    xy = np.asarray(motion.xy_mm, float)
    # board origin so that mark (r0, c0) sits at start_offset_mm when the table is at xy[0]
    origin0 = np.asarray(start_offset_mm, float) - R @ b_start - xy[0]
    w, h = camera.image_size
    blank = {int(k) for k in blank_frames}
    pixel_map = _PixelMap(camera)
    paths = []
    for k in range(len(xy)):
        origin = origin0 + xy[k]
        if k in blank:
            img = np.full((h, w), 250, np.uint8)
        else:
            img = render_frame(board, camera, distance_mm, origin, board_angle_deg, noise_sigma=noise_sigma,
                               blur_px=blur_px, rng=rng, supersample=supersample, pixel_map=pixel_map)
        path = os.path.join(os.fspath(folder), f"{prefix}{k:04d}.png")
        ok, buf = cv2.imencode(".png", img)
        if not ok:  # pragma: no cover
            raise DataError("PNG encoding failed", path=path)
        with atomic_write(path, "wb") as f:
            f.write(buf.tobytes())
        paths.append(path)
    # reference mark: the decodable mark nearest the image centre in the first frame
    rows, cols = np.mgrid[0:board.rows, 0:board.cols]
    b_all = np.column_stack([cols.ravel(), rows.ravel()]) * board.pitch_mm
    p_all = b_all @ R.T + origin0 + xy[0]
    K = camera.camera_matrix
    ideal = np.column_stack([K[0, 0] * p_all[:, 0] / distance_mm + K[0, 2], K[1, 1] * p_all[:, 1] / distance_mm
                             + K[1, 2]])
    px = camera.distort_points(ideal)
    d = np.hypot(px[:, 0] - (w - 1) / 2.0, px[:, 1] - (h - 1) / 2.0)
    i = int(np.argmin(d))
    ref = (int(rows.ravel()[i]), int(cols.ravel()[i]))
    return SimulatedSequence(tuple(paths), xy - xy[0], motion, ref, tuple(map(float, p_all[i])),
                             float(board_angle_deg), float(distance_mm),
                             tuple(sorted(blank)))
