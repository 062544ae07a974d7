"""The positions an axis's readings visit: readings a few micrometres apart are one position.

An alignment reads the linear axes where it stopped them, so a pose measured again is read micrometres apart:
those readings are no finer sampling of the axis. The period search (the shortest period it resolves), the
ambiguity of periods, the local windows (the positions under each coefficient) and the structure test (which
alignments are neighbours) all count positions so.
"""
from __future__ import annotations

import numpy as np

__all__ = ["distinct_positions", "positions_of", "position_starts", "positions_per_axis", "POSITION_TOLERANCE"]

#: Readings closer than this share of the span are one position (the jitter of solved readings is no sampling).
POSITION_TOLERANCE = 1e-3


def distinct_positions(q) -> np.ndarray:
    """The positions an axis's readings ``q`` visit, ascending: readings within :data:`POSITION_TOLERANCE` of their
    span (at least 0.001) of the lowest reading not yet placed count as one position, placed at the middle of
    their range (a reading repeated exactly is its own position, to the last digit). Readings a few µm apart are
    one position wherever they fall, not two when they straddle the boundary of a fixed grid."""
    return np.unique(positions_of(q))


def positions_per_axis(machine, obs) -> dict:
    """Axis name → how many distinct positions (:func:`distinct_positions`) its readings in ``obs`` visit."""
    return {a.name: distinct_positions(obs.axes[:, k]).size for k, a in enumerate(machine.axes)}


def positions_of(q) -> np.ndarray:
    """Each reading of ``q`` replaced by its position (:func:`distinct_positions`), in the readings' order."""
    q = np.asarray(q, float)
    if q.size == 0:
        return q.copy()
    order = np.argsort(q, kind="stable")
    ordered = q[order]
    first = position_starts(ordered, max(POSITION_TOLERANCE * float(ordered[-1] - ordered[0]), 1e-3))
    size = np.diff(np.r_[first, q.size])
    middle = 0.5 * (ordered[first] + ordered[first + size - 1])
    out = np.empty(q.size)
    out[order] = np.repeat(middle, size)
    return out


def position_starts(q_sorted: np.ndarray, within: float) -> np.ndarray:
    """Where each position begins in ascending readings: a position is the lowest reading not yet placed and every
    reading within ``within`` of it."""
    beyond = np.searchsorted(q_sorted, q_sorted + within, side="right").tolist()  # the first reading out of reach
    first = [0] if q_sorted.size else []
    while first and beyond[first[-1]] < q_sorted.size:
        first.append(beyond[first[-1]])
    return np.array(first, dtype=int)
