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
from .board import Board, BoardMatch, load_board, make_board, match_to_board, save_board
from .camera import CalibrationResult, CameraModel, calibrate_camera, load_camera, save_camera
from .circles import CircleResult, locate_disk, locate_hole, locate_sphere, offset_from_image_centre
from .laser_offsets import (OffsetResult, axial_offset, focus_height, radial_offset_from_edges,
                            radial_offset_from_hole, radial_offset_from_sphere)
from .motion_scale import (MatrixResult, ReversalResult, ScaleResult, backlash_from_reversals, pixel_equivalent,
                           pixel_to_machine_matrix)
from .render import (board_coverage, disk_coverage, homography_image_to_plane, render_disk, render_pattern,
                     ring_mark_coverage, similarity_plane_to_image)
from .ringcode import Marker, canonical_code, decode_from_segments, detect_markers
from .template import Template, TemplateMatch, locate_template, make_template

__all__ = ["detect_markers", "Marker", "Board", "make_board", "load_board", "save_board", "match_to_board", "locate_disk", "locate_hole", "locate_sphere", "CircleResult", "make_template", "locate_template", "calibrate_camera", "CameraModel", "load_camera", "save_camera", "pixel_equivalent", "backlash_from_reversals", "pixel_to_machine_matrix", "radial_offset_from_hole", "radial_offset_from_sphere", "axial_offset", "render_pattern", "render_disk", "board_coverage", "MatrixResult", "ScaleResult"]
