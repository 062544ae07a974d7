"""UVW (X-Y-θ) alignment stage: kinematics, the patent's compensation and a better model.

Public API: :class:`UVWGeometry`, :func:`inverse_kinematics`, :func:`forward_kinematics`,
:func:`decompose_move`, :class:`SimulatedUVWStage`, :func:`calibrate` (model-based compensator per
docs/hardware.md), :func:`calibrate_patent` and :func:`patent_compensation_um` (the patent's method),
:func:`fit_actuator_model`, :func:`select_actuator_model`, :func:`phase_residuals`. See ``docs/uvw.md``.
"""
from .calibrate import (UVWCompensator, alignment_targets, calibrate, home_forward, measure_plan, plan_positions,
                        run_moves, run_stage_moves)
from .kinematics import (ACTUATORS, Pose, Strokes, UVWGeometry, decompose_move, forward_kinematics,
                         inverse_kinematics)
from .model import ActuatorModel, fit_actuator_model, parameter_names, phase_residuals, select_actuator_model
from .patent import (PatentCompensator, PatentStatistics, calibrate_patent, measure_patent,
                     patent_compensation_um, patent_statistics, patent_strokes)
from .simulate import ActuatorTruth, SimulatedUVWStage, default_truth

__all__ = ["UVWGeometry", "inverse_kinematics", "forward_kinematics", "decompose_move", "calibrate", "UVWCompensator", "calibrate_patent", "patent_compensation_um", "SimulatedUVWStage", "ACTUATORS"]
