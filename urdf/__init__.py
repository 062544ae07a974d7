"""Machine descriptions shipped with kinid (URDF with ISO 230-1 error joints).

The files follow docs/machines.md. Use :func:`path` to get one by name::

    >>> from kinid.urdf import path
    >>> path("five_axis_bc").name
    'five_axis_bc.urdf'
"""
from __future__ import annotations

from pathlib import Path

__all__ = ["path", "names"]

_HERE = Path(__file__).resolve().parent


def names() -> list[str]:
    """Names (without ``.urdf``) of the machines shipped with kinid."""
    return sorted(p.stem for p in _HERE.glob("*.urdf"))


def path(name: str) -> Path:
    """Path of the shipped machine ``name`` (``"five_axis_bc"`` or ``"five_axis_bc.urdf"``)."""
    stem = name[:-5] if name.endswith(".urdf") else name
    p = _HERE / f"{stem}.urdf"
    if not p.is_file():
        raise FileNotFoundError(f"no shipped machine {name!r}; shipped: {', '.join(names())}")
    return p
