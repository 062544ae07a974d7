"""URDFs keep their joint names: ROS-style motion joints get short axis names, error joints are exact codes."""
from __future__ import annotations

import re

import numpy as np
import pytest

from kinid.errors import MachineError
from kinid.identification.model.machine import evaluate, machine_from_urdf
from kinid.identification.model.urdf_builder import Axis, Fixed, machine_urdf, setup

ROS = {"J1": "shoulder_pan_joint", "J2": "shoulder_lift_joint", "J3": "elbow_joint"}


def _arm_text():
    work = [Fixed("table", (0.45, 0.0, 0.0)), setup("W")]
    tool = [Axis("J1", "revolute", (0, 0, 1), location_errors=("X", "Y"), pdge=False, limit=(-3, 3)),
            Fixed("shoulder", (0, 0, 0.3)),
            Axis("J2", "revolute", (0, 1, 0), location_errors=("X", "Z", "B"), limit=(-3, 3)),
            Fixed("upper_arm", (0.35, 0, 0)),
            Axis("J3", "revolute", (0, 1, 0), location_errors=("Z", "B"), pdge=False, limit=(-3, 3)),
            Fixed("forearm", (0.3, 0, 0)), setup("T")]
    return machine_urdf("arm3", work, tool, "three-joint arm")


def _rename_motion_joints(text, names):
    for short, long in names.items():
        text = text.replace(f'<joint name="{short}"', f'<joint name="{long}"')
    return text


def test_ros_joint_names_get_short_axis_names():
    plain = machine_from_urdf(_arm_text(), "arm.urdf")
    ros = machine_from_urdf(_rename_motion_joints(_arm_text(), ROS), "arm_ros.urdf")
    assert [a.name for a in ros.axes] == ["J1", "J2", "J3"]
    assert [a.joint for a in ros.axes] == list(ROS.values())
    assert [a.column for a in ros.axes] == ["j1_deg", "j2_deg", "j3_deg"]
    assert ros.error_codes == plain.error_codes and "EB0J2" in ros.error_codes and "EBJ2" in ros.error_codes
    rng = np.random.default_rng(0)
    axes = rng.uniform(-60, 60, (5, 3))
    errors = rng.normal(0, 50, len(plain.error_joints))
    np.testing.assert_allclose(evaluate(ros, axes, errors)[0], evaluate(plain, axes, errors)[0], atol=1e-12)


def test_names_given_in_the_urdf():
    text = _rename_motion_joints(_arm_text(), ROS)
    text = re.sub(r'"E([XYZABC])0J3"', r'"E\g<1>0ELB"', text)
    text = text.replace("</robot>", '<kinid><axis joint="elbow_joint" name="ELB"/></kinid>\n</robot>')
    m = machine_from_urdf(text, "arm.urdf")
    assert [a.name for a in m.axes] == ["J1", "J2", "ELB"]
    assert "EB0ELB" in m.error_codes and m.axis("ELB").column == "elb_deg"


def test_elbow_is_a_motion_axis_not_a_bad_error_code():
    text = _arm_text().replace('<joint name="J3"', '<joint name="ELBOW"')
    text = re.sub(r'"E([XYZABC])0J3"', r'"E\g<1>0ELBOW"', text)
    m = machine_from_urdf(text, "arm.urdf")
    assert m.axis("ELBOW").column == "elbow_deg"


@pytest.mark.parametrize("change, message", [
    (lambda t: t.replace('"EB0J2"', '"EQ0J2"'), "looks like an error joint of axis J2"),
    (lambda t: t.replace("</robot>", '<kinid><axis joint="nope" name="J9"/></kinid></robot>'), "no motion joint of that name"),
    (lambda t: t.replace("</robot>", '<kinid><axis joint="shoulder_pan_joint" name="EXX"/></kinid></robot>'), "not an error code"),
    (lambda t: t.replace("</robot>", '<kinid><axis joint="shoulder_pan_joint" name="J2"/></kinid></robot>'), "both get the axis name 'J2'"),
])
def test_naming_mistakes_are_named(change, message):
    with pytest.raises(MachineError, match=re.escape(message)):
        machine_from_urdf(change(_rename_motion_joints(_arm_text(), ROS)), "arm.urdf")
