"""Stage models, simulators and calibration routines, one sub-package per method.

- :mod:`stages.backlash` — lead-screw backlash of an X-Y-θ stage from images
- :mod:`stages.uvw` — UVW alignment stage compensation
- :mod:`stages.dual_axis` — offset table between two parallel Y axes
- :mod:`stages.contour` — planar contour error from image sequences

Each sub-package keeps its own ``calibrate``; import it from there
(``from kinid.stages.uvw import calibrate``). Hardware protocols: :mod:`kinid.stages.protocols`, docs/hardware.md.
"""
__all__ = ["backlash", "uvw", "dual_axis", "contour", "protocols"]


def __getattr__(name: str):
    """The sub-packages and modules, imported on first use (``kinid.stages.uvw`` after ``import kinid.stages``)."""
    import importlib
    import importlib.util

    if not name.startswith("__") and importlib.util.find_spec(f"{__name__}.{name}") is not None:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
