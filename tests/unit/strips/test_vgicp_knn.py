"""The grid's k nearest neighbours against small_gicp's KdTree: the same neighbours, in the same
order, with the same squared distances bit for bit (VGICP's rows must not change; issue 32)."""

from __future__ import annotations

import numpy as np
import pytest
import small_gicp

from calidar.strips.vgicp_knn import GridKnn


def _kdtree(points, queries, k):
    idx, d2 = small_gicp.KdTree(points, num_threads=1).batch_knn_search(queries, k, num_threads=1)
    return idx.astype(np.int64), d2


def _surface(n, seed):  # an airborne-like surface: xy spread, gentle relief, some walls
    rng = np.random.default_rng(seed)
    xy = rng.uniform([-150, -40], [150, 40], (n, 2))
    z = 0.02 * xy[:, 0] + np.sin(xy[:, 1] / 7.0) + rng.normal(0, 0.01, n)
    z[: n // 20] += rng.uniform(0, 8, n // 20)  # points up a wall's height
    return np.column_stack([xy, z])


@pytest.mark.parametrize("k", [1, 12, 30])
def test_same_neighbours_as_kdtree(k):
    pts = _surface(40_000, k)
    rng = np.random.default_rng(100 + k)
    queries = np.vstack([pts[::37] + rng.normal(0, 0.3, (len(pts[::37]), 3)),
                         rng.uniform([-400, -200, -5], [400, 200, 5], (200, 3))])  # some outside
    idx, d2 = GridKnn(pts).batch_knn_search(queries, k)
    want_idx, want_d2 = _kdtree(pts, queries, k)
    assert np.array_equal(d2, want_d2)
    assert np.array_equal(idx, want_idx)


def test_degenerate_clouds():
    rng = np.random.default_rng(7)
    line = np.column_stack([rng.uniform(0, 100, 3000), np.full(3000, 2.0), rng.normal(0, 1, 3000)])
    for pts in (line, line[:12], np.ones((5, 3)) + rng.normal(0, 1e-3, (5, 3))):
        k = min(12, len(pts))
        queries = pts[::7] + 0.05
        idx, d2 = GridKnn(pts).batch_knn_search(queries, k)
        want_idx, want_d2 = _kdtree(pts, queries, k)
        assert np.array_equal(d2, want_d2) and np.array_equal(idx, want_idx)


def test_far_queries():
    """Queries far off the points (10⁵ cells away) start at the grid's nearest ring."""
    pts = _surface(5_000, 2)
    queries = np.array([[4.0e5, 3.0e5, 0.0], [-2.0e5, 10.0, 1.0], [0.0, -5.0e5, 0.0]])
    idx, d2 = GridKnn(pts).batch_knn_search(queries, 12)
    want_idx, want_d2 = _kdtree(pts, queries, 12)
    assert np.array_equal(d2, want_d2) and np.array_equal(idx, want_idx)


def test_k_out_of_range():
    pts = _surface(100, 1)
    with pytest.raises(ValueError):
        GridKnn(pts).batch_knn_search(pts[:3], 101)
    with pytest.raises(ValueError):
        GridKnn(pts).batch_knn_search(pts[:3], 0)


def _ball_rows_numpy(idx, d2, radius2):
    """The balls' averaging rows from a k_max search, as VGICP's rows took them before the bounded
    search: the neighbours within the radius (and the nearest always), each 1 / count."""
    inside = d2 <= radius2[:, None]
    inside[:, 0] = True
    count = inside.sum(axis=1)
    weights = (inside / count[:, None])[inside]
    return weights, idx[inside], np.concatenate([[0], np.cumsum(count)]), count


@pytest.mark.parametrize("k_max", [1, 12, 25])
def test_ball_rows_as_from_the_k_max_nearest(k_max):
    """The bounded ball search (issue 32, eleventh session: it takes no point beyond the ball) gives
    the rows of the k_max search it replaces, bit for bit: radii from none of the points (the
    nearest alone) through a few to more than k_max (capped), queries inside, on walls and far
    outside, duplicated points (ties)."""
    pts = _surface(30_000, 40 + k_max)
    pts[:300] = pts[300:600]  # exact duplicates: equal distances
    rng = np.random.default_rng(k_max)
    queries = np.vstack([pts[::41] + rng.normal(0, 0.2, (len(pts[::41]), 3)), pts[300:330],
                         rng.uniform([-400, -200, -5], [400, 200, 5], (50, 3))])
    grid = GridKnn(pts)
    idx, d2 = grid.batch_knn_search(queries, k_max)
    radius2 = np.concatenate([rng.uniform(0.0, 3.0, len(queries) - 40) ** 2, np.zeros(20),
                              np.full(20, 2500.0)])
    radius2[::3] = d2[::3, k_max // 2]  # a neighbour exactly on the ball: inside
    got = grid.ball_rows(queries, k_max, radius2)
    want = _ball_rows_numpy(idx, d2, radius2)
    for g, w in zip(got, want):
        assert np.array_equal(g, w)
    count = got[3]
    assert count.min() == 1 and count.max() == k_max and (k_max == 1 or np.mean(count > 1) > 0.3)
