"""A simulated X-Y-θ stage with lead-screw backlash and a camera looking down on one round fiducial.

Machine frame: X and Y are the stage's linear axes (mm), right-handed with Z up
(towards the camera); θ turns counter-clockwise seen from above (degrees). The
θ table rides on the X-Y carriage. The fiducial sits on the θ table; with the
stage at its zero position (actual, not commanded) it is at the machine origin,
and the θ rotation centre is at ``theta_centre_mm`` from it.

Camera: looks straight down, image x rotated ``camera_angle_deg`` from machine
X; with ``mirror=True`` (the default, a camera looking down with image y down)
image y points along machine -Y rotated by the same angle. The machine point
``camera_at_mm`` (default the origin) images at ``principal_px``. Images are rendered with
:func:`vision.render.render_disk`.

Backlash: each axis is a play (dead-band) operator: the actual position
follows the commanded one with a lag of half the backlash on the side it was
last driven from; on a reversal the first ``backlash`` of command is lost.
"""
from __future__ import annotations

import numpy as np

from kinid.checks import check_nonnegative, check_positive
from kinid.errors import DataError, StageError

__all__ = ["SimulatedStage", "play"]


def play(actual: float, command: float, backlash: float) -> float:
    """Play (dead-band) operator: new actual position after a command.

    Parameters
    ----------
    actual : float
        Actual position before the move.
    command : float
        New commanded position.
    backlash : float
        Width of the dead band (full lost motion), same unit, >= 0.

    Returns
    -------
    float
        Actual position after the move: ``command - backlash/2`` after a
        positive move that takes up the play, ``command + backlash/2`` after a
        negative one, unchanged inside the dead band.
    """
    half = 0.5 * backlash
    if command - half > actual:
        return command - half
    if command + half < actual:
        return command + half
    return actual


