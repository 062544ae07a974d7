"""The backlash method on a run recorded on a real stage: the plan to run, and the run's log replayed.

A user runs the plan (:func:`plan_rows`, ``kinid backlash --plan-out PLAN.csv``) on the stage, saving
an image after every move that asks for a photo, and writes the log: the plan's rows with the image
file names filled in (docs/backlash.md, "Measured runs"). :class:`RecordedStage` replays the log
as a stage (``move_to`` / ``grab``), so :func:`~kinid.stages.backlash.calibrate.calibrate` runs the
method exactly as on a live stage, and refuses a log that is not the plan's run.
"""
from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from kinid.errors import DataError
from kinid.files import csv_number, read_csv_table, read_image

from .plan import plan_moves

__all__ = ["plan_rows", "plan_text", "RecordedStage", "LOG_COLUMNS"]

#: Columns of a plan and of a run log.
LOG_COLUMNS = ("move", "x_mm", "y_mm", "theta_deg", "photo", "image")
#: A logged command may differ from the plan's by this much (mm or deg): rounding in the log.
COMMAND_TOL = 1e-6


def plan_rows(travel_mm, travel_deg, *, repeats=1, n_targets=1, start=(0.0, 0.0, 0.0)) -> list:
    """The moves to run: (move, x_mm, y_mm, theta_deg, photo, suggested image name) per move."""
    rows = []
    for i, pm in enumerate(plan_moves(travel_mm, travel_deg, repeats=repeats, n_targets=n_targets), start=1):
        cmd = tuple(float(s) + o for s, o in zip(start, pm.offset))
        rows.append((i, *cmd, int(pm.photo), f"move_{i:03d}.png" if pm.photo else ""))
    return rows


def plan_text(rows) -> str:
    """CSV text of :func:`plan_rows`."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(LOG_COLUMNS)
    for move, x, y, t, photo, image in rows:
        w.writerow([move, f"{x:.6f}", f"{y:.6f}", f"{t:.6f}", photo, image])
    return buf.getvalue()


class RecordedStage:
    """A run log replayed as a stage: ``move_to`` checks each command against the log, ``grab`` reads its image.

    Parameters
    ----------
    path : str or Path
        The run log (CSV, columns :data:`LOG_COLUMNS`; ``photo`` optional); images relative to its folder.
    """

    def __init__(self, path):
        self.path = Path(path)
        _, header, rows = read_csv_table(self.path, what="run log", required=("move", "x_mm", "y_mm", "theta_deg", "image"))
        self._rows = []
        for line, cells in rows:
            num = lambda c: csv_number(cells, header.index(c), path=self.path, line=line, column=c)  # noqa: E731
            cmd = (num("x_mm"), num("y_mm"), num("theta_deg"))
            self._rows.append((line, int(num("move")), cmd, cells[header.index("image")].strip()))
        if len(self._rows) < 9:
            raise DataError(f"{len(self._rows)} moves; the plan has at least 21 (kinid backlash --plan-out writes it)",
                            path=self.path)
        self._next = 0
        self._current = None

    @property
    def position(self):
        """The start the plan was centred on: the command of move 9 (the plan's offset 0)."""
        return self._rows[8][2]

    def move_to(self, x_mm, y_mm, theta_deg) -> None:
        if self._next >= len(self._rows):
            raise DataError(f"the log ends after {len(self._rows)} moves but the plan has more; run the whole plan "
                            f"or give the options the run was made with (--travel-mm, --travel-deg, --repeats, "
                            f"--targets)", path=self.path)
        line, move, logged, image = self._rows[self._next]
        want = np.array([x_mm, y_mm, theta_deg], float)
        if np.max(np.abs(want - logged)) > COMMAND_TOL:
            raise DataError(f"move {move} went to ({', '.join(f'{v:g}' for v in logged)}) but the plan's move "
                            f"{self._next + 1} is ({', '.join(f'{v:g}' for v in want)}); give the options the run "
                            f"was made with (--travel-mm, --travel-deg, --repeats, --targets)", path=self.path, line=line)
        self._current = (line, image)
        self._next += 1

    def grab(self) -> np.ndarray:
        line, image = self._current
        if not image:
            raise DataError("the plan takes a photo after this move, and the log names no image", path=self.path,
                            line=line, column="image")
        return read_image(self.path.parent / image)

    def check_complete(self) -> None:
        """DataError if the log holds moves the plan did not make."""
        if self._next != len(self._rows):
            line = self._rows[self._next][0]
            raise DataError(f"the log has {len(self._rows)} moves, the plan {self._next}; give the options the run "
                            f"was made with (--travel-mm, --travel-deg, --repeats, --targets)", path=self.path, line=line)
