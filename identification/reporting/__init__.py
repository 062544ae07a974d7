"""Reports: the diagnosis and ``--auto`` steps as a folder of figures, residuals and an HTML page.

Imports model, data, fitting and diagnosis.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "diagnosis_report": "report", "selection_report": "report",
}

__all__ = ["diagnosis_report", "selection_report"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
