"""From a fit to what a controller loads: axis error tables, constants, set-up, a calibrated URDF
(docs/compensation.md).

- :func:`compensation_model` — the fit with only what belongs in a machine's compensation: the
  machine's significant errors (|value| above its expanded uncertainty, k = 2), without the set-up
  of the board and the sensor (they go to ``setup.json``) and without drifts; what is left out is
  listed with the reason;
- :func:`axis_range` (:mod:`.ranges`) — where a table of an axis goes: the measured readings
  (default), the URDF travel on request where it is finite and at most a turn, one turn as a modulo
  table only where the readings go all the way round and the model repeats every turn;
- :func:`axis_error_columns` — the value of every position-dependent error joint of one axis over a
  grid of that axis (direction + and, where the model has a reversal, direction −);
- :func:`constant_errors` — every constant (location and set-up) error with its standard deviation;
- :func:`setup_offsets` — the board's and the sensor's set-up as the transforms a work offset and a
  tool offset apply;
- :func:`calibrated_urdf` — the machine's URDF with every compensated constant folded into the fixed
  geometry, the error joints kept at zero;
- :func:`write_compensation` — all of it into one folder, plus the controller files of
  :mod:`kinid.axis_tables`, each on a grid fine enough that the controller's own linear
  interpolation follows the model within a stated bound.

Values are the fitted model's own: the same effect bases as the fit, at the identified parameters
(a held, unidentifiable parameter counts as 0, as in the fit's predictions).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from kinid.axis_tables import FileTable, applied, csv_tables
from kinid.axis_tables import AxisErrorTable, TableOptions, controller_format, default_formats, neutral_csv_text
from kinid.errors import DataError
from kinid.stats import K_EXPANDED
from ..model import basis_of, basis_values
from ..fitting import FitResult
from .axis_numbers import AxisNumbers, controller_axis_numbers
from .calibration import calibrated_urdf, constant_errors, setup_offsets
from .ranges import axis_range, not_one_turn, unwrapped_range
from .significance import curves_not_significant, not_significant
from .rotary_geometry import kinematics_files
from .table_check import TableCheck, check_positions, check_tables
from .table_grids import AxisRange, directions, extra_points, left_after, rms, table_grid, with_ends

__all__ = ["Compensation", "compensation_model", "AxisRange", "axis_range", "axis_error_columns",
           "constant_errors", "setup_offsets", "calibrated_urdf", "write_compensation", "positioning_table",
           "CompensationFiles", "BOUND_SHARE"]

#: A table's interpolation may depart from the model by at most this share of the error's RMS.
BOUND_SHARE = 0.10
#: Most points of a plain CSV table when its step is chosen by kinid.
CSV_MAX_POINTS = 20001


# --- what goes into the compensation ------------------------------------------------------------

@dataclass(frozen=True)
class Compensation:
    """The part of a fit that a machine's compensation holds.

    Attributes
    ----------
    result : FitResult
        The fit with every left-out parameter at zero (tables and calibrated URDF are made from it).
    fit : FitResult
        The fit as identified.
    left_out : tuple of (effect name, reason)
    setup_effects : tuple of str
        The set-up effects (workpiece W, sensor/tool T): in ``setup.json``, not in the machine.
    setup_left_out : tuple of (effect name, reason)
        The set-up effects written as 0 in ``setup.json``: within their expanded uncertainty (k = 2),
        unless ``all_terms``.
    """

    result: FitResult
    fit: FitResult
    left_out: tuple
    setup_effects: tuple
    setup_left_out: tuple = ()


def compensation_model(result: FitResult, *, all_terms: bool = False) -> Compensation:
    """Keep the machine's errors that a compensation should hold.

    Left out, each with its reason: the set-up of the workpiece and the sensor (pseudo-axes W and T,
    they belong in the controller's work and tool offsets), drifts with time and sags with the pose (no table holds
    them),
    effects the data could not identify, effects of a size no machine has (``FitResult.implausible``: even
    with ``all_terms``), and — unless ``all_terms`` — effects not known better than they are large
    (:mod:`.significance`: no parameter beyond its expanded uncertainty, or a curve within its own).
    """
    machine = result.machine
    values = np.array(result.values, float)
    left, setup, setup_left, k = [], [], [], 0
    # a size no machine has is not a machine's error: between the readings a fit may need any value (a period
    # that the readings sample at the same phase), and a table would move the axis by it there
    odd = {o.effect: o for o in result.implausible()}
    curves = {} if all_terms else curves_not_significant(result, odd)  # a joint's table is judged whole
    for e in result.effects:
        sl = slice(k, k + e.n_params)
        k += e.n_params
        joint = machine.error_joint(e.code)
        ok = np.asarray(result.identifiable[sl], bool)
        reason = None
        if joint.axis in ("W", "T"):
            setup.append(e.name)
            reason = "set-up of the " + ("workpiece (board)" if joint.axis == "W" else "sensor (tool)") + \
                     ": in setup.json, for the work or tool offset"
            small = None if all_terms or not ok.any() else not_significant(values[sl][ok], result.std[sl][ok])
            if small is not None:
                setup_left.append((e.name, small))
        elif not ok.any():
            reason = "not identifiable from these data"
        elif e.name in odd:
            reason = (f"a size no machine has, {odd[e.name].describe()}: not compensated (a period the readings "
                      f"sample at one phase, poses that do not determine it, or observations that are inconsistent)")
        elif basis_of(e).driver == "time":
            reason = "a drift with time: no table holds it"
        elif basis_of(e).driver == "pose":
            reason = "follows the whole pose (a joint's sag under the weight it carries): no axis table holds it"
        elif basis_of(e).driver == "positions":
            reason = (f"varies with {e.args[0]}: a cross compensation (the controller's table of "
                      f"{e.code} over {e.args[0]}), not written")
        elif e.axis and e.axis != joint.axis:  # a step at another axis's position
            reason = f"varies with {e.axis}: a cross compensation (a table of {e.code} over {e.axis}), not written"
        elif not all_terms:
            reason = curves[e.name] if e.name in curves else not_significant(values[sl][ok], result.std[sl][ok])
        if reason is not None:
            left.append((e.name, reason))
            values[sl] = np.where(ok, 0.0, values[sl])
    return Compensation(replace(result, values=values), result, tuple(left), tuple(setup), tuple(setup_left))


def _effects_by_axis(result: FitResult):
    """Axis -> list of (effect, its parameter values), for bases driven by that axis's position or direction (of the
    joint's own axis: a step at another axis's is a cross compensation, not in the axis's tables)."""
    out, k = {}, 0
    theta = result.theta
    for e in result.effects:
        if basis_of(e).tabulated and result.machine.error_joint(e.code).axis == e.axis:
            out.setdefault(e.axis, []).append((e, theta[k:k + e.n_params]))
        k += e.n_params
    return out


