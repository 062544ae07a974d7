"""``identify`` judges the laser's depth with the board pose it fits (docs/observe.md, "The board's pose").

With the laser beside the camera, ``observe`` judged each row's ``mark_dz_mm`` with the board's slope of the nominal
machine and wrote the lever and slope it used (:data:`~.observe.LEVER_COLUMNS`). ``identify`` fits, takes the board's
slope from its fit and moves each row's depth by ``slope_used · lever_used − slope_fitted · lever_fitted``, refits, and
repeats until
the move is within the fit's noise over √N (N rows: the standard error of a shift the rows share, which a fit takes
for a machine term). The fitted board tilt's standard deviations become shared (type B) columns
``shift_fit_ea0w_dz_mm``, ``shift_fit_eb0w_dz_mm`` of the settled rows, as ``observe --fit`` writes them.
"""
from __future__ import annotations

import csv
from dataclasses import dataclass, replace

import numpy as np

__all__ = ["MAX_PASSES", "TILT_SOURCES", "BoardMove", "Settled", "read_levers", "board_move", "settle"]

#: The passes (fit, re-judge the depths) ``identify`` makes before it says the depths did not settle.
MAX_PASSES = 5
#: The board's set-up tilt: its σ times the lever moves every depth alike (type B).
TILT_SOURCES = ("EA0W", "EB0W")


def read_levers(data_path, obs) -> dict | None:
    """Line -> [lever x, lever y, slope x, slope y, camera turn] of each row of ``obs`` from the observation CSV
    ``data_path`` (the turn, µrad, the mark's part of the lever was taken into the slope's axes with: the column
    ``laser_marks_turn_urad`` ``observe --fit`` writes, else 0, as the first observe judges); None when the file has
    not the four columns (the laser on the camera's axis, or not observed by kinid)."""
    from .observe import LEVER_COLUMNS, MARKS_TURN_COLUMN

    with open(data_path, newline="") as f:
        reader = csv.DictReader(f)
        if not set(LEVER_COLUMNS) <= set(reader.fieldnames or ()):
            return None
        columns = (*LEVER_COLUMNS, MARKS_TURN_COLUMN) if MARKS_TURN_COLUMN in reader.fieldnames else LEVER_COLUMNS
        by_line = {reader.line_num: [*(_number(row[c], data_path, reader.line_num, c) for c in columns), 0.0][:5]
                   for row in reader}
    if not obs.lines or not all(line in by_line for line in obs.lines):
        return None
    return by_line


def _number(text, path, line: int, column: str) -> float:
    """A lever or slope cell as a finite number; one line naming the cell otherwise (a silently skipped pass would
    leave every depth judged with the nominal board)."""
    from kinid.errors import DataError

    try:
        value = float(text)
    except (TypeError, ValueError):
        value = None
    if value is None or not np.isfinite(value):
        raise DataError(f"{text!r} is not a finite number: observe writes the laser's lever (mm) and the board's slope "
                        f"it used with each row; a row edited by hand? (remove the four lever and slope columns to "
                        f"fit the depths as they are)", path=path, line=line, column=column)
    return value


@dataclass(frozen=True)
class BoardMove:
    """How the fitted board pose moves the depths of the rows: ``dz_mm`` (N,), the fitted ``slope`` (N, 2), the
    camera's turn ``turn_urad`` the marks' part of the levers was taken into the machine's axes with, and the tilt's
    shared shifts (source -> (N, 3), mm); ``rms_um`` the move's RMS and ``noise_um`` the fit's σ.

    The depths are settled when the move is within ``limit_um``, the noise over √N: a move within the noise but
    beyond that is common to the rows and biases the fit (a sag of X along Z on the B/C table, the laser 15 mm
    beside the camera: 0.68 µm RMS within the noise 1.44 µm left the held-out error 1.75× the on-axis one)."""

    dz_mm: np.ndarray
    slope: np.ndarray
    shifts_mm: dict
    rms_um: float
    noise_um: float
    turn_urad: float = 0.0

    @property
    def limit_um(self) -> float:
        return self.noise_um / float(np.sqrt(max(len(self.dz_mm), 1)))

    @property
    def within(self) -> bool:
        return not self.rms_um > self.limit_um


def _slopes(machine, axes, errors) -> np.ndarray:
    from ..data import board_pose

    n = board_pose(machine, axes, errors).normals
    return n[:, :2] / n[:, 2:]


