"""Fitted errors too large to be a machine's: flagged, never added by ``--auto`` (docs/identification.md).

A machine tool's geometric errors are micrometres to a few tens of micrometres and microradians to a
few hundred; a fit that needs a millimetre or ten milliradians is explaining something else — a
sensor offset not in the sensor file, a camera model that does not fit the lens, a unit mistake —
and the effect it names is not there. The set-up of the board and the sensor may be off by more
(a board placed by hand), so it has wider limits: the measurement frame (``?0W``) none at all (a laser
tracker stands metres from a robot, turned any way), the point on the tool (``?0T``) half a metre (a
marker on a long tool) and its turn half a radian (a sensor mounted askew). An error that alone carries a
held set-up parameter (``EZ0J6 and EZ0T: only their sum is identified``: the marker's distance along the
last joint's axis is in EZ0J6) is judged by that set-up's limit.

The size of an effect is its largest value over the data: the value of a constant, the largest
|value| of a position-dependent effect over the fitted range of its axis, a drift over an hour.
A maximum a posteriori fit (``identify --prior``) also flags a constant beyond ``PRIOR_MULTIPLE`` times
its prior's standard deviation: the prior said such a size is all but impossible.

A constant whose implausible value lies within its expanded uncertainty U (k = 2), or whose U alone
reaches the limit, is not evidence of inconsistent observations: the plan hardly determines it (a
direction of the parameters the poses barely see), and a little noise or a small misfit elsewhere moves
it that far. It is flagged as ``undetermined``, with the remedy that fits it:
a prior on the sizes (``--prior``) or poses that determine it (``kinid plan``).

The same holds for a weak direction shared by several constants (the B-head + C table's patent plan
barely tells EA0Z from EY0C): the partner with the smaller uncertainty is dragged along with the one the
plan cannot bound. The flagged constants are judged together, in units of their limits: the part of
their values along the directions whose U moves one of them as far as its limit is what the plan
cannot determine; a constant whose remainder is within the limit or within its own U (k = 2) is
undetermined too. For one constant this is the rule above.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .bases import DRIFT_HORIZON_S, basis_of
from .effects import basis_values, parse_effect

__all__ = ["Implausible", "implausible_effects", "implausible_candidate", "warning_lines", "machine_limit",
           "share_of_limit", "LIMITS", "PRIOR_MULTIPLE"]

#: Largest plausible size: a machine's own errors, µm and µrad; the set-up of the point on the tool (``?0T``),
#: µm and µrad; the measurement frame (``?0W``) is placed anywhere (no limit).
LIMITS = {"um": 1000.0, "urad": 10000.0, "tool_um": 500000.0, "tool_urad": 500000.0,
          "frame_um": math.inf, "frame_urad": math.inf}
#: The limits' prefix for the set-up pseudo-axes.
_SETUP_PREFIX = {"W": "frame_", "T": "tool_"}
#: A constant beyond this many of its prior's standard deviations is flagged.
PRIOR_MULTIPLE = 5.0


@dataclass(frozen=True)
class Implausible:
    """An effect whose fitted size is beyond what a machine (or a set-up) could have."""

    effect: str
    size: float
    limit: float
    unit: str
    std: float = math.nan  # of a constant's value; NaN for an effect of several parameters
    partners: tuple = ()  # the flagged constants sharing the weak direction that carries its size
    wrong_sign: str = ""  # the parameter of a signed basis (a compliance) beyond twice its std on the wrong side

    @property
    def undetermined(self) -> bool:
        """The data hardly determine the value: zero lies within its expanded uncertainty U (k = 2), or U alone
        reaches sizes no machine has (the plan cannot bound it; a small misfit elsewhere then moves it that far),
        or its size lies along such a direction shared with ``partners``."""
        return bool(np.isfinite(self.std) and 2.0 * self.std >= min(self.size, self.limit)) or bool(self.partners)

    def describe(self) -> str:
        if self.wrong_sign:
            return (f"{self.wrong_sign} = {self.size:.4g} {self.unit}, of the sign no machine has (an arm droops "
                    f"under its weight: a compliance is not below zero)")
        if self.undetermined:
            why = ("zero is within its uncertainty" if self.size <= 2.0 * self.std else
                   "its uncertainty alone reaches sizes no machine has" if 2.0 * self.std >= self.limit else
                   f"its size lies along a direction the plan does not determine, shared with "
                   f"{', '.join(self.partners)}")
            return (f"{self.effect} = {self.size:.4g} ± {2.0 * self.std:.2g} {self.unit} (k = 2), beyond "
                    f"{self.limit:g} {self.unit}: not determined by these data ({why})")
        return f"{self.effect} = {self.size:.4g} {self.unit}, beyond {self.limit:g} {self.unit}"

    @property
    def remedy(self) -> str:
        """What the flag means and what to do, for this effect alone (the report's note under its table)."""
        if self.wrong_sign:
            return "the residual it explains is not the arm's give under its weight but something the model lacks"
        if self.undetermined:
            return (f"the plan hardly determines it — fit with --prior to hold such errors near zero, or choose poses "
                    f"that determine it (kinid plan --param {self.effect}=U)")
        return ("the observations look inconsistent (a sensor offset, a camera model, a unit) rather than the machine "
                "having it")


#: What :func:`implausible_effects` flags, said once above the list (fit and diagnosis texts).
INCONSISTENT = ("sizes no machine has (the observations look inconsistent — a sensor offset not in the sensor file, a "
                "camera model that does not fit the lens, a unit — rather than these errors being there; check them "
                "before adding effects)")
UNDETERMINED = ("sizes no machine has within the uncertainty of errors the plan hardly determines (its poses barely "
                "tell them from other errors): fit with --prior to hold such errors near zero, or choose poses that "
                "determine them (kinid plan --param NAME=U)")


def warning_lines(odd, prefix: str = "WARNING: ") -> list:
    """The warning lines for flagged effects, the inconsistent ones and the undetermined ones apart, each group
    under its header (``prefix`` before it: the fit's text warns, the diagnosis lists)."""
    lines = []
    for flagged, header in (([a for a in odd if not a.undetermined], INCONSISTENT),
                            ([a for a in odd if a.undetermined], UNDETERMINED)):
        if flagged:
            lines.append(f"{prefix}{header}:")
            lines += [f"  - {a.describe()}" for a in flagged]
    return lines


def machine_limit(machine, code: str, unit: str) -> float:
    """The largest size a machine has for error joint ``code`` (a set-up, for the measurement frame's and the
    tool point's joints W and T: inf for W), in ``unit`` (µm or µrad, written "um"/"urad" or "µm"/"µrad")."""
    prefix = _SETUP_PREFIX.get(machine.error_joint(code).axis, "")
    return LIMITS[prefix + ("urad" if "rad" in unit else "um")]


def share_of_limit(machine, code: str, size: float, unit: str) -> float:
    """``size`` (in ``unit``; a drift per second is judged over DRIFT_HORIZON_S) as a share of
    :func:`machine_limit`: inf for a size not known."""
    if not np.isfinite(size):
        return math.inf
    return abs(size) * (DRIFT_HORIZON_S if unit.endswith("/s") else 1.0) / machine_limit(machine, code, unit)


def _size(effect, theta, machine, axis_ranges) -> float:
    basis = basis_of(effect)
    if basis.driver in ("position", "direction") and effect.axis in axis_ranges:
        lo, hi = axis_ranges[effect.axis]
        q = np.linspace(lo, hi, 201)
        axes = np.zeros((q.size, len(machine.axes)))
        axes[:, machine.axis_names.index(effect.axis)] = q
        dirs = {effect.axis: np.where(np.arange(q.size) % 2 == 0, 1.0, -1.0)}
        return float(np.max(np.abs(basis_values(effect, machine, axes, directions=dirs) @ theta)))
    return basis.extent(effect, theta)


def implausible_effects(result, names=None) -> tuple:
    """The effects of a fit (or only those in ``names``) whose size is beyond :data:`LIMITS`."""
    machine = result.machine
    theta = np.where(result.identifiable, np.nan_to_num(result.values), 0.0)
    carried = _carried_set_ups(machine, getattr(result, "aliases", ()))
    out, index, k = [], [], 0
    for e in result.effects:
        th = theta[k:k + e.n_params]
        k += e.n_params
        limit = max([machine_limit(machine, e.code, e.unit)] +
                    [machine_limit(machine, code, e.unit) for code in carried.get(e.name, ())])
        prior = getattr(result, "prior_std", None)
        if prior is not None and e.n_params == 1 and np.isfinite(prior[k - 1]):
            limit = min(limit, PRIOR_MULTIPLE * float(prior[k - 1]))
        wrong = _wrong_sign(e, th, result.std[k - e.n_params:k], machine)
        if wrong is not None:
            out.append(wrong)
            index.append(k - 1)
            continue
        size = _size(e, th, machine, result.axis_ranges)
        if size > limit:
            std = float(result.std[k - 1]) if e.n_params == 1 and result.identifiable[k - 1] else math.nan
            out.append(Implausible(e.name, size, limit, "µm" if e.unit == "um" else "µrad", std))
            index.append(k - 1)
    out = _weak_partners(out, index, theta, getattr(result, "correlation", None))
    return tuple(a for a in out if names is None or a.effect in names)


def _carried_set_ups(machine, aliases) -> dict:
    """Effect name -> the held set-up joints (W, T) it alone carries: aliases with one partner of the machine's
    own errors (other set-up partners aside: several targets' points share EZ0J6 with the held one), an error joint
    of the set-up's own chain (the tool's for T, the workpiece's for W: EZ0J6 beside EZ0T on an arm; a table's
    EY0C beside a spindle sensor's EY0T is a machine's error the plan cannot tell from the set-up, and keeps its
    limit)."""
    def setup(name):
        code = name.split(":")[0]
        return code in machine.error_codes and machine.error_joint(code).axis in _SETUP_PREFIX

    out = {}
    for a in aliases:
        code = a.name.split(":")[0]
        if a.kind != "aliased" or not setup(a.name):
            continue
        own = [p for p, _ in a.partners if not setup(p)]
        if len(own) != 1:
            continue
        partner = own[0]
        if partner.split(":")[0] in machine.error_codes and _same_chain(machine, code, partner.split(":")[0]):
            out.setdefault(partner, []).append(code)
    return out


def _same_chain(machine, setup_code: str, code: str) -> bool:
    """Error joint ``code`` lies on the chain from the root to the frame set-up joint ``setup_code`` sets up."""
    frame = machine.tool_frame if machine.error_joint(setup_code).axis == "T" else machine.workpiece_frame
    model = machine.model
    joint = next(j for j in range(1, model.njoints) if model.idx_qs[j] == machine.error_joint(code).q_index)
    return joint in model.supports[model.frames[frame].parentJoint]


def implausible_candidate(machine, candidate, axis_ranges) -> Implausible | None:
    """A scored candidate (:class:`~kinid.identification.diagnosis.scoring.Candidate`) whose size at the values the score test
    estimates is beyond :data:`LIMITS`, as for a fitted effect (its largest value over ``axis_ranges``, the fitted
    range of its axis); None when it is within them or its values are not known. Only values the data determine
    count (beyond twice their standard deviation): a term along a direction the model nearly holds takes any value
    the noise gives it (a polynomial's linear term beside the model's squareness), and the fit holds it."""
    if not candidate.coefficients:
        return None
    effect = parse_effect(candidate.effect, machine)
    theta = np.asarray(candidate.coefficients, float)
    std = np.asarray(candidate.coefficient_std, float) if candidate.coefficient_std else np.zeros_like(theta)
    if theta.shape != (effect.n_params,) or std.shape != theta.shape:
        return None
    wrong = _wrong_sign(effect, theta, std, machine)
    if wrong is not None:
        return wrong
    theta = np.where(np.abs(theta) > 2.0 * std, theta, 0.0)
    size, limit = _size(effect, theta, machine, axis_ranges), machine_limit(machine, effect.code, effect.unit)
    return Implausible(effect.name, size, limit, "µm" if effect.unit == "um" else "µrad") if size > limit else None


def _wrong_sign(effect, theta, std, machine) -> Implausible | None:
    """The first parameter of a signed basis (:attr:`~kinid.identification.model.bases.Basis.sign`: a compliance)
    on the wrong side of zero by more than twice its standard deviation, flagged; None for none."""
    sign = basis_of(effect).sign
    if not sign:
        return None
    std = np.nan_to_num(np.asarray(std, float), nan=np.inf)
    wrong = np.flatnonzero(sign * np.asarray(theta, float) < -2.0 * std)
    if not wrong.size:
        return None
    i = int(wrong[0])
    return Implausible(effect.name, float(theta[i]), 0.0, effect.param_units(machine)[i],
                       wrong_sign=effect.param_names()[i])


def _weak_partners(flagged: list, index: list, theta, correlation) -> list:
    """The flagged constants whose size lies along directions the plan does not determine, judged together (the
    module's docstring), each with the partners of its direction; the others unchanged."""
    const = [i for i, a in enumerate(flagged) if np.isfinite(a.std) and a.std > 0]
    if correlation is None or len(const) < 2:
        return flagged
    at = [index[i] for i in const]
    limit = np.array([flagged[i].limit for i in const])
    x = theta[at] / limit  # values in units of their limits
    s = np.array([flagged[i].std for i in const]) / limit
    rho = np.nan_to_num(correlation[np.ix_(at, at)])
    C = rho * np.outer(s, s)
    lam, V = np.linalg.eigh(C)
    # U (k = 2) along the direction moves some constant as far as its limit
    weak = 2.0 * np.sqrt(np.maximum(lam, 0.0)) * np.abs(V).max(axis=0) >= 1.0
    if not weak.any():
        return flagged
    Vw, Vd = V[:, weak], V[:, ~weak]
    rest = x - Vw @ (Vw.T @ x)  # the part of the values the plan determines
    rest_std = np.sqrt(np.maximum(np.einsum("ij,j,ij->i", Vd, lam[~weak], Vd), 0.0))
    out = list(flagged)
    for j, i in enumerate(const):
        if np.abs(rest[j]) <= max(1.0, 2.0 * rest_std[j]) and not flagged[i].undetermined:
            partners = tuple(flagged[m].effect for n, m in enumerate(const) if n != j and abs(rho[j, n]) >= 0.5)
            out[i] = replace(flagged[i], partners=partners or tuple(flagged[m].effect for m in const if m != i))
    return out
