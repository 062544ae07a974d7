"""kinid: identify and compensate the kinematic errors of machine tools and precision stages
from vision measurements.

The package has one ground floor and three domains:

- ``kinid.errors``, ``kinid.files``, ``kinid.reports.figures``, ``kinid.progress``, ``kinid.checks``,
  ``kinid.threads`` — the ground floor that every domain may use;
- :mod:`kinid.identification` — machines (URDF with ISO 230-1 error joints), fit, diagnosis;
- :mod:`kinid.vision` — renderers and locators (ring-coded marks, circles, templates, camera);
- :mod:`kinid.stages` — backlash, UVW stage, dual parallel axes, planar contour;
- :mod:`kinid.urdf` — the machines shipped with kinid;
- :mod:`kinid.cli` — the ``kinid`` command line.

Importing ``kinid`` imports nothing heavy; import the domain you need.
"""
from __future__ import annotations

from .errors import DataError, ImageError, KinidError, MachineError, StageError

__all__ = ["__version__", "KinidError", "MachineError", "DataError", "ImageError", "StageError"]


def __getattr__(name: str):
    # ``__version__`` is read from the installed distribution on first use: importlib.metadata costs
    # about as much as the rest of ``kinid --help``
    if name == "__version__":
        from importlib import metadata

        try:
            version = metadata.version("kinid")
        except metadata.PackageNotFoundError:  # pragma: no cover - a source tree that is not installed
            version = "0+unknown"
        globals()["__version__"] = version
        return version
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
