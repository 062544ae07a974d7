"""urdf/gantry_dual_y.urdf: loads in Pinocchio unchanged and follows docs/machines.md."""
import xml.etree.ElementTree as ET

import numpy as np
import pinocchio as pin
import pytest

from kinid.identification.model.machine import load_machine, tool_in_workpiece_mm
from kinid.urdf import path

URDF = path("gantry_dual_y")
AXES = {"Y", "V", "X"}
ERRORS = {"EXY", "EYY", "ECY", "EC0V", "EXV", "EYV", "ECV", "EC0X",
          "EX0W", "EY0W", "EZ0W", "EA0W", "EB0W", "EC0W", "EX0T", "EY0T", "EZ0T", "EA0T", "EB0T", "EC0T"}


def _joints():
    return {j.get("name"): j for j in ET.parse(URDF).getroot().iter("joint")}


def _child_to_joint():
    return {j.find("child").get("link"): j for j in _joints().values()}


def _parent_joint_of(joint):
    """The joint whose child link is this joint's parent link (None at the root)."""
    return _child_to_joint().get(joint.find("parent").get("link"))


def test_pinocchio_loads_unchanged():
    model = pin.buildModelFromUrdf(str(URDF))
    names = set(model.names[1:])
    assert names == AXES | ERRORS
    assert model.nq == len(AXES | ERRORS)
    assert model.existFrame("tool") and model.existFrame("workpiece")


def test_error_joints_single_dof_zero_origin_and_direction():
    joints = _joints()
    for code in ERRORS:
        j = joints[code]
        d = code[1]
        assert j.get("type") == ("prismatic" if d in "XYZ" else "revolute"), code
        o = j.find("origin")
        assert [float(v) for v in o.get("xyz").split()] == [0.0, 0.0, 0.0], code
        assert [float(v) for v in o.get("rpy").split()] == [0.0, 0.0, 0.0], code
        axis = [float(v) for v in j.find("axis").get("xyz").split()]
        want = np.eye(3)["XYZ".index(d) if d in "XYZ" else "ABC".index(d)]
        assert np.array_equal(axis, want), code


@pytest.mark.parametrize("axis", ["Y", "V"])
def test_pdge_joints_directly_after_their_axis(axis):
    joints = _joints()
    for code in (f"EX{axis}", f"EY{axis}", f"EC{axis}"):
        j = _parent_joint_of(joints[code])
        while j.get("name") != axis:  # only PDGE joints of the same axis in between
            assert j.get("name") in {f"EX{axis}", f"EY{axis}", f"EC{axis}"}, (code, j.get("name"))
            j = _parent_joint_of(j)


@pytest.mark.parametrize("code,axis", [("EC0V", "V"), ("EC0X", "X")])
def test_location_joints_directly_before_their_axis(code, axis):
    assert _parent_joint_of(_joints()[axis]).get("name") == code


@pytest.mark.parametrize("pseudo,link", [("W", "workpiece"), ("T", "tool")])
def test_setup_joints_directly_before_end_link(pseudo, link):
    j = _child_to_joint()[link]
    seen = []
    while j.get("name").endswith(f"0{pseudo}") and j.get("name").startswith("E"):
        seen.append(j.get("name"))
        j = _parent_joint_of(j)
    assert sorted(seen) == sorted(f"E{d}0{pseudo}" for d in "XYZABC")


def test_kinid_loader_accepts_it_and_discovers_axes():
    m = load_machine(URDF)
    assert set(m.axis_names) == AXES
    assert set(m.error_codes) == ERRORS
    assert {a.name: a.chain for a in m.axes} == {"Y": "tool", "V": "workpiece", "X": "workpiece"}


@pytest.mark.parametrize("y,v,x", [(0.0, 0.0, 0.0), (120.0, 120.0, 0.0), (250.0, 240.5, -3.25)])
def test_nominal_geometry_plate_centred_when_y_equals_v(y, v, x):
    m = load_machine(URDF)
    p = tool_in_workpiece_mm(m, {"Y": y, "V": v, "X": x})
    np.testing.assert_allclose(p, [-x, y - v, 0.0], atol=1e-9)


def test_error_joints_act_with_stated_abbe_offsets():
    """1 µrad of yaw moves the point by the Abbe offsets stated in the file (0.10 m camera, 0.30 m head)."""
    m = load_machine(URDF)
    axes = {"Y": 100.0, "V": 100.0, "X": 0.0}
    p0 = tool_in_workpiece_mm(m, axes)
    d = lambda code, val: (tool_in_workpiece_mm(m, axes, {code: val}) - p0) * 1e3  # noqa: E731  µm
    np.testing.assert_allclose(d("EXY", 1.0), [1.0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(d("EXV", 1.0), [-1.0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(d("ECY", 10.0), [0, -1.0, 0], atol=1e-4)   # camera 0.10 m in -x of the carriage
    np.testing.assert_allclose(d("ECV", 10.0), [0, -3.0, 0], atol=1e-4)   # head 0.30 m in +x of the V guide
    # parallelism: V turned counter-clockwise by 10 µrad, at V = 100 mm the plate is 1 µm towards -x (and 3 µm +y)
    np.testing.assert_allclose(d("EC0V", 10.0)[:2], [1.0, -3.0], atol=1e-4)
