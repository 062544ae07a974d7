"""Is structure left in the residuals, whatever its form? A test that needs no candidate and no σ.

The candidates of the diagnosis describe the effects kinid knows; a machine may have one it does not.
Noise is independent from alignment to alignment; an effect of the machine is not: alignments close
to each other in the readings (or in time) have similar residuals. The statistic is the mean squared
difference between each alignment's residual and that of its nearest neighbour, over twice the mean
squared residual: about 1 for noise, well below 1 for a smooth effect. Its null distribution comes
from permutations of the residual rows (no σ, no distribution assumed), for neighbours in the
readings (every axis scaled by its range) and, when the data have times, in time.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data import positions_of, row_groups

__all__ = ["Structure", "structure_left"]

#: Permutations of the null distribution (the smallest p-value is 1 / (PERMUTATIONS + 1)).
PERMUTATIONS = 499
#: At most this many alignments (drawn at random) enter the test: its cost grows with their square.
MAX_ROWS = 1500


@dataclass(frozen=True)
class Structure:
    """The nearest-neighbour test of the residuals.

    Attributes
    ----------
    ratio : float
        Smallest of the statistics (readings, time): ~1 for noise, < 1 for structure.
    p_value : float
        Permutation p-value of that statistic (with the two-look correction).
    along : str
        ``"readings"`` or ``"time"``: where the neighbours agree best.
    axis : str
        The axis (or ``"time"``) along which alone neighbouring residuals agree best: where to look.
    """

    ratio: float
    p_value: float
    along: str
    axis: str = ""

    def describe(self) -> str:
        where = "time" if self.axis == "time" else f"the readings of {self.axis}" if self.axis else "the readings"
        return (f"neighbouring alignments have similar residuals (nearest-neighbour ratio {self.ratio:.2f}, 1 for noise; "
                f"p = {self.p_value:.2g}), most clearly along {where}")


def _neighbours(coords: np.ndarray) -> np.ndarray:
    """Index of each row's nearest other row (Euclidean; of rows as near, the first), by chunks to bound memory."""
    if coords.shape[1] == 1:
        return _neighbours_on_a_line(coords[:, 0])
    out = _first_other_copy(row_groups(coords)[0])  # a pose measured again: its copy, at distance 0
    single = np.flatnonzero(out < 0)  # only the others are searched
    for start in range(0, single.size, 512):
        which = single[start:start + 512]
        d = np.sum((coords[which][:, None, :] - coords[None, :, :]) ** 2, axis=2)
        d[np.arange(which.size), which] = np.inf
        out[which] = np.argmin(d, axis=1)
    return out


def _neighbours_on_a_line(x: np.ndarray) -> np.ndarray:
    """:func:`_neighbours` of points on a line, from their order (n log n, not n²): a point repeated has its first
    other copy; any other the first point of the nearer neighbouring value, or of both if they are as near."""
    n = len(x)
    order = np.argsort(x, kind="stable")  # equal values in the order of their rows
    ordered = x[order]
    starts = np.flatnonzero(np.r_[True, ordered[1:] != ordered[:-1]])
    value, first = ordered[starts], order[starts]
    group = np.empty(n, int)
    group[order] = np.repeat(np.arange(starts.size), np.diff(np.r_[starts, n]))
    out = _first_other_copy(group)
    twin = out >= 0
    g, last = group[~twin], starts.size - 1
    left, right = np.maximum(g - 1, 0), np.minimum(g + 1, last)
    d_left = np.where(g > 0, (x[~twin] - value[left]) ** 2, np.inf)  # the squares the pairwise search compares
    d_right = np.where(g < last, (x[~twin] - value[right]) ** 2, np.inf)
    out[~twin] = np.where(d_left < d_right, first[left],
                          np.where(d_right < d_left, first[right], np.minimum(first[left], first[right])))
    return out


def _first_other_copy(group: np.ndarray) -> np.ndarray:
    """For rows in groups of equal rows (``group``, numbered from 0): the first other row of the group, −1 for a row
    alone in its group."""
    n = len(group)
    order = np.argsort(group, kind="stable")  # each group's rows in their order
    size = np.bincount(group)
    starts = np.r_[0, np.cumsum(size)[:-1]]
    first, second = order[starts], order[np.minimum(starts + 1, n - 1)]
    return np.where(size[group] < 2, -1, np.where(first[group] == np.arange(n), second[group], first[group]))


