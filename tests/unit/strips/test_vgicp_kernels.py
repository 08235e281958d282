"""VGICP's numba kernels against the numpy expressions they replace: the same values, bit for bit
(the pairs' correspondences must not change; docs/validation.md, issue 32, seventh session)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from calidar.strips.vgicp import _spread, overlap_masks
from calidar.strips.vgicp_kernels import (gather_centred, neighbourhood_centroids,
                                          neighbourhood_moments, rows_mean, xy_bounds)
from calidar.strips.vgicp_planes import Grid, near


def _clouds(seed: int = 3):
    rng = np.random.default_rng(seed)
    a = rng.uniform([0, 0, 0], [300, 120, 5], (20_000, 3)) + [1.0e3 + 1 / 3, -2.0e3, 0]
    b = rng.uniform([0, 0, 0], [300, 120, 5], (15_000, 3)) + [1.1e3 + 0.1, -1.95e3, 0]
    return a, b


def _overlap_numpy(pa, pb, cell):  # the expression before the kernels
    xy_a, xy_b = pa[:, :2], pb[:, :2]
    grid = Grid(np.minimum(xy_a.min(axis=0), xy_b.min(axis=0)),
                np.maximum(xy_a.max(axis=0), xy_b.max(axis=0)), cell)
    ka, kb = grid.keys(grid.ij(xy_a)), grid.keys(grid.ij(xy_b))
    common = ka[grid.first(ka)]
    common = common[grid.isin(common, kb)]
    return grid.isin(ka, common), grid.isin(kb, common), common.size * cell**2


def test_bounds_and_overlap_equal_numpy():
    a, b = _clouds()
    lo, hi = xy_bounds(a)
    assert np.array_equal(lo, a[:, :2].min(axis=0)) and np.array_equal(hi, a[:, :2].max(axis=0))
    for cell in (10.0, 7.3, 0.9):
        got, want = overlap_masks(a, b, cell), _overlap_numpy(a, b, cell)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
        assert got[2] == want[2] and 0 < got[2] < 300 * 120


def test_near_and_spread_equal_numpy(monkeypatch):
    a, b = _clouds(5)
    at = a[::97]
    got_near = near(b, at, 2.7)
    got_spread = _spread(a, 500, 300 * 120)
    monkeypatch.setattr(Grid, "MAX_TABLE", 0)  # the sorting fallback: the numpy path
    assert np.array_equal(got_near, near(b, at, 2.7)) and 0 < got_near.size < len(b)
    assert np.array_equal(got_spread, _spread(a, 500, 300 * 120)) and got_spread.size == 500


@pytest.mark.parametrize("m_rows, k", [(1, 3), (700, 12), (2500, 30)])
def test_neighbourhood_moments_equal_numpy(m_rows, k):
    rng = np.random.default_rng(m_rows + k)
    points = rng.normal(0, 1, (5_000, 3)) * [40, 30, 0.5] + [1e3 / 3, -77.7, 12.0]
    idx = rng.integers(0, len(points), (m_rows, k))
    centroid, scatter = neighbourhood_moments(points, idx)
    nb = points[idx]
    want_centroid = nb.mean(axis=1)
    nb = nb - want_centroid[:, None, :]
    assert np.array_equal(centroid, want_centroid)
    assert np.array_equal(neighbourhood_centroids(points, idx), want_centroid)  # (alone)
    assert np.array_equal(scatter, np.einsum("mki,mkj->mij", nb, nb))


def test_wide_enough_decides_as_overlap_width():
    """The registration's width test from one numba pass (issue 32, eleventh session) decides as
    ``overlap_width(points) >= limit`` for strips of 2 … 60 m across and a limit at, just above and
    just below each strip's own width (there the numpy expression decides); the scatter within
    1e-12 relative of numpy's."""
    from calidar.strips.vgicp import overlap_width, wide_enough
    from calidar.strips.vgicp_kernels import xy_scatter

    rng = np.random.default_rng(7)
    for across in (2.0, 19.9, 20.0, 20.1, 60.0):
        xy = rng.uniform([0, 0], [800, across], (30_000, 2))
        angle = rng.uniform(0, np.pi)
        turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        pts = np.column_stack([xy @ turn.T + [4.0e2, -7.0e2], rng.normal(0, 1, len(xy))])
        centred = pts[:, :2] - pts[:, :2].mean(axis=0)
        cov = centred.T @ centred / len(pts)
        np.testing.assert_allclose(xy_scatter(pts), (cov[0, 0], cov[0, 1], cov[1, 1]),
                                   rtol=1e-12, atol=1e-12 * cov.max())
        width = overlap_width(pts)
        for limit in (20.0, width, np.nextafter(width, 0), np.nextafter(width, np.inf),
                      width * (1 + 2e-6), width * (1 - 2e-6)):
            assert wide_enough(pts, limit) == (width >= limit), (across, limit)


@pytest.mark.parametrize("n", [1, 2, 9, 1_000, 100_003])
def test_crop_kernels_equal_numpy(n):
    """The overlap crop's mean and centred gather (issue 32, twelfth session) as ``np.take(points,
    idx, axis=0)``, its ``mean(axis=0)`` and the subtraction: bit for bit, on values whose sums
    round differently in another order (a pairwise or a zero-started sum fails)."""
    rng = np.random.default_rng(n)
    points = rng.normal(0, 1, (n + 50, 3)) * [3e5, 1e-3, 40.0] + [4.2e5 + 1 / 3, -5.5e6, 0.1]
    points[::7] *= -1e3
    points[0, 1] = -0.0
    for idx in (np.arange(n), np.sort(rng.choice(n + 50, n, replace=False))):
        gathered = np.take(points, idx, axis=0)
        origin = rows_mean(points, idx)
        assert np.array_equal(origin, gathered.mean(axis=0))
        assert np.array_equal(np.signbit(origin), np.signbit(gathered.mean(axis=0)))
        assert np.array_equal(gather_centred(points, idx, origin), gathered - origin)
