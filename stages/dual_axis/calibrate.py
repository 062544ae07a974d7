"""Calibration of two parallel Y axes with a camera (the dual-axis method) and its verification.

Protocol (docs/hardware.md): a gantry with ``move(cam_y_mm, head_x_mm,
head_y_mm)`` (absolute) and ``grab() -> 2-D uint8`` of the camera on the
camera Y axis looking at a plate on the head.

The patent's steps, as implemented by :func:`calibrate`:

1. Plate centred under the camera at ``y_start_mm`` / ``head_start_mm``; the
   table starts at zero.
2. A matching template is made from the plate image at the start.
3. Both Y axes step together by ``step_mm`` (``n_steps`` steps); after each
   step the head makes the compensation move of the current table (so the
   head move is :meth:`OffsetTable.head_move`), and the camera grabs an image.
4. Template matching gives the plate's shift from where the template was
   in the start image (px; the template and its start position are recorded
   once, so the start's repeatability error is common to every round and
   cancels in the rounds' comparison);
   ``pixel_to_mm`` turns it into a head X/Y displacement (mm). Because the
   round ran with the current table applied, the measured residual, taken as
   the head move that cancels it (``-pixel_to_mm @ shift``), ADDS to the
   existing entry.
5. If every measured residual of the round is within ``spec_um`` the table
   is done; otherwise the next round starts at step 3.
"""
from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from kinid.checks import check_int
from kinid.errors import DataError, ImageError
from kinid.vision import locate_template, make_template, pixel_to_machine_matrix
from .table import OffsetTable, RoundRecord

__all__ = ["calibrate", "check_plan", "measure_pixel_to_mm", "verify", "default_roi"]


