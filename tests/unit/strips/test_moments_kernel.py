"""The fused per-cell moments kernel (calidar.strips.moments_kernel) against the numpy path it
replaces: the same keys, counts, means and scatters bit for bit."""

import numpy as np
import pytest

from calidar.cells import cell_keys_of
from calidar.strips.cell_moments import CellMoments
from calidar.strips.moments_kernel import dense_moments, stable_key_order


def _same(a: CellMoments, b: CellMoments) -> None:
    assert a.cell_m == b.cell_m
    for f in ("keys", "count", "mean", "scatter"):
        x, y = getattr(a, f), getattr(b, f)
        assert x.dtype == y.dtype and x.shape == y.shape, f
        assert np.array_equal(x, y), f  # bit for bit, not within a tolerance


@pytest.mark.parametrize("cell_m", [1.0, 2, 2.5, 5.0])
@pytest.mark.parametrize("origin", [(0.0, 0.0), (-37.3, -1201.9), (512_345.678, 5_123_456.789)])
def test_kernel_equals_the_numpy_path(cell_m, origin):
    rng = np.random.default_rng(7)
    xy = np.asarray(origin) + rng.uniform(-40, 60, (5000, 2))
    pts = np.c_[xy, 200 + 0.1 * xy[:, 0] - 0.05 * xy[:, 1] + rng.normal(0, 0.03, 5000)]
    fused = CellMoments.of_points(pts, cell_m)
    assert dense_moments(np.ascontiguousarray(pts), cell_m) is not None  # the kernel ran
    _same(fused, CellMoments.sorted_points(pts, cell_m))
    assert fused.count.sum() == 5000 and np.all(np.diff(fused.keys) > 0)


def test_sparse_cells_fall_back_and_empty_input():
    pts = np.array([[0.0, 0.0, 1.0], [1e6, 1e6, 2.0], [0.5, 0.2, 3.0]])  # a box of 10¹² cells: not dense
    assert dense_moments(pts, 1.0) is None
    _same(CellMoments.of_points(pts, 1.0), CellMoments.sorted_points(pts, 1.0))
    empty = CellMoments.of_points(np.zeros((0, 3)), 2.0)
    assert len(empty) == 0 and empty.mean.shape == (0, 3) and empty.scatter.shape == (0, 6)


def test_moments_match_direct_statistics():
    """Counts, means and scatter equal those computed cell by cell from the points (independent check)."""
    rng = np.random.default_rng(3)
    pts = np.c_[rng.uniform(-5, 5, (800, 2)), rng.normal(10, 1, 800)]
    m = CellMoments.of_points(pts, 2.0)
    ij = np.floor(pts[:, :2] / 2.0).astype(np.int64)
    for k, (i, j) in enumerate(zip(m.keys >> 32, ((m.keys & 0xFFFFFFFF) ^ 2**31) - 2**31)):
        sel = pts[(ij[:, 0] == i) & (ij[:, 1] == j)]
        assert m.count[k] == len(sel)
        np.testing.assert_allclose(m.centroid()[k], sel.mean(axis=0), rtol=0, atol=1e-12)
        d = sel - sel.mean(axis=0)
        np.testing.assert_allclose(m.scatter[k], [d[:, a] @ d[:, b] for a, b in
                                                  ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))], atol=1e-9)


@pytest.mark.parametrize("origin", [(0.0, 0.0), (-3000.0, -50.0), (512_345.0, 5_123_456.0)])
def test_dense_cell_counts_equal_the_sort(origin):
    from calidar.strips.moments_kernel import dense_cell_counts
    from calidar.strips.overlap import cell_counts, cell_keys

    rng = np.random.default_rng(11)
    keys = cell_keys(np.asarray(origin) + rng.uniform(-300, 200, (20000, 2)), 5.0)
    dense = dense_cell_counts(keys)
    assert dense is not None
    ks = np.sort(keys)  # the sort it replaces
    start = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1]
    for got, want in zip(dense, (ks[start], np.diff(np.r_[start, ks.size]))):
        assert got.dtype == np.int64 and np.array_equal(got, want)
    assert all(np.array_equal(a, b) for a, b in zip(cell_counts(keys), dense))
    far = np.r_[keys[:3], cell_keys(np.array([[1e7, 1e7]]), 5.0)]
    assert dense_cell_counts(far) is None and cell_counts(far)[1].sum() == 4  # sparse: the sort
    assert [a.size for a in cell_counts(np.zeros(0, np.int64))] == [0, 0]


