"""Stage models, simulators and calibration routines, one sub-package per method.

- :mod:`stages.backlash` — lead-screw backlash of an X-Y-θ stage from images (seed 000)
- :mod:`stages.uvw` — UVW alignment stage compensation (seed 001)
- :mod:`stages.dual_axis` — offset table between two parallel Y axes (seed 003)
- :mod:`stages.contour` — planar contour error from image sequences (seed 002)

Each sub-package keeps its own ``calibrate``; import it from there
(``from kinid.stages.uvw import calibrate``). Hardware protocols: INTERFACES.md §5.
"""
__all__ = ["backlash", "uvw", "dual_axis", "contour"]
