"""UVW (X-Y-θ) alignment stage: kinematics, the patent's compensation and a better model.

Public API: :class:`UVWGeometry`, :func:`inverse_kinematics`, :func:`forward_kinematics`,
:func:`decompose_move`, :class:`SimulatedUVWStage`, :func:`calibrate` (model-based compensator per
docs/hardware.md), :func:`calibrate_patent` and :func:`patent_compensation_um` (the patent's method),
:func:`fit_actuator_model`, :func:`select_actuator_model`, :func:`phase_residuals`. See ``docs/uvw.md``.
"""
from kinid.lazy import front_door as _front_door

#: Each public name and the module of this package that defines it, imported on first use of the name.
_SOURCES = {"calibrate": "calibrate", "UVWCompensator": "calibrate",
            "ACTUATORS": "kinematics", "UVWGeometry": "kinematics", "decompose_move": "kinematics",
            "forward_kinematics": "kinematics", "inverse_kinematics": "kinematics",
            "calibrate_patent": "patent", "patent_compensation_um": "patent",
            "SimulatedUVWStage": "simulate"}

__all__ = ["UVWGeometry", "inverse_kinematics", "forward_kinematics", "decompose_move", "calibrate", "UVWCompensator", "calibrate_patent", "patent_compensation_um", "SimulatedUVWStage", "ACTUATORS"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
