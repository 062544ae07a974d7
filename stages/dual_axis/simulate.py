"""A simulated dual-Y gantry: ``urdf/gantry_dual_y.urdf`` with error values set.

The camera rides on axis ``Y``, the placement head on axis ``V`` (parallel to
``Y``) with its own axis ``X``. Every error joint of the URDF gets a value that
is a smooth function of its axis position (straightness and positioning:
polynomial plus a gentle waviness; yaw with the Abbe offsets of the URDF; the
parallelism ``EC0V`` and squareness ``EC0X`` as constants), so the plate on the
head drifts relative to the camera as both Y axes travel.

:class:`SimulatedGantry` implements the protocol of docs/hardware.md:
``move(cam_y_mm, head_x_mm, head_y_mm)`` and ``grab() -> uint8 image``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinid.errors import DataError, StageError
from kinid.urdf import path as urdf_path
from kinid.vision import render_pattern

__all__ = [
    "ErrorProfile",
    "default_error_profiles",
    "random_error_profiles",
    "random_texture",
    "SimulatedGantry",
]


@dataclass(frozen=True)
class ErrorProfile:
    """Value of one error joint as a smooth function of one axis position.

    ``value(q) = constant + sum_k poly[k-1] * (q / scale_mm)**k
    + wave_amplitude * sin(2 pi q / wave_period_mm + wave_phase_rad)``,
    in µm (translation errors) or µrad (rotation errors), ``q`` in mm.

    Attributes
    ----------
    code : str
        ISO 230-1 code of the error joint (``EXY``, ``EC0V`` ...).
    axis : str or None
        Axis whose position ``q`` the value depends on; None for a constant.
    constant : float
        Constant part, µm or µrad.
    poly : tuple of float
        Coefficients of ``(q/scale_mm)**k`` for k = 1, 2, ..., µm or µrad.
    scale_mm : float
        Normalising length of the polynomial, mm.
    wave_amplitude : float
        Amplitude of the waviness, µm or µrad.
    wave_period_mm : float
        Period of the waviness, mm.
    wave_phase_rad : float
        Phase of the waviness, rad.
    """

    code: str
    axis: str | None = None
    constant: float = 0.0
    poly: tuple = ()
    scale_mm: float = 300.0
    wave_amplitude: float = 0.0
    wave_period_mm: float = 100.0
    wave_phase_rad: float = 0.0

    def value(self, q_mm: float) -> float:
        """Error value at axis position ``q_mm`` (µm or µrad)."""
        u = float(q_mm) / self.scale_mm
        v = self.constant + sum(c * u ** (k + 1) for k, c in enumerate(self.poly))
        if self.wave_amplitude:
            v += self.wave_amplitude * np.sin(2 * np.pi * float(q_mm) / self.wave_period_mm + self.wave_phase_rad)
        return float(v)


def default_error_profiles() -> tuple:
    """The error set of the demo gantry (over 300 mm: ~15 µm relative offset in X, ~10 µm in Y).

    Returns
    -------
    tuple of ErrorProfile
    """
    return (
        ErrorProfile("EXY", "Y", poly=(-3.0, 5.0), wave_amplitude=0.8, wave_period_mm=90.0, wave_phase_rad=0.3),
        ErrorProfile("EYY", "Y", poly=(6.0, -1.5)),
        ErrorProfile("ECY", "Y", poly=(8.0, -6.0)),
        ErrorProfile("EXV", "V", poly=(2.0, -7.0, 3.0), wave_amplitude=0.6, wave_period_mm=120.0, wave_phase_rad=1.1),
        ErrorProfile("EYV", "V", poly=(-4.0, 2.0)),
        ErrorProfile("ECV", "V", poly=(-10.0, 12.0)),
        ErrorProfile("EC0V", constant=35.0),
        ErrorProfile("EC0X", constant=25.0),
    )


def random_error_profiles(rng: np.random.Generator) -> tuple:
    """A random error set of the same kind and size as :func:`default_error_profiles`.

    Parameters
    ----------
    rng : numpy.random.Generator
    """
    def prof(code, axis, amp, wave):
        return ErrorProfile(code, axis, poly=tuple(rng.uniform(-amp, amp, 3)),
                            wave_amplitude=float(rng.uniform(0, wave)),
                            wave_period_mm=float(rng.uniform(80.0, 150.0)),
                            wave_phase_rad=float(rng.uniform(0, 2 * np.pi)))
    return (
        prof("EXY", "Y", 6.0, 1.0), prof("EYY", "Y", 6.0, 0.5), prof("ECY", "Y", 12.0, 2.0),
        prof("EXV", "V", 6.0, 1.0), prof("EYV", "V", 6.0, 0.5), prof("ECV", "V", 12.0, 2.0),
        ErrorProfile("EC0V", constant=float(rng.uniform(-60.0, 60.0))),
        ErrorProfile("EC0X", constant=float(rng.uniform(-60.0, 60.0))),
    )


def random_texture(rng: np.random.Generator, *, n_waves: int = 24, wavelength_mm=(0.05, 0.25)):
    """A random smooth texture (sum of plane waves through a soft threshold).

    Parameters
    ----------
    rng : numpy.random.Generator
    n_waves : int
        Number of plane waves.
    wavelength_mm : tuple of float
        Range of their wavelengths, mm.

    Returns
    -------
    callable
        ``coverage(xy_mm (N, 2)) -> (N,)`` in [0, 1], for
        :func:`vision.render.render_pattern`.
    """
    lam = rng.uniform(wavelength_mm[0], wavelength_mm[1], n_waves)
    ang = rng.uniform(0, np.pi, n_waves)
    k = (2 * np.pi / lam)[:, None] * np.column_stack([np.cos(ang), np.sin(ang)])  # (n, 2) rad/mm
    phase = rng.uniform(0, 2 * np.pi, n_waves)
    gain = 2.0 / np.sqrt(n_waves)

    def coverage(xy_mm):
        xy = np.asarray(xy_mm, float)
        s = np.cos(xy @ k.T + phase).sum(axis=1)
        return 0.5 + 0.5 * np.tanh(gain * s)

    return coverage


class SimulatedGantry:
    """The dual-Y gantry of ``urdf/gantry_dual_y.urdf`` with error values set.

    Parameters
    ----------
    errors : sequence of ErrorProfile, optional
        Error values of the error joints; default :func:`default_error_profiles`.
    pixel_mm : float
        Size of a camera pixel on the plate, mm.
    image_angle_deg : float
        Rotation of the image axes against the head axes, degrees.
    image_shape : tuple of int
        (height, width) of the camera image, pixels.
    noise_sigma : float
        Image noise, grey levels.
    repeat_um : float
        Positioning repeatability of each axis (standard deviation of the
        actual position about the command on every move), µm.
    texture : callable, optional
        Plate texture ``coverage(xy_mm) -> [0, 1]``, plate (workpiece-frame)
        mm; default a :func:`random_texture` drawn from ``rng``.
    machine_path : str or Path, optional
        URDF; default the shipped ``gantry_dual_y``.
    rng : numpy.random.Generator, optional
        Source of the texture, image noise and positioning noise;
        default ``np.random.default_rng(0)``.

    Notes
    -----
    The camera frame: image x is the tool frame's x turned by
    ``image_angle_deg``; image y (down) is the tool frame's -y turned alike.
    A plate displacement ``d_mm`` (head X/Y) shifts the texture in the image by
    ``inv(true_pixel_to_mm) @ d_mm`` pixels. The in-plane rotation of the
    camera against the plate is the sum of the yaw errors (small-angle).
    """

    def __init__(self, errors=None, *, pixel_mm: float = 0.005, image_angle_deg: float = 3.0,
                 image_shape=(160, 200), noise_sigma: float = 1.5, repeat_um: float = 0.0,
                 texture=None, machine_path=None, rng=None):
        from kinid.identification import load_machine  # Pinocchio: imported when a gantry is built

        self.rng = np.random.default_rng(0) if rng is None else rng
        self.machine = load_machine(urdf_path("gantry_dual_y") if machine_path is None else machine_path)
        self.errors = tuple(default_error_profiles() if errors is None else errors)
        codes = set(self.machine.error_codes)
        for e in self.errors:
            if e.code not in codes:
                raise DataError(f"error profile {e.code!r} is not an error joint of the machine "
                                f"(it has {', '.join(self.machine.error_codes)})", path=self.machine.path)
        if not pixel_mm > 0:
            raise DataError(f"pixel_mm must be positive, got {pixel_mm!r}")
        self.pixel_mm = float(pixel_mm)
        self.image_angle_deg = float(image_angle_deg)
        self.image_shape = (int(image_shape[0]), int(image_shape[1]))
        self.noise_sigma = float(noise_sigma)
        self.repeat_um = float(repeat_um)
        self.texture = random_texture(self.rng) if texture is None else texture
        self.limits_mm = {}
        for a in self.machine.axes:
            j = self.machine.model.getJointId(a.joint)
            iq = self.machine.model.idx_qs[j]
            self.limits_mm[a.name] = (float(self.machine.model.lowerPositionLimit[iq]) * 1e3,
                                      float(self.machine.model.upperPositionLimit[iq]) * 1e3)
        self.commanded = {"Y": 0.0, "X": 0.0, "V": 0.0}
        self.actual = dict(self.commanded)
        self.moves = 0
        self.grabs = 0

    # ------------------------------------------------------------------ truth
    @property
    def true_pixel_to_mm(self) -> np.ndarray:
        """The exact 2 x 2 matrix from image shifts of the plate (px) to head X/Y displacement (mm)."""
        a = np.deg2rad(self.image_angle_deg)
        rot = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
        return self.pixel_mm * rot @ np.diag([1.0, -1.0])

    def joint_errors(self, axes_mm) -> dict:
        """Error-joint values (µm / µrad) at axis positions ``axes_mm`` (mapping name -> mm)."""
        return {e.code: e.value(axes_mm[e.axis]) if e.axis is not None else e.constant for e in self.errors}

    def plate_point_mm(self, cam_y_mm: float, head_x_mm: float, head_y_mm: float) -> np.ndarray:
        """Point of the plate under the camera's optical axis (workpiece frame, mm, (x, y)).

        Parameters
        ----------
        cam_y_mm, head_x_mm, head_y_mm : float
            Actual axis positions Y, X, V, mm.
        """
        from kinid.identification import tool_in_workpiece_mm

        axes = {"Y": float(cam_y_mm), "X": float(head_x_mm), "V": float(head_y_mm)}
        return tool_in_workpiece_mm(self.machine, axes, self.joint_errors(axes))[:2]

    def yaw_urad(self, axes_mm) -> float:
        """In-plane rotation of the camera against the plate, µrad (sum of the z-rotation errors)."""
        e = self.joint_errors(axes_mm)
        tool = e.get("ECY", 0.0) + e.get("EC0T", 0.0)
        wp = sum(e.get(c, 0.0) for c in ("EC0V", "ECV", "EC0X", "EC0W"))
        return tool - wp

    def true_correction_mm(self, y_ref_mm: float, head_ref_mm, cam_y_mm: float, *, tol_mm: float = 1e-9):
        """Head correction (X, Y beyond the nominal move) that keeps the plate centred, mm.

        The head position (x, v) at camera ``cam_y_mm`` that puts the same plate
        point under the camera as ``head_ref_mm`` at ``y_ref_mm``, solved by
        Newton iteration on the kinematics; returned as
        ``(x - x_ref, v - v_ref - (cam_y_mm - y_ref_mm))``.
        """
        target = self.plate_point_mm(y_ref_mm, *head_ref_mm)
        h = np.array([head_ref_mm[0], head_ref_mm[1] + cam_y_mm - y_ref_mm], float)
        for _ in range(20):
            r = self.plate_point_mm(cam_y_mm, *h) - target
            if np.max(np.abs(r)) < tol_mm:
                break
            # d(plate point)/d(head) ~ -identity (the plate moves under a fixed camera)
            h = h + r
        return np.array([h[0] - head_ref_mm[0], h[1] - head_ref_mm[1] - (cam_y_mm - y_ref_mm)])

    def plate_offset_um(self, y_ref_mm: float, head_ref_mm, cam_y_mm: float, head_mm) -> np.ndarray:
        """True displacement of the plate from centred (head X/Y, µm), without positioning noise.

        The plate is centred when the camera, at ``cam_y_mm`` with the head at
        ``head_mm``, sees the same plate point as at ``y_ref_mm`` /
        ``head_ref_mm``; the result is how far the plate is displaced from
        that, i.e. the head move still needed, negated.
        """
        ref = self.plate_point_mm(y_ref_mm, *head_ref_mm)
        return -(self.plate_point_mm(cam_y_mm, *head_mm) - ref) * 1e3

    def compensated_offsets_um(self, y_ref_mm: float, head_ref_mm, cam_ys_mm, compensation=None) -> np.ndarray:
        """(N, 2) true plate offsets (µm) at camera positions ``cam_ys_mm`` when the head follows
        ``compensation`` (its ``head_move``), or moves only with the camera (None: uncompensated)."""
        out = []
        for p in cam_ys_mm:
            dx, dy = (0.0, p - y_ref_mm) if compensation is None else compensation.head_move(y_ref_mm, p)
            out.append(self.plate_offset_um(y_ref_mm, head_ref_mm, p, (head_ref_mm[0] + dx, head_ref_mm[1] + dy)))
        return np.array(out)

    # --------------------------------------------------------------- protocol
    def move(self, cam_y_mm: float, head_x_mm: float, head_y_mm: float) -> None:
        """Drive camera Y, head X and head Y (axis V) to absolute positions, mm.

        Raises
        ------
        StageError
            A target that is not finite or outside an axis's travel.
        """
        target = {"Y": cam_y_mm, "X": head_x_mm, "V": head_y_mm}
        for name, value in target.items():
            try:
                v = float(value)
            except (TypeError, ValueError):
                raise StageError(f"move: axis {name} target must be a number, got {value!r}") from None
            lo, hi = self.limits_mm[name]
            if not np.isfinite(v) or not lo <= v <= hi:
                raise StageError(f"move: axis {name} target {v!r} mm is outside its travel [{lo:g}, {hi:g}] mm")
            target[name] = v
        self.commanded = target
        noise = self.rng.normal(0.0, self.repeat_um * 1e-3, 3) if self.repeat_um > 0 else np.zeros(3)
        self.actual = {n: target[n] + d for n, d in zip(("Y", "X", "V"), noise)}
        self.moves += 1

    def grab(self) -> np.ndarray:
        """Camera image (uint8, ``image_shape``) of the plate at the current positions."""
        act = self.actual
        p = self.plate_point_mm(act["Y"], act["X"], act["V"])
        yaw = self.yaw_urad(act) * 1e-6
        rot = np.array([[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]])
        # plate point of a pixel: p + R_yaw @ A' @ (uv - c); A' maps pixels to camera-frame mm
        a_cam = rot @ self.true_pixel_to_mm
        h, w = self.image_shape
        c = np.array([(w - 1) / 2.0, (h - 1) / 2.0])

        def image_to_plane(xy_px):
            return p + (np.asarray(xy_px, float) - c) @ a_cam.T

        self.grabs += 1
        return render_pattern(self.texture, self.image_shape, image_to_plane, low=40, high=210,
                              supersample=1, blur_px=0.6, noise_sigma=self.noise_sigma, rng=self.rng)
