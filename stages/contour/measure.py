"""End to end: frames -> track -> contour error (the body of ``kinid contour``)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from identification.errors import DataError

from .frames import map_frames, open_frames
from .paths import CirclePath, circular_test, contour_error
from .track import TrackBuilder

__all__ = ["ContourMeasurement", "measure_contour", "track_csv"]


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
        """The ``--json`` summary of INTERFACES.md §6."""
        return {"frames": int(len(self.t_s)), "located": int(self.track.located.sum()),
                "rms_error_um": _num(self.contour.rms_um), "max_error_um": _num(self.contour.max_um)}


def _num(v):
    return float(v) if math.isfinite(v) else None


def measure_contour(frames, board, settings, path=None, *, fps=None, workers=2, progress=None):
    """Measure the reference mark's track and its contour error from a sequence.

    Parameters
    ----------
    frames : str or path or FrameSource
        Folder of images (name order) or a video file.
    board : vision.board.Board
    settings : stages.contour.track.FrameSettings
    path : CirclePath or LinePath or PolylinePath or None
        Programmed path; default a least-squares circle.
    fps : float or None
        Frame rate; ``t_s = frame / fps``. Default: the video's frame rate,
        else unknown (NaN times).
    workers : int
        Worker processes.
    progress : identification.progress.Progress or None

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
    builder = TrackBuilder(board, settings)
    for result in map_frames(source, board, settings, workers=workers, progress=progress):
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
    """TRACK.csv text (INTERFACES.md §6): ``frame,t_s,x_mm,y_mm,error_um``.

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
