"""Rows grouped by equal values (exact copies, replicates) — vectorised — against the plain dictionary of tuples."""
import numpy as np

from kinid.identification.data.observations import row_groups


def _plain(*columns):
    n = len(columns[0])
    keys = [tuple(("nan" if v != v else v + 0.0) if isinstance(v, float) else v
                  for c in columns for v in np.atleast_1d(np.asarray(c, dtype=object)[i]).tolist()) for i in range(n)]
    seen, group, first = {}, [], []
    for i, k in enumerate(keys):
        if k not in seen:
            seen[k] = len(first)
            first.append(i)
        group.append(seen[k])
    return np.array(group), np.array(first)


def test_row_groups_match_the_plain_grouping():
    rng = np.random.default_rng(7)
    for _ in range(200):
        n = int(rng.integers(1, 60))
        marks = rng.choice(["M1", "M2", "B10"], n)
        values = rng.choice([0.0, -0.0, 1.5, np.nan, 60.000000001, 2.0], (n, int(rng.integers(1, 4))))
        signs = rng.choice([-1, 1], n)
        group, first = row_groups(marks, values, signs)
        ref_group, ref_first = _plain(list(marks), [tuple(v) for v in values], list(signs))
        # the same partition of the rows, and each group's first row
        assert sorted(first.tolist()) == ref_first.tolist()
        assert np.array_equal(first[group], ref_first[ref_group])


def test_row_groups_when_every_row_has_one_hash(monkeypatch):
    """A hash shared by rows that differ (forced here: a multiplier of 0 gives every row the hash 0) is sorted out
    by the rows' values: the same partition as the plain grouping, groups numbered by their first rows."""
    import kinid.identification.data.observations as observations

    monkeypatch.setattr(observations, "ROW_HASH", 0)
    rng = np.random.default_rng(11)
    for _ in range(50):
        n = int(rng.integers(1, 60))
        marks = rng.choice(["M1", "M2", "B10"], n)
        values = rng.choice([0.0, -0.0, 1.5, np.nan, 2.0], (n, 2))
        group, first = row_groups(tuple(marks.tolist()), values)  # marks as read: a tuple of str
        ref_group, ref_first = _plain(list(marks), [tuple(v) for v in values])
        assert np.array_equal(first, ref_first) and np.array_equal(group, ref_group)


def test_row_groups_are_numbered_by_first_row():
    group, first = row_groups(np.array([3.0, 1.0, 3.0, 2.0, 1.0]))
    assert group.tolist() == [0, 1, 0, 2, 1] and first.tolist() == [0, 1, 3]
