"""Drive a stage through the backlash plan and compute pixel equivalent and backlash.

Stage protocol (docs/hardware.md): ``move_to(x_mm, y_mm, theta_deg)`` (absolute)
and ``grab() -> 2-D uint8`` of a camera looking down on one round fiducial.

Start position: if the stage has a ``position`` attribute (or method) giving
the commanded ``(x_mm, y_mm, theta_deg)``, the plan is centred on it;
otherwise the stage is assumed to stand at (0, 0, 0). Every command stays
within ``±travel_mm`` / ``±travel_deg`` of the start.

θ sense: the rotation centre is fitted assuming θ turns counter-clockwise
seen from above (from machine X towards machine Y). When the stage turns the
other way, ``theta_centre_mm`` / ``theta_centre_px`` come out mirrored across
the chord of the photos, while the θ backlash keeps its sign and its value to
first order (1e-4 relative at the defaults).
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np

from kinid.errors import DataError
from kinid.progress import Progress
from kinid.vision import (MatrixResult, ScaleResult, backlash_from_reversals, pixel_equivalent,
                          pixel_to_machine_matrix)

from .locate import locate_fiducial
from .plan import plan_moves

__all__ = ["BacklashResult", "MoveRecord", "calibrate", "analyse"]

#: Minimum image arc (pixels) of the fiducial over the θ excursion for the θ backlash to be measured.
MIN_THETA_ARC_PX = 2.0


@dataclass(frozen=True)
class MoveRecord:
    """One executed move.

    Attributes
    ----------
    index : int
        1-based move number.
    command : tuple of float
        Absolute command (x_mm, y_mm, theta_deg).
    role, axis, cycle, target
        As in :class:`stages.backlash.plan.PlannedMove`.
    x_px, y_px : float
        Located fiducial centre after the move (NaN when no photo was taken).
    """

    index: int
    command: tuple
    role: str
    axis: str
    cycle: int
    target: float
    x_px: float = float("nan")
    y_px: float = float("nan")


@dataclass(frozen=True)
class BacklashResult:
    """Pixel equivalent and backlash of an X-Y-θ stage.

    Attributes
    ----------
    pixel_mm_x, pixel_mm_y : float
        Pixel equivalent (mm per pixel) from the non-reversal moves along
        machine X and along machine Y (length ratio, rotation-free).
    pixel_mm : float
        Mean over all non-reversal moves (X, Y and oblique), mm per pixel.
    pixel_mm_sigma : float
        Standard deviation of the per-move pixel equivalents, mm per pixel.
    backlash_x_mm, backlash_y_mm : float
        Mean lost motion of X and Y: the signed component, along the axis, of
        the machine displacement (2 x 2 matrix applied to the image shift)
        between the photos approached from the negative and the positive side.
    backlash_theta_deg : float
        Mean lost motion of θ: angle about the fitted rotation centre between
        the two photos of a reversal cycle, degrees.
    backlash_x_patent_mm, backlash_y_patent_mm, backlash_theta_patent_deg : float
        The patent's ``d = r * |p1 - p2|`` (θ: arc length over the radius),
        always >= 0 (biased upward by the locator noise near zero backlash).
    reversals_x_mm, reversals_y_mm, reversals_theta_deg : numpy.ndarray
        Every single reversal measurement.
    spread_x_mm, spread_y_mm, spread_theta_deg : float
        Sample standard deviation of the single measurements (0 for one).
    iso_reversal_x_mm, iso_reversal_y_mm : float
        ISO 230-2 reversal value ``B = max_i |B_i|`` over the target positions,
        ``B_i = mean(x_i up) - mean(x_i down)`` (position deviations approached
        from the negative and from the positive side).
    iso_mean_reversal_x_mm, iso_mean_reversal_y_mm : float
        ISO 230-2 mean reversal value ``mean_i B_i`` (signed as in the standard:
        negative for a lagging screw). With one target it equals ``-backlash``;
        ISO 230-2 asks for at least five targets and five runs (``n_targets``,
        ``repeats``).
    theta_centre_mm : tuple of float
        θ rotation centre in the machine frame, relative to the fiducial in the
        first θ "up" photo, mm.
    theta_centre_px : tuple of float
        θ rotation centre in the image, pixels (may lie far outside it).
    theta_radius_mm : float
        Distance of the fiducial from the θ centre, mm.
    matrix : MatrixResult
        Pixel-to-machine matrix from the pixel-equivalent photos.
    scale : ScaleResult
        Per-move pixel equivalents.
    moves : int
        Number of moves made.
    start : tuple of float
        Start position (x_mm, y_mm, theta_deg) the plan was centred on.
    log : tuple of MoveRecord
        Every move with its command and located fiducial.
    """

    pixel_mm_x: float
    pixel_mm_y: float
    pixel_mm: float
    pixel_mm_sigma: float
    backlash_x_mm: float
    backlash_y_mm: float
    backlash_theta_deg: float
    backlash_x_patent_mm: float
    backlash_y_patent_mm: float
    backlash_theta_patent_deg: float
    reversals_x_mm: np.ndarray
    reversals_y_mm: np.ndarray
    reversals_theta_deg: np.ndarray
    spread_x_mm: float
    spread_y_mm: float
    spread_theta_deg: float
    iso_reversal_x_mm: float
    iso_reversal_y_mm: float
    iso_mean_reversal_x_mm: float
    iso_mean_reversal_y_mm: float
    theta_centre_mm: tuple
    theta_centre_px: tuple
    theta_radius_mm: float
    matrix: MatrixResult
    scale: ScaleResult
    moves: int
    start: tuple
    log: tuple = field(repr=False)

    def summary(self) -> dict:
        """Plain-JSON summary (µm and degrees)."""
        return {
            "pixel_um_x": self.pixel_mm_x * 1e3,
            "pixel_um_y": self.pixel_mm_y * 1e3,
            "pixel_um": self.pixel_mm * 1e3,
            "backlash_x_um": self.backlash_x_mm * 1e3,
            "backlash_y_um": self.backlash_y_mm * 1e3,
            "backlash_theta_deg": self.backlash_theta_deg,
            "spread_x_um": self.spread_x_mm * 1e3,
            "spread_y_um": self.spread_y_mm * 1e3,
            "spread_theta_deg": self.spread_theta_deg,
            "iso_reversal_x_um": self.iso_reversal_x_mm * 1e3,
            "iso_reversal_y_um": self.iso_reversal_y_mm * 1e3,
            "iso_mean_reversal_x_um": self.iso_mean_reversal_x_mm * 1e3,
            "iso_mean_reversal_y_um": self.iso_mean_reversal_y_mm * 1e3,
            "camera_rotation_deg": self.matrix.rotation_deg,
            "theta_radius_mm": self.theta_radius_mm,
            "moves": self.moves,
        }


def _start_of(stage):
    """Commanded start position: ``stage.position`` when usable, else (0, 0, 0)."""
    pos = getattr(stage, "position", None)
    if callable(pos):
        pos = pos()
    if pos is None:
        return (0.0, 0.0, 0.0)
    try:
        start = tuple(float(v) for v in pos)
    except (TypeError, ValueError):
        start = ()
    if len(start) != 3 or not np.all(np.isfinite(start)):
        warnings.warn(f"stage.position is not (x_mm, y_mm, theta_deg) ({pos!r}); assuming the stage starts "
                      "at (0, 0, 0)", stacklevel=3)
        return (0.0, 0.0, 0.0)
    return start


def calibrate(stage, travel_mm=0.8, travel_deg=2.0, *, repeats=1, n_targets=1, locate=None,
              progress=None) -> "BacklashResult":
    """Measure the pixel equivalent and the X, Y and θ backlash of a stage from images.

    Parameters
    ----------
    stage : object
        With ``move_to(x_mm, y_mm, theta_deg)`` and ``grab() -> 2-D uint8``;
        optionally ``position`` (commanded start, see the module notes).
    travel_mm : float
        Every X/Y command stays within ``±travel_mm`` of the start, mm. The
        reversal excursion is ``travel_mm / 2`` and must exceed the backlash;
        the fiducial must stay in the image over ``±travel_mm``.
    travel_deg : float
        Every θ command stays within ``±travel_deg`` of the start, degrees.
    repeats : int
        Reversal cycles per axis and target (1: 4 moves per axis as the patent).
    n_targets : int
        Target positions per linear axis (for the ISO 230-2 reversal value).
    locate : callable or None
        ``locate(image, what=str) -> (x_px, y_px)``; default
        :func:`stages.backlash.locate.locate_fiducial`.
    progress : bool or None
        Show a progress line on stderr (default: when stderr is a terminal).

    Returns
    -------
    BacklashResult
        ``moves`` = 9 + 4 · repeats · (2 · n_targets + 1).

    Raises
    ------
    DataError
        Non-positive travel or counts.
    StageError
        From the stage, when a command lies outside its own limits.
    ImageError
        When an image shows no fiducial.

    References
    ----------
    CN105547173: pixel equivalent from non-reversal moves,
    backlash ``d = r * |p1 - p2|`` across reversals. ISO 230-2:2014, reversal
    value B and mean reversal value.
    """
    from kinid.checks import check_methods

    check_methods("stage", stage, ("move_to", "grab"))
    plan = plan_moves(travel_mm, travel_deg, repeats=repeats, n_targets=n_targets)
    start = _start_of(stage)
    locate = locate_fiducial if locate is None else locate
    log = []
    bar = Progress(len(plan), "backlash moves", enabled=progress)
    try:
        for i, pm in enumerate(plan, start=1):
            cmd = tuple(s + o for s, o in zip(start, pm.offset))
            stage.move_to(*cmd)
            x_px = y_px = float("nan")
            if pm.photo:
                image = stage.grab()
                x_px, y_px = locate(image, what=f"image after move {i} to (x {cmd[0]:g} mm, y {cmd[1]:g} mm, "
                                                f"theta {cmd[2]:g} deg)")
            log.append(MoveRecord(i, cmd, pm.role, pm.axis, pm.cycle, pm.target, float(x_px), float(y_px)))
            bar.update()
    finally:
        bar.close()
    return analyse(log, start=start, travel_mm=float(travel_mm))


def _pixels(recs):
    return np.array([[r.x_px, r.y_px] for r in recs], dtype=float)


def _commands(recs, cols=(0, 1)):
    return np.array([[r.command[c] for c in cols] for r in recs], dtype=float)


def _linear_axis(log, axis, k, matrix):
    """Signed and patent-formula backlash, ISO values of one linear axis."""
    ups = [r for r in log if r.axis == axis and r.role == "up"]
    downs = [r for r in log if r.axis == axis and r.role == "down"]
    direction = np.eye(2)[k]
    signed = backlash_from_reversals(_pixels(ups), _pixels(downs), matrix.matrix, axis_mm=direction)
    patent = backlash_from_reversals(_pixels(ups), _pixels(downs), matrix.matrix)
    # ISO 230-2: deviation up minus deviation down at each target = -(gap along the axis). With two runs or
    # more per target the standard's own evaluation (kinid.stages.iso230_2) gives B and the mean reversal,
    # from deviations measured against the first "up" photo (a common offset, which B does not see).
    targets = np.array([r.target for r in ups])
    if min(int(np.sum(targets == t)) for t in np.unique(targets)) >= 2:
        from ..iso230_2 import evaluate_runs

        ref = _pixels(ups[:1])
        along = lambda recs: matrix.to_machine(_pixels(recs) - ref)[:, k] * 1e3  # noqa: E731  µm
        commanded = np.array([r.target - ups[0].target for r in ups]) * 1e3
        dev = np.r_[along(ups) - commanded, along(downs) - commanded]
        iso = evaluate_runs(np.r_[targets, targets], np.r_[np.ones(len(ups)), -np.ones(len(downs))], dev)
        return signed, patent, iso.B_um * 1e-3, iso.mean_reversal_um * 1e-3
    b_i = [-float(np.mean(signed.per_reversal_mm[targets == t])) for t in np.unique(targets)]
    return signed, patent, float(np.max(np.abs(b_i))), float(np.mean(b_i))


def _rotation(th_deg):
    t = np.radians(th_deg)
    return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])


def analyse(log, *, start=(0.0, 0.0, 0.0), travel_mm=None) -> BacklashResult:
    """Compute a :class:`BacklashResult` from executed moves (see :func:`calibrate`).

    Parameters
    ----------
    log : sequence of MoveRecord
        The moves with located fiducial positions.
    start : tuple of float
        Start position the plan was centred on.
    travel_mm : float or None
        Travel used, for the warning when the backlash approaches the excursion.

    Returns
    -------
    BacklashResult
    """
    log = tuple(log)
    scale_recs = [r for r in log if r.role == "scale"]
    if len(scale_recs) < 3:
        raise DataError(f"need at least 3 pixel-equivalent photos, got {len(scale_recs)}")
    p = _pixels(scale_recs)
    c = _commands(scale_recs)
    scale = pixel_equivalent(np.diff(c, axis=0), np.diff(p, axis=0))
    if scale.n_x < 1 or scale.n_y < 1:
        raise DataError("the pixel-equivalent path needs at least one X and one Y non-reversal move")
    matrix = pixel_to_machine_matrix(p[1:] - p[0], c[1:] - c[0])

    sx, px_, iso_bx, iso_mx = _linear_axis(log, "x", 0, matrix)
    sy, py_, iso_by, iso_my = _linear_axis(log, "y", 1, matrix)

    # θ: rotation centre from the photos approached from the negative side (known commanded angles),
    # q_k = c + R(θ_k) v in machine mm, linear in (c, v).
    th_recs = [r for r in log if r.axis == "theta" and r.role in ("up", "centre")]
    ups = [r for r in log if r.axis == "theta" and r.role == "up"]
    downs = [r for r in log if r.axis == "theta" and r.role == "down"]
    ref_px = np.array([ups[0].x_px, ups[0].y_px])
    q = matrix.to_machine(_pixels(th_recs) - ref_px)
    angles = np.array([r.command[2] for r in th_recs])
    if np.unique(angles).size < 2:
        raise DataError("the θ path needs photos at two or more angles approached from the same side")
    rows, rhs = [], []
    for qk, th in zip(q, angles):
        rot = _rotation(th)
        rows.append(np.hstack([np.eye(2), rot]))
        rhs.append(qk)
    sol, *_ = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)
    centre = sol[:2]
    radius = float(np.hypot(*sol[2:]))
    qu = matrix.to_machine(_pixels(ups) - ref_px) - centre
    qd = matrix.to_machine(_pixels(downs) - ref_px) - centre
    phi_u = np.arctan2(qu[:, 1], qu[:, 0])
    phi_d = np.arctan2(qd[:, 1], qd[:, 0])
    theta_gaps = np.degrees(np.angle(np.exp(1j * (phi_d - phi_u))))
    chord = backlash_from_reversals(_pixels(ups), _pixels(downs), scale.mm_per_px)
    theta_patent = np.degrees(chord.backlash_mm / radius)
    centres = [r for r in log if r.axis == "theta" and r.role == "centre"]
    arc_px = float(np.median(np.hypot(*(_pixels(centres) - _pixels(ups)[:len(centres)]).T))) if centres else 0.0
    if arc_px < MIN_THETA_ARC_PX:
        warnings.warn(f"the fiducial moved only {arc_px:.2f} px over the θ excursion: it is too close to the θ "
                      "rotation centre (or θ did not move); θ backlash not measured (NaN). Put the fiducial far "
                      "from the θ centre or increase travel_deg", stacklevel=2)
        theta_gaps = np.full_like(theta_gaps, np.nan)
        theta_patent = float("nan")
    # Centre in pixels: solve matrix @ (px - ref) = centre.
    centre_px = ref_px + np.linalg.solve(matrix.matrix, centre)

    if travel_mm is not None:
        excursion = 0.5 * travel_mm
        for name, val in (("X", sx.backlash_mm), ("Y", sy.backlash_mm)):
            if abs(val) > 0.5 * excursion:
                warnings.warn(f"measured {name} backlash {val * 1e3:.2f} µm is more than half the reversal "
                              f"excursion {excursion * 1e3:.0f} µm; increase travel_mm", stacklevel=2)
    n_th = theta_gaps.size
    return BacklashResult(
        pixel_mm_x=scale.mm_per_px_x,
        pixel_mm_y=scale.mm_per_px_y,
        pixel_mm=scale.mm_per_px,
        pixel_mm_sigma=scale.sigma,
        backlash_x_mm=sx.backlash_mm,
        backlash_y_mm=sy.backlash_mm,
        backlash_theta_deg=float(theta_gaps.mean()),
        backlash_x_patent_mm=px_.backlash_mm,
        backlash_y_patent_mm=py_.backlash_mm,
        backlash_theta_patent_deg=float(theta_patent),
        reversals_x_mm=sx.per_reversal_mm,
        reversals_y_mm=sy.per_reversal_mm,
        reversals_theta_deg=theta_gaps,
        spread_x_mm=sx.spread_mm,
        spread_y_mm=sy.spread_mm,
        spread_theta_deg=float(theta_gaps.std(ddof=1)) if n_th > 1 else 0.0,
        iso_reversal_x_mm=iso_bx,
        iso_reversal_y_mm=iso_by,
        iso_mean_reversal_x_mm=iso_mx,
        iso_mean_reversal_y_mm=iso_my,
        theta_centre_mm=(float(centre[0]), float(centre[1])),
        theta_centre_px=(float(centre_px[0]), float(centre_px[1])),
        theta_radius_mm=radius,
        matrix=matrix,
        scale=scale,
        moves=len(log),
        start=tuple(start),
        log=log,
    )
