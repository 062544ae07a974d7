"""Write the URDF of a small machine with the builder: three linear axes and a rotary table.

    .venv/bin/python examples/my_machine.py --out my_machine.urdf

Workpiece chain: base -> Y (table carriage) -> C (rotary table on it) -> workpiece (board on the table).
Tool chain:      base -> X (cross slide) -> Z (ram) -> tool (camera at its stand-off).
With all axes at 0 the tool point is on the board's surface at the C axis: the C table surface is
40 mm above the Y carriage reference, the board 8 mm above the table, the tool point 48 mm above
the Z carriage reference.
"""
import argparse
from pathlib import Path

from kinid.identification.model.urdf_builder import Axis, Fixed, machine_urdf, setup

PI = 3.141592653589793

WORKPIECE = [
    # Y: squareness to X (EC0Y) before it, its six position-dependent errors after it
    Axis("Y", "prismatic", (0, 1, 0), location_errors=("C",), limit=(-0.2, 0.2)),
    Fixed("table", (0.0, 0.0, 0.040), comment="C table surface 40 mm above the Y carriage"),
    # C: where its axis line is (EX0C, EY0C) and how it is tilted (EA0C, EB0C)
    Axis("C", "revolute", (0, 0, 1), location_errors=("X", "Y", "A", "B"), limit=(-2 * PI, 2 * PI)),
    Fixed("board", (0.0, 0.0, 0.008), comment="board surface 8 mm above the table"),
    setup("W", "set-up of the board on the table"),
]
TOOL = [
    Axis("X", "prismatic", (1, 0, 0), limit=(-0.3, 0.3)),
    Axis("Z", "prismatic", (0, 0, 1), location_errors=("B", "A"), limit=(-0.1, 0.1)),
    Fixed("sensor", (0.0, 0.0, 0.048), comment="tool point 48 mm above the Z carriage"),
    setup("T", "set-up of the camera on the ram"),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="URDF file to write")
    args = parser.parse_args()
    text = machine_urdf("my_machine", WORKPIECE, TOOL, __doc__.split("\n\n", 2)[2].strip())
    Path(args.out).write_text(text)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
