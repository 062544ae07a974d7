"""The few distribution functions kinid needs, without ``scipy.stats`` (``import scipy.stats`` alone takes
about 0.4 s, more than a whole fit).

- :func:`chi2_sf`, :func:`chi2_isf`, :func:`chi2_logsf` — χ² with ``k`` degrees of freedom;
- :func:`f_logsf` — Fisher's F with ``d1``, ``d2`` degrees of freedom; :func:`f_logsf_each` for arrays of them
  at once (the same numbers, bit for bit: the continued fractions of all run together).

For whole ``k`` up to :data:`CLOSED_K` (the 3 coordinates of a residual, the few parameters of a
candidate) χ² is computed in closed form — ``erfc`` or ``exp`` and a finite sum of positive terms,
within 2e-13 of scipy's values. Other degrees of freedom (the thousands of a large fit) use the
regularized incomplete gamma function by its series or continued fraction, and the F distribution the
regularized incomplete beta function by its continued fraction (Press et al., *Numerical Recipes*,
``gser``, ``gcf``, ``betacf``), within 1e-11 of scipy's values relative up to a thousand degrees of
freedom and 1e-9 up to 100 000 (``lgamma`` of large arguments loses digits). So no command imports
``scipy.special`` (≈ 0.1 s) for a probability.

Examples
--------
>>> round(chi2_isf(0.05, 3), 4)
7.8147
>>> round(chi2_sf(7.8147, 3), 4)
0.05
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["chi2_sf", "chi2_isf", "chi2_logsf", "f_logsf", "f_logsf_each", "CLOSED_K", "K_EXPANDED"]

#: The coverage factor of every expanded uncertainty kinid states, U = k·σ (GUM: about 95 % for a normal
#: distribution): the reports' and the certificate's U, and the test a term must pass to be compensated.
K_EXPANDED = 2.0

#: The largest whole number of degrees of freedom χ² is computed for in closed form.
CLOSED_K = 200


def chi2_sf(x: float, k: float) -> float:
    """P(χ²_k > x)."""
    if _closed(k):
        return _chi2_sf_closed(float(x), int(k))
    return math.exp(_log_gammaincc(k / 2.0, float(x) / 2.0))


def chi2_isf(p: float, k: float) -> float:
    """The x with P(χ²_k > x) = p."""
    if not 0.0 < p < 1.0:
        return math.inf if p <= 0.0 else 0.0
    return _falling_root(lambda x: chi2_sf(x, k), float(p), max(1.0, float(k)))


def chi2_logsf(x: float, k: float) -> float:
    """log P(χ²_k > x), finite far into the tail where the probability underflows.

    Beyond the underflow, the upper incomplete gamma function's asymptotic series:
    log Q(a, z) = (a − 1) log z − z − log Γ(a) + log(1 + (a − 1)/z + (a − 1)(a − 2)/z² ...), a = k/2, z = x/2.
    """
    if not _closed(k):
        return _log_gammaincc(k / 2.0, float(x) / 2.0)
    p = chi2_sf(x, k)
    if p > 0.0:
        return math.log(p)
    a, z = k / 2.0, x / 2.0
    series = 1.0 + (a - 1) / z + (a - 1) * (a - 2) / z**2
    return (a - 1) * math.log(z) - z - math.lgamma(a) + math.log(max(series, 1e-300))


def f_logsf(F: float, d1: float, d2: float) -> float:
    """log P(F_{d1,d2} > F); -inf where the probability underflows a double (callers fall back to χ²).

    P(F_{d1,d2} > F) = I_x(d2/2, d1/2), the regularized incomplete beta function at x = d2/(d2 + d1·F).
    """
    if not F > 0.0:
        return 0.0
    s = d1 * F
    log_p = _log_betainc(d2 / 2.0, d1 / 2.0, d2 / (d2 + s), s / (d2 + s))
    return log_p if math.exp(log_p) > 0.0 else -math.inf


def f_logsf_each(F, d1, d2) -> list:
    """:func:`f_logsf` of each element of the arrays ``F``, ``d1``, ``d2`` (broadcast), the same floats; the
    continued fractions of all run together in numpy (the diagnosis tests hundreds of candidates at once)."""
    F, d1, d2 = np.broadcast_arrays(*(np.asarray(v, float) for v in (F, d1, d2)))
    out, todo = [0.0] * F.size, []  # todo: (index, a, b, x, log_front, which end of I_x the fraction gives)
    for i, (f, n1, n2) in enumerate(zip(F.ravel().tolist(), d1.ravel().tolist(), d2.ravel().tolist())):
        if not f > 0.0:
            continue
        s = n1 * f
        a, b, x, y = n2 / 2.0, n1 / 2.0, n2 / (n2 + s), s / (n2 + s)
        if not x > 0.0 or not y > 0.0:
            out[i] = -math.inf if not x > 0.0 else 0.0
            continue
        log_front = a * math.log(x) + b * math.log(y) + math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
        low = x < (a + 1.0) / (a + b + 2.0)
        todo.append((i, a, b, x, log_front, low) if low else (i, b, a, y, log_front, low))
    if todo:
        fractions = _beta_fractions(*(np.array([t[j] for t in todo]) for j in (1, 2, 3))).tolist()
        for (i, a, _, _, log_front, low), h in zip(todo, fractions):
            out[i] = log_front + math.log(h / a) if low else math.log1p(-math.exp(log_front) * h / a)
    return [v if math.exp(v) > 0.0 else -math.inf for v in out]


def _log_betainc(a: float, b: float, x: float, y: float) -> float:
    """log I_x(a, b) with y = 1 − x given apart (no cancellation near x = 1): x^a y^b / (a B(a, b)) times the
    continued fraction where it converges fast, x < (a + 1)/(a + b + 2), else 1 − I_y(b, a)."""
    if not x > 0.0:
        return -math.inf
    if not y > 0.0:
        return 0.0
    log_front = a * math.log(x) + b * math.log(y) + math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b)
    if x < (a + 1.0) / (a + b + 2.0):
        return log_front + math.log(_beta_fraction(a, b, x) / a)
    return math.log1p(-math.exp(log_front) * _beta_fraction(b, a, y) / b)


def _beta_fraction(a: float, b: float, x: float) -> float:
    """The continued fraction of I_x(a, b) by the modified Lentz method (Press et al., Numerical Recipes,
    ``betacf``): tens of terms for the degrees of freedom of a fit."""
    tiny = 1e-300
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 100_000):
        for numerator in (m * (b - m) * x / ((a + 2 * m - 1.0) * (a + 2 * m)),
                          -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1.0))):
            d = 1.0 + numerator * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + numerator / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            return h
    raise ArithmeticError(f"the incomplete beta function's continued fraction did not converge (a={a}, b={b}, x={x})")


def _beta_fractions(a, b, x) -> np.ndarray:
    """:func:`_beta_fraction` of each element of the arrays ``a``, ``b``, ``x``: the same operations in the same
    order, each element's stopping at its own term."""
    tiny = 1e-300
    out = np.empty(x.shape)
    live = np.arange(x.size)
    c, d = np.ones(x.shape), 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / np.where(np.abs(d) > tiny, d, tiny)
    h = d
    for m in range(1, 100_000):
        for numerator in (m * (b - m) * x / ((a + 2 * m - 1.0) * (a + 2 * m)),
                          -(a + m) * (a + b + m) * x / ((a + 2 * m) * (a + 2 * m + 1.0))):
            d = 1.0 + numerator * d
            d = 1.0 / np.where(np.abs(d) > tiny, d, tiny)
            c = 1.0 + numerator / c
            c = np.where(np.abs(c) > tiny, c, tiny)
            h = h * (d * c)
        done = np.abs(d * c - 1.0) < 1e-15
        if done.any():
            out[live[done]] = h[done]
            going = ~done
            live, a, b, x, c, d, h = (v[going] for v in (live, a, b, x, c, d, h))
            if not live.size:
                return out
    raise ArithmeticError("the incomplete beta function's continued fraction did not converge "
                          f"(a={a[0]}, b={b[0]}, x={x[0]})")


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


