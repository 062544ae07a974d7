"""The diagnosis: the score test of every candidate effect from shared sums, periods and time constants
searched, maps and local errors, ambiguity and structure of the residual, and ``--auto``'s forward
selection.

Imports model, data and fitting.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "ALPHA": "diagnose", "Diagnosis": "diagnose", "diagnose": "diagnose", "forward_select": "selection",
    "what_is_left": "selection",
}

__all__ = ["ALPHA", "Diagnosis", "diagnose", "forward_select", "what_is_left"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
