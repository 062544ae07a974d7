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


def test_other_degrees_of_freedom_and_f_use_scipy():
    assert chi2_sf(3.3, 2.5) == special.chdtrc(2.5, 3.3)
    assert chi2_isf(0.01, CLOSED_K + 1) == special.chdtri(CLOSED_K + 1, 0.01)
    assert f_logsf(2.0, 3, 40) == pytest.approx(math.log(special.fdtrc(3, 40, 2.0)), rel=1e-14)


def test_the_tail_stays_finite():
    assert chi2_sf(0.0, 3) == 1.0 and chi2_sf(-1.0, 3) == 1.0
    far = chi2_logsf(2000.0, 3)
    assert math.isfinite(far) and far == pytest.approx(math.log(special.chdtrc(3, 1400.0)) - 300.0, rel=0.01)