def axis_error_columns(result: FitResult, axis: str, positions) -> dict:
    """Value of each error joint of ``axis`` at ``positions`` (n,): name -> array (n,).

    Columns: every position-dependent error joint of the axis (``EXX_um`` …), and any other joint
    whose fitted effects are driven by this axis; ``<code>_rev_<unit>`` for direction − where the
    model has a reversal effect on the axis.
    """
    machine = result.machine
    q = np.asarray(positions, float)
    n = q.size
    axes = np.zeros((n, len(machine.axes)))
    axes[:, machine.axis_names.index(axis)] = q
    effects = _effects_by_axis(result).get(axis, [])
    codes = [e.code for e in machine.error_joints if e.axis == axis and not e.location]
    codes += [e.code for e, _ in effects if e.code not in codes]
    has_reversal = any(basis_of(e).driver == "direction" for e, _ in effects)
    out = {}
    for direction, suffix in ((1.0, ""), (-1.0, "_rev")) if has_reversal else ((1.0, ""),):
        dirs = {axis: np.full(n, direction)}
        for code in codes:
            joint = machine.error_joint(code)
            v = np.zeros(n)
            for e, th in effects:
                if e.code == code:
                    v += basis_values(e, machine, axes, directions=dirs) @ th
            out[f"{code}{suffix}_{joint.unit}"] = v
    return out


