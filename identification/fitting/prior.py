"""A prior on the size of each error, for small noisy data sets (``kinid identify --prior``).

With few alignments (a robot's 23 poses) the full model fits the noise: the plain least-squares
estimate predicts left-out poses worse than a fit of the measurement frame alone. A prior says how large
errors of each kind usually are — a zero-mean Gaussian of standard deviation ``PRIOR_UM`` for location
errors along an axis and ``PRIOR_URAD`` about one, none for the set-up of the measurement frame and the
measured point (they may be anything) nor for position-dependent effects — and the fit becomes the
maximum a posteriori estimate. How much to trust it is the scale of those sizes, chosen from the data
with the noise σ: by the marginal likelihood (the evidence of the data for each scale and σ, Laplace's
approximation at the estimate: MacKay 1992), or, on request, by the scale whose fits predict left-out
alignments best (leave-one-out up to ``LOO_MAX`` alignments, else ``FOLDS``-fold). On the 23 real poses
of a UR10e the evidence picks the scale cross-validation finds best, and it does so as well on each
22-pose subset (benchmarks/bench_ur10_prior.py), where cross-validation on so few poses wavers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import basis_of

__all__ = ["PRIOR_UM", "PRIOR_URAD", "SCALES", "PriorChoice", "prior_std", "choose_prior", "HeldOutCheck",
           "held_out_check", "pose_folds"]

#: Default size of a location error along an axis (µm) and about one (µrad): a machine or robot built to drawing.
PRIOR_UM = 1000.0
PRIOR_URAD = 1000.0
#: Scales of the default sizes tried.
SCALES = (0.03, 0.1, 0.3, 1.0, 3.0, 10.0)
#: Leave-one-out up to this many poses; more are split into FOLDS blocks (:func:`pose_folds`).
LOO_MAX = 60
FOLDS = 10


@dataclass(frozen=True)
class PriorChoice:
    """The scale and σ chosen, and the score of every scale tried (log evidence, or held-out 3-D RMS in µm)."""

    scale: float
    prior_um: float
    prior_urad: float
    scores: dict
    noise_um: float
    method: str

    def describe(self) -> str:
        if self.method == "evidence":
            tried = "log evidence " + ", ".join(f"×{k:g}: {v:.1f}" for k, v in self.scores.items())
        else:
            tried = "held-out 3-D RMS " + ", ".join(f"×{k:g}: {v:.4g} µm" for k, v in self.scores.items())
        how = "the marginal likelihood" if self.method == "evidence" else self.method
        return (f"prior: location errors ~ {self.prior_um * self.scale:g} µm / {self.prior_urad * self.scale:g} µrad "
                f"(the default sizes ×{self.scale:g}, chosen by {how}; {tried}); set-up and position-dependent "
                f"effects without prior; σ {self.noise_um:.4g} µm")


def prior_std(machine, effects, scale: float = 1.0, prior_um: float = PRIOR_UM, prior_urad: float = PRIOR_URAD):
    """The prior's standard deviation of every parameter of ``effects`` (inf where there is none)."""
    out = []
    for e in effects:
        joint = machine.error_joint(e.code)
        constant = basis_of(e).constant and joint.axis not in ("W", "T")
        size = (prior_um if e.unit == "um" else prior_urad) * scale
        out += [size if constant else np.inf] * e.n_params
    return np.array(out, float)


def pose_folds(obs, loo_max: int, folds: int) -> tuple:
    """(the rows left out in each fold, the method's name): every pose — the rows read from one line of a file
    with the same readings, several targets and the orientation of one pose together — left out in turn up to
    ``loo_max`` poses, else ``folds`` interleaved blocks of poses, in the order of the file. A row of the pose left
    out never stays in the fit: its other targets would tell the fit where the pose is."""
    index = {}
    keys = zip(obs.lines or range(len(obs)), (row.tobytes() for row in np.ascontiguousarray(obs.axes)))
    pose = np.array([index.setdefault(key, len(index)) for key in keys], int)
    n = int(pose.max()) + 1 if len(pose) else 0
    k = n if n <= loo_max else folds
    method = "leave-one-out" if k == n else f"{k}-fold, interleaved"
    if len(pose) > n:
        method = method.replace("leave-one-out", "leave-one-pose-out") + f" over {n} poses"
    return tuple(np.flatnonzero(pose % k == f) for f in range(k)), method


def _held_out_um(machine, obs, effects, noise_um, s, folds) -> float:
    from .fit import fit
    from .residuals import design, residuals

    n = len(obs)
    ss = 0.0
    for test in folds:
        train = np.setdiff1d(np.arange(n), test)
        tr, te = obs.subset(train), obs.subset(test)
        result = fit(machine, tr, effects, noise_um=noise_um, prior_std=s)
        r = residuals(machine, design(machine, effects, te), te, result.theta, jacobian=False)
        ss += float(np.sum(r**2))
    return float(np.sqrt(ss / n))


