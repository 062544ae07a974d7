"""Lead-screw backlash of an X-Y-θ stage from images (CN105547173).

Public API: :class:`SimulatedStage`, :func:`calibrate`, :class:`BacklashResult`,
:func:`plan_moves`, :func:`locate_fiducial`. See ``docs/backlash.md``.
"""
from .calibrate import BacklashResult, MoveRecord, analyse, calibrate
from .locate import locate_fiducial
from .plan import PlannedMove, plan_moves
from .simulate import SimulatedStage, play

__all__ = ["calibrate", "BacklashResult", "plan_moves", "locate_fiducial", "SimulatedStage"]
