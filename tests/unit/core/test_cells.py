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