def default_roi(image_shape) -> tuple:
    """Centre half of the image as a template region ``(x, y, width, height)``, pixels."""
    h, w = int(image_shape[0]), int(image_shape[1])
    return (w // 4, h // 4, w // 2, h // 2)


def _check_matrix(pixel_to_mm) -> np.ndarray:
    try:
        m = np.asarray(pixel_to_mm, dtype=float)
    except (TypeError, ValueError):
        raise DataError(f"pixel_to_mm must be a 2 x 2 matrix of numbers, got {pixel_to_mm!r}") from None
    if m.shape != (2, 2) or not np.all(np.isfinite(m)):
        raise DataError(f"pixel_to_mm must be a finite 2 x 2 matrix (mm per pixel), got shape {m.shape}")
    s = np.linalg.svd(m, compute_uv=False)
    if s[0] == 0 or s[1] / s[0] < 1e-6:
        raise DataError(
            f"pixel_to_mm is not invertible (singular values {s[0]:.3g}, {s[1]:.3g}); it must map image "
            "x/y shifts to two independent head directions - measure it with measure_pixel_to_mm")
    return m


def _number(name, value, *, positive=False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise DataError(f"must be a number, got {value!r}", parameter=name) from None
    if not np.isfinite(v) or (positive and not v > 0):
        raise DataError(f"must be a {'positive' if positive else 'finite'} number, got {value!r}", parameter=name)
    return v


def _head(head_start_mm) -> np.ndarray:
    try:
        h = np.asarray(head_start_mm, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise DataError(f"head_start_mm must be (x, y) in mm, got {head_start_mm!r}") from None
    if h.shape != (2,) or not np.all(np.isfinite(h)):
        raise DataError(f"head_start_mm must be two finite numbers (x, y) in mm, got {head_start_mm!r}")
    return h


class _Locator:
    """Template made once from a reference image; shifts of the plate in later images (px)."""

    def __init__(self, reference_image, roi, search_px):
        image = np.asarray(reference_image)
        if image.ndim != 2:
            raise ImageError(f"grab() must return a 2-D grey image, got shape {image.shape}")
        self.roi = default_roi(image.shape) if roi is None else roi  # make_template validates it
        try:
            self.template = make_template(image, self.roi)
        except ImageError as exc:
            raise ImageError(f"start image: plate not found, no template can be made in region {self.roi} "
                             f"(x, y, width, height px): {exc.message}") from None
        self.search_px = search_px

    def shift_px(self, image, where: str) -> np.ndarray:
        image = np.asarray(image)
        if image.ndim != 2:
            raise ImageError(f"{where}: grab() must return a 2-D grey image, got shape {image.shape}")
        m = locate_template(image, self.template, search_px=self.search_px)
        if not m.found:
            raise ImageError(f"{where}: plate not found in the image ({m.reason}); check the plate is under the "
                             "camera and lit, or enlarge search_px")
        return np.array([m.dx_px, m.dy_px], float)


def check_plan(y_start_mm, head_start_mm, step_mm, n_steps, pixel_to_mm, spec_um, max_rounds=1):
    """Validate the arguments of :func:`calibrate` before any move.

    Returns
    -------
    tuple
        ``(y_start_mm, head_start_mm (2,), step_mm, spec_um, pixel_to_mm (2, 2))`` as floats / arrays.

    Raises
    ------
    DataError
        The first bad argument, named, with what was expected and received.
    """
    y0 = _number("y_start_mm", y_start_mm)
    head0 = _head(head_start_mm)
    step = _number("step_mm", step_mm)
    if not step > 0:
        raise DataError(f"must be positive (the camera steps towards +Y), got {step_mm!r}", parameter="step_mm")
    check_int("n_steps", n_steps, minimum=1)
    spec = _number("spec_um", spec_um, positive=True)
    check_int("max_rounds", max_rounds, minimum=1)
    m = _check_matrix(pixel_to_mm)
    return y0, head0, step, spec, m


def calibrate(gantry, y_start_mm, head_start_mm, step_mm, n_steps, pixel_to_mm, spec_um, *,
              max_rounds: int = 5, roi=None, search_px=None, progress=None) -> OffsetTable:
    """Calibrate the offset table of two parallel Y axes (the dual-axis method).

    Parameters
    ----------
    gantry : object
        ``move(cam_y_mm, head_x_mm, head_y_mm)`` and ``grab() -> 2-D uint8``
        (docs/hardware.md).
    y_start_mm : float
        Camera Y at the start, mm.
    head_start_mm : tuple of float
        Head (x, y) at which the plate is centred under the camera when the
        camera is at ``y_start_mm``, mm.
    step_mm : float
        Step of both Y axes, mm (> 0; the camera moves towards +Y).
    n_steps : int
        Number of steps (>= 1); the table has ``n_steps + 1`` vertices.
    pixel_to_mm : array_like, shape (2, 2)
        Matrix from image shifts of the plate (px) to head X/Y displacement
        (mm), e.g. from :func:`measure_pixel_to_mm`.
    spec_um : float
        Acceptance limit: a round whose measured residuals are all within
        ``spec_um`` (each of X and Y) ends the calibration.
    max_rounds : int
        Rounds to try before giving up (the result then has ``converged``
        False and a warning is issued).
    roi : tuple of int, optional
        Template region ``(x, y, width, height)`` in the start image, pixels;
        default the centre half of the image.
    search_px : float, optional
        Search radius of the template matcher, pixels.
    progress : kinid.progress.Progress, optional
        Updated once per image.

    Returns
    -------
    OffsetTable

    Raises
    ------
    DataError
        Bad arguments: ``n_steps < 1``, ``step_mm <= 0``, a non-invertible
        ``pixel_to_mm``, a non-positive ``spec_um``.
    ImageError
        The plate is not found in an image.
    StageError
        From the gantry, e.g. a move outside travel.

    Examples
    --------
    >>> from kinid.stages.dual_axis import SimulatedGantry        # doctest: +SKIP
    >>> g = SimulatedGantry()                               # doctest: +SKIP
    >>> t = calibrate(g, 0.0, (0.0, 0.0), 10.0, 30, g.true_pixel_to_mm, 1.0)  # doctest: +SKIP
    >>> t.rounds, t.converged                               # doctest: +SKIP
    (2, True)
    """
    from kinid.checks import check_methods

    check_methods("gantry", gantry, ("move", "grab"))
    y0, head0, step, spec, m = check_plan(y_start_mm, head_start_mm, step_mm, n_steps, pixel_to_mm, spec_um,
                                          max_rounds)
    n = int(n_steps)

    y = y0 + step * np.arange(n + 1)
    table = OffsetTable(y, np.zeros((n + 1, 2)), spec_um=spec)
    gantry.move(y0, head0[0], head0[1])
    # step 2: the template and its centre at the start are recorded once; every shift is measured from it
    locator = _Locator(gantry.grab(), roi, search_px)
    if progress is not None:
        progress.update()
    history = []
    for r in range(1, int(max_rounds) + 1):
        gantry.move(y0, head0[0], head0[1])
        head = head0.copy()
        offsets = np.zeros((n + 1, 2))
        for i in range(1, n + 1):
            # 3.1: both Y axes step together; 3.2: the head makes the table's compensation move
            gantry.move(y[i], head[0], head[1] + step)
            dx, dy = table.head_move(y[i - 1], y[i])
            head = head + (dx, dy)
            gantry.move(y[i], head[0], head[1])
            shift = locator.shift_px(gantry.grab(), f"round {r}, step {i} (camera Y {y[i]:g} mm)")
            offsets[i] = -(m @ shift)
            if progress is not None:
                progress.update()
        change = float(np.max(np.abs(offsets)) * 1e3)
        history.append(RoundRecord(r, offsets * 1e3, change))
        done = change <= spec
        table = table.with_offsets(offsets, rounds=r, converged=done, history=tuple(history))
        if done:
            break
    if table.converged:
        msg = f"converged in {table.rounds} round(s): last round's largest change {history[-1].max_change_um:.3f} µm <= {spec:g} µm"
    else:
        msg = (f"not converged after {table.rounds} rounds: last round's largest change "
               f"{history[-1].max_change_um:.3f} µm > {spec:g} µm")
        warnings.warn(msg, stacklevel=2)
    return replace(table, message=msg)


def measure_pixel_to_mm(gantry, cam_y_mm, head_mm, *, move_mm: float = 0.1, roi=None, search_px=None):
    """Measure the 2 x 2 pixel-to-head matrix by moving the head by known X/Y moves.

    The camera stays at ``cam_y_mm``; the head visits ``head_mm`` and the
    eight points of a square of half-side ``move_mm`` around it (all
    approached the same way: straight from ``head_mm``), and
    :func:`vision.motion_scale.pixel_to_machine_matrix` fits
    ``move = M @ shift``.

    Parameters
    ----------
    gantry : object
        The gantry protocol (docs/hardware.md).
    cam_y_mm : float
        Camera Y, mm.
    head_mm : tuple of float
        Head (x, y) with the plate centred under the camera, mm.
    move_mm : float
        Size of the head moves, mm (keep the shift well inside the image).
    roi, search_px
        As in :func:`calibrate`.

    Returns
    -------
    vision.motion_scale.MatrixResult
        ``.matrix`` is the ``pixel_to_mm`` argument of :func:`calibrate`.
    """
    cy = _number("cam_y_mm", cam_y_mm)
    h0 = _head(head_mm)
    d = _number("move_mm", move_mm, positive=True)
    gantry.move(cy, h0[0], h0[1])
    locator = _Locator(gantry.grab(), roi, search_px)
    moves = np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)], float) * d
    shifts = []
    for mv in moves:
        gantry.move(cy, h0[0], h0[1])
        gantry.move(cy, h0[0] + mv[0], h0[1] + mv[1])
        shifts.append(locator.shift_px(gantry.grab(), f"pixel_to_mm move ({mv[0]:g}, {mv[1]:g}) mm"))
    gantry.move(cy, h0[0], h0[1])
    return pixel_to_machine_matrix(np.array(shifts), moves)


