"""Is structure left in the residuals, whatever its form? A test that needs no candidate and no σ.

The candidates of the diagnosis describe the effects kinid knows; a machine may have one it does not.
Noise is independent from alignment to alignment; an effect of the machine is not: alignments close
to each other in the readings (or in time) have similar residuals. The statistic is the mean squared
difference between each alignment's residual and that of its nearest neighbour, over twice the mean
squared residual: about 1 for noise, well below 1 for a smooth effect. Its null distribution comes
from permutations of the residual rows (no σ, no distribution assumed).

Neighbours are looked for in several spaces ("looks"): the readings of every axis at once (each scaled by its
range), each variable alone (an axis, or time when the data have it) and each pair of variables. An effect of
two variables (a roll of Z that changes with both B and C, an error that grows with X and with time) is plain in
its pair's plane and blurred in the readings of every axis at once, where neighbours differ in axes it does not
depend on. The looks are judged together: each look's statistic is standardised by its own permutation mean and
spread, the test statistic is the smallest of them, and its null is the smallest over the looks of each
permutation (the same permutation in every look) — the p-value of the best look with its many looks counted,
with no loss to a Bonferroni factor.
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
#: A pair of variables needs both when its neighbours' statistic is under this share of the better one's alone
#: (a function of B and C: 0.01 against 0.10 along time; a function of time alone in axis-major order: 0.25 along
#: C and time against 0.26 along time).
PAIR_GAIN = 0.5


@dataclass(frozen=True)
class Structure:
    """The nearest-neighbour test of the residuals.

    Attributes
    ----------
    ratio : float
        The statistic of the look where the neighbours agree best, over its mean under the permutations: ~1 for
        noise, < 1 for structure.
    p_value : float
        Permutation p-value of the smallest standardised statistic over every look (the looks counted).
    along : str
        ``"readings"`` (every axis at once), ``"time"``, one axis's name, or two variables' names joined by
        ``" and "``: the look where the neighbours agree best.
    axis : str
        Where to look: the variable (an axis, or ``"time"``) of that look; of a pair the one whose neighbours alone
        agree better, but the axis before time when neither alone comes near the pair (:data:`PAIR_GAIN`: time's
        neighbours also agree where time follows the axes visited); of every axis at once the single variable whose
        neighbours agree best.
    axes : tuple
        The variables of that look (one or two; every single variable's best for ``"readings"``).
    """

    ratio: float
    p_value: float
    along: str
    axis: str = ""
    axes: tuple = ()

    def describe(self) -> str:
        names = [a for a in (self.axes or (self.axis,)) if a]
        readings = [a for a in names if a != "time"]
        where = " and ".join(([f"the readings of {' and '.join(readings)}"] if readings else [])
                             + (["time"] if "time" in names else [])) or "the readings"
        together = " together" if len(names) > 1 else ""
        return (f"neighbouring alignments have similar residuals (nearest-neighbour ratio {self.ratio:.2f}, 1 for noise; "
                f"p = {self.p_value:.2g}), most clearly along {where}{together}")


def _neighbours(coords: np.ndarray) -> np.ndarray:
    """Index of each row's nearest other row (Euclidean; of rows as near, the first), by chunks to bound memory."""
    if coords.shape[1] == 1:
        return _neighbours_on_a_line(coords[:, 0])
    out = _first_other_copy(row_groups(coords)[0])  # a pose measured again: its copy, at distance 0
    single = np.flatnonzero(out < 0)  # only the others are searched
    for start in range(0, single.size, 512):
        which = single[start:start + 512]
        d = (coords[which, 0][:, None] - coords[None, :, 0]) ** 2
        for k in range(1, coords.shape[1]):  # column by column: the sum of squares in the same order, without the
            d += (coords[which, k][:, None] - coords[None, :, k]) ** 2  # (chunk, N, k) temporary
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


def _null_ratios(r: np.ndarray, perms: np.ndarray, nn: np.ndarray, permuted=None) -> np.ndarray:
    """:func:`_ratio` of the residuals ``r`` (N, 3) with their rows permuted by each row of ``perms`` (P, N), from
    ‖r_a − r_b‖² = s_a + s_b − 2 r_a·r_b with each coordinate's products taken from its own column (P × N numbers
    gathered from N, not from an N × N Gram matrix); ``permuted`` is :func:`_permuted` of ``r`` when the caller has
    it (one gather for every look)."""
    s, columns, rp = _permuted(r, perms) if permuted is None else permuted
    other = np.take(perms, nn, axis=1)  # each permuted row's neighbour, as a row of r
    total = float(np.sum(s))
    dots = sum(np.einsum("pn,pn->p", rp[k], np.take(columns[k], other)) for k in range(len(columns)))
    num = (total + np.sum(np.take(s, other), axis=1) - 2.0 * dots) / len(r)
    return num / (2.0 * total / len(r)) if total > 0 else num


def _permuted(r: np.ndarray, perms: np.ndarray) -> tuple:
    """(each row's squared norm (N,), each coordinate's column, each coordinate permuted by ``perms`` (k, P, N))."""
    columns = [np.ascontiguousarray(r[:, k]) for k in range(r.shape[1])]
    return np.einsum("nk,nk->n", r, r), columns, np.stack([np.take(c, perms) for c in columns])


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
    variables = dict(zip(names, a.T))
    if t is not None and np.ptp(t) > 0:
        variables["time"] = (t - np.min(t)) / np.ptp(t)
    if not variables:
        return None
    looks = _looks(a, variables)
    perms = np.stack([rng.permutation(n) for _ in range(PERMUTATIONS)])
    permuted = _permuted(r, perms)
    observed, null, relative = [], [], []
    for _, coords in looks:
        nn = _neighbours(coords)
        ratio = float(_ratio(r, nn))
        ratios = _null_ratios(r, perms, nn, permuted)
        mean, spread = float(np.mean(ratios)), float(np.std(ratios))
        spread = spread if spread > 0 else 1.0
        observed.append((ratio - mean) / spread)
        null.append((ratios - mean) / spread)
        relative.append(ratio / mean if mean > 0 else 1.0)  # against noise in this look (its null's mean), ~1
    observed, null = np.asarray(observed), np.min(np.asarray(null), axis=0)
    best = int(np.argmin(observed))
    p = (1 + int(np.sum(null <= observed[best]))) / (PERMUTATIONS + 1)
    along, ratio = looks[best][0], relative[best]
    single = {nm: float(_ratio(r, _neighbours(v[:, None]))) for nm, v in variables.items()}
    if along == "readings":  # where to look: the single variable whose neighbours agree best
        chosen = (min(single, key=single.get),)
    else:  # the look's variables, the one whose neighbours alone agree better first — unless neither accounts
        # for the structure alone (the pair's statistic under PAIR_GAIN × the better one's): then an axis before time
        # (time's neighbours agree also where time follows the axes visited, through the order)
        pair = along.split(" and ")
        both = float(_ratio(r, _neighbours(looks[best][1]))) < PAIR_GAIN * min(single[nm] for nm in pair)
        chosen = tuple(sorted(pair, key=lambda nm: (both and nm == "time", single[nm])))
    return Structure(ratio, min(1.0, p), along, chosen[0], chosen)


def _looks(a: np.ndarray, variables: dict) -> list:
    """(name, coordinates (N, k)) of every look of the test: every axis at once, each variable alone, each pair."""
    names = list(variables)
    looks = [("readings", a)] if a.shape[1] > 1 else []
    looks += [(u, variables[u][:, None]) for u in names]
    looks += [(f"{u} and {v}", np.column_stack([variables[u], variables[v]]))
              for i, u in enumerate(names) for v in names[i + 1:]]
    return looks
