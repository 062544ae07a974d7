"""Front doors of kinid's packages that import their modules on first use of a name (PEP 562).

A package (``kinid.identification``, ``kinid.vision``, the stage packages) lists each public name with
the module of the package that defines it and calls :func:`front_door`; importing the package (for
instance to build ``kinid VERB --help``) then imports neither NumPy nor Pinocchio, and
``from kinid.stages.uvw import calibrate`` imports :mod:`kinid.stages.uvw.calibrate` when it runs. Where a module and the public name it defines share a
name (``calibrate``), the package's attribute stays the function after the module loads, as it was
when the package imported its modules eagerly.
"""
from __future__ import annotations

import importlib
import importlib.util
import sys
import types

__all__ = ["front_door"]


class _FrontDoor(types.ModuleType):
    """A package whose public names are not replaced by the modules of the same name when these load."""

    def __setattr__(self, name, value):
        sources = self.__dict__.get("_SOURCES", {})
        if (sources.get(name) == name and isinstance(value, types.ModuleType)
                and value.__name__ == f"{self.__name__}.{name}"):
            return
        super().__setattr__(name, value)


def front_door(package: str, sources: dict):
    """Make ``package`` (already in :data:`sys.modules`) load ``sources`` (name -> module) on first use.

    Returns the package's ``__getattr__`` and ``__dir__``, to bind at its module level. A name of
    ``sources`` comes from its module; any other name that is a module of the package is that module;
    anything else is an :class:`AttributeError`.
    """
    module = sys.modules[package]
    module._SOURCES = dict(sources)

    def __getattr__(name: str):
        if name in sources:
            # not kept on the package: the name is the module's at every use (a test that replaces a
            # function in its module replaces it for every caller that imports it through the door)
            return getattr(importlib.import_module(f"{package}.{sources[name]}"), name)
        if not name.startswith("__") and importlib.util.find_spec(f"{package}.{name}") is not None:
            value = importlib.import_module(f"{package}.{name}")
        else:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        setattr(module, name, value)
        return value

    def __dir__():
        return sorted(set(module.__dict__) | set(getattr(module, "__all__", ())))

    module.__class__ = _FrontDoor
    return __getattr__, __dir__
