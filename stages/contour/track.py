"""Track of a reference mark from per-frame mark detections (the monocular contour method, step 4, done by least squares).

Per frame (:func:`process_frame`, pure and picklable, so it runs unchanged in a
process pool or on Dask): decode the ring-coded marks, match them to the board,
and convert their centres to *plane coordinates* ``z`` (complex ``x + iy``,
image axes: x right, y down):

* ``--pixel-um S``: ``z = S / 1000 * pixel`` (mm; no lens correction);
* ``--camera``: lens distortion removed and the camera matrix inverted, then
  scaled by ``fx`` (ideal, square pixels).

Across the sequence (:class:`TrackBuilder`): the board does not rotate on the
table and the scale does not change, so every decoded mark ``b`` (board mm,
complex) of frame ``k`` obeys

    z = c * b + t_k

with ONE complex ``c`` (rotation and scale, plane units per mm) for the whole
sequence and one translation ``t_k`` per frame. Eliminating ``t_k`` makes
``c`` a linear least-squares estimate from all frames jointly,

    c = sum_k sum_i conj(b_i - bbar_k) (z_i - zbar_k) / sum_k sum_i |b_i - bbar_k|^2,

so only six numbers per frame need to be kept (memory flat in the marks). The
reference mark ``b_ref`` (the decoded mark nearest the image centre in the
first located frame) is then at ``z_ref,k = zbar_k + c (b_ref - bbar_k)`` in
every frame, also after it has left the view, and its track in the camera
frame is ``(z_ref,k - z_ref,0) / |c|`` mm. The rotation extrapolated to a mark
100 mm away comes from every pair of marks in every frame, not from two marks
16 mm apart in one frame, so locator noise is not multiplied.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from kinid.errors import DataError

__all__ = ["FrameSettings", "FrameResult", "Track", "TrackBuilder", "process_frame", "estimate_track",
           "consistent_marks"]

#: Relative difference between the board-derived scale and ``--pixel-um`` above which a warning is given.
SCALE_WARN_REL = 0.02
#: A mark farther than this (pixels) from where the board's layout puts it is an outlier (the locators reach
#: ~0.005 px, so this only catches gross errors: a partly hidden or soiled mark, a wrong match).
OUTLIER_PX = 1.0
#: ... or farther than this many times the median residual of the frames (uncorrected lens distortion).
OUTLIER_FACTOR = 10.0
#: Rounds of rejecting frames whose marks disagree with the sequence's rotation and scale.
OUTLIER_ROUNDS = 3


@dataclass(frozen=True)
class FrameSettings:
    """How to turn pixels into plane coordinates (exactly one of ``pixel_mm`` / ``camera``).

    Attributes
    ----------
    pixel_mm : float or None
        Object-side pixel, mm per pixel (no lens correction).
    camera : vision.camera.CameraModel or None
        Calibrated camera; its distortion is removed.
    bits : int
        Ring elements per mark (the board's ``bits``).
    refine : {"fit", "centroid"}
        Centre refinement of :func:`vision.ringcode.detect_markers`.
    roi_px : tuple of int or None
        ``(x0, y0, width, height)``: decode only inside this window (e.g. the
        centre of a large frame, as the patent does); None for the whole frame.
    downsample : int or None
        None: chosen per sequence by :func:`stages.contour.measure.choose_downsample`
        (process_frame then decodes at full resolution). Otherwise decode on a ``downsample``-times box-filtered copy (``cv2.INTER_AREA``):
        faster, and as precise while the centre circle keeps a radius of
        >= ~20 px (box filtering leaves a symmetric blob's centre unbiased);
        centres are mapped back to full-resolution pixels.
    """

    pixel_mm: float | None = None
    camera: object = None
    bits: int = 12
    refine: str = "fit"
    roi_px: tuple | None = None
    downsample: int | None = 1

    def __post_init__(self):
        if (self.pixel_mm is None) == (self.camera is None):
            raise DataError("give exactly one of pixel_mm and camera", column="pixel_mm")
        if self.pixel_mm is not None and not (math.isfinite(self.pixel_mm) and self.pixel_mm > 0):
            raise DataError(f"pixel_mm must be a positive number of mm per pixel, got {self.pixel_mm!r}",
                            column="pixel_mm")
        if self.downsample is not None and (isinstance(self.downsample, bool) or not isinstance(self.downsample, int)
                                            or self.downsample < 1):
            raise DataError(f"downsample must be an integer >= 1, got {self.downsample!r}", column="downsample")
        if self.refine not in ("fit", "centroid"):
            raise DataError(f"refine must be 'fit' or 'centroid', got {self.refine!r}", column="refine")

    @property
    def unit(self) -> str:
        """Unit of plane coordinates: ``"mm"`` or ``"px"`` (ideal pixels)."""
        return "mm" if self.pixel_mm is not None else "px"


@dataclass(frozen=True)
class FrameResult:
    """Marks decoded in one frame (small: a few numbers per mark).

    Attributes
    ----------
    n : int
        Marks matched to the board.
    image_size : tuple of int
        (width, height) of the frame, pixels.
    codes : tuple of int
        Codes of the matched marks.
    board_mm : ndarray, shape (n, 2)
        Board-frame positions of the marks, mm.
    plane : ndarray, shape (n, 2)
        Plane coordinates of the marks (see :class:`FrameSettings`).
    pixels : ndarray, shape (n, 2)
        Raw (distorted) pixel positions of the marks.
    reason : str
        Why no mark was found (empty when ``n > 0``).
    """

    n: int
    image_size: tuple
    codes: tuple
    board_mm: np.ndarray
    plane: np.ndarray
    pixels: np.ndarray
    reason: str = ""


def _to_plane(pixels, settings):
    if settings.pixel_mm is not None:
        return pixels * float(settings.pixel_mm)
    cam = settings.camera
    ideal = cam.undistort_points(pixels)
    K = cam.camera_matrix
    yn = (ideal[:, 1] - K[1, 2]) / K[1, 1]
    xn = (ideal[:, 0] - K[0, 2] - K[0, 1] * yn) / K[0, 0]
    return np.column_stack([xn, yn]) * K[0, 0]


def process_frame(image, board, settings) -> FrameResult:
    """Decode, match and convert the marks of one frame (pure; safe in a worker process).

    Parameters
    ----------
    image : array_like
        Grey (H, W) or BGR (H, W, 3) frame.
    board : vision.board.Board
    settings : FrameSettings

    Returns
    -------
    FrameResult
        ``n == 0`` with a ``reason`` when nothing usable was decoded.
    """
    from kinid.checks import check_image, check_instance
    from kinid.vision import Board, detect_markers, match_to_board

    img = check_image("image", image)
    check_instance("board", board, Board, hint="load it with kinid.vision.load_board(path)")
    check_instance("settings", settings, FrameSettings)
    h, w = img.shape[:2]
    x0 = y0 = 0
    if settings.roi_px is not None:
        x0, y0, rw, rh = (int(v) for v in settings.roi_px)
        x0, y0 = max(0, x0), max(0, y0)
        img = img[y0:min(h, y0 + rh), x0:min(w, x0 + rw)]
    f = settings.downsample or 1
    if f > 1 and img.shape[0] >= f and img.shape[1] >= f:
        import cv2

        hh, ww = img.shape[0] // f, img.shape[1] // f
        img = cv2.resize(np.ascontiguousarray(img[:hh * f, :ww * f]), (ww, hh), interpolation=cv2.INTER_AREA)
    else:
        f = 1
    markers = detect_markers(img, bits=settings.bits, refine=settings.refine) if img.size else []
    empty = np.zeros((0, 2))
    if not markers:
        return FrameResult(0, (w, h), (), empty, empty, empty, "no ring-coded mark decoded")
    matches = match_to_board(board, markers)
    if not matches:
        return FrameResult(0, (w, h), (), empty, empty, empty,
                           f"{len(markers)} mark(s) decoded but none consistent with the board")
    pixels = np.array([[(m.x_px + 0.5) * f - 0.5 + x0, (m.y_px + 0.5) * f - 0.5 + y0] for m in matches], float)
    board_mm = np.array([board.mark_mm(m.row, m.col) for m in matches], float)
    plane = _to_plane(pixels, settings)
    keep = consistent_marks(board_mm, plane, OUTLIER_PX * _plane_per_px(settings))
    codes = tuple(int(m.code) for m, k in zip(matches, keep) if k)
    return FrameResult(int(keep.sum()), (w, h), codes, board_mm[keep], plane[keep], pixels[keep])


def _plane_per_px(settings):
    return float(settings.pixel_mm) if settings.pixel_mm is not None else 1.0


def consistent_marks(board_mm, plane, tol):
    """Marks of one frame that a similarity board -> plane places within ``tol`` (plane units).

    The worst mark beyond ``tol`` is dropped and the similarity refitted while
    at least three marks remain (with two, which one is wrong cannot be told;
    the sequence-level check of :class:`TrackBuilder` handles that).

    Parameters
    ----------
    board_mm : ndarray, shape (n, 2)
        Board-frame positions of the marks, mm.
    plane : ndarray, shape (n, 2)
        Their plane coordinates in the frame.
    tol : float
        Largest accepted distance from the fitted position, plane units.

    Returns
    -------
    ndarray of bool, shape (n,)
    """
    b = board_mm[:, 0] + 1j * board_mm[:, 1]
    z = plane[:, 0] + 1j * plane[:, 1]
    keep = np.ones(len(b), bool)
    while keep.sum() >= 3:
        bb, zz = b[keep], z[keep]
        db, dz = bb - bb.mean(), zz - zz.mean()
        a = np.sum(np.conj(db) * dz) / np.sum(np.abs(db) ** 2)
        res = np.abs(dz - a * db)
        worst = int(np.argmax(res))
        if res[worst] <= tol:
            break
        keep[np.flatnonzero(keep)[worst]] = False
    return keep


@dataclass(frozen=True)
class Track:
    """The reference mark's track over a sequence.

    Attributes
    ----------
    xy_mm : ndarray, shape (N, 2)
        Reference mark position in the camera frame (x right, y down), mm,
        relative to the first located frame; NaN where the frame was not
        located.
    located : ndarray of bool, shape (N,)
        Frames in which at least one mark was matched to the board.
    n_marks : ndarray of int, shape (N,)
        Marks used per frame.
    sigma_um : ndarray, shape (N,)
        Estimated standard deviation of each coordinate of ``xy_mm`` (from the
        pooled fit residuals), µm; NaN where not located or not estimable.
    reference_code : int
        Code of the reference mark.
    reference_rc : tuple of int
        (row, column) of the reference mark on the board.
    angle_deg : float
        Board rotation in the image (clockwise as seen, y down), degrees.
    scale : float
        Plane units per board mm (``|c|``): ~1 with ``--pixel-um`` (its
        departure from 1 is the error of the given pixel size), ideal pixels per
        mm with a camera.
    residual_rms : float
        RMS of the mark residuals about the joint model, plane units per
        coordinate (NaN if no redundancy).
    not_located : tuple of int
        Indices of frames that were not located.
    reasons : dict
        ``frame -> reason`` for frames that were not located.
    """

    xy_mm: np.ndarray
    located: np.ndarray
    n_marks: np.ndarray
    sigma_um: np.ndarray
    reference_code: int
    reference_rc: tuple
    angle_deg: float
    scale: float
    residual_rms: float
    not_located: tuple
    reasons: dict = field(default_factory=dict)


class TrackBuilder:
    """Streaming accumulator: :meth:`add` one :class:`FrameResult` per frame in order, then :meth:`finish`.

    Keeps six numbers per frame (memory grows by ~100 bytes per frame, not
    with the number of marks or the image size).

    Parameters
    ----------
    board : vision.board.Board
    settings : FrameSettings
    """

    def __init__(self, board, settings):
        self.board = board
        self.settings = settings
        self._rows = []  # per frame: n, bbar, zbar, Cbb, Cbz, Czz
        self._reasons = {}
        self._ref = None  # (code, row, col, b complex)

    def add(self, result: FrameResult) -> None:
        """Add the next frame's result."""
        k = len(self._rows)
        if result.n == 0:
            self._rows.append((0, 0j, 0j, 0.0, 0j, 0.0))
            self._reasons[k] = result.reason
            return
        b = result.board_mm[:, 0] + 1j * result.board_mm[:, 1]
        z = result.plane[:, 0] + 1j * result.plane[:, 1]
        bbar, zbar = b.mean(), z.mean()
        db, dz = b - bbar, z - zbar
        self._rows.append((result.n, bbar, zbar, float(np.sum(np.abs(db) ** 2)), complex(np.sum(np.conj(db) * dz)),
                           float(np.sum(np.abs(dz) ** 2))))
        if self._ref is None:
            w, h = result.image_size
            cam = self.settings.camera
            if cam is not None and tuple(cam.image_size) != (w, h):
                warnings.warn(f"frames are {w} x {h} px but the camera was calibrated at {cam.image_size[0]} x "
                              f"{cam.image_size[1]} px; is it the right calibration?", stacklevel=2)
            d = np.hypot(result.pixels[:, 0] - (w - 1) / 2.0, result.pixels[:, 1] - (h - 1) / 2.0)
            i = int(np.argmin(d))
            code = int(result.codes[i])
            r, c = self.board.position_of(code)
            self._ref = (code, r, c, complex(b[i]))

    def finish(self) -> Track:
        """Estimate rotation/scale jointly, then every frame's reference position.

        Raises
        ------
        DataError
            No frame was located, or (with a camera) no frame showed two marks,
            so the scale cannot be known.
        """
        rows = self._rows
        N = len(rows)
        if N == 0:
            raise DataError("no frames to process", column="frames")
        n = np.array([r[0] for r in rows], int)
        located = n > 0
        if not located.any():
            first = next(iter(self._reasons.values()), "")
            raise DataError(f"no frame located: none of the {N} frames shows a decodable mark of this board "
                            f"({first})", column="frames")
        bbar = np.array([r[1] for r in rows])
        zbar = np.array([r[2] for r in rows])
        Cbb = np.array([r[3] for r in rows])
        Cbz = np.array([r[4] for r in rows])
        Czz = np.array([r[5] for r in rows])
        reasons = dict(self._reasons)
        for round_ in range(OUTLIER_ROUNDS + 1):
            sbb = Cbb[located].sum()
            c = self._rotation_scale(Cbz[located].sum(), sbb)
            scale = abs(c)
            rss = np.where(located, Czz - 2.0 * np.real(np.conj(c) * Cbz) + scale ** 2 * Cbb, 0.0)
            multi = located & (n >= 2)
            if round_ == OUTLIER_ROUNDS or not multi.any():
                break
            rms = np.sqrt(np.maximum(rss, 0.0) / np.maximum(n, 1))
            tol = max(OUTLIER_PX * _plane_per_px(self.settings), OUTLIER_FACTOR * float(np.median(rms[multi])))
            bad = multi & (rms > tol)
            if not bad.any() or bad.sum() == located.sum():
                break
            for k in np.flatnonzero(bad):
                reasons[int(k)] = (f"its {n[k]} marks disagree with the board's layout by {rms[k] / scale * 1e3:.1f} "
                                   f"um RMS (rotation and scale of the whole sequence)")
            located = located & ~bad
        if self.settings.pixel_mm is not None and abs(scale - 1.0) > SCALE_WARN_REL:
            warnings.warn(f"the board's pitch gives a pixel size {100 * (scale - 1):+.2f}% different from "
                          f"--pixel-um {self.settings.pixel_mm * 1e3:g}; the track uses the board's scale", stacklevel=2)
        n_loc = int(located.sum())
        dof = 2 * int(n[located].sum()) - 2 * n_loc - (2 if sbb > 0 else 0)
        s = math.sqrt(max(float(rss[located].sum()), 0.0) / dof) if dof > 0 else float("nan")
        code, r_ref, c_ref, b_ref = self._ref
        z_ref = zbar + c * (b_ref - bbar)
        k0 = int(np.argmax(located))
        d = (z_ref - z_ref[k0]) / scale
        xy = np.column_stack([d.real, d.imag])
        xy[~located] = np.nan
        with np.errstate(divide="ignore", invalid="ignore"):
            extra = np.abs(b_ref - bbar) ** 2 / sbb if sbb > 0 else np.zeros(N)
            sig = s / scale * np.sqrt(1.0 / n + 1.0 / n[k0] + extra) * 1e3
        sig = np.where(located, sig, np.nan)
        return Track(xy, located, np.where(located, n, 0), sig, code, (r_ref, c_ref),
                     float(math.degrees(math.atan2(c.imag, c.real))), float(scale), float(s),
                     tuple(int(i) for i in np.flatnonzero(~located)), reasons)

    def _rotation_scale(self, sbz, sbb):
        if sbb > 0:
            return complex(sbz / sbb)
        if self.settings.pixel_mm is not None:
            warnings.warn("no frame shows two marks: the board's rotation cannot be estimated; assuming the "
                          "board is aligned with the image and --pixel-um is exact", stacklevel=3)
            return 1.0 + 0j
        raise DataError("no frame shows two marks of the board, so its rotation and the image scale cannot "
                        "be estimated; use a larger field of view or a board with a smaller pitch",
                        column="frames")


def estimate_track(results, board, settings) -> Track:
    """Track from an iterable of :class:`FrameResult` in frame order (see :class:`TrackBuilder`)."""
    builder = TrackBuilder(board, settings)
    for r in results:
        builder.add(r)
    return builder.finish()
