"""kinid: identify and compensate the kinematic errors of machine tools and precision stages
from vision measurements.

The package has one ground floor and three domains:

- ``kinid.errors``, ``kinid.files``, ``kinid.figures``, ``kinid.progress``, ``kinid.checks``,
  ``kinid.threads`` — the ground floor that every domain may use;
- :mod:`kinid.identification` — machines (URDF with ISO 230-1 error joints), fit, diagnosis;
- :mod:`kinid.vision` — renderers and locators (ring-coded marks, circles, templates, camera);
- :mod:`kinid.stages` — backlash, UVW stage, dual parallel axes, planar contour;
- :mod:`kinid.urdf` — the machines shipped with kinid;
- :mod:`kinid.cli` — the ``kinid`` command line.

Importing ``kinid`` imports nothing heavy; import the domain you need.
"""
from __future__ import annotations

from importlib import metadata as _metadata

from .errors import DataError, ImageError, KinidError, MachineError, StageError

try:
    __version__ = _metadata.version("kinid")
except _metadata.PackageNotFoundError:  # pragma: no cover - running from a source tree that is not installed
    __version__ = "0+unknown"

__all__ = ["__version__", "KinidError", "MachineError", "DataError", "ImageError", "StageError"]
