"""What hardware must provide to plug into a stage method.

A real machine and a simulated one are interchangeable: each stage method
talks to its hardware only through one of these protocols, an object with a
few methods (``typing.Protocol``, checked structurally — no base class to
inherit). The simulated stages of kinid implement them; so must a driver of
real hardware. Units: mm, deg and µm as the method names say; images are 2-D
arrays (8- or 16-bit grey), pixel (0, 0) at the top left, x right, y down.
"""
from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

__all__ = ["CameraStage", "DualAxisGantry", "ActuatorStage"]


@runtime_checkable
class CameraStage(Protocol):
    """An X-Y-θ stage under a fixed camera that looks down on one round fiducial on the stage.

    Used by :func:`kinid.stages.backlash.calibrate`. An optional ``position``
    attribute giving the commanded ``(x_mm, y_mm, theta_deg)`` centres the
    plan on where the stage stands.
    """

    def move_to(self, x_mm: float, y_mm: float, theta_deg: float) -> None:
        """Move to the absolute commanded position and wait until settled."""

    def grab(self) -> np.ndarray:
        """One camera image, a 2-D array."""


@runtime_checkable
class DualAxisGantry(Protocol):
    """A gantry whose camera rides one Y axis and looks at a plate on the head of a parallel Y axis.

    Used by :func:`kinid.stages.dual_axis.calibrate`.
    """

    def move(self, cam_y_mm: float, head_x_mm: float, head_y_mm: float) -> None:
        """Move the camera Y axis and the head (X, and Y on the head's own axis) to absolute positions."""

    def grab(self) -> np.ndarray:
        """One image of the camera on the camera Y axis, a 2-D array."""


@runtime_checkable
class ActuatorStage(Protocol):
    """A UVW alignment stage whose actuators ``"X1"``, ``"X2"``, ``"Y"`` are driven one at a time.

    Used by :func:`kinid.stages.uvw.calibrate`.
    """

    def move(self, actuator: str, target_um: float) -> float:
        """Drive ``actuator`` to the commanded position (µm from home); return the position the vision system measured, µm."""
