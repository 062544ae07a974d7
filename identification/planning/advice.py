"""Pose advice: for each parameter a plan (or a data set) leaves undetermined, the few poses that would determine it.

A parameter is held when the data see it only in a combination with others: a direction ``v`` of the
parameters that moves no residual. A pose determines it when its Jacobian moves along ``v``. From a pool
of poses over the machine's whole travel, the poses that move most along ``v`` are added one at a time
until the parameter is identifiable (:func:`~kinid.identification.fitting.identifiability.analyse`). When no pose
of the pool moves along ``v`` at all, nothing the machine can reach separates the parameters: they act
alike everywhere (a set-up offset of the tool and of the axis it sits on), and the advice says so.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model import Machine, axis_limits
from ..data import Observations

__all__ = ["Advice", "pose_advice", "advice_pool", "advice_lines", "data_advice", "MAX_ADVISED_POSES"]

#: Poses advised per held parameter, at most.
MAX_ADVISED_POSES = 6
#: Alignments of the data turned into Jacobian rows at a time (memory: a chunk's rows, not the data's), when no R
#: factor of the data's Jacobian is given.
ADVICE_CHUNK = 20_000
#: A pose moves along a held direction when its residual changes by more than this share of its typical change.
SEPARATES = 1e-6


@dataclass(frozen=True)
class Advice:
    """What would determine one held parameter.

    Attributes
    ----------
    name : str
    message : str
        The aliasing message of the analysis.
    kind : {"aliased", "invisible"}
    poses : Observations or None
        The advised alignments (None: no pose of the pool separates it).
    seconds : float
        Machine time of the advised alignments, added at the end of the run.
    """

    name: str
    message: str
    poses: Observations | None
    seconds: float
    kind: str = "aliased"

    def text(self, machine: Machine, *, message: bool = True) -> str:
        head = f"{self.message}; " if message else ""
        if self.poses is None and self.kind == "invisible":
            return f"{head}no pose within the machine's travel shows {self.name} (it does not move the measured point)"
        if self.poses is None:
            return (f"{head}no pose within the machine's travel separates {self.name} (the same motion as its partners "
                    f"at every pose): the fit holds it")
        where = "; ".join(_pose_text(machine, self.poses, i) for i in range(len(self.poses)))
        return (f"{head}to determine {self.name}, add {len(self.poses)} alignment"
                f"{'s' if len(self.poses) > 1 else ''} ({where}; about {self.seconds:.0f} s of machine time)")


def _pose_text(machine, obs, i) -> str:
    parts = [f"{a.name} {obs.axes[i, j]:.4g}{'' if a.kind == 'prismatic' else '°'}" for j, a in enumerate(machine.axes)]
    mark = obs.marks[i]
    return (f"mark {mark} " if mark and mark != "P" else "") + ", ".join(parts)


def advice_pool(machine: Machine, marks_mm, *, solve=None, steps: int = 9, samples: int = 2000, rng=None) -> Observations:
    """Poses over the machine's whole travel: each preset axis at ``steps`` values (a turntable every 30°), every
    mark; on a machine without three linear axes, ``samples`` joint configurations within the travel."""
    from .pool import axis_motion, candidate_poses, solved_axes

    solve = solved_axes(machine, solve)
    limits = axis_limits(machine)
    _, turns = axis_motion(machine)
    presets = {}
    for j, a in enumerate(machine.axes):
        if a.name in solve:
            continue
        lo, hi = limits[j]
        if turns[j]:
            presets[a.name] = np.arange(0.0, 360.0, 30.0)
        elif np.isfinite(hi - lo):
            presets[a.name] = np.linspace(lo, hi, steps)
        else:
            presets[a.name] = np.linspace(-500.0, 500.0, steps) if a.kind == "prismatic" else np.linspace(-180, 180, steps)
    return candidate_poses(machine, marks_mm, presets, solve=solve, samples=samples if not solve else 0, rng=rng)


def pose_advice(machine: Machine, effects, obs: Observations, pool: Observations, held, noise_um: float,
                travel=None, *, data_r=None) -> tuple:
    """One :class:`Advice` per held parameter of ``held`` (aliases of the analysis of ``obs``). ``data_r`` (P, P):
    R of the QR of ``obs``'s Jacobian over ``effects``' parameters (µm per parameter unit: a fit's), instead of a
    pass over ``obs``."""
    from ..fitting import analyse
    from .order import TravelModel, move_times_s
    from .pool import axis_motion
    from ..fitting import design, residuals

    travel = travel or TravelModel()
    if not held or pool is None or len(pool) == 0:
        return ()
    names = [n for e in effects for n in e.param_names()]  # Design.param_names, without a basis of every row

    def jac(o):
        d = design(machine, effects, o)
        return residuals(machine, d, o, np.zeros(d.n_params))[1] / noise_um

    Jp = jac(pool)
    scale = np.sqrt(np.einsum("nip,nip->p", Jp, Jp) / len(Jp))
    scale[scale == 0] = 1.0  # a column the pool's points do not see (a tilt the data's orientation rows see): unscaled
    Jp = Jp / scale
    # the data's rows compressed to R of their QR (P × P: the same identifiability), a chunk at a time
    R0 = np.zeros((0, len(names))) if data_r is None else np.linalg.qr(data_r / noise_um / scale, mode="r")
    for first in range(0, len(obs) if data_r is None else 0, ADVICE_CHUNK):
        rows = (jac(obs.subset(np.arange(first, min(first + ADVICE_CHUNK, len(obs))))) / scale).reshape(-1, len(names))
        R0 = np.linalg.qr(np.vstack([R0, rows]), mode="r")[: len(names)]
    linear, wraps = axis_motion(machine)
    out = []
    for alias in held:
        j = names.index(alias.name)
        R = R0
        added = []
        for _ in range(MAX_ADVISED_POSES):
            _, sv, Vt = np.linalg.svd(np.vstack([R, np.zeros((max(len(names) - len(R), 0), len(names)))]))
            rank = int(np.sum(sv > sv[0] * 1e-8)) if sv.size and sv[0] > 0 else 0
            N = Vt[rank:].T
            v = N @ (N.T @ np.eye(len(names))[j])
            if np.linalg.norm(v) < 1e-9:
                break
            v /= np.linalg.norm(v)
            score = np.linalg.norm(Jp @ v, axis=1) / (np.linalg.norm(Jp, axis=(1, 2)) + 1e-300)
            score[added] = -1.0
            c = int(np.argmax(score))
            if score[c] < SEPARATES:
                break
            added.append(c)
            R = np.linalg.qr(np.vstack([R, Jp[c]]), mode="r")[: len(names)]
            if analyse(R, names).identifiable[j]:
                break
        if added and analyse(R, names).identifiable[j]:
            poses = pool.subset(np.array(added))
            path = np.vstack([obs.axes[-1:], poses.axes])
            seconds = float(move_times_s(path[:-1], path[1:], linear, wraps, travel).sum() + len(added) * travel.align_s)
            out.append(Advice(alias.name, alias.message, poses, seconds, alias.kind))
        else:
            out.append(Advice(alias.name, alias.message, None, 0.0, alias.kind))
    return tuple(out)


def advice_lines(advice, machine: Machine, *, message: bool = True) -> list:
    """Text lines: each parameter that poses would determine, with the poses; then, in one line, those none would."""
    lines = [a.text(machine, message=message) for a in advice if a.poses is not None]
    fixed = [a.name for a in advice if a.poses is None]
    if fixed:
        lines.append(f"{', '.join(fixed)}: no pose within the machine's travel determines "
                     f"{'them' if len(fixed) > 1 else 'it'} (the same motion as the parameters named in the aliasing "
                     f"messages, or invisible to a measured point); the fit holds {'them' if len(fixed) > 1 else 'it'}")
    return lines


#: Marks of the data (the first in x, y, z order, to the nm) the advice's pool of poses is made at, at most.
ADVICE_MARKS = 50


def _first_marks(w_mm: np.ndarray, count: int) -> np.ndarray:
    """The first ``count`` distinct marks (rows of ``w_mm`` rounded to the nm) in x, y, z order: those of
    ``np.unique(axis=0)``, which sorts the rows as records (1.9 s a 10⁶ rows), from one integer key per row (the
    ranks of its x, y and z: their order is the rows')."""
    w = np.round(w_mm, 6)
    if not len(w):
        return w[:0]
    (ux, ix), (uy, iy), (uz, iz) = (np.unique(w[:, k], return_inverse=True) for k in range(3))
    key = np.unique((ix.astype(np.int64) * len(uy) + iy) * len(uz) + iz)[:count]
    return np.column_stack([ux[key // (len(uy) * len(uz))], uy[key // len(uz) % len(uy)], uz[key % len(uz)]])


def data_advice(machine: Machine, result, obs: Observations) -> list:
    """Advice lines for the parameters a fit held (``kinid identify``): poses over the machine's travel at the data's
    marks. Effects driven by time, direction or the row's mark (a target's point on the tool: the pool's poses
    measure no target) are left out (no pose determines them). The data's Jacobian at zero
    is the fit's first pass's (``result.jacobian_r_zero``) where it has one, else a pass over ``obs``."""
    from ..model import basis_of
    from .pool import solved_axes

    effects = [e for e in result.effects if basis_of(e).driver not in ("time", "direction", "mark")]
    names = {n for e in effects for n in e.param_names()}
    held = [a for a in result.aliases if a.name in names]
    if not held or len(obs) == 0:
        return []
    from dataclasses import replace

    plain = replace(obs, t_s=None, directions={}, offsets_mm=None, shifts_mm={})
    marks = _first_marks(obs.w_mm, ADVICE_MARKS) if solved_axes(machine, None) else obs.w_mm[:1]
    pool = advice_pool(machine, marks, rng=np.random.default_rng(0))
    noise = result.noise_um if getattr(result, "noise_um", None) else 1.0
    R = getattr(result, "jacobian_r_zero", None)
    data_r = None
    if R is not None and result.n_observations == len(obs) and obs.offsets_mm is None:
        # the fit's first pass (at zero, as the pool's), its columns of these effects
        data_r = R[:, [result.param_names.index(n) for e in effects for n in e.param_names()]]
    return advice_lines(pose_advice(machine, effects, plain, pool, held, noise, data_r=data_r), machine, message=False)
