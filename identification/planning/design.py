"""Which alignments to measure: optimal design over a pool of candidate alignments.

Each candidate alignment ``c`` contributes ``J_c`` (3 × P: the residual's change per parameter unit,
divided by the reading noise σ) to the information ``M(S) = Σ_{c∈S} J_cᵀ J_c`` of a plan ``S``. A
target is a weight matrix ``W`` (P × P) and the criterion is ``φ(S) = trace(M(S)⁻¹ W)``:

- ``W = mean_v J_vᵀ J_v`` over the poses ``v`` of a work volume: ``φ`` is the mean squared prediction
  error of the tool point over the volume (σ² units), summed over x, y, z — I-optimality;
- ``W = e_j e_jᵀ / t_j²`` summed over named parameters with targets ``t_j``: the variances of those
  parameters relative to their targets — A-optimality.

:func:`select` adds candidates greedily (rank-3 Woodbury updates, every candidate scored at once),
then exchanges them (Fedorov) while that lowers ``φ``. :func:`relaxation_bound` gives a certified lower
bound: no plan of ``n`` alignments, even one repeating poses, has ``φ`` below ``bound / n`` (the convex
relaxation of the weights, solved by the multiplicative algorithm; its bound from the equivalence
theorem, ``2 f(w) − max_c d_c(w)``, holds at every iterate). FIGAROH selects robot poses by
D-optimality over the same kind of relaxation; this targets what the user asked (the volume or the
parameters) instead of the determinant.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Selection", "select", "trim", "criterion", "relaxation_bound", "added_bound", "EXCHANGE_PASSES", "RELAXATION_ITERATIONS"]

#: Exchanges tried after the greedy pass, at most, per selected alignment.
EXCHANGE_PASSES = 1
#: Iterations of the multiplicative algorithm for the relaxation's bound, at most.
RELAXATION_ITERATIONS = 400
#: The relaxation stops when its bound is within this share of its value.
RELAXATION_GAP = 0.01
#: Ridge of the greedy start, relative to the pool's mean information (it steers the first picks to
#: the unseen directions and is dropped from every reported figure).
START_RIDGE = 1e-9


@dataclass(frozen=True)
class Selection:
    """Chosen candidates, in the order they were chosen, and the criterion after each count.

    Attributes
    ----------
    index : array (n,) of int
        Candidate indices.
    phi : array (n,)
        ``φ`` of the first ``k + 1`` chosen (inf while ``M`` is singular); after exchanges, the last
        entry is the exchanged plan's.
    exchanges : int
        Swaps that lowered ``φ``.
    """

    index: np.ndarray
    phi: np.ndarray
    exchanges: int = 0


def _scaled(J: np.ndarray, W: np.ndarray):
    """Columns scaled to unit mean information over the pool (``φ`` is invariant)."""
    d = np.sqrt(np.einsum("nip,nip->p", J, J) / len(J))
    d = np.where(d > 0, d, 1.0)
    return J / d, W / np.outer(d, d)


def _information(Js, index=None, weights=None):
    """Σ J_cᵀ J_c over ``index`` (or weighted over all candidates), by one matrix product."""
    X = (Js if index is None else Js[np.asarray(index, int)]).reshape(-1, Js.shape[2])
    if weights is not None:
        return (X * np.repeat(weights, 3)[:, None]).T @ X
    return X.T @ X


def criterion(J: np.ndarray, W: np.ndarray, index) -> float:
    """``φ`` of the candidates ``index`` (inf if they do not determine every parameter)."""
    Js, Ws = _scaled(J, W)
    M = _information(Js, index)
    try:
        L = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        return float("inf")
    if np.min(np.abs(np.diag(L))) < 1e-7 * np.sqrt(np.max(np.diag(M))):
        return float("inf")
    X = np.linalg.solve(L, np.linalg.solve(L, Ws).T)  # L⁻¹ (L⁻¹ W)ᵀ: trace is trace(M⁻¹W)
    return float(np.trace(X))


def _gains(Js, Minv, W):
    """For every candidate, the fall of trace(M⁻¹W) if it were added (Woodbury, rank 3)."""
    A = Js @ Minv  # (N, 3, P)
    At = A.transpose(0, 2, 1)
    G = Js @ At + np.eye(3)
    H = (A @ W) @ At
    return np.trace(np.linalg.solve(G, H), axis1=1, axis2=2), A, G


def _losses(Js, Minv, W, index):
    """For every chosen candidate, the rise of trace(M⁻¹W) if it were removed."""
    Jc = Js[index]
    A = Jc @ Minv
    At = A.transpose(0, 2, 1)
    G = np.eye(3) - Jc @ At
    H = (A @ W) @ At
    # a candidate whose removal leaves the rest unable to determine every parameter (G singular) costs infinitely
    # much; solving with it would spread NaN into the next step
    fine = np.all(np.isfinite(G), axis=(1, 2))
    fine[fine] = np.linalg.eigvalsh(0.5 * (G[fine] + G[fine].transpose(0, 2, 1)))[:, 0] > 1e-9
    out = np.full(len(index), np.inf)
    if fine.any():
        with np.errstate(divide="ignore", invalid="ignore"):
            out[fine] = np.trace(np.linalg.solve(G[fine], H[fine]), axis1=1, axis2=2)
    return np.where(np.isfinite(out) & (out >= 0), out, np.inf)


def _add(Minv, Jc):
    A = Jc @ Minv
    return Minv - A.T @ np.linalg.solve(np.eye(3) + A @ Jc.T, A)


def _positive_definite(M) -> bool:
    try:
        np.linalg.cholesky((M + M.T) / 2.0)
    except np.linalg.LinAlgError:
        return False
    return bool(np.all(np.isfinite(M)))


def _remove(Minv, Jc):
    A = Jc @ Minv
    return Minv + A.T @ np.linalg.solve(np.eye(3) - A @ Jc.T, A)


def select(J: np.ndarray, W: np.ndarray, *, count: int | None = None, enough=None,
           max_count: int = 2000, start=(), exchange: bool = True, distinct: bool = True) -> Selection:
    """Choose candidates minimising ``φ = trace(M⁻¹W)``.

    Parameters
    ----------
    J : array (N, 3, P)
        Whitened Jacobian of each candidate alignment.
    W : array (P, P)
        The target's weight matrix (module docstring).
    count : int, optional
        Choose exactly this many.
    enough : callable(index array) -> bool, optional
        Without ``count``: stop at the first plan it accepts (or at ``max_count``).
    max_count : int
    start : sequence of int
        Candidates already in the plan (kept, counted).
    exchange : bool
        Swap chosen candidates for better ones afterwards (the count stays).
    distinct : bool
        Each candidate at most once.

    Returns
    -------
    Selection
    """
    N, _, P = J.shape
    Js, Ws = _scaled(J, W)
    Minv = np.eye(P) / START_RIDGE
    chosen = []
    for c in start:
        chosen.append(int(c))
        Minv = _add(Minv, Js[c])
    if chosen and not _positive_definite(Minv):
        # a pose repeated many times (a plan's drift checks) loses the rank-3 updates' precision at the ridge's 10⁹
        # scale: the start's information taken at once, by its eigenvalues
        w, V = np.linalg.eigh(_information(Js, chosen))
        Minv = (V / (np.maximum(w, 0.0) + START_RIDGE)) @ V.T
    limit = min(count if count is not None else max_count, N if distinct else max_count)
    phis = []
    used = np.zeros(N, bool)
    used[chosen] = True
    while len(chosen) < limit:
        gain, _, _ = _gains(Js, Minv, Ws)
        if distinct:
            gain[used] = -np.inf
        c = int(np.argmax(gain))
        chosen.append(c)
        used[c] = True
        Minv = _add(Minv, Js[c])
        phis.append(criterion(J, W, chosen) if len(phis) == 0 or not np.isfinite(phis[-1]) else phis[-1] - gain[c])
        if count is None and enough is not None and np.isfinite(phis[-1]) and enough(np.array(chosen, int)):
            break
    index = np.array(chosen, int)
    swaps = 0
    if exchange and np.isfinite(criterion(J, W, index)):
        index, swaps = _exchange(J, Js, Ws, index, keep=len(tuple(start)), distinct=distinct)
        phis[-1] = criterion(J, W, index)
    pad = [float("inf")] * (len(index) - len(phis))
    return Selection(index, np.array(pad + phis, float), swaps)


def trim(J: np.ndarray, W: np.ndarray, index, enough, *, keep: int = 0, distinct: bool = True) -> np.ndarray:
    """Drop the chosen candidate that costs least and exchange again, while ``enough`` still accepts the plan."""
    Js, Ws = _scaled(J, W)
    index = np.asarray(index, int)
    while len(index) > keep + 1:
        loss = _losses(Js, np.linalg.inv(_information(Js, index)), Ws, list(index))
        loss[:keep] = np.inf
        k = int(np.argmin(loss))
        if not np.isfinite(loss[k]):
            break
        fewer = np.delete(index, k)
        if not np.isfinite(criterion(J, W, fewer)):
            break
        fewer, _ = _exchange(J, Js, Ws, fewer, keep=keep, distinct=distinct)
        if not enough(fewer):
            break
        index = fewer
    return index


def _exchange(J, Js, Ws, index, *, keep: int, distinct: bool):
    """Fedorov exchange: drop the chosen candidate that costs least, add the best, while φ falls."""
    index = list(index)
    Minv = np.linalg.inv(_information(Js, index))
    phi = float(np.trace(Minv @ Ws))
    swaps = 0
    for _ in range(EXCHANGE_PASSES * len(index)):
        loss = _losses(Js, Minv, Ws, index)
        loss[:keep] = np.inf
        k = int(np.argmin(loss))
        if not np.isfinite(loss[k]):
            break
        out = index[k]
        Mi = _remove(Minv, Js[out])
        gain, _, _ = _gains(Js, Mi, Ws)
        if distinct:
            gain[index] = -np.inf
        c = int(np.argmax(gain))
        new_phi = phi + loss[k] - gain[c]
        if c == out or new_phi >= phi * (1 - 1e-9):
            break
        index[k] = c
        Minv = _add(Mi, Js[c])
        phi = new_phi
        swaps += 1
    return np.array(index, int), swaps


def relaxation_bound(J: np.ndarray, W: np.ndarray, *, iterations: int = RELAXATION_ITERATIONS,
                     gap: float = RELAXATION_GAP) -> tuple[float, np.ndarray]:
    """A certified lower bound ``b``: every plan of ``n`` alignments from the pool has ``φ ≥ b / n``.

    Returns
    -------
    bound : float
    weights : array (N,)
        The relaxation's design (sums to 1): where an optimal plan puts its alignments.
    """
    N = len(J)
    Js, Ws = _scaled(J, W)
    w = np.full(N, 1.0 / N)
    best = 0.0
    for _ in range(iterations):
        M = _information(Js, weights=w)
        try:
            L = np.linalg.cholesky(M)
        except np.linalg.LinAlgError:
            return 0.0, w
        B = np.linalg.solve(L.T, np.linalg.solve(L, np.linalg.cholesky(Ws + 1e-15 * np.trace(Ws) * np.eye(len(Ws)))))
        d = (Js.reshape(-1, Js.shape[2]) @ B) ** 2
        d = d.reshape(N, -1).sum(axis=1)  # d_c = trace(J_c M⁻¹ W M⁻¹ J_cᵀ)
        f = float(w @ d)  # = trace(M⁻¹ W)
        best = max(best, 2.0 * f - float(d.max()))
        if f - best <= gap * f:
            break
        w = w * np.sqrt(d / f)
        w /= w.sum()
    return best, w


def added_bound(J: np.ndarray, W: np.ndarray, fixed, n: int, *, iterations: int = RELAXATION_ITERATIONS,
                stop_above: float = np.inf) -> float:
    """A certified lower bound on ``φ`` of the rows ``fixed`` plus any ``n`` candidates of the others (repeats
    allowed): the sequential design's bound, the measured rows' information a fixed part.

    The relaxation ``f(w) = trace((M₀ + n Σ w_c J_cᵀJ_c)⁻¹ W)`` over the simplex is convex; at any ``w`` its
    minimum is at least ``f(w) − n (max_c d_c − Σ w_c d_c)``, ``d_c = trace(J_c A⁻¹ W A⁻¹ J_cᵀ)`` (the first-order
    condition). Iterates by the multiplicative algorithm; stops once the bound passes ``stop_above``.
    """
    Js, Ws = _scaled(J, W)
    fixed = np.asarray(fixed, int)
    M0 = _information(Js, fixed) if fixed.size else np.zeros((J.shape[2], J.shape[2]))
    free = np.setdiff1d(np.arange(len(J)), fixed)
    Jf = Js[free]
    if n <= 0:
        return criterion(J, W, fixed) if fixed.size else float("inf")
    w = np.full(len(free), 1.0 / len(free))
    Wroot = np.linalg.cholesky(Ws + 1e-15 * np.trace(Ws) * np.eye(len(Ws)))
    best = 0.0
    for _ in range(iterations):
        A = M0 + n * _information(Jf, weights=w)
        try:
            L = np.linalg.cholesky(A)
        except np.linalg.LinAlgError:
            return 0.0
        B = np.linalg.solve(L.T, np.linalg.solve(L, Wroot))
        f = float(np.sum(np.linalg.solve(L, Wroot) ** 2))  # trace(A⁻¹ W)
        d = ((Jf.reshape(-1, Jf.shape[2]) @ B) ** 2).reshape(len(free), -1).sum(axis=1)
        wd = float(w @ d)
        best = max(best, f - n * (float(d.max()) - wd))
        if best > stop_above or f - best <= RELAXATION_GAP * f:
            break
        w = w * np.sqrt(d / wd)
        w /= w.sum()
    return best
