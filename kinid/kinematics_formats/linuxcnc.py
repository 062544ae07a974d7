"""LinuxCNC trunnion kinematics (``xyzac-trt-kins``, ``xyzbc-trt-kins``): the HAL parameters as ``setp`` lines.

The trunnion kinematics, as its source states: a tilting table (A about x, or B about y) carrying a
rotary table C about z. Its parameters, machine units (mm): ``x-rot-point``, ``y-rot-point``,
``z-rot-point`` a point of the C axis; ``y-offset``/``z-offset`` (xyzac) or ``x-offset``/``z-offset``
(xyzbc) from that point to the tilting axis; ``tool-offset`` the tool length (connected to
``motion.tooloffset.z``). Forward, for xyzbc, with ``r`` the rot point, ``d`` the offsets and ``J`` the
joints: ``pos = r + Rz(−c)·(d + Ry(−b)·(J − r − d))`` — the table turns right-handed about +y and +z for
+ readings.

The trunnion kinematics has no parameter for an axis that is not parallel to x/y or z: such a tilt is
named as left out (one line), and the file holds the pivot points where the axes cross the tilting
axis's height. A layout that is not two table axes in that order (a head, one axis) is not written.
"""
from __future__ import annotations

import math

from .formats import KinematicsFit, KinematicsFormat, check_geometry, number, register_kinematics_format

__all__ = ["trt_parameters", "linuxcnc_trt_text"]

#: Tilting axis direction -> (kinematics module, its offset letters, the axis letter).
_TILTING = {0: ("xyzac-trt-kins", ("y", "z"), "A"), 1: ("xyzbc-trt-kins", ("x", "z"), "B")}
#: A direction is taken for a machine axis where it departs from it by less than this, rad.
_ALIGNED_RAD = 0.01
#: A direction's departure below this is not named (the files' axis vectors hold 9 decimals: 0.001 µrad), µrad.
TILT_RESOLUTION_URAD = 1e-3


def _aligned(direction) -> int | None:
    """The machine axis (0, 1, 2) ``direction`` points along (+), or None."""
    for k in range(3):
        if direction[k] > 1.0 - _ALIGNED_RAD ** 2 / 2:
            return k
    return None


def _layout(g):
    """(tilting axis index 0/1, why not) of a geometry."""
    if g.kind != "table-table":
        return None, f"trunnion kinematics hold two table axes (a tilting table carrying a C table); {g.machine} is " \
                     f"{g.kind}"
    first, second = (_aligned(a.nominal_direction) for a in g.axes)
    if first not in _TILTING or second != 2:
        return None, (f"trunnion kinematics turn the tilting table about +x or +y and the rotary table about +z for "
                      f"+ readings; {g.axes[0].name} and {g.axes[1].name} of {g.machine} do not")
    return first, None


def trt_parameters(geometry) -> dict:
    """The HAL parameters of the trunnion kinematics for ``geometry`` (mm), with ``module`` and ``left_out``.

    The C axis's point at the tilting axis's height is the rot point; the offsets go from it to the tilting
    axis (where its line crosses the plane through the rot point normal to the tilting axis).
    """
    g = check_geometry(geometry)
    tilt, why = _layout(g)
    if why:
        raise ValueError(why)
    a, c = g.axes
    module, offsets, letter = _TILTING[tilt]
    # C's line at the height of the tilting axis's line
    h = a.pivot_mm[2]
    t = (h - c.pivot_mm[2]) / c.direction[2]
    r = tuple(c.pivot_mm[k] + t * c.direction[k] for k in range(3))
    # the tilting axis's line where it crosses the plane through r normal to it
    s = (r[tilt] - a.pivot_mm[tilt]) / a.direction[tilt]
    p = tuple(a.pivot_mm[k] + s * a.direction[k] for k in range(3))
    d = {"x": p[0] - r[0], "y": p[1] - r[1], "z": p[2] - r[2]}
    out = {"module": module, "tilting": letter, "x-rot-point": r[0], "y-rot-point": r[1], "z-rot-point": r[2]}
    out.update({f"{k}-offset": d[k] for k in offsets})
    out["tool-offset"] = 0.0
    left = []
    for axis, along in ((a, tilt), (c, 2)):
        off_urad = 1e6 * math.asin(min(1.0, math.hypot(*(axis.direction[k] for k in range(3) if k != along))))
        if off_urad >= TILT_RESOLUTION_URAD:
            left.append(f"{axis.name}'s direction departs from {'xyz'[along]} by {off_urad:.3g} µrad: trunnion "
                        f"kinematics have no parameter for it (written along {'xyz'[along]})")
    out["left_out"] = tuple(left)
    return out


def linuxcnc_trt_text(geometry, comment: str = "") -> str:
    """``setp`` lines of the trunnion kinematics' HAL parameters for ``geometry``."""
    p = trt_parameters(geometry)
    m = p["module"]
    lines = [f"# {comment}"] if comment else []
    lines += [f"# {m} for {geometry.machine}: load it with 'loadrt {m}' in place of trivkins; mm, the machine "
              f"frame with every axis at 0, its origin at the tool point",
              f"# axes: {geometry.mapping_words()}; {geometry.axes[0].name} -> {p['tilting']}, "
              f"{geometry.axes[1].name} -> C",
              "# tool-offset: the tool's length, usually 'net tooloffset motion.tooloffset.z => "
              f"{m}.tool-offset' (0 here: kinid's tool point)"]
    lines += [f"# left out: {line}" for line in p["left_out"]]
    for key in ("x-rot-point", "y-rot-point", "z-rot-point", "x-offset", "y-offset", "z-offset"):
        if key in p:
            lines.append(f"setp {m}.{key} {number(p[key], 6)}")
    return "\n".join(lines) + "\n"


def _fit(geometry) -> KinematicsFit:
    g = check_geometry(geometry)
    _, why = _layout(g)
    if why:
        return KinematicsFit(False, (why,))
    return KinematicsFit(True, trt_parameters(g)["left_out"])


LINUXCNC_TRT = register_kinematics_format(KinematicsFormat(
    name="linuxcnc", title="LinuxCNC trunnion kinematics (xyzac-trt-kins / xyzbc-trt-kins HAL parameters)",
    file_name="trt-kins.hal", fit=_fit, write=linuxcnc_trt_text))
