"""Where the laser sits beside the camera, from the method's set-up measurements (``kinid sensor``): the
readings of a hole or sphere measurement become tool-point positions on the nominal machine, so the sign and the
axes' directions come from the URDF, and the vision locators give the offset (docs/observe.md, "The laser beside
the camera")."""
from __future__ import annotations

import numpy as np

from kinid.errors import DataError
from kinid.vision import radial_offset_from_hole, radial_offset_from_sphere

from ..model import evaluate, tool_rotation_in_workpiece

__all__ = ["laser_offset"]

#: Linear readings of a set-up measurement all within this of zero (mm) look like metres: the camera and the laser
#: on the same feature are millimetres apart, and the feature is rarely within a millimetre of the machine's zero.
METRES_REACH_MM = 1.0


def laser_offset(machine, table, *, method: str, standoff_mm=None, radius_mm=None, sigma_mm=None):
    """(offset (x, y), std (x, y), the locator's result) of the laser in the tool frame, mm.

    ``table`` is an :class:`~kinid.identification.data.axis_columns.AxisTable` with a ``role`` column.
    """
    roles = [r.lower() for r in table.texts("role", "role")]
    linear = [i for i, a in enumerate(machine.axes) if a.kind == "prismatic"]
    reach = float(np.abs(table.axes[:, linear]).max()) if linear and len(table.axes) else 0.0
    if 0.0 < reach < METRES_REACH_MM:
        import warnings

        warnings.warn(f"{table.path}: every linear reading is within ±{reach:.3g} mm of zero, the camera and the laser "
                      f"on one feature included; if the readings are metres, multiply by 1000", stacklevel=2)
    bad = sorted(set(roles) - {"camera", "laser"})
    if bad:
        raise DataError(f"role must be camera or laser, found {bad[0]!r}", path=table.path, column="role")
    zero = np.zeros(len(machine.error_joints))
    points = evaluate(machine, table.axes, zero, jacobian=False)  # tool point in the workpiece frame, mm
    R = tool_rotation_in_workpiece(machine, table.axes, zero)
    tilt = np.abs(R[:, 2, 2])
    if np.any(tilt < 0.999):
        i = int(np.argmin(tilt))
        raise DataError("the tool axis is not the workpiece's z axis at this reading; take the set-up readings with "
                        "the rotary axes at zero", path=table.path, line=table.lines[i])
    cam, las = np.array(roles) == "camera", np.array(roles) == "laser"
    if not cam.any() or not las.any():
        raise DataError("needs camera rows and laser rows", path=table.path, column="role")
    if method == "hole":
        result = radial_offset_from_hole(points[las, :2], points[cam, :2], sigma_mm=sigma_mm)
    else:
        if standoff_mm is None:
            raise DataError("the sphere method needs the laser's stand-off: --standoff-mm or a --base sensor file with "
                            "laser_standoff_mm")
        # the tool point with the laser at its stand-off: the surface lies standoff below the laser along −z,
        # i.e. at the spot's tool-frame depth; radial_offset_from_sphere takes the reading's position
        result = radial_offset_from_sphere(points[las] + np.array([0.0, 0.0, standoff_mm]), standoff_mm,
                                           points[cam, :2], radius_mm=radius_mm, sigma_mm=sigma_mm)
    d = np.array([result.dx_mm, result.dy_mm])
    Rm = R[las].mean(axis=0)[:2, :2]
    offset = Rm.T @ (-d)  # the tool moved by d to bring the laser onto the feature: the spot sits at −d
    cov = Rm.T @ np.asarray(result.covariance_mm2, float)[:2, :2] @ Rm
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return offset, std, result
