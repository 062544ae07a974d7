"""The machine model: a URDF with ISO 230-1 error joints loaded into Pinocchio, the effect bases and effects
that may act on its joints, their names and the sizes a machine can plausibly have.

Imports only the ground floor (``kinid.*``) and the shipped machine files.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "LINEAR_PERIODS_MM": "bases", "ROTARY_PERIODS_DEG": "bases", "basis_of": "bases", "chosen_of": "bases",
    "local_column_index": "bsplines", "local_columns": "bsplines", "local_effect": "effects", "local_grid": "bsplines",
    "TABLE_POSITIONS": "effects", "axis_dependent_joints": "derived", "basis_values": "effects",
    "candidate_library": "effects", "check_effects": "effects", "default_model": "effects",
    "model_effects": "effects", "param_codes": "effects", "parse_effect": "effects", "position_tables": "effects",
    "Machine": "machine",
    "axis_limits": "machine", "check_machine": "machine", "evaluate": "machine", "evaluate_blocks": "machine",
    "load_machine": "machine",
    "machine_from_urdf": "machine", "tool_in_workpiece_mm": "machine", "tool_rotation_in_workpiece": "machine",
    "axis_directions": "names", "effect_description": "names", "plain_name": "names",
    "implausible_candidate": "plausibility", "implausible_effects": "plausibility",
    "share_of_limit": "plausibility", "warning_lines": "plausibility", "rigid_transform": "rigid",
    "MAX_URDF_BYTES": "urdf_checks", "joint_kind": "urdf_checks", "identification_urdf": "urdf_import",
}

__all__ = ["LINEAR_PERIODS_MM", "MAX_URDF_BYTES", "Machine", "ROTARY_PERIODS_DEG", "TABLE_POSITIONS",
           "axis_dependent_joints", "axis_directions", "axis_limits", "basis_of", "basis_values",
           "candidate_library", "check_effects", "check_machine", "chosen_of", "default_model",
           "effect_description", "evaluate", "evaluate_blocks", "identification_urdf", "implausible_candidate",
           "implausible_effects", "joint_kind", "load_machine", "local_column_index", "local_columns", "local_effect",
           "local_grid", "machine_from_urdf", "model_effects", "param_codes", "parse_effect", "plain_name",
           "position_tables",
           "rigid_transform", "share_of_limit", "tool_in_workpiece_mm", "tool_rotation_in_workpiece",
           "warning_lines"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