def _falling_root(sf, p: float, hi: float) -> float:
    """The x with sf(x) = p for a survival function sf falling from 1 at x = 0, by bisection to 1e-14."""
    lo = 0.0
    while sf(hi) > p:
        lo, hi = hi, 2.0 * hi
    while hi - lo > 1e-14 * hi:
        mid = 0.5 * (lo + hi)
        if sf(mid) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _log_gammaincc(a: float, z: float) -> float:
    """log Q(a, z), the regularized upper incomplete gamma function: 1 − the series of P below z = a + 1,
    the continued fraction of Q above (each converges fast there; finite far into the tail)."""
    if not z > 0.0:
        return 0.0
    log_front = a * math.log(z) - z - math.lgamma(a)
    if z < a + 1.0:
        term = total = 1.0 / a
        n = a
        while abs(term) > 1e-16 * abs(total):
            n += 1.0
            term *= z / n
            total += term
        return math.log1p(-math.exp(log_front) * total)
    tiny = 1e-300
    b = z + 1.0 - a
    c, d = 1.0 / tiny, 1.0 / b
    h = d
    for i in range(1, 100_000):
        numerator = -i * (i - a)
        b += 2.0
        d = numerator * d + b
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = b + numerator / c
        c = c if abs(c) > tiny else tiny
        h *= d * c
        if abs(d * c - 1.0) < 1e-15:
            return log_front + math.log(h)
    raise ArithmeticError(f"the incomplete gamma function's continued fraction did not converge (a={a}, z={z})")