def test_block_ids_numbered_as_numpy_unique():
    from calidar.strips.moments_kernel import dense_row_ids
    from calidar.strips.planimetric import block_ids

    rng = np.random.default_rng(5)
    for origin in ((0.0, 0.0), (-450.0, 3.0), (423_000.0, 5_205_000.0)):
        centre = np.asarray(origin) + rng.uniform(-200, 300, (3000, 2))
        want = np.unique(np.floor(centre / 20.0).astype(np.int64), axis=0, return_inverse=True)[1].ravel()
        inv, n = block_ids(centre, 20.0)
        assert dense_row_ids(np.floor(centre / 20.0).astype(np.int64)) is not None
        assert np.array_equal(inv, want) and n == want.max() + 1
    far = np.array([[0.0, 0.0], [1e9, 1e9], [5.0, 1.0]])
    inv, n = block_ids(far, 20.0)  # not dense: np.unique
    assert inv.tolist() == [0, 1, 0] and n == 2
    assert block_ids(np.zeros((0, 2)), 20.0)[1] == 0


def test_point_cell_keys_bit_for_bit_numpys():
    # cell_keys' numba pass (issue 32) against the numpy it replaces: negative, large, on edges,
    # strided; a NaN goes the numpy way
    from calidar.strips.overlap import cell_keys

    def numpy_keys(xy, c):
        ij = np.floor(np.asarray(xy, float)[:, :2] / c).astype(np.int64)
        return (ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF)

    rng = np.random.default_rng(5)
    for spread in (1.0, 1e3, 1e6, 1e9):
        p = rng.normal(0.0, spread, (20_000, 3))
        p[::7] = np.round(p[::7] / 5) * 5  # exactly on cell edges
        for c in (0.5, 2.0, 5.0, 3.7):
            assert np.array_equal(cell_keys(p, c), numpy_keys(p, c))
            assert np.array_equal(cell_keys(p[::3, :2], c), numpy_keys(p[::3, :2], c))
    assert cell_keys(np.zeros((0, 3)), 5.0).shape == (0,)
    q = p.copy()
    q[5, 1] = np.nan
    with np.errstate(invalid="ignore"):
        assert np.array_equal(cell_keys(q, 5.0), numpy_keys(q, 5.0))


def test_common_cells_intersection_is_numpys():
    # common_cells' binary-search intersection (issue 32) against np.intersect1d, sizes 0 to 10⁵
    from calidar.strips.overlap import _intersection, common_cells

    rng = np.random.default_rng(8)
    for n in (0, 1, 5, 1000, 100_000):
        for m in (0, 1, 7, 2000, 50_000):
            a = np.unique(rng.integers(-2**40, 2**40, n))
            extra = rng.choice(a, min(a.size, m // 2)) if a.size else np.zeros(0, np.int64)
            b = np.unique(np.r_[extra, rng.integers(-2**40, 2**40, m)].astype(np.int64))
            got, want = _intersection(a, b), np.intersect1d(a, b, assume_unique=True)
            assert got.dtype == want.dtype and np.array_equal(got, want), (n, m)
    occupied = {1: np.arange(0, 100), 2: np.arange(50, 300, 2), 3: np.arange(1000, 1010)}
    assert [(a, b, c.tolist()) for a, b, c in common_cells(occupied, 4)] == [
        (1, 2, list(range(50, 100, 2)))]


def test_stable_key_order_is_the_stable_argsort():
    """The counting sort of cell keys gives ``np.argsort(kind="stable")``'s indices: cells on
    both sides of j = 0 and of i = 0 (j < 0 sort after j ≥ 0 in key order), many points a cell
    (ties kept in input order), one point, none, and a sparse box (the argsort itself)."""
    rng = np.random.default_rng(32)
    for n, span in [(0, 5), (1, 5), (17, 3), (5000, 40), (200_000, 300), (3000, 10**6)]:
        ij = rng.integers(-span, span + 1, (n, 2))
        keys = cell_keys_of(ij[:, 0], ij[:, 1])
        got = stable_key_order(keys)
        assert got.dtype == np.int64
        assert np.array_equal(got, np.argsort(keys, kind="stable")), (n, span)