def positioning_table(result: FitResult, axis: str, positions) -> AxisErrorTable:
    """The axis's own positioning error (``E<a><a>``: EXX for X, ECC for C) as a controller table."""
    machine = result.machine
    code = f"E{axis}{axis}" if len(axis) == 1 else None
    cols = axis_error_columns(result, axis, positions)
    rotary = machine.axis(axis).kind == "revolute"
    unit = "urad" if rotary else "um"
    if code is None or f"{code}_{unit}" not in cols:
        raise DataError(f"axis {axis} has no positioning error joint E{axis}{axis} in the URDF; a controller's "
                        f"axis table holds only that error", parameter="axis")
    fwd = cols[f"{code}_{unit}"]
    rev = cols.get(f"{code}_rev_{unit}")
    return AxisErrorTable(axis, rotary, np.asarray(positions, float), fwd, rev)


# --- the compensation folder -------------------------------------------------------------------

@dataclass(frozen=True)
class CompensationFiles:
    """What :func:`write_compensation` wrote.

    Attributes
    ----------
    files : tuple of str
        File names in the folder.
    notes : tuple of str
        One line per controller file that cannot follow the model within the bound (and why), per
        axis whose tables cover less than its travel, and per effect left out of the compensation.
    controller : tuple of dict
        Per controller file: format, axis, points, range, the error's RMS and what the controller's
        interpolation leaves of it (RMS and largest), in µm or µrad, and what its check found
        (``never_worse``).
    axis_numbers : AxisNumbers
        The controller's number of each axis and where it came from.
    checked : int
        Tables (controller files and CSV columns) applied as their controllers apply them and found never
        worse than no compensation inside the measured range.
    """

    files: tuple
    notes: tuple
    controller: tuple = ()
    axis_numbers: AxisNumbers | None = None
    checked: int = 0
    geometry: object = None  # the rotary axes' geometry (kinid.kinematics_formats.RotaryGeometry), or None


