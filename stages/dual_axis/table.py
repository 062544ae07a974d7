"""The offset table of two parallel Y axes and the head move it commands.

The table holds, at each vertex ``y_i`` of camera Y, the head correction
``c(y_i) = (cx, cy)`` in mm: how far head X and head Y (axis V) must move
beyond the nominal move (head Y = camera Y travel) so that the plate stays
centred under the camera. ``c(y_0) = 0`` at the start of the calibration by
definition; between vertices ``c`` is piecewise linear (the dual-axis method, Fig. 3).

The head move for a camera-Y move from ``Ps`` to ``Pe`` (docs/hardware.md)::

    dx = cx(Pe) - cx(Ps)
    dy = (Pe - Ps) + cy(Pe) - cy(Ps)

so moves compose: ``head_move(a, b) + head_move(b, c) == head_move(a, c)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from kinid.errors import StageError

__all__ = ["RoundRecord", "OffsetTable", "head_move_from"]


@dataclass(frozen=True)
class RoundRecord:
    """What one calibration round measured.

    Attributes
    ----------
    round : int
        1-based round number.
    offsets_um : numpy.ndarray, shape (n_steps + 1, 2)
        Measured residual at each vertex, expressed as the head X/Y move that
        cancels it, µm (row 0, the start, is 0). It is added to the table.
    max_change_um : float
        Largest component of ``offsets_um``: the largest change of a table entry.
    """

    round: int
    offsets_um: np.ndarray
    max_change_um: float


@dataclass(frozen=True)
class OffsetTable:
    """Piecewise-linear head correction as a function of camera Y.

    Attributes
    ----------
    y_mm : numpy.ndarray, shape (n + 1,)
        Camera Y of the vertices, increasing, mm.
    offset_mm : numpy.ndarray, shape (n + 1, 2)
        Head X and head Y correction at each vertex, mm (row 0 is zero).
    rounds : int
        Number of calibration rounds run.
    converged : bool
        Whether the last round's offsets were all within ``spec_um``.
    spec_um : float
        The acceptance limit per entry, µm.
    history : tuple of RoundRecord
        One record per round.
    message : str
        Human-readable outcome.
    """

    y_mm: np.ndarray
    offset_mm: np.ndarray
    rounds: int = 0
    converged: bool = False
    spec_um: float = float("nan")
    history: tuple = field(default=())
    message: str = ""

    def csv_text(self) -> str:
        """The table as CSV: ``camera_y_mm,head_dx_mm,head_dy_mm`` per vertex (docs/dual_axis.md)."""
        lines = [f"# kinid dual-axis offset table: {self.rounds} round(s), "
                 f"{'converged' if self.converged else 'NOT converged'} within {self.spec_um:g} µm",
                 "camera_y_mm,head_dx_mm,head_dy_mm"]
        lines += [f"{y:.6f},{dx:.6f},{dy:.6f}" for y, (dx, dy) in zip(self.y_mm, self.offset_mm)]
        return "\n".join(lines) + "\n"

    @property
    def y_range_mm(self) -> tuple:
        """(first, last) camera Y the table covers, mm."""
        return float(self.y_mm[0]), float(self.y_mm[-1])

    def correction_mm(self, y_mm):
        """Head correction (X, Y) at camera Y ``y_mm`` by linear interpolation, mm.

        Parameters
        ----------
        y_mm : float or array_like
            Camera Y position(s), mm, within :attr:`y_range_mm`.

        Returns
        -------
        numpy.ndarray
            Shape (2,) for a scalar, (N, 2) for an array.

        Raises
        ------
        StageError
            A position outside the calibrated range.
        """
        y = np.asarray(y_mm, float)
        lo, hi = self.y_range_mm
        tol = 1e-9 * max(1.0, abs(lo), abs(hi))
        if np.any(~np.isfinite(y)) or np.any(y < lo - tol) or np.any(y > hi + tol):
            bad = float(y[(~np.isfinite(y)) | (y < lo - tol) | (y > hi + tol)].ravel()[0])
            raise StageError(f"camera Y {bad:g} mm is outside the calibrated range [{lo:g}, {hi:g}] mm")
        yc = np.clip(y, lo, hi)
        out = np.stack([np.interp(yc, self.y_mm, self.offset_mm[:, 0]),
                        np.interp(yc, self.y_mm, self.offset_mm[:, 1])], axis=-1)
        return out

    def head_move(self, ps_mm, pe_mm):
        """Head move (X, and Y on the head's own axis) for a camera-Y move ``ps_mm`` -> ``pe_mm``.

        Parameters
        ----------
        ps_mm, pe_mm : float
            Start and end camera Y, mm.

        Returns
        -------
        tuple of float
            ``(dx_mm, dy_mm)`` with ``dx = cx(Pe) - cx(Ps)`` and
            ``dy = (Pe - Ps) + cy(Pe) - cy(Ps)``.

        Examples
        --------
        >>> t = OffsetTable(np.array([0.0, 10.0]), np.array([[0.0, 0.0], [0.004, -0.002]]))
        >>> [round(v, 6) for v in t.head_move(0.0, 5.0)]
        [0.002, 4.999]
        """
        return head_move_from(self.correction_mm, ps_mm, pe_mm)

    def with_offsets(self, offsets_mm, **changes) -> "OffsetTable":
        """A copy with ``offsets_mm`` (n + 1, 2) ADDED to the entries (the patent's update rule)."""
        add = np.asarray(offsets_mm, float)
        if add.shape != self.offset_mm.shape:
            raise ValueError(f"offsets must have shape {self.offset_mm.shape}, got {add.shape}")
        return replace(self, offset_mm=self.offset_mm + add, **changes)

    def to_dict(self) -> dict:
        """JSON-ready form (µm)."""
        return {
            "y_mm": self.y_mm.tolist(),
            "offset_x_um": (self.offset_mm[:, 0] * 1e3).tolist(),
            "offset_y_um": (self.offset_mm[:, 1] * 1e3).tolist(),
            "rounds": self.rounds,
            "converged": self.converged,
            "spec_um": self.spec_um,
            "max_change_um": [r.max_change_um for r in self.history],
        }


def head_move_from(correction_mm, ps_mm, pe_mm):
    """``(dx_mm, dy_mm)`` of a head move from a correction function ``c(y) -> (cx, cy)``.

    Parameters
    ----------
    correction_mm : callable
        ``correction_mm(y_mm) -> array (2,)`` head correction, mm.
    ps_mm, pe_mm : float
        Start and end camera Y, mm.
    """
    ps, pe = float(ps_mm), float(pe_mm)
    cs, ce = np.asarray(correction_mm(ps)), np.asarray(correction_mm(pe))
    return float(ce[0] - cs[0]), float((pe - ps) + ce[1] - cs[1])
