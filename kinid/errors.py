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
    parameter : str or None
        The argument of the called function that is wrong (``noise_um``);
        ``message`` then completes a sentence that starts with its name
        ("must be positive, got -1"). The command line shows the option's
        name instead (``--noise-um``): see :meth:`renamed`.
    """

    def __init__(self, message: str, *, path=None, line=None, column=None, parameter=None):
        self.message = message
        self.path = None if path is None else str(path)
        self.line = line
        self.column = column
        self.parameter = parameter
        super().__init__(str(self))

    def renamed(self, parameter: str) -> "KinidError":
        """The same error naming the wrong argument ``parameter`` (e.g. the command-line option)."""
        return type(self)(self.message, path=self.path, line=self.line, column=self.column, parameter=parameter)

    def __str__(self) -> str:
        where = []
        if self.path is not None:
            where.append(self.path if self.line is None else f"{self.path}:{self.line}")
        elif self.line is not None:
            where.append(f"line {self.line}")
        if self.column is not None:
            where.append(f"column {self.column!r}")
        prefix = ", ".join(where)
        message = self.message if self.parameter is None else f"{self.parameter} {self.message}"
        return f"{prefix}: {message}" if prefix else message


class MachineError(KinidError):
    """The machine description (URDF) does not follow the convention of docs/machines.md."""


class DataError(KinidError):
    """A data file or a numeric argument is malformed or out of range."""


class ImageError(KinidError):
    """An image cannot be read or does not show what the method needs."""


class StageError(KinidError):
    """A stage cannot do what was asked (a move outside its travel, an actuator it does not have).

    A wrong argument value (a non-positive lead, too few repeats) is a
    :class:`DataError`, in every stage method alike.
    """
