"""The order of a plan's alignments: little machine time, and time that follows no axis.

Machine time is moves, settling and the alignments themselves. A move takes, on each axis, a trapezoidal
profile (accelerate, cruise, brake); the axes move together, so a move lasts as long as its slowest axis,
plus the settling time. A rotary axis without limits (a turntable) takes the shorter way round.

The shortest tour (nearest neighbour, then 2-opt) runs one axis as its outer loop, and then time follows
that axis: a drift or a warm-up during the run looks like an error of the axis, and no fit can tell them
apart afterwards. So the tour is dealt into blocks — every k-th alignment of the tour to block k, so each
block spans every axis's whole range — the blocks are run one after another, every other one backwards,
and a reference alignment is repeated at the start of every block and at the end. The fewest blocks
whose correlation of time with every axis is within :data:`MAX_TIME_CORRELATION` is taken.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TravelModel", "Order", "order_for_time", "with_checks", "move_times_s", "MAX_TIME_CORRELATION",
           "BLOCK_COUNTS"]

#: Largest |correlation| of time with an axis reading a plan's order may leave.
MAX_TIME_CORRELATION = 0.2
#: Block counts tried, fewest first.
BLOCK_COUNTS = (2, 3, 4, 5, 6, 8, 10, 12)
#: 2-opt passes over a tour, at most.
TWO_OPT_PASSES = 20


@dataclass(frozen=True)
class TravelModel:
    """How fast the machine moves between alignments and how long one takes (defaults: a machine tool's
    positioning moves with a vision alignment of about 10 s)."""

    speed_mm_s: float = 100.0
    accel_mm_s2: float = 500.0
    speed_deg_s: float = 20.0
    accel_deg_s2: float = 60.0
    settle_s: float = 1.0
    align_s: float = 10.0

    def describe(self) -> str:
        return (f"linear {self.speed_mm_s:g} mm/s, {self.accel_mm_s2:g} mm/s²; rotary {self.speed_deg_s:g} °/s, "
                f"{self.accel_deg_s2:g} °/s²; settling {self.settle_s:g} s; {self.align_s:g} s per alignment")


@dataclass(frozen=True)
class Order:
    """A visiting order.

    Attributes
    ----------
    index : array (n,) of int
        Rows of the plan in visiting order (the reference row appears once per repeat).
    t_s : array (n,)
        When each alignment is made, s from the start of the run.
    total_s, move_s : float
        Machine time of the run, and the part spent moving and settling.
    blocks : int
    reference : int
        Row repeated as the reference alignment (-1: none).
    correlation : dict axis -> float
        Correlation of time with the axis's readings over the run.
    """

    index: np.ndarray
    t_s: np.ndarray
    total_s: float
    move_s: float
    blocks: int
    reference: int
    correlation: dict

    @property
    def worst_correlation(self) -> float:
        return max((abs(v) for v in self.correlation.values()), default=0.0)


def _profile_s(d, speed, accel):
    """Time of a trapezoidal move of length ``d`` (triangular when it never reaches ``speed``)."""
    d = np.abs(d)
    cruise = d > speed**2 / accel
    return np.where(cruise, d / speed + speed / accel, 2.0 * np.sqrt(d / accel))


def move_times_s(a: np.ndarray, b: np.ndarray, linear: np.ndarray, wraps: np.ndarray, travel: TravelModel) -> np.ndarray:
    """Time of the moves from readings ``a`` (..., n_axes) to ``b``, settling included where anything moves."""
    d = np.abs(b - a)
    d = np.where(wraps, np.minimum(d, 360.0 - np.mod(d, 360.0)), d)
    t = np.where(linear, _profile_s(d, travel.speed_mm_s, travel.accel_mm_s2),
                 _profile_s(d, travel.speed_deg_s, travel.accel_deg_s2))
    t = t.max(axis=-1)
    return np.where(t > 0, t + travel.settle_s, 0.0)


def _tour(X, linear, wraps, travel, start: int) -> list:
    """Nearest neighbour from ``start``, then 2-opt on the move times (an open path)."""
    n = len(X)
    D = move_times_s(X[:, None, :], X[None, :, :], linear, wraps, travel)
    path = [start]
    left = np.ones(n, bool)
    left[start] = False
    for _ in range(n - 1):
        d = np.where(left, D[path[-1]], np.inf)
        k = int(np.argmin(d))
        path.append(k)
        left[k] = False
    path = np.array(path)
    for _ in range(TWO_OPT_PASSES):
        improved = False
        for i in range(1, n - 1):
            a, b = path[i - 1], path[i]
            c, d_next = path[i:-1], path[i + 1:]
            # reverse path[i..j]: edges (a,b),(c_j,d_j) -> (a,c_j),(b,d_j)
            delta = D[a, c] + D[b, d_next] - D[a, b] - D[c, d_next]
            j = int(np.argmin(delta))
            if delta[j] < -1e-9:
                path[i:i + j + 1] = path[i:i + j + 1][::-1]
                improved = True
        if not improved:
            break
    return list(path)


def _time_line(X, order, linear, wraps, travel):
    moves = move_times_s(X[order[:-1]], X[order[1:]], linear, wraps, travel) if len(order) > 1 else np.zeros(0)
    t = np.r_[0.0, np.cumsum(moves + travel.align_s)]
    return t, float(moves.sum()), float(t[-1] + travel.align_s)


def _correlations(X, t, names) -> dict:
    out = {}
    for j, name in enumerate(names):
        x = X[:, j]
        out[name] = 0.0 if np.ptp(x) == 0 or np.ptp(t) == 0 else float(np.corrcoef(t, x)[0, 1])
    return out


def with_checks(order: Order, X, checks: int, linear, wraps, travel: TravelModel, names) -> Order:
    """``order`` with its reference alignment (the block starts' one, else its first) made ``checks`` readings in
    all, in place of the block starts' repeats: the run's first alignment and (``checks`` ≥ 2) its last, each other
    repeat added where the time between two readings of the reference is longest, at the alignment nearest the
    middle of that gap (the drift checks of :mod:`~kinid.identification.planning.drift`)."""
    ref = order.reference if order.reference >= 0 else int(order.index[0])
    seq = [ref] + [int(i) for i in order.index if i != ref] + ([ref] if checks >= 2 else [])
    t = _time_line(X, np.array(seq), linear, wraps, travel)[0]
    while sum(i == ref for i in seq) < checks:
        at = np.array([k for k, i in enumerate(seq) if i == ref])
        gaps = np.where(np.diff(at) >= 3, np.diff(t[at]), -1.0)  # a repeat between two others' alignments only
        g = int(np.argmax(gaps))
        if gaps[g] < 0:
            break
        inside = np.arange(at[g] + 2, at[g + 1])  # insert before one of these
        k = int(inside[np.argmin(np.abs(t[inside] - (t[at[g]] + t[at[g + 1]]) / 2.0))])
        seq.insert(k, ref)
        t = _time_line(X, np.array(seq), linear, wraps, travel)[0]
    seq = np.array(seq, int)
    t, move, total = _time_line(X, seq, linear, wraps, travel)
    return Order(seq, t, total, move, order.blocks, ref, _correlations(X[seq], t, names))


def order_for_time(readings: np.ndarray, names, linear, wraps, travel: TravelModel = TravelModel(), *,
                   blocks: int | None = None, reference: bool = True,
                   max_correlation: float = MAX_TIME_CORRELATION) -> Order:
    """The quickest order, in blocks, whose time follows no axis (module docstring).

    Parameters
    ----------
    readings : array (n, n_axes)
        Every axis's reading at each alignment (mm / deg).
    names : sequence of str
        Axis names, for :attr:`Order.correlation`.
    linear, wraps : array (n_axes,) of bool
        Linear axes; rotary axes that take the shorter way round.
    travel : TravelModel
    blocks : int, optional
        Use this many blocks (default: the fewest of :data:`BLOCK_COUNTS` within ``max_correlation``;
        1 is the plain shortest tour, with no reference repeats).
    reference : bool
        Repeat a reference alignment at every block's start and at the end.
    """
    X = np.asarray(readings, float)
    linear, wraps = np.asarray(linear, bool), np.asarray(wraps, bool)
    n = len(X)
    centre = np.median(X, axis=0)
    ref = int(np.argmin(np.sum(((X - centre) / (np.ptp(X, axis=0) + 1e-12)) ** 2, axis=1)))
    home = int(np.argmin(np.abs(X - X.min(axis=0)).sum(axis=1)))
    tour = _tour(X, linear, wraps, travel, home)
    best = None
    for k in ([blocks] if blocks else BLOCK_COUNTS):
        k = max(1, min(int(k), n))
        parts = [tour[i::k] for i in range(k)]
        order = []
        for i, part in enumerate(parts):
            part = [p for p in part if p != ref] if reference and k > 1 else part
            seq = _tour(X[part], linear, wraps, travel, 0) if len(part) > 2 else list(range(len(part)))
            seq = [part[s] for s in seq]
            if i % 2:
                seq = seq[::-1]
            order += ([ref] if reference and k > 1 else []) + seq
        if reference and k > 1:
            order.append(ref)
        order = np.array(order, int)
        t, move, total = _time_line(X, order, linear, wraps, travel)
        result = Order(order, t, total, move, k, ref if reference and k > 1 else -1, _correlations(X[order], t, names))
        if blocks or result.worst_correlation <= max_correlation:
            return result
        if best is None or result.worst_correlation < best.worst_correlation:
            best = result
    return best
