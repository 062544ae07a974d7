"""The diagnosis: the score test of every candidate effect from shared sums, periods and time constants
searched, maps and local errors, ambiguity and structure of the residual, and ``--auto``'s forward
selection; an instrument's stated standard deviations checked against a fit's residuals.

Imports model, data and fitting.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "ALPHA": "diagnose", "Diagnosis": "diagnose", "diagnose": "diagnose", "forward_select": "selection",
    "what_is_left": "selection", "StdCheck": "stated_std", "check_stated_std": "stated_std",
}

__all__ = ["ALPHA", "Diagnosis", "StdCheck", "check_stated_std", "diagnose", "forward_select", "what_is_left"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
