"""Pixel equivalent, reversal (backlash) gaps and the 2 x 2 pixel-to-machine matrix.

A camera looks at a feature on a stage. Commanded stage moves (machine mm) and
the feature's image shifts (pixels) relate the two frames:

* the **pixel equivalent** ``r = |move| / |shift|`` (mm per pixel) of the
  lead-screw backlash patent CN105547173 (seed ``000``): a length ratio, so it
  does not depend on how the camera is rotated relative to the stage axes;
* the **reversal gap** ``d = r * |p1 - p2|`` between two images of the feature
  taken at the same commanded position approached from opposite sides;
* the **pixel-to-machine matrix** ``M`` (2 x 2, mm per pixel) with
  ``move_mm = M @ shift_px`` that also carries the rotation, the skew and a
  possible mirror between image and stage axes (the "hand-eye" matrix of the
  dual-axis method, seed ``003``).

Pixel coordinates follow OpenCV (x right, y down). Machine coordinates are the
stage's X and Y axes, in mm.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError

__all__ = [
    "ScaleResult",
    "ReversalResult",
    "MatrixResult",
    "pixel_equivalent",
    "backlash_from_reversals",
    "pixel_to_machine_matrix",
]


@dataclass(frozen=True)
class ScaleResult:
    """Pixel equivalent from non-reversal moves.

    Attributes
    ----------
    mm_per_px : float
        Mean of the per-move ratios, mm per pixel.
    mm_per_px_x, mm_per_px_y : float
        Mean over the moves classified as along machine X (Y); NaN when there
        is no such move (or when move lengths were given without axes).
    per_move : numpy.ndarray, shape (N,)
        ``|move_mm| / |shift_px|`` of every move, mm per pixel.
    sigma : float
        Sample standard deviation of ``per_move`` (0 for one move), mm per pixel.
    axes : tuple of str
        ``"x"``, ``"y"`` or ``"xy"`` (oblique) for every move.
    n_x, n_y : int
        Number of X and Y moves.
    """

    mm_per_px: float
    mm_per_px_x: float
    mm_per_px_y: float
    per_move: np.ndarray
    sigma: float
    axes: tuple
    n_x: int
    n_y: int


@dataclass(frozen=True)
class ReversalResult:
    """Backlash (lost motion) from pairs of images across reversals.

    Attributes
    ----------
    backlash_mm : float
        Mean of ``per_reversal_mm``.
    per_reversal_mm : numpy.ndarray, shape (N,)
        Gap of every reversal, mm (``r * |p1 - p2|``, or ``|M @ (p2 - p1)|``,
        or the signed component along ``axis_mm`` when one is given).
    spread_mm : float
        Sample standard deviation of ``per_reversal_mm`` (0 for one reversal).
    sigma_mm : float
        Standard error of the mean, ``spread_mm / sqrt(N)``.
    n : int
        Number of reversals.
    """

    backlash_mm: float
    per_reversal_mm: np.ndarray
    spread_mm: float
    sigma_mm: float
    n: int


@dataclass(frozen=True)
class MatrixResult:
    """Least-squares 2 x 2 pixel-to-machine matrix ``move_mm = matrix @ shift_px``.

    Attributes
    ----------
    matrix : numpy.ndarray, shape (2, 2)
        mm per pixel; column 0 is the machine displacement of one pixel along
        image x, column 1 of one pixel along image y.
    scale_x, scale_y : float
        Lengths of the two columns: mm per pixel along image x and image y.
    rotation_deg : float
        Direction of the image x axis in the machine frame,
        ``atan2(M[1, 0], M[0, 0])``, degrees (counter-clockwise from machine X
        towards machine Y).
    skew_deg : float
        Departure of the two image axes from perpendicular as seen in the
        machine frame, degrees (0 for square pixels).
    mirrored : bool
        True when ``det(matrix) < 0`` (image y down while machine Y points up
        in the image, the usual case of a camera looking down on a stage).
    residual_rms_mm : float
        RMS of ``|matrix @ shift - move|`` over the moves, mm.
    n : int
        Number of moves used.
    """

    matrix: np.ndarray
    scale_x: float
    scale_y: float
    rotation_deg: float
    skew_deg: float
    mirrored: bool
    residual_rms_mm: float
    n: int

    def to_machine(self, shifts_px) -> np.ndarray:
        """Map pixel offsets (N, 2) or (2,) to machine mm with the matrix."""
        s = np.asarray(shifts_px, float)
        return s @ self.matrix.T


def _as_points(name, value, n=None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"must be an (N, 2) array of numbers, got {type(value).__name__}", parameter=name) from None
    if arr.ndim == 1 and arr.shape[0] == 2 and n == 1:
        arr = arr.reshape(1, 2)
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise DataError(f"{name} must have shape (N, 2), got shape {arr.shape}", column=name)
    if n is not None and arr.shape[0] != n:
        raise DataError(f"{name} must have {n} rows to match the other argument, got {arr.shape[0]}", column=name)
    if not np.all(np.isfinite(arr)):
        raise DataError(f"{name} holds a non-finite value (NaN or inf)", column=name)
    return arr


def _classify(move_mm: np.ndarray, axis_tol: float) -> str:
    ax, ay = abs(move_mm[0]), abs(move_mm[1])
    if ay <= axis_tol * ax:
        return "x"
    if ax <= axis_tol * ay:
        return "y"
    return "xy"


def pixel_equivalent(moves_mm, shifts_px, *, axes=None, axis_tol=1e-6) -> ScaleResult:
    """Pixel equivalent ``r = |move| / |shift|`` averaged over non-reversal moves.

    Each move must be a non-reversal one (or, more generally, its two images
    must be taken after approaching from the same side on every axis), so that
    the lead-screw backlash cancels and the actual displacement equals the
    commanded one (CN105547173, claims 1-3).

    Parameters
    ----------
    moves_mm : array_like, shape (N, 2) or (N,)
        Commanded stage displacement of every move (machine X, Y), mm; or the
        move lengths, mm.
    shifts_px : array_like, shape (N, 2)
        Image displacement of the feature for every move, pixels.
    axes : sequence of str or None
        ``"x"``/``"y"`` for every move when ``moves_mm`` holds lengths; ignored
        for (N, 2) moves, which are classified by direction.
    axis_tol : float
        A move is along X when ``|dy| <= axis_tol * |dx|`` (and vice versa).

    Returns
    -------
    ScaleResult

    Raises
    ------
    DataError
        On mismatched shapes, a zero-length move or a zero image shift.

    Examples
    --------
    >>> r = pixel_equivalent([[1.0, 0.0], [0.0, 0.5]], [[200.0, 0.0], [0.0, -100.0]])
    >>> round(r.mm_per_px, 6), round(r.mm_per_px_y, 6)
    (0.005, 0.005)
    """
    from kinid.checks import check_array

    moves = check_array("moves_mm", moves_mm, finite=False)
    if moves.ndim == 1:
        lengths = np.abs(moves)
        n = lengths.shape[0]
        if axes is None:
            axis_names = ("xy",) * n
        else:
            axis_names = tuple(str(a).lower() for a in axes)
            if len(axis_names) != n or any(a not in ("x", "y", "xy") for a in axis_names):
                raise DataError(f"axes must give 'x', 'y' or 'xy' for each of the {n} moves, got {axes!r}",
                                column="axes")
    else:
        moves = _as_points("moves_mm", moves)
        n = moves.shape[0]
        lengths = np.hypot(moves[:, 0], moves[:, 1])
        axis_names = tuple(_classify(m, axis_tol) for m in moves)
    if n < 1:
        raise DataError("pixel_equivalent needs at least one move, got none", column="moves_mm")
    shifts = _as_points("shifts_px", shifts_px, n)
    dist = np.hypot(shifts[:, 0], shifts[:, 1])
    if not np.all(np.isfinite(lengths)) or np.any(lengths <= 0):
        i = int(np.flatnonzero(~(lengths > 0))[0])
        raise DataError(f"move {i} has length {float(lengths[i])!r} mm; every move must be non-zero",
                        column="moves_mm")
    if np.any(dist <= 0):
        i = int(np.flatnonzero(dist <= 0)[0])
        raise DataError(f"move {i}: the feature did not move in the image (shift 0 px); "
                        "is the stage moving and the camera looking at it?", column="shifts_px")
    ratios = lengths / dist
    names = np.array(axis_names)
    rx = ratios[names == "x"]
    ry = ratios[names == "y"]
    return ScaleResult(
        mm_per_px=float(ratios.mean()),
        mm_per_px_x=float(rx.mean()) if rx.size else float("nan"),
        mm_per_px_y=float(ry.mean()) if ry.size else float("nan"),
        per_move=ratios,
        sigma=float(ratios.std(ddof=1)) if n > 1 else 0.0,
        axes=axis_names,
        n_x=int(rx.size),
        n_y=int(ry.size),
    )


def backlash_from_reversals(p1_px, p2_px, mm_per_px, *, axis_mm=None) -> ReversalResult:
    """Backlash ``d = r * |p1 - p2|`` across reversals, averaged (CN105547173, claims 1, 4).

    ``p1`` and ``p2`` are the feature's image positions at the *same commanded
    position* approached from opposite sides, so that they differ by one full
    lost motion.

    Parameters
    ----------
    p1_px, p2_px : array_like, shape (N, 2)
        Feature positions before and after every reversal, pixels.
    mm_per_px : float or array_like, shape (2, 2)
        Pixel equivalent (mm per pixel), or the pixel-to-machine matrix of
        :func:`pixel_to_machine_matrix`, which maps ``p2 - p1`` to machine mm.
    axis_mm : array_like, shape (2,), optional
        A machine direction (needs the matrix form of ``mm_per_px``): the gap is
        then the *signed* component of ``M @ (p2 - p1)`` along it, which is
        unbiased when the backlash is near zero, where the norm is not.

    Returns
    -------
    ReversalResult

    Examples
    --------
    >>> res = backlash_from_reversals([[10, 10], [50, 10]], [[10.6, 10.8], [50.8, 10.6]], 0.005)
    >>> round(res.backlash_mm, 6)
    0.005
    """
    p1 = _as_points("p1_px", p1_px)
    p2 = _as_points("p2_px", p2_px, p1.shape[0])
    n = p1.shape[0]
    if n < 1:
        raise DataError("backlash_from_reversals needs at least one reversal, got none", column="p1_px")
    diff = p2 - p1
    from kinid.checks import check_array

    scale = check_array("mm_per_px", mm_per_px, finite=False)
    if scale.ndim == 0:
        if not (np.isfinite(scale) and scale > 0):
            raise DataError(f"mm_per_px must be a positive number, got {mm_per_px!r}", column="mm_per_px")
        if axis_mm is not None:
            raise DataError("axis_mm needs mm_per_px as a 2 x 2 pixel-to-machine matrix", column="axis_mm")
        gaps = float(scale) * np.hypot(diff[:, 0], diff[:, 1])
    elif scale.shape == (2, 2):
        if not np.all(np.isfinite(scale)):
            raise DataError("mm_per_px matrix holds a non-finite value", column="mm_per_px")
        moved = diff @ scale.T
        if axis_mm is None:
            gaps = np.hypot(moved[:, 0], moved[:, 1])
        else:
            axis = np.asarray(axis_mm, dtype=float).reshape(-1)
            norm = np.hypot(*axis) if axis.shape == (2,) else 0.0
            if not norm > 0:
                raise DataError(f"axis_mm must be a non-zero 2-vector, got {axis_mm!r}", column="axis_mm")
            gaps = moved @ (axis / norm)
    else:
        raise DataError(f"mm_per_px must be a scalar or a 2 x 2 matrix, got shape {scale.shape}",
                        column="mm_per_px")
    spread = float(gaps.std(ddof=1)) if n > 1 else 0.0
    return ReversalResult(backlash_mm=float(gaps.mean()), per_reversal_mm=gaps, spread_mm=spread,
                          sigma_mm=spread / np.sqrt(n), n=n)


def pixel_to_machine_matrix(shifts_px, moves_mm, *, rcond=1e-9) -> MatrixResult:
    """Least-squares 2 x 2 matrix ``M`` with ``moves_mm ≈ M @ shifts_px``.

    Parameters
    ----------
    shifts_px : array_like, shape (N, 2)
        Image displacements of the feature, pixels (relative to any common
        reference, or move by move).
    moves_mm : array_like, shape (N, 2)
        The corresponding stage displacements (machine X, Y), mm. Every image
        must have been taken after approaching from the same side (see
        :func:`pixel_equivalent`).
    rcond : float
        Relative singular-value threshold below which the moves are taken as
        not spanning the plane.

    Returns
    -------
    MatrixResult

    Raises
    ------
    DataError
        When fewer than two linearly independent shifts are given.

    Examples
    --------
    >>> res = pixel_to_machine_matrix([[200, 0], [0, -200]], [[1.0, 0.0], [0.0, 1.0]])
    >>> res.matrix.round(6).tolist(), res.mirrored
    ([[0.005, 0.0], [0.0, -0.005]], True)
    """
    shifts = _as_points("shifts_px", shifts_px)
    moves = _as_points("moves_mm", moves_mm, shifts.shape[0])
    n = shifts.shape[0]
    sv = np.linalg.svd(shifts, compute_uv=False) if n else np.zeros(0)
    if n < 2 or sv[-1] <= rcond * sv[0]:
        raise DataError(f"pixel_to_machine_matrix needs at least 2 linearly independent image shifts, "
                        f"got {n} spanning rank {int(np.sum(sv > rcond * (sv[0] if sv.size else 1)))}; "
                        "move along both machine X and Y", column="shifts_px")
    mt, *_ = np.linalg.lstsq(shifts, moves, rcond=None)
    m = mt.T
    res = shifts @ m.T - moves
    c0, c1 = m[:, 0], m[:, 1]
    sx, sy = float(np.hypot(*c0)), float(np.hypot(*c1))
    det = float(np.linalg.det(m))
    mirrored = det < 0
    # Angle from column 0 to column 1, in the sense that makes it +90 deg for an unskewed matrix.
    ang = np.degrees(np.arctan2(c0[0] * c1[1] - c0[1] * c1[0], c0 @ c1))
    skew = (90.0 - ang) if not mirrored else (ang + 90.0)
    return MatrixResult(
        matrix=m,
        scale_x=sx,
        scale_y=sy,
        rotation_deg=float(np.degrees(np.arctan2(c0[1], c0[0]))),
        skew_deg=float(skew),
        mirrored=bool(mirrored),
        residual_rms_mm=float(np.sqrt(np.mean(np.sum(res ** 2, axis=1)))),
        n=n,
    )
