"""Lead-screw backlash of an X-Y-θ stage from images (CN105547173).

Public API: :class:`SimulatedStage`, :func:`calibrate`, :class:`BacklashResult`,
:func:`plan_moves`, :func:`locate_fiducial`. See ``docs/backlash.md``.
"""
from kinid.lazy import front_door as _front_door

#: Each public name and the module of this package that defines it, imported on first use of the name.
_SOURCES = {"calibrate": "calibrate", "BacklashResult": "calibrate", "locate_fiducial": "locate",
            "plan_moves": "plan", "SimulatedStage": "simulate"}

__all__ = ["calibrate", "BacklashResult", "plan_moves", "locate_fiducial", "SimulatedStage"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
