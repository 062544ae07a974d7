"""Vision locators shared by all kinid methods.

=====================  =========================================================
module                 what it does
=====================  =========================================================
``render``             anti-aliased renderer of marks, boards and patterns (tests, printing)
``circles``            sub-pixel centres of round marks, holes and spheres
``ringcode``           ring-coded marks: detection, decoding, centres
``board``              board files (docs/formats.md, "Board file") and matching decoded marks to a board
``template``           template matching with sub-pixel refinement
``camera``             camera calibration (Zhang), distortion and undistortion
``motion_scale``       pixel equivalent, backlash from feature positions, pixel-to-machine matrix
``laser_offsets``      camera / laser displacement sensor offsets (hole, sphere, edges, axial)
=====================  =========================================================
"""
from .board import Board, load_board, make_board, match_to_board, save_board
from .camera import CameraModel, calibrate_camera, circle_centre_bias, load_camera, save_camera
from .circles import CircleResult, locate_disk, locate_hole, locate_sphere
from .laser_offsets import axial_offset, radial_offset_from_hole, radial_offset_from_sphere
from .motion_scale import MatrixResult, ScaleResult, backlash_from_reversals, pixel_equivalent, pixel_to_machine_matrix
from .render import board_coverage, render_disk, render_pattern
from .ringcode import Marker, detect_markers
from .template import locate_template, make_template

__all__ = ["detect_markers", "Marker", "Board", "make_board", "load_board", "save_board", "match_to_board", "locate_disk", "locate_hole", "locate_sphere", "CircleResult", "make_template", "locate_template", "calibrate_camera", "circle_centre_bias", "CameraModel", "load_camera", "save_camera", "pixel_equivalent", "backlash_from_reversals", "pixel_to_machine_matrix", "radial_offset_from_hole", "radial_offset_from_sphere", "axial_offset", "render_pattern", "render_disk", "board_coverage", "MatrixResult", "ScaleResult"]