class SimulatedStage:
    """X-Y-θ stage with backlash on every axis, seen by a camera above one round fiducial.

    Parameters
    ----------
    pixel_mm : float or tuple of float
        Pixel pitch projected on the stage, mm (a pair for different pitch
        along image x and image y).
    camera_angle_deg : float
        Rotation of the image x axis from machine X, degrees.
    mirror : bool
        Image y along machine -Y (camera looking down, image y down).
    backlash_x_mm, backlash_y_mm : float
        Lost motion of the X and Y lead screws, mm.
    backlash_theta_deg : float
        Lost motion of the θ drive, degrees.
    theta_centre_mm : tuple of float
        θ rotation centre relative to the fiducial at the zero position, mm.
    fiducial_radius_mm : float
        Radius of the round fiducial, mm.
    image_shape : tuple of int
        (height, width) of the camera image, pixels.
    principal_px : tuple of float or None
        Pixel at which the machine point ``camera_at_mm`` images; None: the
        image centre.
    camera_at_mm : tuple of float
        Machine point (mm) on the camera's optical axis (the fiducial at the
        zero position is at the machine origin).
    noise_sigma : float
        Image noise, grey levels (of 255).
    blur_px : float
        Optical blur (Gaussian sigma), pixels.
    repeatability_mm : float
        Standard deviation of a random positioning error added to X and Y on
        every move (0: perfectly repeatable), mm.
    limits_mm : tuple
        ((xmin, xmax), (ymin, ymax)) commanded travel limits of the stage, mm.
    limits_deg : tuple
        (θmin, θmax) commanded travel limits, degrees.
    initial_command : tuple of float
        Commanded (x_mm, y_mm, theta_deg) at start.
    initial_side : int
        +1 or -1: side from which every axis was last driven before the start.
    rng : numpy.random.Generator or None
        Source of image noise and positioning scatter.

    Attributes
    ----------
    position : tuple of float
        Current commanded (x_mm, y_mm, theta_deg).
    history : list of tuple
        Every command given through :meth:`move_to`.
    """

    def __init__(self, *, pixel_mm=0.005, camera_angle_deg=7.0, mirror=True, backlash_x_mm=0.004,
                 backlash_y_mm=0.003, backlash_theta_deg=0.01, theta_centre_mm=(-12.0, 8.0),
                 fiducial_radius_mm=0.2, image_shape=(480, 640), principal_px=None, camera_at_mm=(0.0, 0.0),
                 noise_sigma=2.0, blur_px=0.8, repeatability_mm=0.0, limits_mm=((-50.0, 50.0), (-50.0, 50.0)),
                 limits_deg=(-180.0, 180.0), initial_command=(0.0, 0.0, 0.0), initial_side=1, rng=None):
        p = np.broadcast_to(np.asarray(pixel_mm, dtype=float), (2,))
        self.pixel_mm = (check_positive("pixel_mm", p[0]), check_positive("pixel_mm", p[1]))
        self.camera_angle_deg = float(camera_angle_deg)
        self.mirror = bool(mirror)
        self.backlash_x_mm = check_nonnegative("backlash_x_mm", backlash_x_mm)
        self.backlash_y_mm = check_nonnegative("backlash_y_mm", backlash_y_mm)
        self.backlash_theta_deg = check_nonnegative("backlash_theta_deg", backlash_theta_deg)
        self.theta_centre_mm = tuple(float(v) for v in theta_centre_mm)
        self.fiducial_radius_mm = check_positive("fiducial_radius_mm", fiducial_radius_mm)
        self.image_shape = (int(image_shape[0]), int(image_shape[1]))
        h, w = self.image_shape
        self.principal_px = ((w - 1) / 2.0, (h - 1) / 2.0) if principal_px is None else tuple(
            float(v) for v in principal_px)
        self.camera_at_mm = tuple(float(v) for v in camera_at_mm)
        self.noise_sigma = check_nonnegative("noise_sigma", noise_sigma)
        self.blur_px = check_nonnegative("blur_px", blur_px)
        self.repeatability_mm = check_nonnegative("repeatability_mm", repeatability_mm)
        self.limits_mm = tuple(tuple(float(v) for v in lim) for lim in limits_mm)
        self.limits_deg = tuple(float(v) for v in limits_deg)
        if initial_side not in (1, -1):
            raise DataError(f"initial_side must be +1 or -1, got {initial_side!r}", column="initial_side")
        self.rng = np.random.default_rng() if rng is None else rng
        cmd = tuple(float(v) for v in initial_command)
        self._check_limits(*cmd)
        self.position = cmd
        b = (self.backlash_x_mm, self.backlash_y_mm, self.backlash_theta_deg)
        self._actual = [c - initial_side * 0.5 * bi for c, bi in zip(cmd, b)]
        self._jitter = np.zeros(2)
        self.history = []

    # -- geometry -----------------------------------------------------------------------------
    def machine_to_pixel_matrix(self) -> np.ndarray:
        """2 x 2 matrix mapping machine mm displacements to image pixel displacements."""
        a = np.radians(self.camera_angle_deg)
        c, s = np.cos(a), np.sin(a)
        # Rows: image x and image y directions expressed in the machine frame.
        ex = np.array([c, s])
        ey = np.array([-s, c]) * (-1.0 if self.mirror else 1.0)
        return np.vstack([ex / self.pixel_mm[0], ey / self.pixel_mm[1]])

    def true_pixel_mm_along(self, axis) -> float:
        """True mm per pixel for a move along a machine direction (2-vector)."""
        d = np.asarray(axis, float) / np.hypot(*axis)
        return float(1.0 / np.hypot(*(self.machine_to_pixel_matrix() @ d)))

    @property
    def actual(self) -> tuple:
        """Actual (x_mm, y_mm, theta_deg) after backlash (and scatter)."""
        return (self._actual[0] + self._jitter[0], self._actual[1] + self._jitter[1], self._actual[2])

    def fiducial_mm(self) -> np.ndarray:
        """Fiducial position in the machine frame, mm."""
        x, y, th = self.actual
        c = np.array(self.theta_centre_mm)
        t = np.radians(th)
        rot = np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
        return np.array([x, y]) + c + rot @ (-c)

    def fiducial_px(self) -> np.ndarray:
        """True image position (x, y) of the fiducial centre, pixels."""
        rel = self.fiducial_mm() - np.asarray(self.camera_at_mm)
        return np.asarray(self.principal_px) + self.machine_to_pixel_matrix() @ rel

    # -- protocol -----------------------------------------------------------------------------
    def _check_limits(self, x_mm, y_mm, theta_deg):
        for name, v, (lo, hi), unit in (("x", x_mm, self.limits_mm[0], "mm"), ("y", y_mm, self.limits_mm[1], "mm"),
                                        ("theta", theta_deg, self.limits_deg, "deg")):
            if not np.isfinite(v):
                raise StageError(f"move_to: {name} must be finite, got {v!r}", column=name)
            if not lo <= v <= hi:
                raise StageError(f"move_to: {name} = {v:g} {unit} is outside the stage travel "
                                 f"[{lo:g}, {hi:g}] {unit}", column=name)

    def move_to(self, x_mm, y_mm, theta_deg) -> None:
        """Command an absolute move; every axis loses its backlash on a reversal.

        Raises
        ------
        StageError
            When a target lies outside the stage's travel limits.
        """
        cmd = (float(x_mm), float(y_mm), float(theta_deg))
        self._check_limits(*cmd)
        b = (self.backlash_x_mm, self.backlash_y_mm, self.backlash_theta_deg)
        self._actual = [play(a, c, bi) for a, c, bi in zip(self._actual, cmd, b)]
        if self.repeatability_mm > 0:
            self._jitter = self.rng.normal(0.0, self.repeatability_mm, 2)
        self.position = cmd
        self.history.append(cmd)

    def grab(self) -> np.ndarray:
        """Image of the fiducial at the current actual position (uint8, ``image_shape``)."""
        from kinid.vision import render_disk

        radius_px = self.fiducial_radius_mm / np.sqrt(self.pixel_mm[0] * self.pixel_mm[1])
        return render_disk(self.image_shape, tuple(self.fiducial_px()), radius_px, blur_px=self.blur_px,
                           noise_sigma=self.noise_sigma, rng=self.rng)