def verify(gantry, compensator, y_start_mm, head_start_mm, positions_mm, pixel_to_mm, *, roi=None,
           search_px=None) -> np.ndarray:
    """Measure how far the plate is from centred at camera positions, with compensation.

    For each camera Y ``p`` the head goes to ``head_start + head_move(y_start, p)``
    of the compensator; the plate's image shift from the start image is turned
    into head X/Y by ``pixel_to_mm``.

    Parameters
    ----------
    gantry : object
        The gantry protocol.
    compensator : object
        Anything with ``head_move(ps_mm, pe_mm) -> (dx_mm, dy_mm)``
        (:class:`OffsetTable`, :class:`~stages.dual_axis.smooth.SmoothModel`).
    y_start_mm, head_start_mm
        As in :func:`calibrate`.
    positions_mm : array_like, shape (N,)
        Held-out camera Y positions, mm.
    pixel_to_mm : array_like, shape (2, 2)

    Returns
    -------
    numpy.ndarray, shape (N, 2)
        Remaining plate displacement (head X, head Y), µm.
    """
    y0 = _number("y_start_mm", y_start_mm)
    h0 = _head(head_start_mm)
    m = _check_matrix(pixel_to_mm)
    gantry.move(y0, h0[0], h0[1])
    locator = _Locator(gantry.grab(), roi, search_px)
    out = []
    for p in np.asarray(positions_mm, float).reshape(-1):
        dx, dy = compensator.head_move(y0, p)
        gantry.move(p, h0[0] + dx, h0[1] + dy)
        shift = locator.shift_px(gantry.grab(), f"verify at camera Y {p:g} mm")
        out.append(m @ shift * 1e3)
    return np.array(out).reshape(-1, 2)
