"""The controller's number of each axis (TwinCAT ``kopf.achs_nr``, SINUMERIK ``AX<n>``), given or from the URDF.

Rule for an axis not given with ``--axis-number``: its place among the machine's motion joints in the
URDF's kinematic tree, counted from 1 — depth first from the base link, the order Pinocchio numbers
the joints (``machine.axes``). That is rarely the controller's numbering, so the mapping is printed and
recorded in ``compensation.json`` with its source.
"""
from __future__ import annotations

from dataclasses import dataclass

from kinid.errors import DataError

__all__ = ["AxisNumbers", "controller_axis_numbers", "URDF_RULE"]

#: How kinid numbers an axis that is not given (docs/compensation.md).
URDF_RULE = ("the axis's place among the motion joints of the URDF's chain, from 1, depth first from the base "
             "link (the order the machine lists its axes)")


@dataclass(frozen=True)
class AxisNumbers:
    """The controller's axis numbers and where each came from.

    Attributes
    ----------
    numbers : dict axis -> int
        Every motion axis of the machine, in the machine's order.
    given : tuple of str
        The axes whose number was given (``--axis-number``); the others are from the URDF's chain.
    """

    numbers: dict
    given: tuple

    @property
    def source(self) -> str:
        """"given" (every axis given), "urdf" (none given) or "given+urdf"."""
        if len(self.given) == len(self.numbers):
            return "given"
        return "given+urdf" if self.given else "urdf"

    def line(self) -> str:
        """One console line: ``axis numbers: X=1 Y=2 Z=3 B=4 C=5 (from the URDF's chain; ...)``."""
        pairs = " ".join(f"{a}={n}" for a, n in self.numbers.items())
        why = {"urdf": "from the URDF's chain; --axis-number to set them",
               "given": "given with --axis-number",
               "given+urdf": f"{', '.join(self.given)} given with --axis-number, the others from the URDF's chain"}
        return f"axis numbers: {pairs} ({why[self.source]})"

    def as_dict(self) -> dict:
        """The ``axis_numbers`` entry of ``compensation.json``."""
        return {"numbers": dict(self.numbers), "source": self.source,
                "from_urdf": [a for a in self.numbers if a not in self.given], "given": list(self.given),
                "rule": URDF_RULE}


def controller_axis_numbers(machine, given=None) -> AxisNumbers:
    """Every axis's controller number: ``given`` (axis -> int) where given, else its place in the URDF's chain.

    Raises
    ------
    DataError
        ``given`` names an axis the machine does not have, or an axis not given would get by the URDF's rule a
        number given to another axis (give every axis its number then).
    """
    given = dict(given or {})
    unknown = sorted(set(given) - set(machine.axis_names))
    if unknown:
        raise DataError(f"names no axis of the machine: {', '.join(unknown)}; axes: {', '.join(machine.axis_names)}",
                        parameter="axis_numbers")
    numbers = {}
    for place, name in enumerate(machine.axis_names, start=1):
        if name in given:
            numbers[name] = int(given[name])
            continue
        taken = next((a for a, n in given.items() if n == place), None)
        if taken is not None:
            raise DataError(f"gives axis {taken} the number {place}, which the URDF's chain gives axis {name}; give "
                            f"{name} its number too (axes: {', '.join(machine.axis_names)})", parameter="axis_numbers")
        numbers[name] = place
    return AxisNumbers(numbers, tuple(a for a in machine.axis_names if a in given))
