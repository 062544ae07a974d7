"""Compensation: the fitted errors as geometry, axis tables on controller grids, the files a
controller loads, and ``verify`` of the run made after loading them.

Imports model, data, fitting and diagnosis.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "write_compensation": "compensate", "compensation_model": "compensate", "K_MOVED": "history",
    "SCHEMES": "history",
    "add_calibration": "history", "database_path": "history", "machine_history": "history",
    "history_text": "history_report", "plot_history": "history_report", "verify": "verify",
    "verification_report": "verify_report", "geometry_lines": "rotary_geometry",
}

__all__ = ["K_MOVED", "SCHEMES", "add_calibration", "compensation_model", "database_path", "geometry_lines",
           "history_text", "machine_history", "plot_history", "verification_report", "verify", "write_compensation"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
