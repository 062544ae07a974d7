"""Vision locators shared by all kinid methods.

=====================  =========================================================
module                 what it does
=====================  =========================================================
``render``             anti-aliased renderer of marks, boards and patterns (tests, printing)
``circles``            sub-pixel centres of round marks, holes and spheres
``disk_fit``           one mark's centre from a model of its image (blurred disk, weighted centroid)
``ringcode``           ring-coded marks: detection, decoding, centres (a sub-package: detect, blobs, read)
``board``              board files (docs/formats.md, "Board file") and matching decoded marks to a board
``template``           template matching with sub-pixel refinement
``camera``             camera calibration (Zhang), distortion and undistortion
``motion_scale``       pixel equivalent, backlash from feature positions, pixel-to-machine matrix
``laser_offsets``      camera / laser displacement sensor offsets (hole, axial, focus height)
``laser_shapes``       camera / laser radial offsets from a scanned ball or two edges
=====================  =========================================================
"""
from kinid.lazy import front_door as _front_door

#: Each public name and the module of this package that defines it. The module is imported on first
#: use of the name (PEP 562): importing the package (for instance to build the ``kinid`` command
#: line's parsers) imports neither OpenCV nor NumPy.
_SOURCES = {
    "Board": "board", "load_board": "board", "make_board": "board", "match_to_board": "board",
    "save_board": "board",
    "CameraModel": "camera", "calibrate_camera": "camera", "circle_centre_bias": "camera", "load_camera": "camera", "camera_from_dict": "camera",
    "save_camera": "camera",
    "CircleResult": "circles", "locate_disk": "circles", "locate_hole": "circles", "locate_sphere": "circles",
    "axial_offset": "laser_offsets", "radial_offset_from_hole": "laser_offsets",
    "radial_offset_from_sphere": "laser_shapes",
    "MatrixResult": "motion_scale", "ScaleResult": "motion_scale", "backlash_from_reversals": "motion_scale",
    "pixel_equivalent": "motion_scale", "pixel_to_machine_matrix": "motion_scale",
    "board_coverage": "render", "render_disk": "render", "render_pattern": "render",
    "Marker": "ringcode", "detect_markers": "ringcode",
    "locate_template": "template", "make_template": "template",
}

__all__ = ["detect_markers", "Marker", "Board", "make_board", "load_board", "save_board", "match_to_board", "locate_disk", "locate_hole", "locate_sphere", "CircleResult", "make_template", "locate_template", "calibrate_camera", "circle_centre_bias", "CameraModel", "load_camera", "camera_from_dict", "save_camera", "pixel_equivalent", "backlash_from_reversals", "pixel_to_machine_matrix", "radial_offset_from_hole", "radial_offset_from_sphere", "axial_offset", "render_pattern", "render_disk", "board_coverage", "MatrixResult", "ScaleResult"]


__getattr__, __dir__ = _front_door(__name__, _SOURCES)
