"""The exception family of kinid.

Every error a user can cause (a malformed URDF, a bad CSV cell, an image with
no fiducial, a move outside travel) is a :class:`KinidError`. The ``kinid``
command line turns one into a single line on stderr and exit status 2; any
other exception is a bug.
"""
from __future__ import annotations

__all__ = ["KinidError", "MachineError", "DataError", "ImageError", "StageError"]


class KinidError(Exception):
    """Base of all errors caused by user input.

    Parameters
    ----------
    message : str
        What is wrong and, where possible, what was expected and a likely fix.
    path : str or None
        File the problem is in.
    line : int or None
        1-based line number in ``path``.
    column : str or None
        Column name (CSV) or element (URDF) the problem is in.
    """

    def __init__(self, message: str, *, path=None, line=None, column=None):
        self.message = message
        self.path = None if path is None else str(path)
        self.line = line
        self.column = column
        super().__init__(str(self))

    def __str__(self) -> str:
        where = []
        if self.path is not None:
            where.append(self.path if self.line is None else f"{self.path}:{self.line}")
        elif self.line is not None:
            where.append(f"line {self.line}")
        if self.column is not None:
            where.append(f"column {self.column!r}")
        prefix = ", ".join(where)
        return f"{prefix}: {self.message}" if prefix else self.message


class MachineError(KinidError):
    """The machine description (URDF) does not follow docs/machines.md."""


class DataError(KinidError):
    """A data file or a numeric argument is malformed or out of range."""


class ImageError(KinidError):
    """An image cannot be read or does not show what the method needs."""


class StageError(KinidError):
    """A stage request is invalid (a move outside travel, a non-positive lead)."""
