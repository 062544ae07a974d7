"""Write the shipped five-axis machine URDFs: ``python -m kinid.urdf.generate --out DIR``.

The files are written into ``DIR`` (never into the installed package); the
gantry (``gantry_dual_y.urdf``) is written by hand and not produced here. To
refresh the files shipped in a source checkout, run it with ``--out urdf``
from the repository's top folder.
"""
from __future__ import annotations

from pathlib import Path

from kinid.identification import urdf_builder

Axis, Fixed, machine_urdf, setup = urdf_builder.Axis, urdf_builder.Fixed, urdf_builder.machine_urdf, urdf_builder.setup

HERE = Path(__file__).resolve().parent
PI = 3.141592653589793

BC = """five_axis_bc: B/C double turntable (the machine of the five-axis patent method).

Workpiece chain: base -> Y -> B (tilt about y) -> C (table about z) -> workpiece (calibration board).
Tool chain:      base -> X -> Z -> tool (camera optical axis at the laser-set stand-off).

Nominal geometry (all axes at 0): the tool point coincides with the workpiece origin (board surface centre).
  B axis line: 150 mm above the Y carriage reference, along y.
  C table surface: 50 mm below the B axis line; C axis along z through the B axis.
  Board surface (workpiece frame): 10 mm above the C table, on the C axis.
  Tool point: 110 mm above the Z carriage reference.
Error joints (ISO 230-1): 30 position-dependent (E<d>X, E<d>Y, E<d>Z, E<d>B, E<d>C),
11 location errors (EC0Y; EB0Z EA0Z; EX0B EZ0B EA0B EC0B; EX0C EY0C EA0C EB0C),
set-up of the board (EX0W..EC0W) and of the sensor (EX0T..EC0T)."""

AC = """five_axis_ac: A/C double turntable (a swapped-in variant: no code change is needed to use it).

Workpiece chain: base -> Y -> A (tilt about x) -> C (table about z) -> workpiece.
Tool chain:      base -> X -> Z -> tool.
Nominal: A axis line 120 mm above the Y carriage; C table surface 40 mm below the A axis line;
board 10 mm above the table; tool point 90 mm above the Z carriage. All axes 0: tool point at the board origin."""

BHEAD = """five_axis_bhead_c: swivelling B head over a C rotary table (a swapped-in variant).

Workpiece chain: base -> Y -> C (table about z) -> workpiece.
Tool chain:      base -> X -> Z -> B (head about y) -> 150 mm pivot -> tool.
Nominal: board 10 mm above the C table; B pivot 150 mm above the tool point at B = 0, and
the tool point at the board origin when all axes are 0."""

TRAVEL = (-0.6, 0.6)
TURN = (-2 * PI, 2 * PI)


def five_axis_bc() -> str:
    work = [
        Axis("Y", "prismatic", (0, 1, 0), location_errors=("C",), limit=TRAVEL, comment="Y: table carriage along y"),
        Fixed("b_axis_line", (0, 0, 0.150), comment="B axis line 150 mm above the Y carriage"),
        Axis("B", "revolute", (0, 1, 0), location_errors=("X", "Z", "A", "C"), limit=(-PI / 2, PI / 2), comment="B: tilt about y"),
        Fixed("c_table", (0, 0, -0.050), comment="C table surface 50 mm below the B axis line"),
        Axis("C", "revolute", (0, 0, 1), location_errors=("X", "Y", "A", "B"), limit=TURN, comment="C: rotary table about z"),
        Fixed("board", (0, 0, 0.010), comment="calibration board surface 10 mm above the table"),
        setup("W", "set-up of the calibration board on the C table"),
    ]
    tool = [
        Axis("X", "prismatic", (1, 0, 0), limit=TRAVEL, comment="X: reference axis (no location errors)"),
        Axis("Z", "prismatic", (0, 0, 1), location_errors=("B", "A"), limit=TRAVEL, comment="Z: squareness to X (EB0Z) and Y (EA0Z)"),
        Fixed("sensor_mount", (0, 0, 0.110), comment="tool point 110 mm above the Z carriage reference"),
        setup("T", "set-up of the camera / laser sensor on Z"),
    ]
    return machine_urdf("five_axis_bc", work, tool, BC)


def five_axis_ac() -> str:
    work = [
        Axis("Y", "prismatic", (0, 1, 0), location_errors=("C",), limit=TRAVEL),
        Fixed("a_axis_line", (0, 0, 0.120), comment="A axis line 120 mm above the Y carriage"),
        Axis("A", "revolute", (1, 0, 0), location_errors=("Y", "Z", "B", "C"), limit=(-PI / 2, PI / 2)),
        Fixed("c_table", (0, 0, -0.040)),
        Axis("C", "revolute", (0, 0, 1), location_errors=("X", "Y", "A", "B"), limit=TURN),
        Fixed("board", (0, 0, 0.010)),
        setup("W"),
    ]
    tool = [
        Axis("X", "prismatic", (1, 0, 0), limit=TRAVEL),
        Axis("Z", "prismatic", (0, 0, 1), location_errors=("B", "A"), limit=TRAVEL),
        Fixed("sensor_mount", (0, 0, 0.090)),
        setup("T"),
    ]
    return machine_urdf("five_axis_ac", work, tool, AC)


def five_axis_bhead_c() -> str:
    work = [
        Axis("Y", "prismatic", (0, 1, 0), location_errors=("C",), limit=TRAVEL),
        Axis("C", "revolute", (0, 0, 1), location_errors=("X", "Y", "A", "B"), limit=TURN),
        Fixed("board", (0, 0, 0.010)),
        setup("W"),
    ]
    tool = [
        Axis("X", "prismatic", (1, 0, 0), limit=TRAVEL),
        Axis("Z", "prismatic", (0, 0, 1), location_errors=("B", "A"), limit=TRAVEL),
        Fixed("b_pivot", (0, 0, 0.160), comment="B pivot 150 mm above the tool point"),
        Axis("B", "revolute", (0, 1, 0), location_errors=("X", "Z", "A", "C"), limit=(-PI / 2, PI / 2)),
        Fixed("pivot_arm", (0, 0, -0.150), comment="tool point 150 mm below the B pivot"),
        setup("T"),
    ]
    return machine_urdf("five_axis_bhead_c", work, tool, BHEAD)


MACHINES = (five_axis_bc, five_axis_ac, five_axis_bhead_c)


def main(argv=None) -> int:
    """Command-line entry: write each five-axis URDF into ``--out DIR``; returns the exit status."""
    import argparse
    import sys

    from kinid.files import write_text

    parser = argparse.ArgumentParser(prog="python -m kinid.urdf.generate",
                                     description="Write the five-axis machine URDFs shipped with kinid into a folder.")
    parser.add_argument("--out", required=True, metavar="DIR", help="existing folder to write the .urdf files into")
    args = parser.parse_args(argv)
    out = Path(args.out)
    if not out.is_dir():
        print(f"python -m kinid.urdf.generate: {args.out}: not an existing folder", file=sys.stderr)
        return 2
    if out.resolve() == HERE and not (HERE.parent / "pyproject.toml").is_file():
        print(f"python -m kinid.urdf.generate: {args.out}: refusing to write into the installed package", file=sys.stderr)
        return 2
    for make in MACHINES:
        write_text(out / f"{make.__name__}.urdf", make())
        print(out / f"{make.__name__}.urdf")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
