"""The kinematics formats' registry: the rotary axes' geometry as a controller's kinematics description.

Beside the axis tables' formats (:mod:`kinid.axis_tables.formats`), which hold one axis's positioning
error, a kinematics format holds where the rotary axes turn: their pivot points and directions
(:class:`~kinid.kinematics_formats.geometry.RotaryGeometry`). A format is a
:class:`KinematicsFormat` with one interface — a name, the file it writes, what of a geometry it cannot
hold, and ``write(geometry) -> text``; a new one is one :func:`register_kinematics_format` call, and
``kinid compensate`` takes it from the registry.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..errors import DataError
from ..registry import Registry
from .geometry import RotaryGeometry

__all__ = ["KinematicsFormat", "KinematicsFit", "KINEMATICS_FORMATS", "register_kinematics_format",
           "kinematics_format", "default_kinematics_formats", "number"]


@dataclass(frozen=True)
class KinematicsFit:
    """What a format can hold of one geometry.

    Attributes
    ----------
    writable : bool
        False where the format has no layout for the machine (then no file is written).
    notes : tuple of str
        One line each: why it is not writable, or what the file leaves out (a tilt it has no parameter for).
    """

    writable: bool
    notes: tuple = ()


@dataclass(frozen=True)
class KinematicsFormat:
    """One controller's kinematics description.

    Attributes
    ----------
    name : str
        Registry key and ``--kinematics-format`` value.
    title : str
        What the file is, in the controller's words.
    file_name : str
        The file written into the compensation folder.
    fit : callable (RotaryGeometry) -> KinematicsFit
        Whether the format has a layout for the geometry, and what it leaves out.
    write : callable (RotaryGeometry, comment: str) -> str
        The file's text; called only where ``fit`` says writable.
    default : bool
        Written by ``kinid compensate`` when no ``--kinematics-format`` is given (where it applies).
    """

    name: str
    title: str
    file_name: str
    fit: Callable
    write: Callable
    default: bool = True


#: Kinematics format name -> :class:`KinematicsFormat`.
KINEMATICS_FORMATS = Registry("kinematics format", KinematicsFormat, parameter="kinematics_format",
                              variant_parameter="fmt")


def register_kinematics_format(fmt: KinematicsFormat) -> KinematicsFormat:
    """Add ``fmt`` to :data:`KINEMATICS_FORMATS` (replacing one of the same name) and return it."""
    return KINEMATICS_FORMATS.register(fmt)


def kinematics_format(name) -> KinematicsFormat:
    """The registered format ``name`` (or ``name`` itself when it is a :class:`KinematicsFormat`)."""
    return KINEMATICS_FORMATS.look_up(name)


def default_kinematics_formats() -> tuple:
    """Names of the formats written when none is asked for."""
    return KINEMATICS_FORMATS.defaults()


def check_geometry(geometry) -> RotaryGeometry:
    if not isinstance(geometry, RotaryGeometry):
        raise DataError(f"must be a RotaryGeometry, got {type(geometry).__name__}", parameter="geometry")
    return geometry


def number(x: float, digits: int = 6) -> str:
    """``x`` with ``digits`` decimals, trailing zeros dropped (``-0`` as ``0``)."""
    s = f"{x:.{digits}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s
