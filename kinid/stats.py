"""The few distribution functions kinid needs, without ``scipy.stats`` (``import scipy.stats`` alone takes
about 0.4 s, more than a whole fit).

- :func:`chi2_sf`, :func:`chi2_isf`, :func:`chi2_logsf` — χ² with ``k`` degrees of freedom;
- :func:`f_logsf` — Fisher's F with ``d1``, ``d2`` degrees of freedom.

For whole ``k`` up to :data:`CLOSED_K` (the 3 coordinates of a residual, the few parameters of a
candidate) χ² is computed in closed form — ``erfc`` or ``exp`` and a finite sum of positive terms,
within 2e-13 of scipy's values — so ``kinid identify`` never imports ``scipy.special`` (≈ 0.1 s). Other
degrees of freedom and the F distribution use ``scipy.special``, the functions scipy.stats calls underneath.

Examples
--------
>>> round(chi2_isf(0.05, 3), 4)
7.8147
>>> round(chi2_sf(7.8147, 3), 4)
0.05
"""
from __future__ import annotations

import math

__all__ = ["chi2_sf", "chi2_isf", "chi2_logsf", "f_logsf", "CLOSED_K"]

#: The largest whole number of degrees of freedom χ² is computed for in closed form.
CLOSED_K = 200


def chi2_sf(x: float, k: float) -> float:
    """P(χ²_k > x)."""
    if _closed(k):
        return _chi2_sf_closed(float(x), int(k))
    from scipy import special

    return float(special.chdtrc(k, x))


def chi2_isf(p: float, k: float) -> float:
    """The x with P(χ²_k > x) = p."""
    if _closed(k) and 0.0 < p < 1.0:
        return _chi2_isf_closed(float(p), int(k))
    from scipy import special

    return float(special.chdtri(k, p))


def chi2_logsf(x: float, k: float) -> float:
    """log P(χ²_k > x), finite far into the tail where the probability underflows.

    Beyond the underflow, the upper incomplete gamma function's asymptotic series:
    log Q(a, z) = (a − 1) log z − z − log Γ(a) + log(1 + (a − 1)/z + (a − 1)(a − 2)/z² ...), a = k/2, z = x/2.
    """
    p = chi2_sf(x, k)
    if p > 0.0:
        return math.log(p)
    a, z = k / 2.0, x / 2.0
    series = 1.0 + (a - 1) / z + (a - 1) * (a - 2) / z**2
    return (a - 1) * math.log(z) - z - math.lgamma(a) + math.log(max(series, 1e-300))


def f_logsf(F: float, d1: float, d2: float) -> float:
    """log P(F_{d1,d2} > F); -inf where the probability underflows (callers fall back to χ²)."""
    from scipy import special

    p = float(special.fdtrc(d1, d2, F))
    return math.log(p) if p > 0.0 else -math.inf


def _closed(k) -> bool:
    try:
        return float(k).is_integer() and 1 <= k <= CLOSED_K
    except (TypeError, ValueError):
        return False


def _chi2_sf_closed(x: float, k: int) -> float:
    """P(χ²_k > x) for whole k: Q(k/2, h) = [erfc(√h) for odd k] + Σ h^a e^(−h) / Γ(a + 1) over a = 0 or 1/2, …,
    k/2 − 1 (h = x/2): positive terms, no cancellation, summed in logs scaled by the largest (no underflow
    while the sum itself is a double)."""
    if not x > 0.0:
        return 1.0
    h = x / 2.0
    a = 0.5 if k % 2 else 0.0
    base = math.erfc(math.sqrt(h)) if k % 2 else 0.0
    log_h = math.log(h)
    log_term = a * log_h - h - math.lgamma(a + 1.0)
    logs = []
    while a < k / 2.0:
        logs.append(log_term)
        a += 1.0
        log_term += log_h - math.log(a)
    if not logs:  # k = 1
        return base
    top = max(logs)
    return base + math.exp(top) * math.fsum(math.exp(v - top) for v in logs)


def _chi2_isf_closed(p: float, k: int) -> float:
    """The x with :func:`_chi2_sf_closed` (x, k) = p, by bisection (the function falls with x) to 1e-14."""
    lo, hi = 0.0, max(1.0, float(k))
    while _chi2_sf_closed(hi, k) > p:
        lo, hi = hi, 2.0 * hi
    while hi - lo > 1e-14 * hi:
        mid = 0.5 * (lo + hi)
        if _chi2_sf_closed(mid, k) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
