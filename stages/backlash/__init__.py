"""Lead-screw backlash of an X-Y-θ stage from images (CN105547173).

Public API: :class:`SimulatedStage`, :func:`calibrate`, :class:`BacklashResult`,
:func:`plan_moves`, :func:`locate_fiducial`. See ``docs/backlash.md``.
"""
from .calibrate import BacklashResult, calibrate
from .locate import locate_fiducial
from .plan import plan_moves
from .simulate import SimulatedStage

__all__ = ["calibrate", "BacklashResult", "plan_moves", "locate_fiducial", "SimulatedStage"]
