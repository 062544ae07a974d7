"""The data: the observation CSV and its axis columns, the run log and images turned into observations
(``observe``), and the distinct positions at which each axis was read.

Imports the ground floor, vision's front door and :mod:`~kinid.identification.model`.
"""
from kinid.lazy import front_door as _front_door

#: The names the other sub-packages use, and the module of this one that defines each (imported on first use).
_SOURCES = {
    "read_axis_table": "axis_columns", "Export": "exports", "is_observation_csv": "exports",
    "parse_point_columns": "exports", "read_export": "exports", "euler_rotations": "exports",
    "ROTATION_MARK": "exports", "ORIENTATION_PATTERNS": "exports", "EULER_SEQUENCES": "exports", "BoardPose": "laser_depth",
    "board_pose": "laser_depth", "drawing_turn_um": "laser_depth", "lever_in_machine_mm": "laser_depth",
    "turned_xy": "laser_depth", "laser_offset": "laser_offset",
    "MIN_ROWS": "observations", "Observations": "observations", "SetAside": "observations",
    "check_observations": "observations", "check_row_count": "observations", "exact_duplicates": "observations",
    "observations_text": "observations", "read_observations": "observations", "row_groups": "observations",
    "write_observations": "observations", "SENSOR_SCHEMA": "observe", "board_mark_mm": "observe",
    "check_laser_offset": "observe", "default_board_origin_mm": "observe", "load_sensor": "observe",
    "observe": "observe", "read_run_log": "observe", "distinct_positions": "positions",
    "position_starts": "positions", "positions_of": "positions", "positions_per_axis": "positions",
    "UnitHint": "units", "unit_hints": "units", "warn_units": "units",
}

__all__ = ["BoardPose", "EULER_SEQUENCES", "Export", "MIN_ROWS", "ORIENTATION_PATTERNS", "ROTATION_MARK", "Observations", "SENSOR_SCHEMA", "SetAside", "UnitHint",
           "board_mark_mm", "board_pose", "check_laser_offset", "check_observations", "check_row_count",
           "default_board_origin_mm", "distinct_positions", "drawing_turn_um", "euler_rotations", "exact_duplicates",
           "is_observation_csv", "laser_offset", "lever_in_machine_mm", "load_sensor", "observations_text", "observe",
           "parse_point_columns", "position_starts", "positions_of", "positions_per_axis", "read_axis_table",
           "read_export", "read_observations", "read_run_log", "row_groups", "turned_xy", "unit_hints", "warn_units",
           "write_observations"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
