"""group_cells: the same grouping from the dense table and from the sort it falls back to."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.cells import group_cells


@pytest.mark.parametrize("spread", [30, 10**7])  # a compact chunk (dense table); cells far apart (sort)
def test_groups_are_the_cells(spread):
    rng = np.random.default_rng(1)
    ij = rng.integers(-spread, spread, (5000, 2))
    inv, first = group_cells(ij)
    assert inv.shape == (5000,) and np.array_equal(ij[first][inv], ij)  # each point's group is its cell
    assert np.unique(ij, axis=0).shape[0] == first.size  # one group per occupied cell
    assert np.all(first == np.array([np.flatnonzero(inv == g)[0] for g in range(first.size)]))  # its first point


def test_no_points():
    inv, first = group_cells(np.zeros((0, 2), np.int64))
    assert inv.size == 0 and first.size == 0


def test_take_rows_equals_indexing():
    from calidar.cells import index_rows, take_rows

    rng = np.random.default_rng(2)
    for a in (rng.normal(size=(1000, 3)), rng.integers(0, 9, 1000).astype(np.uint16),
              rng.normal(size=(1000, 6))[:, 1:4]):  # (N, 3), (N,), a strided view
        for mask in (rng.random(1000) < 0.4, np.zeros(1000, bool), np.ones(1000, bool)):
            got = take_rows(a, index_rows(mask, 1000))
            assert got.dtype == a.dtype and got.flags.c_contiguous
            np.testing.assert_array_equal(got, a[mask])
        for rows in (np.array([5, 0, 999, -1, 5]), np.zeros(0, np.int64),
                     np.array([3, 2], np.uint32)):
            np.testing.assert_array_equal(take_rows(a, index_rows(rows, 1000)), a[rows])
        np.testing.assert_array_equal(take_rows(a, index_rows(slice(3, 9), 1000)), a[3:9])
    with pytest.raises(IndexError):
        take_rows(np.zeros((4, 3)), np.array([4]))
    with pytest.raises(IndexError):  # a mask of another length: numpy's error
        take_rows(np.zeros((4, 3)), index_rows(np.ones(5, bool), 4))
