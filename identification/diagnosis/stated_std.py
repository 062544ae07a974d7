"""The instrument's stated standard deviations checked against the residuals of a fit: measured beats declared.

A laser tracker writes a standard deviation beside each coordinate it measures (``measurement_std_x`` …). The fit
takes one σ for every coordinate (:mod:`~kinid.identification.fitting.noise`), so the stated std are judged after it,
on two counts:

- **scale**: the RMS of residual/std over every coordinate, the residuals scaled by ``sqrt(3N / dof)`` for the
  degrees of freedom the fit took (a residual is smaller than the noise that made it); within a factor
  :data:`AGREE_FACTOR` of 1 the stated std agree with the residuals;
- **tracking**: whether rows with larger stated std scatter more. Two models of the residuals, each with one free
  scale, are compared by their Gaussian log-likelihood: σ_i = k·s_i (the stated std, scaled) against σ_i = c (one
  σ). The stated std track the residuals when the first is better by more than :data:`TRACK_LOG_LIKELIHOOD`; with
  stated std that hardly vary (:data:`VARY_FACTOR`) the question does not arise. The residual RMS in the thirds of
  the stated std shows it in numbers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["AGREE_FACTOR", "StdCheck", "check_stated_std"]

#: Stated std within this factor of what the residuals show agree with them (RMS of residual/std in [1/1.5, 1.5]).
AGREE_FACTOR = 1.5
#: The stated std's 90th percentile over their 10th below this: they hardly vary, and cannot tell rows apart.
VARY_FACTOR = 1.3
#: Log-likelihood by which σ_i = k·s_i must beat one σ for the stated std to track the residuals (a likelihood ratio
#: of e³ ≈ 20; both models have one free parameter).
TRACK_LOG_LIKELIHOOD = 3.0


@dataclass(frozen=True)
class StdCheck:
    """The stated standard deviations against the residuals.

    Attributes
    ----------
    median_um : float
        Median stated std, µm.
    ratio : float
        RMS of residual/std over every coordinate (dof-corrected): 1 when the stated std are right, 3 when they are
        3× too small.
    ratio_xyz : tuple of 3 float
        The same per coordinate of the measurement frame.
    tracks : bool or None
        Whether rows with larger stated std scatter more; None when the stated std hardly vary.
    log_likelihood : float
        log L(σ_i = k·s_i) − log L(σ_i = c), the evidence for ``tracks``.
    bins : tuple of (median stated std µm, residual RMS µm, coordinates)
        The coordinates in thirds of their stated std.
    """

    median_um: float
    ratio: float
    ratio_xyz: tuple
    tracks: bool | None
    log_likelihood: float
    bins: tuple

    @property
    def agree(self) -> bool:
        return 1.0 / AGREE_FACTOR <= self.ratio <= AGREE_FACTOR

    @property
    def line(self) -> str:
        """One plain line: whether the stated std agree with what the residuals show."""
        said = f"the instrument's stated std (median {self.median_um:.3g} µm)"
        thirds = ", ".join(f"{r:.3g}" for _, r, _ in self.bins)
        of = ", ".join(f"{s:.3g}" for s, _, _ in self.bins)
        binned = f"residual RMS {thirds} µm in thirds of stated std {of} µm"
        if self.tracks is False:
            return (f"{said} do not follow the residuals: rows with larger stated std scatter no more ({binned}; "
                    f"RMS of residual/std {self.ratio:.3g}): the fit's σ comes from the residuals, not from them")
        if self.agree:
            out = f"{said} agree with the residuals: RMS of residual/std {self.ratio:.3g}"
        else:
            factor, word = (self.ratio, "smaller") if self.ratio > 1 else (1 / self.ratio, "larger")
            out = (f"{said} are {factor:.2g}× {word} than the residuals show (RMS of residual/std {self.ratio:.3g}): "
                   f"the fit's σ comes from the residuals, not from them")
        if self.tracks:
            out += (f"; rows with larger stated std scatter more ({binned}), though the fit takes one σ for every "
                    f"coordinate")
        return out

    def summary(self) -> dict:
        """The check as FIT.json records it (``stated_std``)."""
        return {"line": self.line, "median_um": self.median_um, "ratio": self.ratio,
                "ratio_xyz": list(self.ratio_xyz), "agree": self.agree, "tracks": self.tracks,
                "log_likelihood": self.log_likelihood,
                "bins": [{"stated_um": s, "residual_rms_um": r, "coordinates": k} for s, r, k in self.bins]}


def check_stated_std(residuals_um, std_um, dof: int) -> StdCheck | None:
    """The stated std ``std_um`` of each coordinate against the fit's residuals (module docstring: the rule).

    Parameters
    ----------
    residuals_um : array (N, 3)
        The fit's residuals, µm, in the frame the std are stated in (the measurement frame).
    std_um : array (N, 3)
        The stated standard deviations, µm.
    dof : int
        The fit's residual degrees of freedom, 3N − rank.

    Returns
    -------
    StdCheck, or None when no coordinate has a positive stated std or the fit has no degree of freedom left.
    """
    r = np.asarray(residuals_um, float).reshape(-1, 3)
    s = np.asarray(std_um, float).reshape(-1, 3)
    ok = (s > 0) & np.isfinite(s) & np.isfinite(r)
    if dof <= 0 or ok.sum() < 3:
        return None
    scale = np.sqrt(r.size / dof)  # the residuals of a fit are smaller than the noise by sqrt(dof / 3N)
    z = np.where(ok, r / np.where(ok, s, 1.0), 0.0) * scale
    ratio_xyz = tuple(float(np.sqrt(np.sum(z[:, c] ** 2) / max(ok[:, c].sum(), 1))) for c in range(3))
    rv, sv = r[ok] * scale, s[ok]
    n = rv.size
    ratio = float(np.sqrt(np.mean((rv / sv) ** 2)))
    lo, hi = np.percentile(sv, [10, 90])
    tiny = 1e-12 * max(float(np.mean(rv**2)), 1e-300)  # a residual of exactly zero (noise-free data)
    loglik = float(0.5 * n * (np.log(np.mean(rv**2) + tiny) - np.log(np.mean((rv / sv) ** 2) + tiny / lo**2))
                   - np.sum(np.log(sv)))
    tracks = None if hi < VARY_FACTOR * lo else loglik > TRACK_LOG_LIKELIHOOD
    order = np.argsort(sv, kind="stable")
    bins = tuple((float(np.median(sv[k])), float(np.sqrt(np.mean(rv[k] ** 2))), int(k.size))
                 for k in np.array_split(order, 3) if k.size)
    return StdCheck(float(np.median(sv)), ratio, ratio_xyz, tracks, loglik, bins)
