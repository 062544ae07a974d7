"""Reports: the diagnosis and ``--auto`` steps as a folder of figures, residuals and an HTML page; the one-page
certificate a customer signs (PDF and HTML).

Imports model, data, fitting and diagnosis.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "diagnosis_report": "report", "selection_report": "report", "build_certificate": "certificate",
    "write_certificate": "certificate", "read_meta": "certificate_meta",
}

__all__ = ["build_certificate", "diagnosis_report", "read_meta", "selection_report", "write_certificate"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
