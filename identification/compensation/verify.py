"""The run after the compensation: did it work, and what is left (``kinid verify``, docs/compensation.md).

After the compensation is loaded, the machine is measured again with the same kind of run. In the
controller's (compensated) coordinates a machine whose errors were removed behaves as the nominal
machine; only the set-up of the board and the sensor (which a new run may change) is refitted. What
that fit leaves is the error the compensation did not remove, plus noise.

- *before*: the tool point error the fit predicts at the second run's poses, as a set-up-only fit
  would see it on the uncompensated machine (or, given the first run, what a set-up-only fit leaves
  of it);
- *after*: what a set-up-only fit leaves of the second run;
- whether that is at the noise level (χ² test against σ; an F test where σ is the fit's estimate from its own
  residuals, itself uncertain), and a diagnosis of what remains.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import math

from kinid.stats import chi2_sf, f_logsf

from ..model import default_model, evaluate
from ..data import Observations
from ..fitting import FitResult, Noise, design, fit, joint_values
from ..diagnosis import Diagnosis, diagnose

__all__ = ["Verification", "verify", "setup_effects", "ALPHA"]

#: Significance level of the test "what is left is noise".
ALPHA = 0.01


@dataclass(frozen=True)
class Verification:
    """Result of :func:`verify`.

    Attributes
    ----------
    n_observations : int
        Alignments of the second run.
    before_um, after_um : dict
        RMS of the tool point error per coordinate (``x``, ``y``, ``z``, in the workpiece frame) and
        3-D (``3d``, the RMS of the distance), µm.
    before_source : str
        "predicted by the fit at these poses" or "measured in the first run".
    noise : Noise
        σ of one coordinate used for the test.
    noise_level_3d_um : float
        The 3-D RMS noise alone would leave after the set-up fit, µm.
    chi2_p : float
        P-value of what is left against σ (NaN where σ was estimated from these data): χ², or F where σ is the
        fit's estimate from its own residuals (``noise_dof`` degrees of freedom).
    at_noise_level : bool
        What is left is consistent with noise (p ≥ ALPHA).
    setup_fit : FitResult
        The set-up-only fit of the second run.
    diagnosis : Diagnosis
        What remains, ranked over the candidate library.
    noise_dof : float
        Degrees of freedom of σ: infinite where it was given or known, the fit's where the fit estimated it
        from its residuals.
    grew_most : dict or None
        The alignment of this run where the tool point error grew most against the fit's prediction of the error
        before at the same pose: ``mark``, ``line`` (of the CSV, where known), ``readings`` (axis -> mm / deg),
        ``before_um`` and ``after_um`` (3-D); None where it grew nowhere.
    before_max_3d_um, after_max_3d_um : float
        The largest 3-D tool point error before and after (over the same alignments as the RMS), µm.
    """

    n_observations: int
    before_um: dict
    before_source: str
    after_um: dict
    noise: Noise
    noise_level_3d_um: float
    chi2_p: float
    at_noise_level: bool
    setup_fit: FitResult
    diagnosis: Diagnosis
    noise_dof: float = math.inf
    grew_most: dict | None = None
    before_max_3d_um: float = math.nan
    after_max_3d_um: float = math.nan

    @property
    def made_worse(self) -> bool:
        """The error after is larger than before (3-D RMS) and more than the noise leaves."""
        return (not self.at_noise_level) and self.after_um["3d"] > self.before_um["3d"]

    @property
    def where_words(self) -> str:
        """Where the error grew most, in words ("" where it grew nowhere)."""
        g = self.grew_most
        if g is None:
            return ""
        at = ", ".join(f"{k} = {v:.4g}" for k, v in g["readings"].items())
        return (f"the error grew most at {at} (mark {g['mark']}" + (f", line {g['line']}" if g.get("line") else "")
                + f"): {g['after_um']:.3g} µm after against {g['before_um']:.3g} µm before")

    @property
    def noise_words(self) -> str:
        """Where σ came from and which test it makes, in words."""
        if self.noise.source == "given":
            return "given"
        if self.noise.source == "residuals":
            return "estimated from this run's residuals: no noise test"
        if math.isfinite(self.noise_dof):
            return (f"the fit's estimate from its own residuals, {self.noise_dof:.0f} degrees of freedom, hence an F "
                    f"test; what the fit's model left unexplained counts as noise in it")
        return f"known to the fit ({self.noise.source})" if self.noise.source != "fit" else "known to the fit"

    @property
    def test(self) -> str:
        """The noise test's name: χ² against a σ known, F against the fit's estimate."""
        return "F test" if math.isfinite(self.noise_dof) else "χ²"

    def summary(self) -> dict:
        """The JSON object of ``kinid verify --json`` (docs/cli.md)."""
        best = self.diagnosis.advised[0]
        return {"n_observations": self.n_observations, "before_um": self.before_um,
                "before_source": self.before_source, "after_um": self.after_um,
                "before_max_3d_um": _finite(self.before_max_3d_um), "after_max_3d_um": _finite(self.after_max_3d_um),
                "noise_um": self.noise.value_um, "noise_source": self.noise.source,
                "noise_dof": None if not math.isfinite(self.noise_dof) else float(self.noise_dof),
                "noise_level_3d_um": self.noise_level_3d_um,
                "chi2_p": None if not np.isfinite(self.chi2_p) else float(self.chi2_p),
                "at_noise_level": self.at_noise_level, "made_worse": self.made_worse, "grew_most": self.grew_most,
                "remaining_verdict": self.diagnosis.verdict,
                "machine_sha256": self.setup_fit.machine.urdf_sha256,
                "remaining_best_candidate": None if best is None else
                {"effect": best.effect, "p_value": float(best.p_value), "rms_after_um": float(best.rms_after_um)}}

    def text(self) -> str:
        """A readable report."""
        def row(d):
            return "  ".join(f"{d[k]:8.3f}" for k in ("x", "y", "z", "3d"))

        lines = [f"tool point error over {self.n_observations} alignments, RMS in µm:",
                 f"  {'':<46}{'x':>8}  {'y':>8}  {'z':>8}  {'3-D':>8}",
                 f"  {'before (' + self.before_source + ')':<46}{row(self.before_um)}",
                 f"  {'after (this run, set-up refitted)':<46}{row(self.after_um)}",
                 f"  noise alone would leave about {self.noise_level_3d_um:.3f} µm 3-D "
                 f"(σ = {self.noise.value_um:.3g} µm per coordinate, {self.noise_words})"]
        removed = 1.0 - self.after_um["3d"] / self.before_um["3d"] if self.before_um["3d"] > 0 else float("nan")
        if self.at_noise_level:
            lines.append("verdict: the compensation worked — what is left is at the noise level"
                         + (f" ({self.test} p = {self.chi2_p:.3g})" if np.isfinite(self.chi2_p) else "")
                         + (f"; {removed:.0%} of the 3-D error removed" if np.isfinite(removed) else ""))
        elif self.made_worse:
            lines.append(f"verdict: made worse — {self.after_um['3d']:.3g} µm 3-D RMS after against "
                         f"{self.before_um['3d']:.3g} µm before ({self.before_source})"
                         + (f"; {self.where_words}" if self.where_words else "") + ": check the "
                         "compensation's ranges and signs (compensation.json) and that it was made from this "
                         "machine's fit; unload it until then")
        else:
            lines.append(f"verdict: error remains — {self.after_um['3d']:.3g} µm 3-D RMS against "
                         f"{self.noise_level_3d_um:.3g} µm from noise ({self.test} p = {self.chi2_p:.3g})"
                         + (f"; {removed:.0%} of the 3-D error removed" if np.isfinite(removed) and removed > 0.1
                            else "; the error is as large as before: check that the compensation is loaded and "
                                 "active (the axes referenced)"))
        if not self.at_noise_level and not self.made_worse:  # made worse: unload first, then look again
            best = self.diagnosis.advised[0]
            if best is not None and best.p_value < self.diagnosis.threshold:
                lines.append(f"  what remains looks like {best.effect} (p = {best.p_value:.3g}; "
                             f"{best.rms_after_um:.3g} µm RMS per coordinate after adding it): identify it on this run "
                             f"(kinid identify --data ... --add {best.effect}) and compensate again")
            else:
                lines.append("  no candidate of the library explains it: check the set-up, the sensor offsets and "
                             "the σ given")
        return "\n".join(lines)


def _finite(x: float):
    return float(x) if math.isfinite(x) else None


def setup_effects(machine) -> list:
    """The constant set-up effects of the workpiece (W) and the sensor (T)."""
    return [e for e in default_model(machine) if machine.error_joint(e.code).axis in ("W", "T")]


def _rms(r_um: np.ndarray) -> dict:
    r = np.asarray(r_um, float)
    out = {k: float(np.sqrt(np.mean(r[:, i] ** 2))) for i, k in enumerate("xyz")}
    out["3d"] = float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))
    return out


def _largest(r_um: np.ndarray) -> float:
    """The largest 3-D tool point error of an (N, 3) residual, µm."""
    return float(np.max(np.linalg.norm(np.asarray(r_um, float), axis=1)))


def _predicted_before(result: FitResult, obs: Observations, effects) -> np.ndarray:
    """(N, 3) residual, µm, that a set-up-only fit would leave at the poses of ``obs`` on the machine as
    fitted (its machine errors, the set-up aside) and without noise: the error the compensation removes,
    as the second run measures it."""
    from dataclasses import replace

    machine = result.machine
    d = design(machine, result.effects, obs)
    values = joint_values(machine, d, result.theta)
    values[:, [j.axis in ("W", "T") for j in machine.error_joints]] = 0.0
    moved = evaluate(machine, obs.axes, values, jacobian=False)  # where that machine puts the tool point
    pseudo = replace(obs, w_mm=moved, offsets_mm=None)
    return fit(machine, pseudo, effects, noise_um=Noise(1.0, "given")).residuals_um


def verify(result: FitResult, after: Observations, *, before: Observations | None = None,
           noise_um: float | None = None) -> Verification:
    """Compare the run made after loading the compensation of ``result`` with the error it removed.

    Parameters
    ----------
    result : FitResult
        The fit the compensation was made from.
    after : Observations
        The second run, read against the same machine, in the controller's (compensated) readings.
    before : Observations, optional
        The first run; default: the error before is the fit's prediction at the second run's poses.
    noise_um : float, optional
        σ of one coordinate, µm. Default: the fit's σ where it was known, else estimated from the
        second run (no noise test then).
    """
    machine = result.machine
    effects = setup_effects(machine)
    noise_dof = math.inf
    if noise_um is not None:
        noise = Noise(float(noise_um), "given")
    elif result.noise.known:
        noise = Noise(result.noise_um, "fit")
    elif result.dof > 0 and math.isfinite(result.noise_um) and result.noise_um > 0:
        # the fit estimated σ from its own residuals: an estimate with the fit's degrees of freedom, tested by F
        noise, noise_dof = Noise(result.noise_um, "fit"), float(result.dof)
    else:
        noise = None
    after_fit = fit(machine, after, effects, noise_um=noise)
    predicted = _predicted_before(result, after, effects)
    if before is not None:
        before_r = fit(machine, before, effects, noise_um=noise).residuals_um
        source = "measured in the first run"
    else:
        before_r = predicted
        source = "predicted by the fit at these poses"
    before_um, after_um = _rms(before_r), _rms(after_fit.residuals_um)
    grew = _grew_most(machine, after, predicted, after_fit.residuals_um)
    n = after.axes.shape[0]
    dof = after_fit.dof
    if noise is None:
        noise, p = after_fit.noise, float("nan")
    elif dof <= 0:
        p = float("nan")
    elif math.isfinite(noise_dof):
        ratio = float(np.sum(after_fit.residuals_um ** 2)) / dof / noise.value_um ** 2
        p = math.exp(f_logsf(ratio, dof, noise_dof))
    else:
        p = chi2_sf(float(np.sum(after_fit.residuals_um ** 2)) / noise.value_um ** 2, dof)
    level = noise.value_um * float(np.sqrt(max(dof, 0) / n))
    remaining = diagnose(machine, after, effects, noise_um=noise.value_um if noise.known else None)
    at_noise = bool(np.isfinite(p) and p >= ALPHA) or (not np.isfinite(p) and remaining.verdict == "noise")
    return Verification(n_observations=n, before_um=before_um, before_source=source, after_um=after_um, noise=noise,
                        noise_level_3d_um=level, chi2_p=p, at_noise_level=at_noise, setup_fit=after_fit,
                        diagnosis=remaining, noise_dof=noise_dof, grew_most=grew,
                        before_max_3d_um=_largest(before_r), after_max_3d_um=_largest(after_fit.residuals_um))


def _grew_most(machine, obs: Observations, before_um: np.ndarray, after_um: np.ndarray) -> dict | None:
    """The alignment where the 3-D error grew most from ``before_um`` to ``after_um`` (N, 3), or None."""
    growth = np.linalg.norm(after_um, axis=1) - np.linalg.norm(before_um, axis=1)
    if growth.size == 0 or not np.max(growth) > 0:
        return None
    i = int(np.argmax(growth))
    lines = getattr(obs, "lines", None)
    return {"mark": str(obs.marks[i]), "line": None if lines is None or len(lines) <= i else int(lines[i]),
            "readings": {a.name: float(obs.axes[i, j]) for j, a in enumerate(machine.axes)
                         if np.isfinite(obs.axes[i, j])},
            "before_um": float(np.linalg.norm(before_um[i])), "after_um": float(np.linalg.norm(after_um[i]))}
