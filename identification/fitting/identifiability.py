"""Which parameters the data can separate, and which combinations they cannot.

The whitened Jacobian's columns are scaled to unit length and factorised by QR
in the model's own order (location errors of the axes, then the set-up of the
board and of the sensor, then added effects): a column whose component
orthogonal to the columns before it is below ``tol`` (a sine of the angle to
their span) cannot be separated from them. Such a parameter is held fixed and
reported by name together with the parameters it aliases with — never returned
as a number. Observability indices follow Sun & Hollerbach (2008): O1 of Borm
& Menq (geometric mean of the singular values over √m) and O3 (the minimum
singular value), on the column-scaled Jacobian.

References
----------
J.-H. Borm, C.-H. Menq, "Determination of optimal measurement configurations
for robot calibration based on observability measure", IJRR 10(1), 1991.
Y. Sun, J. M. Hollerbach, "Observability index selection for robot
calibration", ICRA 2008.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Alias", "Identifiability", "analyse", "identifiable_columns", "observability", "RANK_TOL", "INVISIBLE_TOL"]

#: A unit column whose distance to the span of the earlier columns is below this is dependent.
RANK_TOL = 1e-8
#: A column whose norm is below this fraction of the largest column norm has no effect on the data.
INVISIBLE_TOL = 1e-12


@dataclass(frozen=True)
class Alias:
    """A parameter the data cannot determine.

    Attributes
    ----------
    name : str
    kind : {"invisible", "aliased"}
        ``invisible``: it does not change the residuals of these data at all;
        ``aliased``: it changes them only as a combination of other parameters.
    partners : tuple of (str, float)
        For ``aliased``: parameters p_i and coefficients c_i such that the data
        see p_i + c_i · name.
    message : str
    """

    name: str
    kind: str
    partners: tuple = ()
    message: str = ""


@dataclass(frozen=True)
class Identifiability:
    """Result of :func:`analyse`.

    Attributes
    ----------
    identifiable : array (P,) of bool
    rank : int
    aliases : tuple of Alias
        One per parameter that is not identifiable, in model order.
    singular_values : array
        Of the unit-column Jacobian of the identifiable parameters.
    condition_number, o1, o3 : float
    """

    identifiable: np.ndarray
    rank: int
    aliases: tuple
    singular_values: np.ndarray
    condition_number: float
    o1: float
    o3: float


def _describe(name, partners):
    if not partners:
        return f"{name} cannot be identified from these data (held fixed)"
    if len(partners) == 1:
        other, c = partners[0]
        if abs(c - 1) < 1e-6:
            return f"{other} and {name}: only their sum is identified ({name} held fixed)"
        if abs(c + 1) < 1e-6:
            return f"{other} and {name}: only their difference is identified ({name} held fixed)"
    seen = ", ".join(f"{p} {'+' if c >= 0 else '-'} {abs(c):.4g}·{name}" for p, c in partners)
    return f"{name} is aliased with {', '.join(p for p, _ in partners)}: the data see only {seen} ({name} held fixed)"


def analyse(J: np.ndarray, names, *, tol: float = RANK_TOL, invisible_tol: float = INVISIBLE_TOL,
            rows: int | None = None) -> Identifiability:
    """Identifiability of the parameters of Jacobian ``J``.

    Parameters
    ----------
    J : array (M, P)
        Whitened Jacobian (residuals / σ per parameter unit).
    names : sequence of str
        Parameter names, in priority order (earlier ones are kept when aliased).
    tol : float
        Rank tolerance on unit columns (see module docstring).
    invisible_tol : float
        Relative column norm below which a parameter is invisible.
    rows : int, optional
        The rows of the Jacobian when ``J`` is its R factor (the same analysis; ``o1`` is per row).

    Returns
    -------
    Identifiability
    """
    M, P = J.shape
    M = M if rows is None else rows
    norms, visible, Jn, accepted, _ = _rank_test(J, tol, invisible_tol)
    aliases = []
    if P:
        acc = np.flatnonzero(accepted)
        # a held column as a combination of the accepted ones before it, by least squares: from one QR of the
        # accepted columns (independent: each passed the rank test), as the QR of their first k is its first k columns
        Q, Ra = np.linalg.qr(Jn[:, acc]) if len(acc) < P else (None, None)
        for j in range(P):
            if accepted[j]:
                continue
            if not visible[j]:
                aliases.append(Alias(names[j], "invisible", (), f"{names[j]} has no effect on these data (held fixed)"))
                continue
            k = int(np.searchsorted(acc, j))
            earlier = acc[:k]
            c = np.linalg.solve(Ra[:k, :k], Q[:, :k].T @ Jn[:, j]) if k else np.zeros(0)
            order = np.argsort(-np.abs(c))
            partners = tuple((names[earlier[i]], float(c[i] * norms[j] / norms[earlier[i]])) for i in order if abs(c[i]) > 1e-3)
            aliases.append(Alias(names[j], "aliased", partners, _describe(names[j], partners)))
    s = np.linalg.svd(Jn[:, accepted], compute_uv=False) if accepted.any() else np.zeros(0)
    cond, o1, o3 = observability(s, M)
    return Identifiability(accepted, int(accepted.sum()), tuple(aliases), s, cond, o1, o3)


def identifiable_columns(J: np.ndarray, *, tol: float = RANK_TOL, invisible_tol: float = INVISIBLE_TOL) -> np.ndarray:
    """(P,) bool: the parameters :func:`analyse` finds identifiable (its rank test alone, without the aliases
    and the singular values)."""
    return _rank_test(J, tol, invisible_tol)[3]


def observability(s: np.ndarray, rows: int) -> tuple:
    """(condition number, O1, O3) from the singular values ``s`` of the unit-column Jacobian of ``rows`` rows."""
    L = len(s)
    o1 = float(np.exp(np.mean(np.log(s))) / np.sqrt(rows)) if L and s.min() > 0 else 0.0
    o3 = float(s.min()) if L else 0.0
    cond = float(s.max() / s.min()) if L and s.min() > 0 else float("inf")
    return cond, o1, o3


def _rank_test(J, tol, invisible_tol):
    """Column norms, visible, unit columns, accepted (see the module docstring) and |diag R| of their QR."""
    P = J.shape[1]
    norms = np.linalg.norm(J, axis=0)
    biggest = norms.max() if P else 0.0
    visible = norms > invisible_tol * max(biggest, np.finfo(float).tiny)
    Jn = np.where(visible, J / np.where(visible, norms, 1.0), 0.0)
    accepted = np.zeros(P, dtype=bool)
    diag = np.zeros(P)
    if P:
        R = np.linalg.qr(Jn, mode="r")
        diag = np.abs(np.diag(R)) if R.shape[0] >= P else np.r_[np.abs(np.diag(R)), np.zeros(P - R.shape[0])]
        accepted = visible & (diag > tol)
    return norms, visible, Jn, accepted, diag
