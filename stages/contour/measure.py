"""End to end: frames -> track -> contour error (the body of ``kinid contour``)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError

from .frames import map_frames, map_frames_dask, open_frames
from .paths import CirclePath, circular_test, contour_error
from .track import TrackBuilder

__all__ = ["ContourMeasurement", "measure_contour", "track_csv", "choose_downsample"]

#: ``downsample="auto"`` keeps the centre circle at least this many pixels in radius.
AUTO_MIN_RADIUS_PX = 20.0
#: ... and downsamples at most this many times.
AUTO_MAX_FACTOR = 2


@dataclass(frozen=True)
class ContourMeasurement:
    """Result of :func:`measure_contour`.

    Attributes
    ----------
    track : stages.contour.track.Track
    contour : stages.contour.paths.ContourError
        Error per frame, µm (NaN for frames not located).
    circular : stages.contour.paths.CircularTest or None
        ISO 230-4 figures when the path is a circle.
    t_s : ndarray, shape (N,)
        Time of each frame, s (NaN when no frame rate is known).
    fps : float or None
        Frame rate used.
    """

    track: object
    contour: object
    circular: object
    t_s: np.ndarray
    fps: float | None

    @property
    def summary(self) -> dict:
        """The ``--json`` summary of docs/formats.md."""
        return {"frames": int(len(self.t_s)), "located": int(self.track.located.sum()),
                "rms_error_um": _num(self.contour.rms_um), "max_error_um": _num(self.contour.max_um)}


def _num(v):
    return float(v) if math.isfinite(v) else None


def choose_downsample(source, board, settings, *, probe_frames=5) -> int:
    """Decoding downsample factor for a sequence: as large as keeps the centre circle >= 20 px in radius.

    The object-side pixel comes from the first located frame (mark spacing
    against the board pitch), or from ``settings.pixel_mm``. Measured on
    rendered 1024² sequences of the patent board (k1 = −0.1, σ = 2): track RMS
    0.21 / 0.22 µm at 30 µm pixels with factor 1 / 2, and 0.20 / 0.15 µm at
    40 µm, while the throughput of ``kinid contour`` rises from 67 to 112
    frames/s at 30 µm. Factor 3 was measured too (0.23 µm at 30 µm, 0.19 µm at
    40 µm) and gave no further speed, so 2 is the largest automatic choice.
    Returns 1 when nothing can be measured.
    """
    from dataclasses import replace

    from kinid.errors import ImageError
    from kinid.files import read_image

    from .track import process_frame

    probe = replace(settings, downsample=1)
    mm_per_px = settings.pixel_mm
    for k, frame in enumerate(source):
        if k >= probe_frames:
            break
        try:
            image = read_image(frame) if isinstance(frame, str) else frame
        except ImageError:
            continue
        r = process_frame(image, board, probe)
        if r.n >= 2:
            d_px = np.linalg.norm(np.diff(r.pixels, axis=0), axis=1)
            d_mm = np.linalg.norm(np.diff(r.board_mm, axis=0), axis=1)
            mm_per_px = float(np.median(d_mm / d_px))
            break
    if not mm_per_px:
        return 1
    radius_px = board.center_d_mm / 2.0 / mm_per_px
    return int(max(1, min(AUTO_MAX_FACTOR, radius_px // AUTO_MIN_RADIUS_PX)))


def measure_contour(frames, board, settings, path=None, *, fps=None, workers=2, progress=None, scheduler=None):
    """Measure the reference mark's track and its contour error from a sequence.

    Parameters
    ----------
    frames : str or path or FrameSource
        Folder of images (name order) or a video file.
    board : vision.board.Board
    settings : stages.contour.track.FrameSettings
        ``downsample=None`` chooses the factor with :func:`choose_downsample`.
    path : CirclePath or LinePath or PolylinePath or None
        Programmed path; default a least-squares circle.
    fps : float or None
        Frame rate; ``t_s = frame / fps``. Default: the video's frame rate,
        else unknown (NaN times).
    workers : int
        Worker processes (of the local pool, or of a local Dask cluster).
    progress : kinid.progress.Progress or None
    scheduler : str or None
        Map the frames on a Dask cluster: its scheduler's address, or ``"local"`` for a local cluster
        (:func:`~kinid.stages.contour.frames.map_frames_dask`); default the local process pool.

    Returns
    -------
    ContourMeasurement
    """
    source = frames if hasattr(frames, "kind") else open_frames(frames)
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise DataError(f"fps must be a positive number, got {fps!r}", column="fps")
    if fps is None:
        fps = source.fps
    path = CirclePath() if path is None else path
    if settings.downsample is None:
        from dataclasses import replace

        settings = replace(settings, downsample=choose_downsample(source, board, settings))
    builder = TrackBuilder(board, settings)
    if scheduler is None:
        results = map_frames(source, board, settings, workers=workers, progress=progress)
    else:
        results = map_frames_dask(source, board, settings, scheduler, workers=workers, progress=progress)
    for result in results:
        builder.add(result)
    track = builder.finish()
    n = len(track.located)
    t_s = np.arange(n) / fps if fps else np.full(n, np.nan)
    contour = contour_error(track.xy_mm, path)
    circular = None
    if isinstance(path, CirclePath) and int(track.located.sum()) >= 3:
        circular = circular_test(track.xy_mm, nominal_radius_mm=contour.path.radius_mm,
                                 centre_mm=contour.path.centre_mm)
    return ContourMeasurement(track, contour, circular, t_s, fps)


def track_csv(measurement) -> str:
    """TRACK.csv text (docs/formats.md, "Contour track"): ``frame,t_s,x_mm,y_mm,error_um``.

    Frames that were not located keep their row with empty ``x_mm``, ``y_mm``
    and ``error_um``; ``t_s`` is empty when no frame rate is known.
    """
    m = measurement
    out = ["frame,t_s,x_mm,y_mm,error_um"]
    for k in range(len(m.t_s)):
        t = "" if not math.isfinite(m.t_s[k]) else f"{m.t_s[k]:.6f}"
        x, y = m.track.xy_mm[k]
        e = m.contour.error_um[k]
        if math.isfinite(x) and math.isfinite(y):
            err = f"{e:.4f}" if math.isfinite(e) else ""
            out.append(f"{k},{t},{x:.7f},{y:.7f},{err}")
        else:
            out.append(f"{k},{t},,,")
    return "\n".join(out) + "\n"
