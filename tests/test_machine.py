"""Machines: URDF convention checks, nominal kinematics, Jacobians against finite differences."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from kinid.errors import MachineError
from kinid.identification.model.machine import evaluate, load_machine, machine_from_urdf, tool_in_workpiece_mm
from kinid.identification.model.urdf_builder import Axis, Fixed, machine_urdf, setup
from kinid.urdf import names, path

MACHINES = ["five_axis_bc", "five_axis_ac", "five_axis_bhead_c"]


@pytest.fixture(scope="module", params=MACHINES)
def machine(request):
    return load_machine(path(request.param))


def test_shipped_machines_are_listed():
    assert set(MACHINES) <= set(names())
    assert "gantry_dual_y" in names()


def test_five_axis_bc_has_the_patent_errors():
    m = load_machine(path("five_axis_bc"))
    assert m.axis_names == ("Y", "B", "C", "X", "Z")
    pdge = [e.code for e in m.error_joints if not e.location]
    location = [e.code for e in m.error_joints if e.location and e.axis not in "WT"]
    assert len(pdge) == 30
    assert sorted(location) == sorted(["EC0Y", "EB0Z", "EA0Z", "EX0B", "EZ0B", "EA0B", "EC0B", "EX0C", "EY0C", "EA0C", "EB0C"])
    assert sorted(e.code for e in m.error_joints if e.axis == "W") == sorted(f"E{d}0W" for d in "XYZABC")
    assert sorted(e.code for e in m.error_joints if e.axis == "T") == sorted(f"E{d}0T" for d in "XYZABC")
    assert [a.column for a in m.axes] == ["y_mm", "b_deg", "c_deg", "x_mm", "z_mm"]


def _rot(axis, deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-300, 300), y=st.floats(-300, 300), z=st.floats(-200, 200),
    b=st.floats(-90, 90), c=st.floats(-360, 360),
)
def test_nominal_bc_kinematics_match_hand_formula(x, y, z, b, c):
    """Errors at zero reproduce the nominal double-turntable kinematics written by hand (mm)."""
    m = load_machine(path("five_axis_bc"))
    tool_world = np.array([x, 0.0, z + 110.0])
    # workpiece: Y carriage (0, y, 0) -> B line +150 z -> rot_y(b) -> table -50 z -> rot_z(c) -> board +10 z
    R = _rot("y", b) @ _rot("z", c)
    p_w = np.array([0, y, 150.0]) + _rot("y", b) @ np.array([0, 0, -50.0]) + R @ np.array([0, 0, 10.0])
    expected = R.T @ (tool_world - p_w)
    got = tool_in_workpiece_mm(m, {"X": x, "Y": y, "Z": z, "B": b, "C": c})
    np.testing.assert_allclose(got, expected, atol=1e-9)


def test_jacobians_match_finite_differences(machine):
    rng = np.random.default_rng(3)
    n_ax, n_err = len(machine.axes), len(machine.error_joints)
    scale = np.array([100.0 if a.kind == "prismatic" else 40.0 for a in machine.axes])
    axes = rng.uniform(-1, 1, size=(4, n_ax)) * scale
    errors = rng.normal(0, 50, size=n_err)
    p, d_err, d_ax = evaluate(machine, axes, errors)
    h = 1e-3  # µm / µrad, and mm / deg below
    for k in range(n_err):
        e1, e2 = errors.copy(), errors.copy()
        e1[k] += h
        e2[k] -= h
        fd = (evaluate(machine, axes, e1, jacobian=False) - evaluate(machine, axes, e2, jacobian=False)) / (2 * h) * 1e3
        np.testing.assert_allclose(d_err[:, :, k], fd, atol=1e-6, err_msg=machine.error_codes[k])
    for k in range(n_ax):
        a1, a2 = axes.copy(), axes.copy()
        a1[:, k] += h
        a2[:, k] -= h
        fd = (evaluate(machine, a1, errors, jacobian=False) - evaluate(machine, a2, errors, jacobian=False)) / (2 * h) * 1e3
        np.testing.assert_allclose(d_ax[:, :, k], fd, rtol=1e-6, atol=1e-4, err_msg=machine.axis_names[k])


def test_error_joint_moves_the_point_in_its_direction():
    m = load_machine(path("five_axis_bc"))
    base = tool_in_workpiece_mm(m, {"X": 5.0})
    np.testing.assert_allclose(tool_in_workpiece_mm(m, {"X": 5.0}, {"EX0T": 10.0}) - base, [0.010, 0, 0], atol=1e-12)
    # a board shifted by +10 µm in x sees the tool 10 µm further in -x
    np.testing.assert_allclose(tool_in_workpiece_mm(m, {"X": 5.0}, {"EX0W": 10.0}) - base, [-0.010, 0, 0], atol=1e-12)


def test_unknown_axis_and_error_names_are_rejected():
    m = load_machine(path("five_axis_bc"))
    with pytest.raises(MachineError, match="unknown axes"):
        tool_in_workpiece_mm(m, {"Q": 1.0})
    with pytest.raises(MachineError, match="unknown error joints"):
        tool_in_workpiece_mm(m, {}, {"EXQ": 1.0})


# --- malformed machines: one test per broken element --------------------------------------------

def _urdf(work=None, tool=None):
    work = work if work is not None else [Axis("Y", "prismatic", (0, 1, 0), location_errors=("C",)), setup("W")]
    tool = tool if tool is not None else [Axis("X", "prismatic", (1, 0, 0)), Fixed("mount", (0, 0, 0.1)), setup("T")]
    return machine_urdf("m", work, tool)


def test_builder_machine_loads():
    m = machine_from_urdf(_urdf())
    assert m.axis_names == ("Y", "X")


def test_missing_file():
    with pytest.raises(MachineError, match="not found"):
        load_machine("/nonexistent/machine.urdf")


def test_not_xml():
    with pytest.raises(MachineError, match="not valid XML"):
        machine_from_urdf("<robot name='m'><link name='base'>", "bad.urdf")


def test_missing_tool_link():
    text = _urdf().replace('"tool"', '"camera"')
    with pytest.raises(MachineError, match="no link named 'tool'"):
        machine_from_urdf(text, "m.urdf")


def test_error_joint_with_nonzero_origin():
    text = _urdf().replace('<joint name="EXY" type="prismatic">\n    <parent link="y_link"/>\n    <child link="EXY_link"/>\n    <origin xyz="0 0 0"',
                           '<joint name="EXY" type="prismatic">\n    <parent link="y_link"/>\n    <child link="EXY_link"/>\n    <origin xyz="0 0 0.1"')
    with pytest.raises(MachineError, match="'EXY'.*zero origin"):
        machine_from_urdf(text, "m.urdf")


def test_error_joint_of_wrong_type():
    text = _urdf().replace('<joint name="EAY" type="revolute">', '<joint name="EAY" type="prismatic">')
    with pytest.raises(MachineError, match="'EAY'.*needs a revolute joint"):
        machine_from_urdf(text, "m.urdf")


def test_error_joint_with_wrong_direction():
    i = _urdf().index('<joint name="EYY"')
    text = _urdf()
    j = text.index('<axis xyz="0 1 0"/>', i)
    text = text[:j] + '<axis xyz="1 0 0"/>' + text[j + len('<axis xyz="0 1 0"/>'):]
    with pytest.raises(MachineError, match="'EYY'.*axis must be"):
        machine_from_urdf(text, "m.urdf")


def test_error_code_for_unknown_axis():
    text = _urdf().replace('"EC0Y"', '"EC0Q"')
    with pytest.raises(MachineError, match="'EC0Q'.*not a motion axis"):
        machine_from_urdf(text, "m.urdf")


def test_malformed_error_name():
    text = _urdf().replace('"EXY"', '"EQY"')
    with pytest.raises(MachineError, match="'EQY'.*ISO 230-1 error code"):
        machine_from_urdf(text, "m.urdf")


def test_pdge_not_after_its_axis():
    # X's position-dependent errors named as Y's: they sit after X, not after Y
    work = [Axis("Y", "prismatic", (0, 1, 0), pdge=False), setup("W")]
    tool = [Axis("X", "prismatic", (1, 0, 0)), setup("T")]
    text = machine_urdf("m", work, tool).replace('"EXX"', '"EXY"')
    with pytest.raises(MachineError, match="'EXY'.*directly after joint 'Y'"):
        machine_from_urdf(text, "m.urdf")


def test_location_error_not_before_its_axis():
    work = [Axis("Y", "prismatic", (0, 1, 0), pdge=False), Axis("U", "prismatic", (1, 0, 0), pdge=False, location_errors=("C",)), setup("W")]
    text = machine_urdf("m", work, [Axis("X", "prismatic", (1, 0, 0), pdge=False), setup("T")]).replace('"EC0U"', '"EC0Y"')
    with pytest.raises(MachineError, match="'EC0Y'.*before joint 'Y'"):
        machine_from_urdf(text, "m.urdf")


def test_setup_joint_not_at_the_end():
    work = [setup("W"), Axis("Y", "prismatic", (0, 1, 0), pdge=False)]
    text = machine_urdf("m", work, [Axis("X", "prismatic", (1, 0, 0), pdge=False), setup("T")])
    with pytest.raises(MachineError, match="set-up joints must sit directly before link 'workpiece'"):
        machine_from_urdf(text, "m.urdf")


def test_unsupported_joint_type():
    text = _urdf().replace('<joint name="Y" type="prismatic">', '<joint name="Y" type="floating">')
    with pytest.raises(MachineError, match="'Y'.*only 1-DOF"):
        machine_from_urdf(text, "m.urdf")
