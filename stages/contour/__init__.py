"""Planar contour error of a machine from image sequences of a ring-coded board (the monocular contour method).

``process_frame`` (per frame, pure) -> ``TrackBuilder`` (rotation and scale once
from all frames, then the reference mark's track) -> ``contour_error`` /
``circular_test`` (ISO 230-4 G, F, H). ``kinid contour`` is the command line.
"""
from .frames import open_frames
from .measure import ContourMeasurement, measure_contour
from .paths import CirclePath, LinePath, PolylinePath, circular_test, contour_error
from .track import TrackBuilder, process_frame

__all__ = ["measure_contour", "ContourMeasurement", "process_frame", "TrackBuilder", "contour_error", "circular_test", "CirclePath", "LinePath", "PolylinePath", "open_frames"]
