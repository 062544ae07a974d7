"""The alignments a verb reads with ``--data`` (identify, diagnose, verify): kinid's observation CSV or an
instrument export, with one set of options for the export on every verb (docs/formats.md, "Instrument exports")."""
from __future__ import annotations

import sys

from kinid.errors import DataError

__all__ = ["add_export_options", "export_options_text", "is_observation_file", "read_data", "refuse_export",
           "stated_std_of"]

#: The export options, as argparse names them.
_OPTIONS = ("point", "point_unit", "joint_unit", "target", "orientation", "orientation_mount_deg", "orientation_std_urad")


def add_export_options(p) -> None:
    """The instrument export's options (``--point``, ``--point-unit``, ``--joint-unit``, ``--target``) on ``p``."""
    g = p.add_argument_group("instrument exports (docs/formats.md)")
    g.add_argument("--point", default=None, metavar="x=COL,y=COL,z=COL",
                   help="the measured point's columns (default: measurement_x/_y/_z in mm, x1/y1/z1 … in m)")
    g.add_argument("--point-unit", choices=("mm", "m"), default=None, help="the measured point's unit")
    g.add_argument("--joint-unit", choices=("rad", "deg"), default=None,
                   help="the unit of reading columns without a _rad/_deg suffix (default: the URDF's, rad)")
    g.add_argument("--target", default=None, metavar="LABEL",
                   help="with several targets per pose (x1/y1/z1, x2/y2/z2 …): the one read, T1, T2 … "
                        "(default: every target; identify fits them together, each its own tool point)")
    g.add_argument("--orientation", default=None, metavar="SEQUENCE",
                   help="the Euler sequence of the measured orientation's angles (measurement_rx/_ry/_rz, rx/ry/rz, "
                        "a/b/c): XYZ (the default: intrinsic, R = Rx·Ry·Rz), xyz, ZYX, zyx, ZYZ, zyz; off: the points "
                        "only")
    g.add_argument("--orientation-mount-deg", type=float, nargs=3, default=None, metavar=("A1", "A2", "A3"),
                   help="the measured body's orientation in the tool frame, the same sequence, deg (default: 0 0 0, "
                        "or the turn the data show when 0 0 0 does not fit; a note says so)")
    g.add_argument("--orientation-std-urad", type=float, default=None, metavar="S",
                   help="σ of every pose's orientation, µrad (default: from the export's std columns)")


def export_options_text(args) -> str:
    """The export options given in ``args``, as a command line repeats them (`` --point x=a,y=b,z=c``), or ''."""
    import shlex

    def text(v):
        return " ".join(f"{x:g}" for x in v) if isinstance(v, (list, tuple)) else shlex.quote(str(v))

    return "".join(f" --{o.replace('_', '-')} {text(getattr(args, o))}" for o in _OPTIONS
                   if getattr(args, o, None) is not None)


def is_observation_file(path) -> bool:
    """Whether ``path`` is a file and kinid's own observation CSV (not an instrument export)."""
    from pathlib import Path

    from ..data import is_observation_csv

    return Path(path).is_file() and is_observation_csv(path)


def _mount_from_data(check, args) -> bool:
    """Whether the measured body's mount is taken from the data: none was given, the angles as read are beyond what a
    machine's errors explain, no other sequence or unit fits, and one turn on the tool does
    (:class:`~kinid.identification.fitting.OrientationCheck`)."""
    from ..fitting import ORIENTATION_LIMIT_DEG

    return (not check.ok and getattr(args, "orientation_mount_deg", None) is None
            and check.readings[0][1] > ORIENTATION_LIMIT_DEG and check.spread_deg <= ORIENTATION_LIMIT_DEG)


