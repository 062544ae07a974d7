"""Direction tracking shared by the UVW compensators (docs/hardware.md).

A compensator turns a target position of an actuator (µm from home) into the
command that brings the table there. Backlash makes the answer depend on the
approach direction, so the compensator remembers, per actuator, the last
command it gave and the direction of that move, and assumes every command it
returns is sent to the stage.
"""
from __future__ import annotations

import math

from kinid.errors import StageError

from .kinematics import ACTUATORS, check_actuator

__all__ = ["DirectionTrackingCompensator"]


class DirectionTrackingCompensator:
    """Base class: subclasses define ``_command_for(actuator, target_um, direction)``.

    ``_command_for`` returns the command that puts the table at ``target_um``
    when the actuator arrives moving in ``direction`` (+1 forward, −1
    reverse). It must be increasing in ``target_um``.

    The state starts at home: last command 0, approached forward (as after
    homing).
    """

    def __init__(self, actuators=ACTUATORS):
        self._actuators = tuple(actuators)
        self._state = {}
        self.reset()

    def reset(self, actuator=None, *, command_um: float = 0.0, target_um: float = 0.0, direction: int = 1) -> None:
        """Tell the compensator where an actuator is (all actuators if ``actuator`` is None).

        Parameters
        ----------
        actuator : str or None
            ``"X1"``, ``"X2"``, ``"Y"`` or None for all.
        command_um : float
            The last command sent to the actuator, µm.
        target_um : float
            The position that command was meant to reach, µm.
        direction : int
            +1 if the actuator last moved forward, −1 if in reverse.
        """
        if direction not in (1, -1):
            raise StageError(f"direction must be +1 or -1, got {direction!r}")
        names = self._actuators if actuator is None else (self._check(actuator),)
        for name in names:
            self._state[name] = (float(command_um), float(target_um), int(direction))

    def state(self, actuator: str):
        """``(last_command_um, last_target_um, last_direction)`` of ``actuator``."""
        return self._state[self._check(actuator)]

    def command(self, actuator: str, target_um: float) -> float:
        """Command that brings ``actuator`` to ``target_um``.

        The approach direction is chosen from the current state: moving on in
        the last direction if the target lies ahead, reversing (and taking up
        the backlash) otherwise. The state is updated as if the command were
        sent.

        Parameters
        ----------
        actuator : str
            ``"X1"``, ``"X2"`` or ``"Y"``.
        target_um : float
            Wanted table position of the actuator, µm from home.

        Returns
        -------
        float
            Position to command, µm from home.

        Raises
        ------
        StageError
            Unknown or uncalibrated actuator, or a target that is not a finite number.
        """
        self._check(actuator)
        try:
            target = float(target_um)
        except (TypeError, ValueError):
            raise StageError(f"target_um for {actuator} must be a number, got {target_um!r}") from None
        if not math.isfinite(target):
            raise StageError(f"target_um for {actuator} must be finite, got {target_um!r}")
        last_cmd, last_target, last_dir = self._state[actuator]
        if target == last_target:
            return last_cmd
        ahead = self._command_for(actuator, target, last_dir)
        if (ahead - last_cmd) * last_dir >= 0:
            cmd, direction = ahead, last_dir
        else:
            cmd, direction = self._command_for(actuator, target, -last_dir), -last_dir
        self._state[actuator] = (float(cmd), target, direction)
        return float(cmd)

    def _check(self, actuator):
        check_actuator(actuator)
        if actuator not in self._actuators:
            raise StageError(f"actuator {actuator!r} was not calibrated; calibrated: {list(self._actuators)}")
        return actuator

    def _command_for(self, actuator, target_um, direction):  # pragma: no cover - abstract
        raise NotImplementedError
