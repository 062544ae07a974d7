"""The local-error basis ``CODE:local:<step>:<from>:<to>``: cubic B-splines whose support lies inside the window."""
from __future__ import annotations

import numpy as np
import pytest

from kinid.errors import DataError
from kinid.identification import load_machine, parse_effect
from kinid.identification.effects import basis_values
from kinid.urdf import path


@pytest.fixture(scope="module")
def bc():
    return load_machine(path("five_axis_bc"))


def test_local_basis_is_smooth_and_zero_outside(bc):
    e = parse_effect("EXX:local:5:-30:0", bc)
    assert e.n_params == 3 and e.param_names() == ["EXX:local:5:-30:0[-20]", "EXX:local:5:-30:0[-15]",
                                                   "EXX:local:5:-30:0[-10]"]
    x = np.linspace(-60, 30, 9001)
    axes = np.zeros((x.size, len(bc.axes)))
    axes[:, bc.axis_names.index("X")] = x
    B = basis_values(e, bc, axes)
    assert np.all(B[(x <= -30) | (x >= 0)] == 0)
    # a cubic B-spline: value 2/3 at its knot, 1/6 one step away, and C2 (its differences vanish smoothly)
    k = np.argmin(np.abs(x + 15))
    assert B[k, 1] == pytest.approx(2 / 3) and B[np.argmin(np.abs(x + 10)), 1] == pytest.approx(1 / 6)
    d2 = np.diff(B, 2, axis=0) / (x[1] - x[0]) ** 2
    assert np.max(np.abs(np.diff(d2, axis=0))) < 1e-2  # no jump in the second derivative
    # the splines sum to 1 in the middle of a wide window (they reproduce a constant there)
    wide = parse_effect("EXX:local:5:-40:40", bc)
    Bw = basis_values(wide, bc, axes)
    mid = np.abs(x) <= 20
    np.testing.assert_allclose(Bw[mid].sum(axis=1), 1.0, atol=1e-12)


@pytest.mark.parametrize("name, message", [
    ("EXX:local:5:0:10", "at least four steps"),
    ("EXX:local:5:10:0", "a range from < to"),
    ("EX0W:local:5:0:40", "needs the position of an axis"),
])
def test_local_grammar_errors(bc, name, message):
    with pytest.raises(DataError, match=message):
        parse_effect(name, bc)