def _ratio(r: np.ndarray, nn: np.ndarray) -> np.ndarray:
    """The statistic for residual matrices ``r`` (..., N, 3) and neighbours ``nn``."""
    num = np.mean(np.sum((r - r[..., nn, :]) ** 2, axis=-1), axis=-1)
    den = 2.0 * np.mean(np.sum(r**2, axis=-1), axis=-1)
    return num / np.where(den > 0, den, 1.0)


def _null_ratios(r: np.ndarray, perms: np.ndarray, nn: np.ndarray) -> np.ndarray:
    """:func:`_ratio` of the residuals ``r`` (N, 3) with their rows permuted by each row of ``perms`` (P, N), from
    their Gram matrix: ‖r_a − r_b‖² = s_a + s_b − 2 r_a·r_b gathers P × N numbers, not P × N × 3 twice."""
    gram = r @ r.T
    s = np.einsum("nk,nk->n", r, r)
    other = perms[:, nn]
    total = float(np.sum(s))
    num = (total + np.sum(s[other], axis=1) - 2.0 * np.sum(gram[perms, other], axis=1)) / len(r)
    return num / (2.0 * total / len(r)) if total > 0 else num


def structure_left(residuals_um, axes, t_s=None, *, names=(), rng=None) -> Structure | None:
    """The nearest-neighbour test of ``residuals_um`` (N, 3) over readings ``axes`` (N, n_axes) and times.

    ``names`` are the axes' names (for :attr:`Structure.axis`). Returns None when there are too few
    alignments (< 12) to tell.
    """
    r = np.asarray(residuals_um, float)
    n = len(r)
    if n < 12:
        return None
    rng = np.random.default_rng(0) if rng is None else rng
    a = np.asarray(axes, float)
    t = None if t_s is None else np.asarray(t_s, float)
    if n > MAX_ROWS:
        keep = np.sort(rng.choice(n, MAX_ROWS, replace=False))
        r, a, t, n = r[keep], a[keep], None if t is None else t[keep], MAX_ROWS
    names = list(names) or [f"axis {k + 1}" for k in range(a.shape[1])]
    # readings within 0.1 % of an axis's range one position (as every test counts them: readings solved from a
    # measurement carry its noise, so replicas micrometres apart would be neighbours through their shared noise, not
    # through the machine); the axes read everywhere, at more than one position, each scaled by its range
    usable = np.all(np.isfinite(a), axis=0)
    a, names = a[:, usable], [nm for nm, u in zip(names, usable) if u]
    a = np.column_stack([positions_of(a[:, k]) for k in range(a.shape[1])]) if a.shape[1] else a
    moving = np.ptp(a, axis=0) > 0
    a, names = a[:, moving] / np.ptp(a[:, moving], axis=0), [nm for nm, m in zip(names, moving) if m]
    looks = [("readings", a)]
    if t is not None and np.ptp(t) > 0:
        looks.append(("time", t[:, None]))
    perms = np.stack([rng.permutation(n) for _ in range(PERMUTATIONS)])
    best = None
    for along, coords in looks:
        if coords.shape[1] == 0:
            continue
        nn = _neighbours(coords)
        ratio = float(_ratio(r, nn))
        null = _null_ratios(r, perms, nn)
        p = (1 + int(np.sum(null <= ratio))) / (PERMUTATIONS + 1)
        if best is None or p < best.p_value:
            best = Structure(ratio, p, along)
    if best is None:
        return None
    # where to look: the single coordinate whose neighbours agree best
    singles = [(float(_ratio(r, _neighbours(a[:, [k]]))), nm) for k, nm in enumerate(names)]
    if t is not None and np.ptp(t) > 0:
        singles.append((float(_ratio(r, _neighbours(t[:, None]))), "time"))
    axis = min(singles)[1] if singles else ""
    return Structure(best.ratio, min(1.0, best.p_value * len(looks)), best.along, axis)
