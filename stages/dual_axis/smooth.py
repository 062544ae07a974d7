"""A smooth model of the head correction: parallelism angle plus straightness polynomial.

Instead of the patent's piecewise-linear table, the head correction of each
head axis is modelled as a polynomial of camera Y without constant term
(``c(y0) = 0``)::

    cx(y) = sum_{k=1..d} a_k * u**k,   cy(y) = sum_{k=1..d} b_k * u**k,   u = (y - y0) / span

fitted by least squares to the table's vertices. Its straight-line part gives
the two numbers a machine builder reads: the parallelism angle of the head Y
axis (V) against the camera Y axis (slope of the least-squares line of
``cx``; positive when V turns counter-clockwise from Y, so the head drifts
towards -X and must move towards +X; the linear trends of the two
straightness errors are part of it) and the relative scale of the two axes
(slope of the least-squares line of ``cy``). The rest is their relative
straightness and positioning error.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError
from .table import head_move_from

__all__ = ["SmoothModel", "fit_smooth"]


@dataclass(frozen=True)
class SmoothModel:
    """Polynomial head correction fitted to an offset table.

    Attributes
    ----------
    y0_mm : float
        Camera Y of the table's first vertex, mm.
    span_mm : float
        Normalising length (the table's span), mm.
    coef_x_mm, coef_y_mm : numpy.ndarray, shape (degree,)
        Coefficients of ``u**1 .. u**degree`` for head X and head Y, mm.
    rms_um : numpy.ndarray, shape (2,)
        RMS of the fit residual at the vertices (X, Y), µm.
    parallelism_urad : float
        Slope of the least-squares line of the X correction, µrad: the
        parallelism angle of V against Y (counter-clockwise positive).
    scale_um_per_m : float
        Slope of the least-squares line of the Y correction (extra head Y move
        per metre of camera Y), µm/m.
    """

    y0_mm: float
    span_mm: float
    coef_x_mm: np.ndarray
    coef_y_mm: np.ndarray
    rms_um: np.ndarray
    parallelism_urad: float
    scale_um_per_m: float

    @property
    def degree(self) -> int:
        return int(len(self.coef_x_mm))

    def correction_mm(self, y_mm):
        """Head correction (X, Y) at camera Y ``y_mm``, mm; shape (2,) or (N, 2)."""
        u = (np.asarray(y_mm, float) - self.y0_mm) / self.span_mm
        powers = np.stack([u ** (k + 1) for k in range(self.degree)], axis=-1)
        return np.stack([powers @ self.coef_x_mm, powers @ self.coef_y_mm], axis=-1)

    def head_move(self, ps_mm, pe_mm):
        """Head move ``(dx_mm, dy_mm)`` for a camera-Y move ``ps_mm`` -> ``pe_mm`` (as :meth:`OffsetTable.head_move`)."""
        return head_move_from(self.correction_mm, ps_mm, pe_mm)


def fit_smooth(table, degree: int = 3) -> SmoothModel:
    """Fit the parallelism + straightness polynomial to an offset table by least squares.

    Parameters
    ----------
    table : OffsetTable
        A calibrated table (its vertices and entries are the data).
    degree : int
        Highest power of the polynomial (1 = parallelism and scale only).

    Returns
    -------
    SmoothModel

    Raises
    ------
    DataError
        ``degree < 1`` or fewer vertices (besides the start) than ``degree``.
    """
    if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)) or degree < 1:
        raise DataError(f"degree must be an integer >= 1, got {degree!r}")
    y = np.asarray(table.y_mm, float)
    if len(y) - 1 < degree:
        raise DataError(f"a degree-{degree} model needs at least {degree} steps in the table, it has {len(y) - 1}")
    y0, span = float(y[0]), float(y[-1] - y[0])
    u = (y - y0) / span
    a = np.stack([u ** (k + 1) for k in range(int(degree))], axis=1)
    coef, *_ = np.linalg.lstsq(a, np.asarray(table.offset_mm, float), rcond=None)
    resid = a @ coef - table.offset_mm
    rms = np.sqrt(np.mean(resid ** 2, axis=0)) * 1e3
    line = np.column_stack([y - y0, np.ones_like(y)])
    slope, *_ = np.linalg.lstsq(line, np.asarray(table.offset_mm, float), rcond=None)
    return SmoothModel(y0, span, coef[:, 0].copy(), coef[:, 1].copy(), rms,
                       float(slope[0, 0] * 1e6), float(slope[0, 1] * 1e6))
