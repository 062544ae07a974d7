"""Two parallel Y axes of a gantry (the dual-axis method): offset table, smooth model, simulated gantry.

The camera rides on one Y axis, the placement head on a second one (V) with
its own X axis. :func:`calibrate` steps both Y axes together, images a plate
on the head and builds the patent's piecewise-linear offset table of camera
Y (:class:`OffsetTable`, whose ``head_move(ps_mm, pe_mm)`` is the head move
for a camera-Y move, docs/hardware.md); :func:`fit_smooth` fits a parallelism
angle plus straightness polynomial instead. :class:`SimulatedGantry` is
``urdf/gantry_dual_y.urdf`` with error values set.
"""
from kinid.lazy import front_door as _front_door

#: Each public name and the module of this package that defines it, imported on first use of the name
#: (SimulatedGantry needs Pinocchio).
_SOURCES = {"calibrate": "calibrate", "verify": "calibrate", "SimulatedGantry": "simulate",
            "SmoothModel": "smooth", "fit_smooth": "smooth", "OffsetTable": "table"}

__all__ = ["calibrate", "verify", "OffsetTable", "fit_smooth", "SmoothModel", "SimulatedGantry"]

__getattr__, __dir__ = _front_door(__name__, _SOURCES)
