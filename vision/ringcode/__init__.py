"""Ring-coded marks: a centre circle surrounded by a ring of ``n`` equal angular elements, each printed (1)
or not (0); the code is the smallest value over the cyclic rotations of the bits.

- :mod:`.detect` — :func:`detect_markers`: candidate centre circles on a scale pyramid, read and refined;
- :mod:`.blobs` — the candidates: round blobs of a thresholded image and the global thresholds;
- :mod:`.read` — one mark read: its ring's code (:func:`read_ring`), the patent's arithmetic on segments
  (:func:`decode_from_segments`), :func:`canonical_code`, and its centre refined.
"""
from kinid.lazy import front_door as _front_door

_SOURCES = {
    "detect_markers": "detect",
    "Marker": "read", "canonical_code": "read", "decode_from_segments": "read", "read_ring": "read",
}

__all__ = ["Marker", "canonical_code", "decode_from_segments", "detect_markers", "read_ring"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
