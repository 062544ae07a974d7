"""Wrong calls to the Python API of the vision locators and the stage methods raise kinid's errors naming
the argument (not AttributeError or numpy's messages)."""
from __future__ import annotations

import numpy as np
import pytest

import kinid.stages.backlash as backlash
import kinid.stages.contour as contour
import kinid.stages.dual_axis as dual_axis
import kinid.stages.uvw as uvw
import kinid.vision as vision
from kinid.errors import KinidError

CASES = [
    ("image", lambda: vision.detect_markers("frame.png")),
    ("image", lambda: vision.detect_markers(None)),
    ("image", lambda: vision.detect_markers(np.full((20, 20), np.nan))),
    ("bits", lambda: vision.detect_markers(np.zeros((50, 50), np.uint8), bits="x")),
    ("polarity", lambda: vision.detect_markers(np.zeros((50, 50), np.uint8), polarity="white")),
    ("rows", lambda: vision.make_board(rows="a")),
    ("pitch_mm", lambda: vision.make_board(pitch_mm=-1)),
    ("moves_mm", lambda: vision.pixel_equivalent("a", [[1, 0]])),
    ("p1_px", lambda: vision.backlash_from_reversals("a", "b", 0.005)),
    ("mm_per_px", lambda: vision.backlash_from_reversals([[0, 0]], [[1, 1]], "x")),
    ("camera_matrix", lambda: vision.CameraModel("a", [0] * 5, (10, 10))),
    ("image_shape", lambda: vision.render_pattern(lambda p: p[:, 0], "a", lambda p: p)),
    ("coverage", lambda: vision.render_pattern(None, (10, 10), lambda p: p)),
    ("board", lambda: vision.match_to_board("board.json", [])),
    ("stage", lambda: backlash.calibrate(None)),
    ("travel_mm", lambda: backlash.calibrate(backlash.SimulatedStage(), travel_mm="a")),
    ("geometry", lambda: uvw.inverse_kinematics(None, 1.0, 2.0, 3.0)),
    ("theta_deg", lambda: uvw.inverse_kinematics(uvw.UVWGeometry(50, 50), 1.0, 2.0, "a")),
    ("gantry", lambda: dual_axis.calibrate(None, 0.0, (0.0, 0.0), 10.0, 3, np.eye(2), 1.0)),
    ("image", lambda: contour.process_frame("frame.png", None, None)),
    ("board", lambda: contour.process_frame(np.zeros((20, 20), np.uint8), "board.json", None)),
    ("track_xy_mm", lambda: contour.contour_error("a", contour.CirclePath())),
    ("path", lambda: contour.contour_error(np.zeros((3, 2)), "circle")),
    ("radius_mm", lambda: contour.CirclePath(radius_mm=-1)),
]


@pytest.mark.parametrize("argument, call", CASES, ids=[f"{i}-{a}" for i, (a, _) in enumerate(CASES)])
def test_bad_argument_is_named(argument, call):
    with pytest.raises(KinidError) as err:
        call()
    assert err.value.parameter == argument or str(err.value).startswith(argument), str(err.value)