def _log_evidence(machine, obs, effects, noise_um, s) -> float:
    """log p(data | prior s, σ) by Laplace's approximation at the maximum a posteriori estimate (parameters
    without a prior: flat, the same constant for every scale)."""
    from .fit import fit
    from .residuals import design, residuals

    result = fit(machine, obs, effects, noise_um=noise_um, prior_std=s)
    r, J, _ = residuals(machine, design(machine, effects, obs), obs, result.theta)
    keep = result.identifiable
    J, sk, th = J.reshape(-1, J.shape[-1])[:, keep], s[keep], result.theta[keep]
    has = np.isfinite(sk)
    H = J.T @ J / noise_um**2 + np.diag(np.where(has, 1.0 / np.where(has, sk, 1.0) ** 2, 0.0))
    _, logdet = np.linalg.slogdet(H)
    return float(-0.5 * (np.sum(r**2) / noise_um**2 + np.sum((th[has] / sk[has]) ** 2)) - 0.5 * logdet
                 - np.sum(np.log(sk[has])) - r.size * np.log(noise_um))


#: σ tried with the evidence, as factors of the plain fit's σ.
NOISE_FACTORS = (0.6, 0.8, 1.0, 1.25, 1.6)


def choose_prior(machine, obs, effects, *, noise_um=None, scales=SCALES, prior_um=PRIOR_UM,
                 prior_urad=PRIOR_URAD, method: str = "evidence") -> PriorChoice:
    """The scale of the default sizes (and σ, unless given) for the maximum a posteriori fit.

    ``method``: ``"evidence"`` (the marginal likelihood over the scales and, when ``noise_um`` is not given,
    σ around the plain fit's) or ``"cross-validation"`` (the held-out error of each scale, σ the plain fit's).
    """
    from kinid.errors import DataError

    from .fit import fit

    if method not in ("evidence", "cross-validation"):
        raise DataError(f"must be 'evidence' or 'cross-validation', got {method!r}", parameter="method")
    given = noise_um is not None
    if not given:
        plain = fit(machine, obs, effects)
        noise_um = float(np.sqrt(np.sum(plain.residuals_um**2) / max(plain.dof, 1)))
    stds = {float(a): prior_std(machine, effects, a, prior_um, prior_urad) for a in scales}
    if method == "evidence":
        sigmas = (noise_um,) if given else tuple(noise_um * f for f in NOISE_FACTORS)
        table = {(a, sg): _log_evidence(machine, obs, effects, sg, s) for a, s in stds.items() for sg in sigmas}
        best_a, best_s = max(table, key=table.get)
        scores = {a: max(v for (aa, _), v in table.items() if aa == a) for a in stds}
        return PriorChoice(best_a, prior_um, prior_urad, scores, float(best_s), "evidence")
    folds, how = pose_folds(obs, LOO_MAX, FOLDS)
    held = {a: _held_out_um(machine, obs, effects, noise_um, s, folds) for a, s in stds.items()}
    best = min(held, key=held.get)
    how = how.replace(", interleaved", " cross-validation")
    return PriorChoice(best, prior_um, prior_urad, held, float(noise_um), how)


#: The held-out check of ``identify --prior``: leave-one-out up to this many poses, else CHECK_FOLDS blocks.
CHECK_LOO_MAX = 30
CHECK_FOLDS = 10


@dataclass(frozen=True)
class HeldOutCheck:
    """Held-out 3-D RMS (µm) of the prior's fit — its scale and σ chosen on the training alignments alone — and of
    the plain least-squares fit, over the same folds."""

    method: str
    prior_um: float
    plain_um: float

    def describe(self) -> str:
        better = "better" if self.prior_um < self.plain_um else "not better"
        mm = max(self.prior_um, self.plain_um) >= 1000.0
        size = (lambda v: f"{v / 1e3:.4g} mm") if mm else (lambda v: f"{v:.4g} µm")
        return (f"held-out check ({self.method}, the prior's scale and σ chosen without the left-out alignments): "
                f"3-D RMS {size(self.prior_um)} with the prior, {size(self.plain_um)} plain least squares — the "
                f"prior predicts {better}")


def held_out_check(machine, obs, effects, *, noise_um=None, prior_um=PRIOR_UM, prior_urad=PRIOR_URAD) -> HeldOutCheck:
    """Nested cross-validation of the prior against the plain fit (leave-one-out up to ``CHECK_LOO_MAX``
    poses, else ``CHECK_FOLDS`` interleaved blocks: :func:`pose_folds`)."""
    from .fit import fit
    from .residuals import design, residuals

    n = len(obs)
    folds, method = pose_folds(obs, CHECK_LOO_MAX, CHECK_FOLDS)
    ss = np.zeros(2)
    for test in folds:
        train = np.setdiff1d(np.arange(n), test)
        tr, te = obs.subset(train), obs.subset(test)
        choice = choose_prior(machine, tr, effects, noise_um=noise_um, prior_um=prior_um, prior_urad=prior_urad)
        fits = (fit(machine, tr, effects, noise_um=choice.noise_um,
                    prior_std=prior_std(machine, effects, choice.scale, prior_um, prior_urad)),
                fit(machine, tr, effects, noise_um=noise_um))
        for m, result in enumerate(fits):
            r = residuals(machine, design(machine, effects, te), te, result.theta, jacobian=False)
            ss[m] += float(np.sum(r**2))
    rms = np.sqrt(ss / n)
    return HeldOutCheck(method, float(rms[0]), float(rms[1]))
