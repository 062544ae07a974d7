"""A stage seen through a backlash compensation: each command moved by half the backlash against its direction.

With lost motion B the axis stops B/2 short of the mean when it arrives moving + and B/2 past it when
it arrives moving − (error = actual − commanded: −B/2 forward, +B/2 reverse, the tables of
``kinid backlash --tables``). Commanding ``c + B/2`` moving + and ``c − B/2`` moving − brings both to the
same place: what a controller's bidirectional compensation does.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CompensatedStage"]


class CompensatedStage:
    """Wrap a stage (``move_to``, ``grab``): commands corrected by the measured X, Y and θ backlash.

    Parameters
    ----------
    stage : object
        With ``move_to(x_mm, y_mm, theta_deg)`` and ``grab()``.
    backlash : (float, float, float)
        X mm, Y mm, θ degrees.
    """

    def __init__(self, stage, backlash):
        self.stage = stage
        self.backlash = np.asarray(backlash, float)
        self._last = None
        self._direction = np.ones(3)

    @property
    def position(self):
        pos = getattr(self.stage, "position", None)
        return pos() if callable(pos) else pos

    def move_to(self, x_mm, y_mm, theta_deg) -> None:
        cmd = np.array([x_mm, y_mm, theta_deg], float)
        if self._last is not None:
            step = cmd - self._last
            self._direction = np.where(step > 0, 1.0, np.where(step < 0, -1.0, self._direction))
        self._last = cmd
        self.stage.move_to(*(cmd + 0.5 * self.backlash * self._direction))

    def grab(self):
        return self.stage.grab()
