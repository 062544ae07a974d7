"""Orientation rows: a measured tool orientation against the model's (docs/formats.md, "Measured orientation").

A 6-DoF probe or a motion-capture rigid body gives each pose's orientation as well as its point. Such a pose has
one more observation row (:attr:`~kinid.identification.data.Observations.rotations`): its residual is the small-angle
vector ω of the model's tool orientation against the measured one, ``R_model = exp([ω]×) R_measured``, in the
workpiece (measurement) frame, µrad, times the row's ``rotation_um_per_urad`` (the points' σ over the orientation's):
three numbers in µm, whitened as the points' are, so the fit, its σ, its uncertainties, the held-out check and the
diagnosis take them as they take a point's (:func:`~kinid.identification.fitting.residuals.put_rotation_rows`).

The angles' convention is checked against the data before a fit (:func:`check_orientation`): at the measurement
frame fitted in closed form to the points, the measured orientation must lie within :data:`ORIENTATION_LIMIT_DEG`
of the model's; tens of degrees is a convention, a unit or a mount, and the check names which reading fits.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from kinid.errors import DataError
from ..model import Machine, default_model
from ..data import euler_rotations
from .residuals import design, joint_values, rotation_residual_urad, tool_rotations
from .start import closed_form_start

__all__ = ["OrientationCheck", "OrientationResiduals", "check_orientation", "orientation_residuals", "ORIENTATION_LIMIT_DEG"]

#: The largest RMS angle (deg) between the measured orientation and the model's at the closed-form start that a
#: machine's errors explain: 17 mrad, beyond the 10 mrad no machine's error reaches
#: (:mod:`~kinid.identification.model.plausibility`) and far below a convention's or a unit's mistake.
ORIENTATION_LIMIT_DEG = 1.0


@dataclass(frozen=True)
class OrientationCheck:
    """The measured orientation against the model's at the measurement frame fitted to the points.

    Attributes
    ----------
    rms_deg : float
        RMS angle of ω over the poses, deg, read as the export says.
    spread_deg : float
        The same about the one turn on the tool that fits best (what is left once the mount is any): a wrong mount
        has a large ``rms_deg`` and a small spread.
    mount_deg : (3,) float
        That turn as the mount the export's sequence gives (the measured body in the tool frame, deg).
    readings : tuple of (description, rms_deg)
        Every other reading tried (sequence and unit), best first.
    ok : bool
        ``rms_deg`` within :data:`ORIENTATION_LIMIT_DEG`.
    line : str
        One line: the figures and, where not ok, the likely mistake.
    """

    rms_deg: float
    spread_deg: float
    mount_deg: tuple
    readings: tuple
    ok: bool
    line: str


def check_orientation(machine: Machine, export, effects=None) -> OrientationCheck:
    """Check an export's measured orientation against the model before a fit: the measurement frame (and the point
    on the tool) fitted in closed form to the points at the nominal machine
    (:func:`~kinid.identification.fitting.start.closed_form_start`), then the orientation read as the export says,
    and as every other Euler sequence and unit reading, against the model's.

    Parameters
    ----------
    machine : Machine
    export : Export
        With orientation rows (``export.orientation`` has ``angles_deg``).
    effects : sequence of Effect, optional
        The model (default: the default model): its set-up joints place the frame.

    Raises
    ------
    DataError
        When the export has no orientation rows.
    """
    o = export.orientation
    obs = export.observations
    rows = obs.rotation_rows
    if "angles_deg" not in o or not rows.any():
        raise DataError("the export has no orientation rows to check", path=obs.source)
    effects = tuple(default_model(machine)) if effects is None else tuple(effects)
    points = obs.subset(~rows)
    d = design(machine, effects, points)
    start = closed_form_start(machine, d, points, np.zeros(d.n_params))
    theta = np.zeros(d.n_params) if start is None else start.theta
    turned = obs.subset(rows)
    R_model = tool_rotations(machine, turned.axes, joint_values(machine, design(machine, effects, turned), theta))
    mount = euler_rotations(o["mount_deg"], o["sequence"])[0]

    def rms(R_measured):
        return float(np.sqrt(np.mean(np.sum(rotation_residual_urad(R_model, R_measured) ** 2, axis=1)))) * 1e-6 * 180 / np.pi

    given = rms(turned.rotations)
    on_tool = Rotation.from_matrix(np.einsum("nji,njk->nik", R_model, turned.rotations)).mean()  # the turn left on it
    spread = rms(turned.rotations @ on_tool.as_matrix().T)
    found_mount = tuple(float(v) for v in (on_tool * Rotation.from_matrix(mount)).as_euler(o["sequence"], degrees=True))
    angles = o["angles_deg"]
    tried = []
    for sequence in ("XYZ", "xyz", "ZYX", "zyx"):
        for factor, unit in ((1.0, ""), (180 / np.pi, " (the angles in radians)"), (np.pi / 180, " (the angles in degrees read as radians)")):
            if (sequence, factor) != (o["sequence"], 1.0):
                R = euler_rotations(angles * factor, sequence) @ euler_rotations(o["mount_deg"], sequence)[0].T
                tried.append((f"Euler {sequence}{unit}", rms(R)))
    tried.sort(key=lambda t: t[1])
    ok = given <= ORIENTATION_LIMIT_DEG
    line = (f"measured orientation against the model's at the frame fitted to the points: {given:.3g}° RMS over "
            f"{len(turned)} poses (Euler {o['sequence']}, the mount {', '.join(f'{v:g}' for v in o['mount_deg'])}°)")
    if not ok:
        line += f", beyond the {ORIENTATION_LIMIT_DEG:g}° a machine's errors explain"
        if tried[0][1] <= ORIENTATION_LIMIT_DEG:
            line += f": read as {tried[0][0]} it is {tried[0][1]:.3g}° — the likely convention (--orientation)"
        elif spread <= ORIENTATION_LIMIT_DEG:
            line += (f": about one turn on the tool it is {spread:.3g}° — the measured body sits turned "
                     f"{', '.join(f'{v:.4g}' for v in found_mount)}° in the tool frame: give that mount "
                     f"(--orientation-mount-deg)")
        else:
            line += (f"; no other reading fits (best {tried[0][0]}: {tried[0][1]:.3g}°): check the columns, their "
                     f"unit and the mount, or leave the orientation out (--orientation off)")
    return OrientationCheck(given, spread, found_mount, tuple(tried), ok, line)


@dataclass(frozen=True)
class OrientationResiduals:
    """A fit's orientation residuals, and as weighted beside the points'.

    Attributes
    ----------
    rms_urad : float
        RMS of the orientation residuals' components (ω), µrad.
    weighted_rms_um : float
        The same weighted as the fit took them (σ of the points over the orientation's), µm.
    points_rms_um : float
        The points' residual RMS per coordinate, µm.
    ratio : float
        ``weighted_rms_um / points_rms_um``: 1 where the σ the weights came from fit the residuals alike; 3 where the
        orientation's residuals are 3× larger than its σ says, against the points'.
    line : str
    """

    rms_urad: float
    weighted_rms_um: float
    points_rms_um: float
    ratio: float
    line: str


def orientation_residuals(obs, residuals_um) -> OrientationResiduals:
    """The orientation residuals of a fit (``residuals_um`` (N, 3) of ``obs``, its orientation rows weighted)
    in µrad and weighted beside the points': where they differ, the weights the fit gave the orientation
    (their σ against the points') are off by as much (measured beats declared)."""
    rows = obs.rotation_rows
    if not rows.any():
        raise DataError("the observations have no orientation rows", parameter="obs")
    r = np.asarray(residuals_um, float)
    weight = obs.rotation_um_per_urad[rows]
    rms = float(np.sqrt(np.mean((r[rows] / weight[:, None]) ** 2)))
    weighted = float(np.sqrt(np.mean(r[rows] ** 2)))
    points = float(np.sqrt(np.mean(r[~rows] ** 2))) if (~rows).any() else float("nan")
    ratio = weighted / points if points > 0 else float("nan")
    if not 1 / 1.5 <= ratio <= 1.5:
        verdict = (f"the orientation's residuals are {ratio:.3g}× what its σ (against the points') says: its rows weigh "
                   f"{'more' if ratio > 1 else 'less'} in the fit than they should")
    else:
        verdict = "its σ and the points' agree with the residuals alike"
    line = (f"orientation residuals: RMS {rms:.4g} µrad per component over {int(rows.sum())} poses; weighted "
            f"{weighted:.4g} µm against the points' {points:.4g} µm (ratio {ratio:.3g}): {verdict}")
    return OrientationResiduals(rms, weighted, points, ratio, line)