def write_compensation(result: FitResult, folder, *, step_mm: float | None = None, step_deg: float | None = None,
                       formats=None, fit_path=None, range_policy: str = "data", beyond: str = "hold",
                       all_terms: bool = False, axis_numbers: dict | None = None,
                       kinematics_formats=None) -> CompensationFiles:
    """Write the compensation of ``result`` into ``folder``.

    Files: ``<AXIS>.csv`` per motion axis with compensated errors, ``constants.json``,
    ``setup.json`` (the board's and the sensor's set-up, for the work and tool offsets),
    ``calibrated.urdf``, ``compensation.json`` (provenance, ranges, what was left out and why, how
    closely each controller file follows the model), per controller format one file per axis with a
    positioning error, and the rotary axes' geometry per kinematics format (:mod:`.rotary_geometry`).

    Parameters
    ----------
    step_mm, step_deg : float, optional
        Fixed grid steps. Default: per table, the fewest equal steps for which linear interpolation
        departs from the model by at most 10 % of the error's RMS (and the format's resolution).
    formats : sequence of str, optional
        Controller formats (:data:`kinid.axis_tables.CONTROLLER_FORMATS`); default: the default ones.
    range_policy : {"data", "travel"}
        Tables over the measured readings of each axis (default) or the URDF travel.
    beyond : {"hold", "zero"}
        Beyond a table's ends the end values are held, or the compensation returns to zero.
    all_terms : bool
        Compensate every identified term, significant or not.
    axis_numbers : dict axis -> int, optional
        The controller's axis numbers; an axis not given gets its place in the URDF's chain
        (:func:`controller_axis_numbers`).
    kinematics_formats : sequence of str, optional
        Kinematics formats (:data:`kinid.kinematics_formats.KINEMATICS_FORMATS`) for the rotary axes' geometry;
        default: every default one that has a layout for the machine (:mod:`.rotary_geometry`).
    """
    from kinid import __version__
    from kinid.files import check_outputs, json_text, write_text
    from kinid.folders import check_output_folder, staged_folder

    if beyond not in ("hold", "zero"):
        raise DataError(f"must be 'hold' or 'zero', got {beyond!r}", parameter="beyond")
    fmts = [controller_format(f) for f in (default_formats() if formats is None else formats)]
    comp = compensation_model(result, all_terms=all_terms)
    model = comp.result
    machine = model.machine
    numbers = controller_axis_numbers(machine, axis_numbers)
    # every file is made first, then written into a new folder that replaces ``folder`` whole (staged_folder);
    # no input may lie in that folder (the fit, the machine's URDF it names)
    check_outputs([("output", folder, "replaced folder")],
                  [("fit_path", fit_path), ("the fit's machine", getattr(machine, "path", None))])
    check_output_folder(folder, foreign=_not_earlier_compensation)
    files = {}  # name -> text, in the order written
    written, tables, skipped, controller, notes, checks, csv_checks = [], {}, [], [], [], [], []
    for a in machine.axes:
        rotary = a.kind == "revolute"
        unit_q, unit = ("deg", "µrad") if rotary else ("mm", "µm")
        rng = axis_range(model, a.name, range_policy)
        if rng is None:
            skipped.append({"axis": a.name, "reason": "the fit has no readings of this axis"})
            continue
        cols_at = lambda q, name=a.name: axis_error_columns(model, name, q)  # noqa: E731
        probe = cols_at(np.linspace(rng.low, rng.high, 257))
        if not any(np.any(v != 0) for v in probe.values()):
            skipped.append({"axis": a.name, "reason": "no compensated error on this axis"})
            continue
        step = step_mm if a.kind == "prismatic" else step_deg
        names = list(probe)
        stack = lambda q, f=cols_at: np.vstack(list(f(q).values()))  # noqa: E731
        not_modulo = not_one_turn(a.name, names, cols_at, rng) if rng.modulo else None
        if not_modulo is not None:
            if range_policy == "travel":
                raise DataError(f"travel: {not_modulo['reason']}, and {a.name}'s travel is more than a turn; give "
                                f"--table-range data (the measured readings)", parameter="range_policy")
            rng = replace(rng, low=rng.measured[0], high=rng.measured[1], source="measured readings", modulo=False)
            notes.append(f"{a.name}: {not_modulo['reason']}; its tables are not modulo, over the measured readings "
                         f"{rng.low:.4g} .. {rng.high:.4g}°, " + ("end values held" if beyond == "hold" else
                                                                   "zero") + " beyond" + not_modulo["scale_words"])
        span = rng.measured or (rng.low, rng.high)
        # a one-turn table's figures over its whole turn (readings in −180 … 175° are that turn too)
        inside = np.linspace(rng.low, rng.high, 2001) if rng.modulo else \
            np.linspace(max(span[0], rng.low), min(span[1], rng.high), 2001)
        checked_at = check_positions(model.axis_readings.get(a.name), span)
        travel_ends = [] if rng.modulo else [t for t in rng.travel if np.isfinite(t) and not rng.low <= t <= rng.high]
        bounds = np.maximum(BOUND_SHARE * np.sqrt(np.mean(stack(inside) ** 2, axis=1)), 1e-3)
        q = table_grid(stack, rng, bounds, CSV_MAX_POINTS - extra_points(rng, beyond, False), step)
        q_ext, cols = with_ends(q, cols_at(q), rng, beyond, False)
        files[f"{a.name}.csv"] = neutral_csv_text(a.column, q_ext, cols)
        written.append(f"{a.name}.csv")
        for column, read in csv_tables(files[f"{a.name}.csv"], rng.modulo).items():
            csv_checks.append((TableCheck(f"{a.name}.csv (column {column})", a.name, (unit_q, unit),
                                      lambda x, f=cols_at, c=column: f(x)[c][None],
                                      lambda x, t=read: applied(t, x)[None], floor=1e-3), checked_at, travel_ends))
        tables[a.name] = {"file": f"{a.name}.csv", "column": a.column, "from": float(rng.low), "to": float(rng.high),
                          "points": int(q_ext.size), "range": rng.source, "modulo": rng.modulo,
                          "measured": None if rng.measured is None else list(rng.measured),
                          "travel": [v if np.isfinite(v) else None for v in rng.travel], "columns": names,
                          "not_modulo": None if not_modulo is None else
                          {k: v for k, v in not_modulo.items() if k != "scale_words"}}
        travel_span = rng.travel[1] - rng.travel[0]
        if rng.measured is not None and not rng.modulo and not_modulo is None and np.isfinite(travel_span) and \
                (rng.high - rng.low) < 0.9 * travel_span:
            notes.append(f"{a.name}: tables over {rng.source} {rng.low:.4g} .. {rng.high:.4g} {unit_q} of the travel "
                         f"{rng.travel[0]:.4g} .. {rng.travel[1]:.4g} {unit_q}; beyond, "
                         + ("the end values are held" if beyond == "hold" else "the compensation returns to zero")
                         + (" (--table-range travel for the whole travel)" if range_policy == "data" and
                            (not rotary or rng.travel[1] - rng.travel[0] <= 360.0 + 1e-9) else ""))
        code = f"E{a.name}{a.name}"
        key = f"{code}_{'urad' if rotary else 'um'}"
        if code not in machine.error_codes or not np.any(probe.get(key, np.zeros(1)) != 0):
            continue
        pos_at = lambda x, name=a.name: directions(positioning_table(model, name, x))  # noqa: E731
        error_rms = rms(pos_at(inside))
        for fmt in fmts:
            # a format that does not wrap compensates the reading as it is: its one-turn table where the readings are
            frng = rng if fmt.modulo else unwrapped_range(rng)
            f_inside = inside if frng is rng else np.linspace(frng.low, frng.high, 2001)
            f_ends = travel_ends if frng is rng else \
                [t for t in frng.travel if np.isfinite(t) and not frng.low <= t <= frng.high]
            res = fmt.resolution(rotary)
            target = BOUND_SHARE * error_rms - res / 2
            limited = "resolution" if target < res / 2 else None
            target = max(target, res / 2)
            most = fmt.max_points - extra_points(frng, beyond, fmt.equidistant)
            values_at = pos_at if fmt.bidirectional else (lambda x, f=pos_at: f(x).mean(axis=0, keepdims=True))
            fq = table_grid(values_at, frng, [target] * values_at(inside[:2]).shape[0], most, step)
            base = positioning_table(model, a.name, fq)
            fq_ext, ends = with_ends(fq, {"f": base.forward, "b": base.backward}, frng, beyond, fmt.equidistant)
            table = AxisErrorTable(a.name, rotary, fq_ext, ends["f"], None if base.reverse is None else ends["b"])
            options = TableOptions(axis_number=numbers.numbers[a.name], modulo=frng.modulo,
                                   comment=f"kinid {__version__}: {code} of {Path(machine.path).name}, "
                                           f"error = actual - commanded")
            name = fmt.file_name(a.name)
            files[name] = fmt.write(table, options)
            written.append(name)
            if fmt.read is None:
                notes.append(f"{name}: {fmt.title} has no reader in kinid; checked as the table given to its writer")
            read = (FileTable(table.positions, table.forward, table.backward, frng.modulo)
                    if fmt.read is None else fmt.read(files[name], rotary))
            both = (lambda x, t=read: np.vstack([applied(t, x, True), applied(t, x, False)])) if fmt.bidirectional \
                else (lambda x, t=read: applied(t, x)[None])
            checks.append((TableCheck(name, a.name, (unit_q, unit), values_at, both, floor=res), checked_at,
                           f_ends))
            left = left_after(fmt, table, values_at, f_inside, res)
            if fq.size >= most and left["rms"] > BOUND_SHARE * error_rms:
                limited = "points"
            entry = {"file": name, "format": fmt.name, "axis": a.name, "axis_number": options.axis_number,
                     "points": int(table.positions.size), "step": float(fq[1] - fq[0]),
                     "from": float(fq[0]), "to": float(fq[-1]), "ends_added": int(fq_ext.size - fq.size),
                     "modulo": frng.modulo, "unit": unit,
                     "error_rms": error_rms, "left_rms": left["rms"], "left_max": left["max"],
                     "bound_rms": BOUND_SHARE * error_rms, "beyond": fmt.beyond, "sign": fmt.sign}
            if not fmt.bidirectional and base.reverse is not None:
                entry["reversal"] = float(np.mean(base.reverse - base.forward))
                notes.append(f"{name}: one table for both directions (their mean); set the reversal "
                             f"{entry['reversal']:.3g} {unit} in the controller's backlash compensation")
            controller.append(entry)
            if left["rms"] > BOUND_SHARE * error_rms:
                why = {"points": f"{fmt.title} holds {fmt.max_points} points",
                       "resolution": f"{fmt.title} stores values in steps of {res:.3g} {unit}"}.get(limited, "")
                notes.append(f"{name}: the controller's interpolation leaves {left['rms']:.3g} {unit} RMS of the "
                             f"{error_rms:.3g} {unit} RMS error ({left['rms'] / error_rms:.0%}, more than "
                             f"{BOUND_SHARE:.0%}){': ' + why if why else ''}")
    # never worse than none: every table applied as its controller applies it, before anything is written (the axis
    # tables of kinid's own CSV, always written, are refused rather than left out)
    check_tables(csv_checks, by_name=True)
    outcome, worse = check_tables(checks, by_name=formats is not None)
    for name, why in worse:  # a default format that cannot follow the error is left out, the others written
        del files[name]
        written.remove(name)
        notes[:] = [n for n in notes if not n.startswith(f"{name}: ")]
        notes.append(f"{name}: left out — {why}")
    controller = [entry for entry in controller if entry["file"] in outcome]
    for entry in controller:
        entry["never_worse"] = outcome[entry["file"]]
    setup = setup_offsets(result, written_as_zero=dict(comp.setup_left_out))
    files["constants.json"] = json_text({"errors": constant_errors(result, comp)},
                                        path=Path(folder) / "constants.json")
    written.append("constants.json")
    if setup:
        files["setup.json"] = json_text({
            "meaning": "where the workpiece (board) and the sensor (tool) really are, in their nominal frames: "
                       "oMw_actual = oMw_nominal · S_W, oMt_actual = oMt_nominal · S_T; load them as the work "
                       "offset and the tool offset, not into the machine's compensation",
            **setup}, path=Path(folder) / "setup.json")
        written.append("setup.json")
    files["calibrated.urdf"] = calibrated_urdf(model)
    written.append("calibrated.urdf")
    kinematics = kinematics_files(comp, kinematics_formats, f"kinid {__version__}: rotary axes of "
                                                            f"{Path(machine.path).name}")
    if kinematics is not None:
        files.update(kinematics.files)
        written += list(kinematics.files)
        notes += list(kinematics.notes)
    notes += [f"{n}: left out ({why})" for n, why in comp.left_out if not why.startswith("set-up")]
    notes += [f"{n}: written as 0 in setup.json ({why})" for n, why in comp.setup_left_out]
    info = {
        "kinid_version": __version__,
        "fit": None if fit_path is None else {"file": str(fit_path), "sha256": _sha256(fit_path)},
        "machine": machine.path,
        "sign_convention": "error = actual - commanded, µm (linear) or µrad (rotary); direction + unless _rev",
        "range_policy": {"data": "the measured readings of each axis", "travel": "the URDF travel"}[range_policy],
        "beyond": {"hold": "end values held beyond a table", "zero": "zero one step beyond a table's ends"}[beyond],
        "significance": ("every identified term" if all_terms else
                         f"terms with a parameter beyond its expanded uncertainty (k = {K_EXPANDED:g})"),
        "interpolation_bound": f"{BOUND_SHARE:.0%} of the error's RMS inside the measured range, "
                               f"or the format's resolution",
        "fitted_ranges": {k: list(v) for k, v in result.axis_ranges.items()},
        "tables": tables,
        "controller_files": controller,
        "axes_without_tables": skipped,
        "left_out": [{"effect": n, "reason": why} for n, why in comp.left_out],
        "axis_numbers": numbers.as_dict(),
        "setup_significance": ("every identified set-up term" if all_terms else
                               f"set-up terms beyond their expanded uncertainty (k = {K_EXPANDED:g}); the others "
                               f"written as 0"),
        "setup_written_as_zero": [{"effect": n, "reason": why} for n, why in comp.setup_left_out],
        "setup_file": "setup.json" if setup else None,
        "kinematics": None if kinematics is None else kinematics.info,
        "never_worse": {"tables_checked": len(outcome), "rule": (
            "each table, read back and applied as its controller applies it, leaves at no measured position (the "
            "readings and 2001 points over the measured range) more than the error itself plus 10 % of its RMS (or "
            "the format's resolution), and beyond the data no more than the largest error inside it")},
    }
    files["compensation.json"] = json_text(info, path=Path(folder) / "compensation.json")
    written.append("compensation.json")
    with staged_folder(folder, foreign=_not_earlier_compensation) as stage:
        for name, text in files.items():
            write_text(stage / name, text)
    return CompensationFiles(tuple(written), tuple(notes), tuple(controller), numbers, len(outcome),
                             None if kinematics is None else kinematics.geometry)


