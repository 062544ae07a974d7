"""Argument checks at the public entry points; every message names the argument.

Each check returns the value converted (a float, an int, an array) or raises
:class:`~kinid.errors.DataError` with ``parameter`` set to the argument's
name, so the message reads "noise_um must be positive, got -1" in Python and
"--noise-um must be positive, got -1" on the command line (the ``kinid`` roof
maps argument names to option names in one place).

Examples
--------
>>> check_positive("noise_um", 1)
1.0
>>> check_positive("noise_um", -1)
Traceback (most recent call last):
...
kinid.errors.DataError: noise_um must be a positive number, got -1
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from .errors import DataError

__all__ = ["check_number", "check_positive", "check_plausible", "PLAUSIBLE", "check_nonnegative", "check_int", "check_array", "check_choice",
           "check_image", "check_instance", "check_methods"]


def check_number(name: str, value, *, error=DataError) -> float:
    """``value`` as a finite float."""
    if isinstance(value, bool) or not isinstance(value, (numbers.Real, np.floating, np.integer)):
        raise error(f"must be a number, got {value!r} ({type(value).__name__})", parameter=name)
    v = float(value)
    if not math.isfinite(v):
        raise error(f"must be a finite number, got {value!r}", parameter=name)
    return v


def check_positive(name: str, value, *, error=DataError) -> float:
    """``value`` as a finite float > 0."""
    v = float(value) if _is_number(value) else math.nan
    if not (math.isfinite(v) and v > 0):
        raise error(f"must be a positive number, got {value!r}", parameter=name)
    return v


#: Plausible bounds (least, most) of a quantity that enters at the door, by kind and unit: wide enough for any
#: machine, sensor or run, narrow enough that nothing computed from it over- or underflows (a σ of 1e-300 µm
#: divides to infinity, one of 1e300 mm squares to it, an alignment of 1e308 s sums to infinity).
PLAUSIBLE = {
    "sigma_um": (1e-4, 1e5),       # σ of a reading: 0.1 nm .. 100 mm
    "sigma_mm": (1e-7, 100.0),
    "size_mm": (1e-4, 1e5),        # a stand-off, a radius, a target: 0.1 µm .. 100 m
    "size_um": (1e-4, 1e8),
    "step_mm": (1e-3, 1e4),        # a table's grid step: 1 µm .. 10 m
    "step_deg": (1e-4, 360.0),
    "speed_mm_s": (1e-3, 1e6),
    "accel_mm_s2": (1e-3, 1e8),
    "speed_deg_s": (1e-3, 1e6),
    "accel_deg_s2": (1e-3, 1e8),
    "time_s": (0.0, 1e6),          # a settling or alignment time: up to 11 days
}


def check_plausible(name: str, value, kind: str, *, error=DataError) -> float:
    """``value`` as a float within the plausible bounds :data:`PLAUSIBLE` of ``kind`` (``"sigma_um"``, ...).

    >>> check_plausible("noise_um", 1e-300, "sigma_um")
    Traceback (most recent call last):
    ...
    kinid.errors.DataError: noise_um must be a number in [0.0001, 100000] (σ in µm), got 1e-300
    """
    low, high = PLAUSIBLE[kind]
    v = float(value) if _is_number(value) else math.nan
    if not (math.isfinite(v) and low <= v <= high):
        what, _, unit = kind.partition("_")
        unit = {"um": "µm", "mm_s": "mm/s", "mm_s2": "mm/s²", "deg_s": "°/s", "deg_s2": "°/s²", "deg": "°"}.get(unit, unit)
        what = "σ" if what == "sigma" else what
        raise error(f"must be a number in [{low:g}, {high:g}] ({what} in {unit}), got {value!r}", parameter=name)
    return v


def check_nonnegative(name: str, value, *, error=DataError) -> float:
    """``value`` as a finite float >= 0."""
    v = float(value) if _is_number(value) else math.nan
    if not (math.isfinite(v) and v >= 0):
        raise error(f"must be a number >= 0, got {value!r}", parameter=name)
    return v


def check_int(name: str, value, *, minimum: int | None = None, maximum: int | None = None, error=DataError) -> int:
    """``value`` as an int within [minimum, maximum]."""
    if minimum is not None and maximum is not None:
        wanted = f"an integer in {minimum}..{maximum}"
    elif minimum is not None:
        wanted = f"an integer >= {minimum}"
    elif maximum is not None:
        wanted = f"an integer <= {maximum}"
    else:
        wanted = "an integer"
    integral = not isinstance(value, bool) and isinstance(value, (numbers.Integral, np.integer))
    if not integral or (minimum is not None and value < minimum) or (maximum is not None and value > maximum):
        raise error(f"must be {wanted}, got {value!r}", parameter=name)
    return int(value)


def check_array(name: str, value, *, shape: tuple | None = None, finite: bool = True, dtype=float,
                error=DataError) -> np.ndarray:
    """``value`` as an array of ``dtype``; ``shape`` entries of None match any length.

    ``check_array("axes", a, shape=(None, 5))`` accepts an (N, 5) array.
    """
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise error(f"must be an array of numbers, got {type(value).__name__}", parameter=name) from None
    if shape is not None:
        ok = arr.ndim == len(shape) and all(s is None or s == n for s, n in zip(shape, arr.shape))
        if not ok:
            want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ")"
            raise error(f"must have shape {want}, got {arr.shape}", parameter=name)
    if finite and arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        where = ", ".join(map(str, bad)) if arr.ndim else ""
        raise error(f"must be finite; element [{where}] is {arr[tuple(bad)]}", parameter=name)
    return arr


def check_choice(name: str, value, choices, *, error=DataError):
    """``value`` if it is one of ``choices``."""
    if value not in choices:
        raise error(f"must be one of {', '.join(map(repr, choices))}, got {value!r}", parameter=name)
    return value


def check_image(name: str, value, *, error=DataError) -> np.ndarray:
    """``value`` as an image array: 2-D (grey) or 3-D with 1, 3 or 4 channels, real numbers, not empty.

    A file name is refused with the hint to read it first (kinid.files.read_image).
    """
    if isinstance(value, (str, bytes)) or hasattr(value, "__fspath__"):
        raise error(f"must be an image array, got a path {str(value)!r}; read it with kinid.files.read_image(path)",
                    parameter=name)
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        arr = np.asarray(None)
    if arr.dtype.kind not in "uif" or not (arr.ndim == 2 or (arr.ndim == 3 and arr.shape[2] in (1, 3, 4))):
        raise error(f"must be a 2-D grey image or an (H, W, 3) colour image of numbers, got "
                    f"{type(value).__name__} with shape {getattr(arr, 'shape', ())}", parameter=name)
    if arr.size == 0:
        raise error("must not be empty", parameter=name)
    if arr.dtype.kind == "f" and not np.all(np.isfinite(arr)):
        raise error("must hold finite numbers (found NaN or infinity)", parameter=name)
    return arr


def check_instance(name: str, value, kind, *, hint: str = "", error=DataError):
    """``value`` if it is an instance of ``kind`` (a class or tuple of classes)."""
    if not isinstance(value, kind):
        want = kind.__name__ if isinstance(kind, type) else " or ".join(k.__name__ for k in kind)
        raise error(f"must be a {want}{' (' + hint + ')' if hint else ''}, got {type(value).__name__}", parameter=name)
    return value


def check_methods(name: str, value, methods, *, error=DataError):
    """``value`` if it has every method in ``methods`` (a hardware protocol, docs/hardware.md)."""
    missing = [m for m in methods if not callable(getattr(value, m, None))]
    if missing:
        raise error(f"must have the method(s) {', '.join(m + '()' for m in missing)} (docs/hardware.md), got "
                    f"{type(value).__name__}", parameter=name)
    return value


def _is_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (numbers.Real, np.floating, np.integer))
