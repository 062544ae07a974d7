"""Instrument exports: a laser tracker's or a motion-capture system's table read as observations as it arrives
(docs/formats.md, "Instrument exports").

One rule, in this order:

- **delimiter**: ``;`` if the header has one, else a tab if it has one, else ``,``; in a ``;`` or tab file a
  number may have a decimal comma (``0,000121973``, ``2,02011E+13``);
- **axes**: a column named as the URDF joint (``shoulder_pan_joint``), the short name (``J1``) or kinid's column
  (``j1_deg``), with an optional unit suffix ``_rad``, ``_deg``, ``_m``, ``_mm``; without one, the URDF's own
  units (rad, m; ``joint_unit`` overrides);
- **measured point**: the columns given (``point={"x": ..., "y": ..., "z": ...}``), else the first pattern found
  of :data:`POINT_PATTERNS` — ``measurement_x/_y/_z`` (mm, a tracker's export), ``x1/y1/z1``, ``x2/y2/z2`` … (m,
  one target each, motion capture); ``point_unit`` overrides the unit;
- several targets per pose give one row per target, its mark the target's label (``T1``, ``T2`` …); a target
  whose point equals an earlier one's on every row is a copy (a capture export repeating its last marker) and
  is left out, with a note;
- standard deviations of the point (``measurement_std_x``, ``x1_std``) are read (``Export.std_mm``), not used as
  weights: the fit takes one σ for every coordinate, and ``kinid identify`` checks them against its residuals
  (:mod:`~kinid.identification.diagnosis.stated_std`);
- **measured orientation** (a 6-DoF probe's, a rigid body's): the first pattern found of
  :data:`ORIENTATION_PATTERNS` (``measurement_rx/_ry/_rz``, ``rx/ry/rz``, ``a/b/c``, in degrees unless a ``_rad``
  suffix says otherwise), three Euler angles in ``orientation`` (scipy's sequence: ``XYZ``, intrinsic x-y′-z″,
  R = Rx·Ry·Rz, is the default), the measured body turned ``orientation_mount_deg`` in the tool frame: one more row
  per pose (mark ``R``), whose residual is the model's orientation against it (:attr:`Observations.rotations`),
  weighted by its σ (the columns' std, or ``orientation_std_urad``) against the points' (their median stated std);
  every other column is ignored, with a note naming it.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinid.errors import DataError
from kinid.files import MAX_CSV_BYTES
from kinid.untrusted import read_limited_text, read_untrusted_bytes
from ..model import Machine
from .axis_columns import check_travel
from .observations import Observations

__all__ = ["Export", "ORIENTATION_PATTERNS", "POINT_PATTERNS", "ROTATION_MARK", "is_observation_csv", "read_export",
           "parse_point_columns", "euler_rotations", "EULER_SEQUENCES"]

#: Factor to kinid's units (mm, deg) of each unit a column may be in.
_TO_KINID = {"mm": 1.0, "m": 1e3, "deg": 1.0, "rad": 180.0 / np.pi}
_AXIS_UNITS = {"prismatic": ("m", "mm"), "revolute": ("rad", "deg")}
_SI = {"prismatic": "m", "revolute": "rad"}
#: A header with one of these is kinid's own observation CSV.
_OWN_COLUMNS = {"mark", "wx_mm", "wy_mm", "wz_mm"}

#: The measured point's columns recognised without ``point``: (pattern with {c} for x/y/z and {k} for the
#: target number, its unit, the pattern of its standard deviation's column or None), the first that matches wins.
POINT_PATTERNS = (
    ("measurement_{c}", "mm", "measurement_std_{c}"),
    ("{c}{k}", "m", "{c}{k}_std"),
)

#: The measured orientation's columns: (pattern with {c} for its three angles, the letters {c} takes, the pattern of
#: the standard deviation's column); matched without case, after an optional ``_deg``/``_rad`` suffix.
ORIENTATION_PATTERNS = (
    ("measurement_r{c}", "xyz", "measurement_std_r{c}"),
    ("r{c}", "xyz", "r{c}_std"),
    ("{c}", "abc", "{c}_std"),
)
#: The mark of an orientation row.
ROTATION_MARK = "R"
#: The Euler sequences an orientation may be given in (scipy's: upper case intrinsic, lower case extrinsic).
EULER_SEQUENCES = ("XYZ", "ZYX", "xyz", "zyx", "ZYZ", "zyz")


def euler_rotations(angles_deg, sequence: str) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of Euler angles (N, 3) in degrees, in ``sequence`` (scipy's ``from_euler``:
    ``XYZ`` intrinsic x-y′-z″, R = Rx(a)·Ry(b)·Rz(c); ``xyz`` extrinsic, R = Rz(c)·Ry(b)·Rx(a))."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler(sequence, np.atleast_2d(angles_deg), degrees=True).as_matrix()


@dataclass(frozen=True)
class Export:
    """An instrument export read as observations.

    Attributes
    ----------
    observations : Observations
        One row per pose and target, marks ``T1``, ``T2`` …, points in mm, readings in mm / deg.
    delimiter : str
    decimal_comma : bool
        Whether a number of the file was written with a decimal comma.
    axes : tuple of (column, axis name, unit)
    targets : tuple of (label, (x, y, z columns), unit)
    std_columns : tuple of str
        The point's standard deviations found (not used as weights).
    ignored : tuple of str
        Columns read neither as axes nor as the point.
    std_mm : array (N, 3) or None
        The point's stated standard deviations of each row of ``observations``, mm; None unless every target has
        the three columns (the orientation rows, after the points', have none).
    copies : tuple of (label, (x, y, z columns), label of the target it repeats)
        Targets left out: their point equals an earlier target's on every row (a copy is no second measurement; read
        twice it would count one point's error twice and make σ look smaller).
    orientation : dict
        The measured orientation read into rows (empty when none): ``columns``, ``std_columns``, ``unit``,
        ``sequence``, ``mount_deg``, ``angles_deg`` (poses, 3: as read, in degrees), ``std_urad`` (poses,: the σ of
        each pose's orientation), ``point_std_um`` (the points' σ it is weighed against); or ``left_out``: why the
        columns found were not used.
    """

    observations: Observations
    delimiter: str
    decimal_comma: bool
    axes: tuple
    targets: tuple
    std_columns: tuple
    ignored: tuple
    std_mm: np.ndarray | None = None
    orientation: dict = field(default_factory=dict)
    copies: tuple = ()

    def notes(self) -> list:
        """Lines saying how the file was read: delimiter, the axes' mapping, the point, what was left out."""
        obs = self.observations
        sep = {";": "';'", "\t": "tab", ",": "','"}[self.delimiter]
        points = len(obs) - int(obs.rotation_rows.sum())
        out = [f"{obs.source}: instrument export, {sep}-separated{' with decimal commas' if self.decimal_comma else ''}"
               f", {points} rows ({points // max(len(self.targets), 1)} poses × {len(self.targets)} target(s))",
               "  axes: " + ", ".join(f"{c} [{u}] -> {a}" for c, a, u in self.axes)]
        out += [f"  point {label}: {', '.join(cols)} [{unit}]" for label, cols, unit in self.targets]
        out += [f"  {', '.join(cols)}: the same numbers as {first}'s on every row, a copy, not another target (left "
                f"out)" for label, cols, first in self.copies]
        if self.std_columns:
            out.append(f"  stated std, not used as weights (the fit takes one σ for every coordinate, --noise-um; "
                       f"identify checks them against its residuals): {', '.join(self.std_columns)}")
        o = self.orientation
        if o.get("left_out"):
            out.append(f"  orientation not used: {o['left_out']}")
        elif o:
            out.append(f"  orientation: {', '.join(o['columns'])} [{o['unit']}], Euler {o['sequence']}, the measured "
                       f"body turned {', '.join(f'{v:g}' for v in o['mount_deg'])}° in the tool frame: one row per pose "
                       f"(mark {ROTATION_MARK}), σ {np.median(o['std_urad']):.3g} µrad (median; "
                       f"{', '.join(o['std_columns']) or 'given'}) against the points' {o['point_std_um']:.3g} µm")
        if self.ignored:
            out.append(f"  ignored: {', '.join(self.ignored)}")
        return out


def is_observation_csv(path) -> bool:
    """Whether ``path`` is kinid's own observation CSV: its header (the first line neither blank nor a ``#``
    comment) has one of its columns ``mark``, ``wx_mm``, ``wy_mm``, ``wz_mm`` (one of them misspelt is then named by
    kinid's reader); an unreadable file counts as kinid's, whose reader names the problem."""
    try:
        raw = read_untrusted_bytes(path, what="CSV file", max_bytes=MAX_CSV_BYTES)
    except DataError:
        return True
    if raw.isascii():  # UTF-8 whatever follows: only the lines up to the header are decoded
        lines = (line.decode("ascii") for line in _lines(raw))
    else:
        try:
            lines = _lines(raw.decode("utf-8-sig"))  # as read_limited_text decodes it
        except UnicodeDecodeError:
            return True
    for line in lines:
        if line.strip() and not line.lstrip().startswith("#"):
            return bool(_OWN_COLUMNS & {c.strip() for c in next(csv.reader([line]))})
    return True


def _lines(text):
    """The lines of ``text`` (str or bytes) one at a time (ended by CR LF, CR or LF): a header found without
    splitting a million-row file into a million strings."""
    import re

    start = 0
    for end in re.finditer(r"\r\n|\r|\n" if isinstance(text, str) else rb"\r\n|\r|\n", text):
        yield text[start:end.start()]
        start = end.end()
    if start < len(text):
        yield text[start:]


def parse_point_columns(text: str) -> dict:
    """``x=COL,y=COL,z=COL`` -> {"x": COL, "y": COL, "z": COL}; DataError naming ``--point`` otherwise."""
    pairs = [p.partition("=") for p in text.split(",") if p.strip()]
    found = {k.strip().lower(): v.strip() for k, eq, v in pairs if eq and v.strip()}
    if len(pairs) != 3 or sorted(found) != ["x", "y", "z"]:
        raise DataError(f"expected x=COLUMN,y=COLUMN,z=COLUMN, got {text!r}", parameter="--point")
    return found


def _delimiter(header: str) -> str:
    return ";" if ";" in header else "\t" if "\t" in header else ","


def _rows(path: Path):
    """(delimiter, header line, header, [(line, cells)]) of the file; DataError on a short or long row."""
    text = read_limited_text(path, what="instrument export", max_bytes=MAX_CSV_BYTES)
    numbered = [(i, ln) for i, ln in enumerate(text.splitlines(), 1) if ln.strip() and not ln.lstrip().startswith("#")]
    if not numbered:
        raise DataError("no header row (the file is empty)", path=path)
    header_line, header_text = numbered[0]
    delimiter = _delimiter(header_text)
    reader = csv.reader([ln for _, ln in numbered], delimiter=delimiter)
    rows = [(line, [c.strip() for c in cells]) for (line, _), cells in zip(numbered, reader)]
    header = rows[0][1]
    seen = set()
    for name in header:
        if not name or name in seen:
            raise DataError("an empty column name" if not name else "the column appears twice", path=path,
                            line=header_line, column=name or None)
        seen.add(name)
    for line, cells in rows[1:]:
        if len(cells) != len(header):
            raise DataError(f"{len(cells)} cells, the header has {len(header)}: check the delimiter "
                            f"({delimiter!r}, from the header)", path=path, line=line)
    if len(rows) < 2:
        raise DataError("no data rows after the header", path=path, line=header_line)
    return delimiter, header_line, header, rows[1:]


def _numbers(path, rows, k, column, decimal_comma):
    """The finite numbers of column ``k``; DataError naming the line and column of the first other cell."""
    out = np.empty(len(rows))
    for i, (line, cells) in enumerate(rows):
        cell = cells[k]
        text = cell.replace(",", ".", 1) if decimal_comma and cell.count(",") == 1 and "." not in cell else cell
        try:
            v = float(text)
        except ValueError:
            v = None
        if v is None or not np.isfinite(v):
            raise DataError(f"{cell!r} is not a finite number" + (" (an empty cell)" if not cell else ""),
                            path=path, line=line, column=column)
        out[i] = v
    return out


def _unit_suffix(name: str, units) -> tuple:
    """(stem, unit) of a column name ending in ``_<unit>`` for a unit in ``units``, else (name, None)."""
    for u in units:
        if name.lower().endswith("_" + u):
            return name[: -len(u) - 1], u
    return name, None


def _axis_columns(machine, header, joint_unit, path, header_line):
    """[(column index, column, axis index, unit)] for every axis; DataError naming a missing or doubled axis."""
    found = {}
    for k, name in enumerate(header):
        for j, a in enumerate(machine.axes):
            stem, unit = _unit_suffix(name, _AXIS_UNITS[a.kind] + tuple(u for u in _TO_KINID if u not in
                                                                         _AXIS_UNITS[a.kind]))
            if stem.lower() not in (a.joint.lower(), a.name.lower()):
                continue
            if unit is not None and unit not in _AXIS_UNITS[a.kind]:
                raise DataError(f"axis {a.name} ({a.joint}) is {a.kind}: its unit is one of "
                                f"{', '.join(_AXIS_UNITS[a.kind])}, not {unit}", path=path, line=header_line,
                                column=name)
            if j in found:
                raise DataError(f"a second column for axis {a.name} ({a.joint}), after {header[found[j][0]]!r}",
                                path=path, line=header_line, column=name)
            if unit is None:
                unit = joint_unit if joint_unit in _AXIS_UNITS[a.kind] else _SI[a.kind]
            found[j] = (k, unit)
    missing = [a for j, a in enumerate(machine.axes) if j not in found]
    if missing:
        names = ", ".join(f"{a.joint}" + (f" or {a.name}" if a.name != a.joint else "") for a in missing)
        raise DataError(f"no column for {names} (a column is named as the URDF joint or its short name, with an "
                        f"optional _rad/_deg/_m/_mm)", path=path, line=header_line)
    return [(k, header[k], j, unit) for j, (k, unit) in sorted(found.items())]


def _targets(header, point, point_unit, path, header_line):
    """[(label, (x, y, z columns), unit, std columns)] of the measured point(s)."""
    lower = {h.lower(): h for h in header}
    if point is not None:
        cols = tuple(point[c] for c in "xyz")
        for c in cols:
            if c not in header:
                raise DataError(f"--point names column {c!r}, which the file does not have", path=path,
                                line=header_line)
        units = {_unit_suffix(c, ("mm", "m"))[1] for c in cols}
        unit = point_unit or (units.pop() if len(units) == 1 and None not in units else None)
        if unit is None:
            raise DataError(f"the unit of {', '.join(cols)} is not in their names: add --point-unit mm or m",
                            path=path, line=header_line)
        return [("T1", cols, unit, ())]
    for pattern, unit, std in POINT_PATTERNS:
        numbered = "{k}" in pattern
        out = []
        for k in range(1, 1000 if numbered else 2):
            cols = [lower.get(pattern.format(c=c, k=k)) for c in "xyz"]
            if None in cols:
                break
            stds = tuple(s for s in (lower.get(std.format(c=c, k=k)) for c in "xyz") if s)
            out.append((f"T{k}", tuple(cols), point_unit or unit, stds))
        if out:
            return out
    raise DataError("no measured-point columns: name them with --point x=COLUMN,y=COLUMN,z=COLUMN (recognised: "
                    "measurement_x/_y/_z, x1/y1/z1 …)", path=path, line=header_line)


def read_export(path, machine: Machine, *, point: dict | None = None, point_unit: str | None = None,
                joint_unit: str | None = None, check_limits: bool = True, orientation: str = "XYZ",
                orientation_mount_deg=(0.0, 0.0, 0.0), orientation_std_urad: float | None = None,
                point_std_um: float | None = None) -> Export:
    """Read an instrument export as observations (module docstring: the rule).

    Parameters
    ----------
    path : str or Path
    machine : Machine
        Its axes' URDF joint names and short names name the reading columns.
    point : dict {"x", "y", "z"} -> column, optional
        The measured point's columns (:func:`parse_point_columns`); default: :data:`POINT_PATTERNS`.
    point_unit : {"mm", "m"}, optional
        The point's unit, over its pattern's or its columns' suffix.
    joint_unit : {"rad", "deg"}, optional
        The unit of reading columns without a suffix (default the URDF's: rad, m).
    check_limits : bool
        Refuse a reading outside its axis's URDF travel.
    orientation : str
        The Euler sequence of the measured orientation's angles (:data:`EULER_SEQUENCES`, scipy's naming), or
        ``"off"``: the points only.
    orientation_mount_deg : (3,) float
        The measured body's orientation in the tool frame, the same sequence, deg: the measured orientation is the
        tool's times this turn (a 6-DoF probe mounted turned on the flange).
    orientation_std_urad : float, optional
        σ of every pose's orientation, µrad (default: the RMS of each pose's three std columns).
    point_std_um : float, optional
        σ of the points the orientation rows are weighed against, µm (default: the median of the points' std).

    Raises
    ------
    DataError
        One line naming the file, line and column: a row of another length, a cell that is not a number, an axis
        without a column, no measured point.
    """
    for name, value, allowed in (("--point-unit", point_unit, ("mm", "m")), ("--joint-unit", joint_unit, ("rad", "deg"))):
        if value is not None and value not in allowed:
            raise DataError(f"expected {' or '.join(allowed)}, got {value!r}", parameter=name)
    path = Path(path)
    delimiter, header_line, header, rows = _rows(path)
    decimal_comma = delimiter != ","
    axis_cols = _axis_columns(machine, header, joint_unit, path, header_line)
    targets = _targets(header, point, point_unit, path, header_line)
    for _, cols, _, _ in targets:
        for c in cols:
            if c in {name for _, name, _, _ in axis_cols}:
                raise DataError("a column cannot be both an axis reading and the measured point", path=path,
                                line=header_line, column=c)
    n, m = len(rows), len(targets)
    axes = np.empty((n, len(machine.axes)))
    for k, name, j, unit in axis_cols:
        axes[:, j] = _numbers(path, rows, k, name, decimal_comma) * _TO_KINID[unit]
    lines = tuple(line for line, _ in rows)
    if check_limits:
        check_travel(machine, axes, lines, path)
    points = np.stack([np.column_stack([_numbers(path, rows, header.index(c), c, decimal_comma) for c in cols])
                       * _TO_KINID[unit] for _, cols, unit, _ in targets], axis=1)  # (n, m, 3)
    copies = _copies(points, targets)
    if copies:  # a target equal to an earlier one on every row is that point written twice: read once
        keep = [k for k, (label, *_) in enumerate(targets) if label not in copies]
        targets, points, m = [targets[k] for k in keep], points[:, keep], len(keep)
    used = ({c for _, c, _, _ in axis_cols} | {c for t in targets for c in t[1]}
            | {c for _, t in copies.values() for c in t[1] + t[3]})
    stds = tuple(s for t in targets for s in t[3])
    marks = tuple(label for _ in range(n) for label, *_ in targets)
    obs = Observations(marks, points.reshape(n * m, 3), np.repeat(axes, m, axis=0), None, {},
                       tuple(np.repeat(lines, m).tolist()), str(path))
    std_mm = None
    if all(len(t[3]) == 3 for t in targets):
        std_mm = np.stack([np.column_stack([_numbers(path, rows, header.index(c), c, decimal_comma) for c in stds])
                           * _TO_KINID[unit] for _, _, unit, stds in targets], axis=1).reshape(n * m, 3)
        if np.any(std_mm < 0):
            line, k = np.argwhere(std_mm.reshape(n, m * 3) < 0)[0]
            raise DataError("a standard deviation cannot be negative", path=path, line=lines[line],
                            column=[s for t in targets for s in t[3]][k])
    found = _orientation_columns(header, used | set(stds), orientation, path, header_line)
    o = {}
    if found:
        o = _orientation(path, rows, header, found, decimal_comma, orientation, orientation_mount_deg,
                         orientation_std_urad, point_std_um if point_std_um is not None else
                         None if std_mm is None else float(np.median(std_mm)) * 1e3)
        used |= set(found[0]) | set(found[2])
    if "rotations" in o:
        n_rows = len(obs)
        obs = Observations(obs.marks + (ROTATION_MARK,) * n, np.vstack([obs.w_mm, np.zeros((n, 3))]),
                           np.vstack([obs.axes, axes]), None, {}, obs.lines + lines, obs.source,
                           rotations=np.concatenate([np.full((n_rows, 3, 3), np.nan), o.pop("rotations")]),
                           rotation_um_per_urad=np.concatenate([np.zeros(n_rows), o["point_std_um"] / o["std_urad"]]))
    comma = decimal_comma and any("," in cells[k] for _, cells in rows for k in range(len(header)) if header[k] in used)
    return Export(obs, delimiter, bool(comma), tuple((c, machine.axes[j].name, u) for _, c, j, u in axis_cols),
                  tuple((label, cols, unit) for label, cols, unit, _ in targets), stds,
                  tuple(h for h in header if h not in used and h not in stds), std_mm, o,
                  tuple((label, t[1], first) for label, (first, t) in copies.items()))


def _copies(points, targets) -> dict:
    """{label: (the earlier target's label, the target)} of every target whose point equals an earlier target's on
    every row (``points`` (rows, targets, 3)): a copy, not a second measurement (a capture export that repeats its
    last marker)."""
    out = {}
    for k in range(1, len(targets)):
        for j in range(k):
            if targets[j][0] not in out and np.array_equal(points[:, j], points[:, k]):
                out[targets[k][0]] = (targets[j][0], targets[k])
                break
    return out


def _orientation_columns(header, used, sequence, path, header_line):
    """(angle columns, unit, std columns or ()) of the first of :data:`ORIENTATION_PATTERNS` the header has (its
    columns not read otherwise), or None; DataError for an orientation sequence not known."""
    if sequence == "off":
        return None
    if sequence not in EULER_SEQUENCES:
        raise DataError(f"expected one of {', '.join(EULER_SEQUENCES)} or off, got {sequence!r}",
                        parameter="--orientation")
    lower = {}
    for h in header:
        if h not in used:
            stem, unit = _unit_suffix(h, ("deg", "rad"))
            lower.setdefault(stem.lower(), (h, unit))
    for pattern, letters, std in ORIENTATION_PATTERNS:
        cols = [lower.get(pattern.format(c=c)) for c in letters]
        if None in cols:
            continue
        units = {u for _, u in cols}
        if len(units) > 1:
            raise DataError(f"the orientation's columns {', '.join(c for c, _ in cols)} are in different units",
                            path=path, line=header_line)
        stds = tuple(lower[std.format(c=c)][0] for c in letters if std.format(c=c) in lower)
        return tuple(c for c, _ in cols), units.pop() or "deg", stds if len(stds) == 3 else ()
    return None


def _orientation(path, rows, header, found, decimal_comma, sequence, mount_deg, std_urad, point_std_um) -> dict:
    """The orientation's rotations (poses, 3, 3) in the tool frame's terms and what :attr:`Export.orientation`
    holds; ``left_out`` (and no rotations) where σ is not known."""
    cols, unit, std_cols = found
    info = dict(columns=cols, std_columns=std_cols if std_urad is None else (), unit=unit, sequence=sequence,
                mount_deg=tuple(float(v) for v in mount_deg))
    if std_urad is None and not std_cols:
        return dict(info, left_out=f"{', '.join(cols)} have no std columns: give their σ (--orientation-std-urad)")
    if point_std_um is None:
        return dict(info, left_out="the points have no std columns to weigh the orientation against: give the "
                                   "points' σ (point_std_um)")
    for name, value in (("--orientation-std-urad", std_urad), ("point_std_um", point_std_um)):
        if value is not None and not (np.isfinite(value) and value > 0):
            raise DataError(f"must be a positive number, got {value!r}", parameter=name)
    mount = np.asarray(mount_deg, float)
    if mount.shape != (3,) or not np.all(np.isfinite(mount)):
        raise DataError(f"expected three angles in degrees, got {mount_deg!r}", parameter="--orientation-mount-deg")
    angles = np.column_stack([_numbers(path, rows, header.index(c), c, decimal_comma) for c in cols]) * _TO_KINID[unit]
    if std_urad is None:
        s = np.column_stack([_numbers(path, rows, header.index(c), c, decimal_comma) for c in std_cols])
        bad = np.argwhere(~(s > 0))
        if len(bad):
            raise DataError("a standard deviation of the orientation must be positive (it weighs the row)", path=path,
                            line=rows[bad[0][0]][0], column=std_cols[bad[0][1]])
        sigma = np.sqrt(np.mean(s**2, axis=1)) * _TO_KINID[unit] * np.pi / 180 * 1e6
    else:
        sigma = np.full(len(rows), float(std_urad))
    R = euler_rotations(angles, sequence) @ euler_rotations(mount, sequence)[0].T
    return dict(info, angles_deg=angles, std_urad=sigma, point_std_um=float(point_std_um), rotations=R)