def _sha256(path) -> str:
    try:
        return hashlib.sha256(Path(path).read_bytes()).hexdigest()
    except OSError as exc:
        raise DataError(f"cannot read the fit file ({exc.strerror or exc})", path=path) from None


#: Files every compensation folder holds (``setup.json`` where the fit has a set-up).
FIXED_FILES = ("constants.json", "setup.json", "calibrated.urdf", "compensation.json")


def _not_earlier_compensation(folder) -> list:
    """Names in ``folder`` that are not an earlier result of :func:`write_compensation`.

    An earlier result holds ``compensation.json`` written by kinid and only the files it lists (tables,
    controller files) besides :data:`FIXED_FILES`; anything else — the user's files, a sub-folder, a
    link, or no such ``compensation.json`` at all — keeps the folder from being replaced.
    """
    import os

    from kinid.files import read_json

    folder = Path(folder)
    names = sorted(os.listdir(folder))
    marker = folder / "compensation.json"
    try:
        info = read_json(marker, what="compensation file") if marker.is_file() and not marker.is_symlink() else None
    except DataError:
        info = None
    if not isinstance(info, dict) or "kinid_version" not in info:
        return names
    own = set(FIXED_FILES)
    tables, controller = info.get("tables"), info.get("controller_files")
    kin = info["kinematics"].get("files") if isinstance(info.get("kinematics"), dict) else None
    for entry in [*(tables.values() if isinstance(tables, dict) else ()),
                  *(controller if isinstance(controller, list) else ()), *(kin if isinstance(kin, list) else ())]:
        if isinstance(entry, dict) and isinstance(entry.get("file"), str):
            own.add(entry["file"])
    return [n for n in names if n not in own or (folder / n).is_symlink() or not (folder / n).is_file()]
