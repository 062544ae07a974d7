"""kinid.stats against scipy.special (the reference): χ² in closed form for whole degrees of freedom."""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import special

from kinid.stats import CLOSED_K, chi2_isf, chi2_logsf, chi2_sf, f_logsf


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5, 6, 7, 10, 19, 50, 99, 150, CLOSED_K])
def test_chi2_sf_and_isf_match_scipy(k):
    x = np.concatenate([np.linspace(1e-3, 5.0 * k + 60.0, 200), [1e-9, 0.5, k, 10.0 * k + 300.0]])
    for v in x:
        ref = special.chdtrc(k, v)
        if ref > 1e-290:
            assert chi2_sf(v, k) == pytest.approx(ref, rel=5e-13, abs=0), (k, v)
    for p in (0.9, 0.5, 0.05, 0.01, 1e-3, 1e-6, 1e-9, 1e-12, 1e-20, 1e-40):
        assert chi2_isf(p, k) == pytest.approx(special.chdtri(k, p), rel=1e-12), (k, p)


@pytest.mark.parametrize("k", [0.5, 2.5, 7.5, CLOSED_K + 1, 1_000, 9_999, 100_000])
def test_chi2_of_other_degrees_of_freedom_matches_scipy(k):
    """The incomplete gamma function's series and continued fraction: fractional k, and the thousands of
    degrees of freedom of a large fit's residual, from the bulk to the tail."""
    x = k + np.sqrt(2.0 * k) * np.linspace(-4.0, 12.0, 81)
    for v in np.concatenate([x[x > 0], [1e-6, 0.01 * k, 3.0 * k + 50.0]]):
        ref = special.chdtrc(k, v)
        rel = 1e-11 if k <= 1_000 else 1e-9
        if ref > 1e-300:
            assert chi2_sf(v, k) == pytest.approx(ref, rel=rel, abs=0), (k, v)
            assert chi2_logsf(v, k) == pytest.approx(math.log(ref), rel=rel, abs=rel), (k, v)
    for p in (0.9, 0.5, 0.05, 1e-3, 1e-9, 1e-40):
        assert chi2_isf(p, k) == pytest.approx(special.chdtri(k, p), rel=1e-10), (k, p)


@pytest.mark.parametrize("d1", [1, 2, 3, 4, 5, 7, 10, 30, 100, 2.5])
def test_f_tail_matches_scipy(d1):
    """P(F > f) relative to scipy's, from the bulk to the far tail, for the degrees of freedom of candidates
    (d1 a few parameters) against fits of a few to 100 000 residual degrees of freedom."""
    rng = np.random.default_rng(int(d1 * 10))
    F = np.concatenate([[1e-6, 0.01, 0.3, 0.9, 1.0, 1.1, 1.5, 2.0, 3.0, 5.0, 10.0, 30.0, 100.0, 1e3, 1e5],
                        rng.uniform(0.3, 4.0, 20)])
    for d2 in (1, 5, 40, 300, 1_000, 10_000, 100_000, 12.5):
        for f in F:
            ref = special.fdtrc(d1, d2, f)
            if ref > 1e-300:
                rel = 1e-11 if d2 <= 1_000 else 1e-9  # lgamma of large arguments loses digits in B(a, b)
                assert math.exp(f_logsf(f, d1, d2)) == pytest.approx(ref, rel=rel, abs=0), (d1, d2, f)
            else:
                assert f_logsf(f, d1, d2) == -math.inf, (d1, d2, f)
    assert f_logsf(0.0, d1, 40) == 0.0 and f_logsf(-1.0, d1, 40) == 0.0


def test_the_tail_stays_finite():
    assert chi2_sf(0.0, 3) == 1.0 and chi2_sf(-1.0, 3) == 1.0
    far = chi2_logsf(2000.0, 3)
    assert math.isfinite(far) and far == pytest.approx(math.log(special.chdtrc(3, 1400.0)) - 300.0, rel=0.01)


def test_f_tail_of_arrays_is_f_logsf_of_each_bit_for_bit():
    """f_logsf_each gives the floats f_logsf gives one value at a time: bulk, far tail (-inf), F ≤ 0 and NaN,
    whole and fractional degrees of freedom."""
    from kinid.stats import f_logsf_each

    rng = np.random.default_rng(2)
    F = np.concatenate([10 ** rng.uniform(-5, 4, 2000), [0.0, -1.0, np.nan, 1e6, 1e300]])
    d1 = np.concatenate([rng.integers(1, 30, F.size - 5), [2.5, 3, 1, 4, 2]])
    d2 = np.concatenate([rng.integers(1, 100_000, F.size - 5).astype(float), [12.5, 40, 10, 3000, 5]])
    at_once = f_logsf_each(F, d1, d2)
    one_by_one = [f_logsf(f, a, b) for f, a, b in zip(F.tolist(), d1.tolist(), d2.tolist())]
    assert np.array_equal(np.array(at_once), np.array(one_by_one), equal_nan=True)
    assert -math.inf in at_once and 0.0 in at_once
    assert f_logsf_each([], [], []) == []