def read_data(path, machine, args, *, check_units: bool = True, others=(), together: bool = False,
              orientation: bool = False):
    """(observations, stated std) of ``path``: kinid's observation CSV, or an instrument export read with the
    export options of ``args`` (its mapping printed on standard error), one target of several chosen by
    ``--target``, or every target where the verb fits them ``together``.

    Parameters
    ----------
    path : str
        The file (``--data``, ``--before``).
    machine : Machine
    args : argparse.Namespace
        With the export options, and ``allow_outside_limits`` where the verb has it (else the limits are checked).
    check_units : bool
        Warn of the unit mistakes an observation CSV shows.
    others : sequence of str
        The verb's other files read the same way: an export option is refused only when none of them is an export.
    together : bool
        Without ``--target``, read every target of several (the rows' marks ``T1``, ``T2`` …), and say so; else
        several targets without ``--target`` are refused.
    orientation : bool
        Read a measured orientation into rows of its own (the verbs that fit: identify, diagnose); else the points
        only (``--orientation off``: the angle columns are named among the ignored).

    Returns
    -------
    Observations, and dict (line, mark) -> array (3,) of the point's stated standard deviations in mm (empty for
    an observation CSV or an export without them).

    Raises
    ------
    DataError
        One line: an export option given for observation CSVs only, a target not in the file, several targets
        without ``--target`` (unless ``together``), or what the file's reader names.
    """
    import numpy as np

    from ..data import is_observation_csv, parse_point_columns, read_export, read_observations

    check_limits = not getattr(args, "allow_outside_limits", False)
    given = [o for o in _OPTIONS if getattr(args, o, None) is not None]
    if is_observation_csv(path):
        if given and all(is_observation_csv(f) for f in others):
            raise DataError(f"--{given[0].replace('_', '-')} is for an instrument export; {path} is an "
                            f"observation CSV (its header has mark or wx_mm)")
        return read_observations(path, machine, check_limits=check_limits, check_units=check_units), {}
    point = parse_point_columns(args.point) if args.point is not None else None
    turn = {k: getattr(args, k) for k in ("orientation", "orientation_mount_deg", "orientation_std_urad")
            if getattr(args, k, None) is not None}
    if not orientation:
        turn["orientation"] = "off"  # a verb that reads the points only (verify, plan)
    export = read_export(path, machine, point=point, point_unit=args.point_unit, joint_unit=args.joint_unit,
                         check_limits=check_limits, **turn)
    obs = export.observations
    std = {} if export.std_mm is None else {(ln, m): s for ln, m, s in zip(obs.lines, obs.marks, export.std_mm)}
    labels = [label for label, *_ in export.targets]
    if args.target is not None and args.target not in labels:
        raise DataError(f"--target {args.target!r}: the file's targets are {', '.join(labels)}")
    notes = export.notes()
    if obs.rotation_rows.any():  # the angles' convention, unit and mount checked before any fit (one line if off)
        from ..fitting import check_orientation

        check = check_orientation(machine, export)
        if _mount_from_data(check, args):  # no mount given, and one turn on the tool explains the angles: a set-up
            mount = tuple(round(v, 2) for v in check.mount_deg)
            export = read_export(path, machine, point=point, point_unit=args.point_unit, joint_unit=args.joint_unit,
                                 check_limits=check_limits, **{**turn, "orientation_mount_deg": mount})
            obs, notes = export.observations, export.notes()
            check = check_orientation(machine, export)
            notes.append(f"  the measured body's mount on the tool taken from the data: "
                         f"{' '.join(f'{v:g}' for v in mount)}° (no --orientation-mount-deg given; a tilt of the tool "
                         f"is then carried by the mount: give the mount from its drawing to identify the tilt)")
        if not check.ok:
            raise DataError(check.line, path=path)
        notes.append(f"  {check.line}")
    if args.target is None and together and len(labels) > 1:
        notes.append(f"  targets {', '.join(labels)} fitted together: each its own point on the tool "
                     f"(E?0T:target:<mark>), the machine's errors and the measurement frame shared")
    elif args.target is not None and len(labels) > 1:
        notes.append(f"  target {args.target} fitted (--target), the others left out")
    print("\n".join(notes), file=sys.stderr)
    if args.target is not None:
        return obs.subset(np.array([m == args.target for m in obs.marks])), std
    if len(labels) > 1 and not together:
        raise DataError(f"{len(labels)} targets per pose ({', '.join(labels)}): choose one with --target "
                        f"{labels[0]} (kinid identify fits them together)", path=path)
    return obs, std


def stated_std_of(obs, std: dict):
    """The stated standard deviations (N, 3) in mm of the rows of ``obs`` (by CSV line and mark), or None when a
    row has none."""
    import numpy as np

    if not std or not obs.lines:
        return None
    rows = [std.get((ln, m)) for ln, m in zip(obs.lines, obs.marks)]
    if any(s is None for s in rows):
        return None
    return np.array(rows, float).reshape(len(obs), 3)


def refuse_export(path, option: str, why: str) -> None:
    """DataError when ``path`` is an instrument export where the verb takes kinid's observation CSV only: ``why``
    says what the verb needs that an export does not hold."""
    from ..data import is_observation_csv

    if not is_observation_csv(path):
        raise DataError(f"{option} {path} is an instrument export (its header has none of mark, wx_mm, wy_mm, "
                        f"wz_mm): {why}")
