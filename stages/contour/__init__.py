"""Planar contour error of a machine from image sequences of a ring-coded board (the monocular contour method).

``process_frame`` (per frame, pure) -> ``TrackBuilder`` (rotation and scale once
from all frames, then the reference mark's track) -> ``contour_error`` /
``circular_test`` (ISO 230-4 G, F, H). ``kinid contour`` is the command line.
"""
from kinid.lazy import front_door as _front_door

#: Each public name and the module of this package that defines it, imported on first use of the name.
_SOURCES = {"open_frames": "frames", "ContourMeasurement": "measure", "measure_contour": "measure",
            "CirclePath": "paths", "LinePath": "paths", "PolylinePath": "paths", "circular_test": "paths",
            "contour_error": "paths", "TrackBuilder": "track", "process_frame": "track"}

__all__ = ["measure_contour", "ContourMeasurement", "process_frame", "TrackBuilder", "contour_error", "circular_test", "CirclePath", "LinePath", "PolylinePath", "open_frames"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
