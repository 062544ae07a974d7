"""UVW (X-Y-θ) alignment stage: kinematics, the patent's compensation and a better model.

Public API: :class:`UVWGeometry`, :func:`inverse_kinematics`, :func:`forward_kinematics`,
:func:`decompose_move`, :class:`SimulatedUVWStage`, :func:`calibrate` (model-based compensator per
docs/hardware.md), :func:`calibrate_patent` and :func:`patent_compensation_um` (the patent's method),
:func:`fit_actuator_model`, :func:`select_actuator_model`, :func:`phase_residuals`. See ``docs/uvw.md``.
"""
from .calibrate import UVWCompensator, calibrate
from .kinematics import ACTUATORS, UVWGeometry, decompose_move, forward_kinematics, inverse_kinematics
from .patent import calibrate_patent, patent_compensation_um
from .simulate import SimulatedUVWStage

__all__ = ["UVWGeometry", "inverse_kinematics", "forward_kinematics", "decompose_move", "calibrate", "UVWCompensator", "calibrate_patent", "patent_compensation_um", "SimulatedUVWStage", "ACTUATORS"]
