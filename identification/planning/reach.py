"""What a plan detects: every error the model lacks, of a stated size at the tool, found by the diagnosis.

A plan sized for its model's promise alone may be too small to see what the model lacks: an error that leaves
half a micrometre at the tool, as large as the target, can stay below the diagnosis's threshold, so ``identify
--auto`` adds nothing and ``plan --augment`` has nothing to plan for. A plan made for a model that may grow is
therefore also sized for detection. Each **probe** is a candidate of the diagnosis's library (every
position-driven effect it tests: scale, straightness, curvature and cubic of every error joint of every axis, its
periods and couplings). Its size is what it leaves at the tool once the model has absorbed what it can: twice the
RMS per coordinate over the volume (the candidates' poses) of the effect's displacement less its least-squares fit
by the model's parameters, the scale of the target and of a held-out 2·RMS (an error of that size the model lacks
adds it in quadrature to the held-out figure). At that size and its least detectable shape, the diagnosis's F test
(σ from the residuals, at its Bonferroni level over the library) must detect it with the power asked; alignments
are added, the weakest probe first, until each does. A probe that even every candidate leaves below the power is
named, not planned for.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Reach", "probes_of", "keep_reach", "probe_powers"]

#: A direction of an effect whose displacement at the tool the model absorbs but for this share of its square (the
#: effect's own largest, 10⁻⁶: 0.1 % of its amplitude) is no error the model lacks: not probed.
ABSORBED_TOL = 1e-6


@dataclass(frozen=True)
class Reach:
    """What a plan detects (:func:`keep_reach`).

    Attributes
    ----------
    size_um : float
        The size probed: 2·RMS per coordinate over the volume of what the model cannot absorb, µm.
    power : float
        The power asked.
    alpha : float
        The diagnosis's level per candidate (its α over the library).
    probes : int
        Effects probed (the library's position-driven candidates that leave anything at the tool).
    weakest : str
        The probe detected least surely by the plan.
    weakest_power : float
        Its power.
    unreachable : tuple of str
        Probes even every candidate detects with less than ``power``: not planned for.
    added : int
        Alignments added for detection beyond those the target needs.
    """

    size_um: float
    power: float
    alpha: float
    probes: int
    weakest: str
    weakest_power: float
    unreachable: tuple
    added: int


def probes_of(machine, effects, candidates, J, noise_um: float):
    """The probes of the model ``effects``: ((names, whitened Jacobians (N, 3, k) over ``candidates``, weights: (the
    (k, k) weight of what the model cannot absorb over them, µm² per coordinate per unit², the largest eigenvalue of
    the effect's own)), the library's size: the Bonferroni count). ``J``: the model's whitened Jacobian over ``candidates`` (N, 3, P)."""
    from ..fitting import design, residuals
    from ..model import basis_of, candidate_library

    library = candidate_library(machine, effects, has_directions=False, has_time=True)
    probes = [e for e in library if basis_of(e).driver in ("position", "positions", "none")]
    X = J.reshape(-1, J.shape[2]) * noise_um  # µm per unit
    d = design(machine, probes, candidates)
    _, J_probes, _ = residuals(machine, d, candidates, np.zeros(d.n_params))
    names, blocks, weights, start = [], [], [], 0
    Q, _ = np.linalg.qr(X)
    for e in probes:
        k = e.n_params
        Je = J_probes[:, :, start:start + k]
        start += k
        Z = Je.reshape(-1, k)
        R = Z - Q @ (Q.T @ Z)  # what the model cannot absorb over the volume
        W = R.T @ R / len(R)
        weights.append((W, float(np.linalg.eigvalsh(Z.T @ Z / len(Z)).max())))
        names.append(e.name)
        blocks.append(Je / noise_um)
    return (names, blocks, weights), len(library)


def _shapes(weight):
    """``T`` (k, r): the effect's coefficients of unit size at the tool along each direction the model does not
    absorb (``cᵀ W c = 1`` for ``c = T v``, ``|v| = 1``); r = 0 where the model absorbs it all. ``weight``: (W, the
    largest eigenvalue of the effect's own weight before the model absorbs it)."""
    W, own = weight
    d, U = np.linalg.eigh(W)
    keep = d > ABSORBED_TOL * max(own, 1e-300)
    return U[:, keep] / np.sqrt(d[keep])


def _lambda_min(J_model_rows, Je_rows, T, half_size):
    """(least non-centrality of the test over the effect's shapes of this size, that shape's coefficients)."""
    X = J_model_rows.reshape(-1, J_model_rows.shape[2])
    Z = Je_rows.reshape(-1, Je_rows.shape[2]) @ T
    R = Z - X @ np.linalg.lstsq(X, Z, rcond=None)[0]
    w, V = np.linalg.eigh(R.T @ R)
    return max(float(w[0]), 0.0) * half_size**2, T @ V[:, 0] * half_size


def _power(lam, k, dof, alpha):
    from scipy.special import fdtri, ncfdtr

    if dof < 1:
        return 0.0
    crit = fdtri(k, dof, 1.0 - alpha)
    power = float(1.0 - ncfdtr(k, dof, lam, crit))
    return power if np.isfinite(power) else float(lam > k * crit)  # ncfdtr fails far out in the tail


def probe_powers(J, index, probes, size_um: float, alpha: float) -> dict:
    """Each probe's power on the rows ``index`` of the model's whitened Jacobian ``J`` (N, 3, P)."""
    names, blocks, weights = probes
    out = {}
    for name, Je, W in zip(names, blocks, weights):
        T = _shapes(W)
        if T.shape[1] == 0:
            continue
        lam, _ = _lambda_min(J[index], Je[index], T, size_um / 2.0)
        out[name] = _power(lam, T.shape[1], 3 * len(index) - J.shape[2] - T.shape[1], alpha)
    return out


def keep_reach(J, index, probes, library: int, size_um: float, power: float, alpha_total: float, limit: int):
    """``index`` grown until every probe of size ``size_um`` is detected with ``power`` (module docstring): the
    weakest reachable probe first, the candidate that raises its least non-centrality most (the recursive
    least-squares update of the residual sum of squares of its least detectable shape). At most ``limit`` added.
    Returns (index, :class:`Reach`)."""
    names, blocks, weights = probes
    alpha = alpha_total / max(library, 1)
    shapes = {n: _shapes(W) for n, W in zip(names, weights)}
    live = [i for i, n in enumerate(names) if shapes[n].shape[1]]
    every = np.arange(len(J))
    reach = {i: _power(_lambda_min(J, blocks[i], shapes[names[i]], size_um / 2.0)[0], shapes[names[i]].shape[1],
                       3 * len(J) - J.shape[2] - shapes[names[i]].shape[1], alpha) for i in live}
    reachable = [i for i in live if reach[i] >= power]
    index = list(index)
    start = len(index)

    def powers():
        out = {}
        for i in live:
            T = shapes[names[i]]
            lam, c = _lambda_min(J[index], blocks[i][index], T, size_um / 2.0)
            out[i] = (_power(lam, T.shape[1], 3 * len(index) - J.shape[2] - T.shape[1], alpha), c)
        return out

    now = powers()
    for _ in range(limit):
        short = [i for i in reachable if now[i][0] < power]
        if not short:
            break
        weakest = min(short, key=lambda i: now[i][0])
        c = now[weakest][1]
        y = blocks[weakest] @ c  # (N, 3): the least detectable shape's residual per candidate
        X = J[index].reshape(-1, J.shape[2])
        Minv = np.linalg.pinv(X.T @ X)
        beta = Minv @ (X.T @ y[index].reshape(-1))
        e = y - J @ beta  # what the model fitted to the plan leaves of it at every candidate
        G = np.einsum("nip,pq,njq->nij", J, Minv, J) + np.eye(3)
        score = np.einsum("ni,ni->n", e, np.linalg.solve(G, e[:, :, None])[:, :, 0])
        score[index] = -np.inf
        index.append(int(every[np.argmax(score)]))
        now = powers()
    name_of = {i: names[i] for i in live}
    weakest = min(live, key=lambda i: now[i][0]) if live else None
    return np.array(index, int), Reach(
        float(size_um), float(power), float(alpha), len(live), name_of.get(weakest, ""),
        float(now[weakest][0]) if live else 1.0, tuple(names[i] for i in live if i not in reachable),
        len(index) - start)
