"""The structure test's nearest neighbours on a line (sorted, n log n) against the pairwise search (n²)."""
import numpy as np

from kinid.identification.structure import _neighbours


def _pairwise(x):
    d = (x[:, None] - x[None, :]) ** 2
    np.fill_diagonal(d, np.inf)
    return np.argmin(d, axis=1)  # of rows as near, the first


def test_neighbours_on_a_line_are_the_pairwise_ones():
    rng = np.random.default_rng(1)
    for k in range(800):
        n = int(rng.integers(2, 80))
        x = [rng.choice([0.0, 1.0, 2.0, 3.0, 5.0, -0.0], n),  # repeated values and ties either side
             rng.normal(size=n),
             np.round(rng.uniform(-3, 3, n), 1),
             rng.choice([0.1, 0.2, 0.3, 0.30000000000000004], n)][k % 4]
        assert np.array_equal(_neighbours(x[:, None]), _pairwise(x)), x
