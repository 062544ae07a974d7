"""One shape for every registry of variants: the controller table formats (:mod:`kinid.axis_tables`), the
kinematics formats (:mod:`kinid.kinematics_formats`) and the effect bases (``kinid.identification.model.bases``).

A :class:`Registry` is a dict of name -> variant that also knows what it holds: ``register`` checks the type and
adds (a variant of the same name is replaced), ``look_up`` gives a variant or one line naming the known ones, and
``defaults`` the names written when none is asked for::

    FORMATS = Registry("controller format", ControllerFormat, parameter="fmt")
    LINUXCNC = FORMATS.register(ControllerFormat(name="linuxcnc", ...))
    FORMATS.look_up("linuxcnc")
"""
from __future__ import annotations

from kinid.errors import DataError

__all__ = ["Registry"]


class Registry(dict):
    """Name -> variant of one kind. ``what`` names the kind in messages, ``kind`` is the variants' class, ``key`` the
    attribute a variant is registered under, ``parameter`` the argument a wrong name is reported against and
    ``variant_parameter`` the one a wrong variant is."""

    def __init__(self, what: str, kind: type, *, key: str = "name", parameter: str = "name",
                 variant_parameter: str = "variant"):
        super().__init__()
        self.what, self.kind, self.key = what, kind, key
        self.parameter, self.variant_parameter = parameter, variant_parameter

    def register(self, variant):
        """Add ``variant`` (replacing one of the same name) and return it."""
        if not isinstance(variant, self.kind):
            raise DataError(f"must be a {self.kind.__name__}, got {type(variant).__name__}",
                            parameter=self.variant_parameter)
        self[getattr(variant, self.key)] = variant
        return variant

    def look_up(self, name):
        """The variant registered as ``name`` (or ``name`` itself when it is a variant)."""
        if isinstance(name, self.kind):
            return name
        if name not in self:
            raise DataError(f"unknown {self.what} {name!r}; known: {', '.join(sorted(self))}",
                            parameter=self.parameter)
        return self[name]

    def defaults(self) -> tuple:
        """Names of the variants whose ``default`` is true, sorted: those used when none is asked for."""
        return tuple(sorted(n for n, v in self.items() if getattr(v, "default", False)))