def board_move(machine, fit, obs, by_line) -> BoardMove:
    """The move of each row's ``mark_dz_mm`` when the board's slope is the one ``fit`` finds at the row's pose.

    The slope is taken in the machine's axes (the camera's turn on the tool, ``EC0T``, held at 0), the frame the laser's
    offset was measured in; the mark's own part of the lever (its tool-frame x, y, up to half a millimetre, seen in
    the camera's axes) is turned into them by the fitted turn: held at 0, a turn of 2.25 mrad times the board's slope
    at a 40° tilt (0.84) times that part left the settled depths 0.45 µm RMS off the truth, following the pose, which
    ``--auto`` took for an effect the machine lacks (a cubic EZZ on a B/C table with a straightness of Y: the chain's
    proving ground, scenario 300010). A turn the images determine to no better than the laser's noise over that part
    of the lever, or one ``compensate`` writes as 0 (within its uncertainty), is left at 0."""
    from ..data import lever_in_machine_mm
    from ..fitting import joint_values
    from .observe import _usable, marks_turn

    table = np.array([list(by_line[line]) + [0.0] * (5 - len(by_line[line])) for line in obs.lines])
    lever, used, used_turn = table[:, :2], table[:, 2:4], table[:, 4]
    reach = float(np.sqrt(np.mean(np.sum(lever**2, axis=1))))
    d, values, vague = _usable(fit, machine, obs, reach)
    codes = list(fit.param_names)
    marks = obs.offsets_mm[:, :2]
    if "EC0T" in codes:
        values[codes.index("EC0T")] = 0.0
    turn, reach_limit_mm = marks_turn(fit)
    turn = turn if float(np.sqrt(np.mean(np.sum(marks**2, axis=1)))) <= reach_limit_mm else 0.0
    lever_used, lever = lever_in_machine_mm(lever, marks, used_turn), lever_in_machine_mm(lever, marks, turn)
    slope = _slopes(machine, obs.axes, joint_values(machine, d, values))
    shifts = {}
    for name in TILT_SOURCES:
        k = codes.index(name) if name in codes else None
        if k is None or vague[k] or not (np.isfinite(fit.std[k]) and fit.std[k] > 0):
            continue
        moved = values.copy()
        moved[k] += fit.std[k]
        shift = np.zeros((len(obs), 3))
        shift[:, 2] = np.sum((slope - _slopes(machine, obs.axes, joint_values(machine, d, moved))) * lever, axis=1)
        shifts["fit_" + name.lower()] = shift
    dz_mm = np.sum(used * lever_used, axis=1) - np.sum(slope * lever, axis=1)
    return BoardMove(dz_mm, slope, shifts, float(np.sqrt(np.mean(dz_mm**2))) * 1e3, float(fit.noise.value_um), turn)


def _moved(obs, by_line, move: BoardMove):
    """``obs`` with the depths moved and the tilt's shifts; ``by_line`` takes the slopes and the turn now used."""
    offsets = obs.offsets_mm.copy()
    offsets[:, 2] += move.dz_mm
    for i, line in enumerate(obs.lines):
        by_line[line][2:] = [float(move.slope[i, 0]), float(move.slope[i, 1]), move.turn_urad]
    kept = {k: v for k, v in obs.shifts_mm.items() if not k.startswith("fit_")}  # observe --fit's: judged again
    return replace(obs, offsets_mm=offsets, shifts_mm={**kept, **move.shifts_mm})


@dataclass(frozen=True)
class Settled:
    """The rows with their depths judged with the fitted board pose, and how that went: ``passes`` fits made,
    ``move_um`` the last pass's move (RMS) against ``limit_um`` (the noise ``noise_um`` over √N), ``settled`` whether
    it was within."""

    obs: object
    passes: int
    move_um: float
    noise_um: float
    limit_um: float
    settled: bool

    def record(self, passes_before: int = 0) -> dict:
        """The fit file's ``board_pose`` entry."""
        return {"passes": passes_before + self.passes, "move_um": self.move_um, "noise_um": self.noise_um,
                "settled": self.settled}


def settle(machine, obs, by_line, fit_once, *, say=print, max_passes: int = MAX_PASSES, first=None,
           start: int = 1) -> Settled:
    """Fit (``fit_once(obs) -> FitResult``), move the depths by the fitted board pose, refit, until the move is within
    the fit's noise over √N (:attr:`BoardMove.limit_um`; that last move is made too: the caller fits the rows returned) or ``max_passes`` fits were
    made; one line per pass through ``say``, the passes numbered from
    ``start``. ``first``: a fit of ``obs`` the first pass takes instead of fitting. ``by_line`` is updated with the
    slopes used."""
    for k in range(start, start + max_passes):
        result = first if k == start and first is not None else fit_once(obs)
        move = board_move(machine, result, obs, by_line)
        if move.within:
            say(f"board pose: pass {k} moved mark_dz_mm by {move.rms_um:.3f} µm RMS, {_against(move)}: settled")
            return Settled(_moved(obs, by_line, move), k - start + 1, move.rms_um, move.noise_um, move.limit_um, True)
        obs = _moved(obs, by_line, move)
        say(f"board pose: pass {k} moved mark_dz_mm by {move.rms_um:.3f} µm RMS, {_against(move)}: judged again "
            f"with the fitted board pose")
    say(f"board pose: mark_dz_mm did not settle in {max_passes} passes (the last moved it by {move.rms_um:.3f} µm RMS, "
        f"{_against(move)}): the rows of the last pass are used; check the laser's offset and the board")
    return Settled(obs, max_passes, move.rms_um, move.noise_um, move.limit_um, False)


def _against(move: BoardMove) -> str:
    return (f"{'within' if move.within else 'more than'} {move.limit_um:.3f} µm (the noise {move.noise_um:.2f} µm over "
            f"√{len(move.dz_mm)} rows)")
