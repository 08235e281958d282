"""Pass 2's fused per-chunk loops (ingest/line_kernels.py, issue 32) equal the numpy steps they
replace: each point's flight line, the kept-cell and class test, the rows per line; the class
table masks (strips/selection.among) and the re-georeferencing's NaN rows (ingest/regeoref)."""

from __future__ import annotations

import numpy as np
import pytest

from calidar.ingest.line_kernels import chunk_lines, kept_mask, kept_table
from calidar.ingest.regeoref import _nan_rows
from calidar.ingest.source import group_keys
from calidar.ingest.strips import rows_in_kept_cells
from calidar.strips.overlap import cell_keys
from calidar.strips.selection import EXCLUDED_CLASSES, among, excluded

GAP_S = 10.0


def _groups(rng, n=50_000):
    """Points in time order over a few point_source_ids, their groups and a line per group."""
    t = np.sort(rng.uniform(-30.0, 4e5, n))
    psid = rng.integers(0, 6, n).astype(np.uint16)
    psid[: n // 2] = 3  # long runs of one key, as files hold them
    groups = np.unique(group_keys(psid, t, GAP_S))
    return psid, t, groups, rng.integers(0, 9, groups.size).astype(np.int64)


@pytest.mark.parametrize("with_psid", [True, False])
def test_each_point_s_line_as_the_numpy_lookup(with_psid):
    psid, t, groups, line = _groups(np.random.default_rng(1))
    psid = psid if with_psid else None
    groups = np.unique(group_keys(psid, t, GAP_S))
    line = np.arange(groups.size, dtype=np.int64) * 7 % 5
    ids, found = chunk_lines(psid, t, GAP_S, groups, line)
    g = group_keys(psid, t, GAP_S)
    ref = line[np.minimum(np.searchsorted(groups, g), groups.size - 1)]
    assert found
    np.testing.assert_array_equal(ids, ref)
    assert np.unique(ids).size > 1  # several lines: a wrong lookup would show


def test_a_group_not_seen_and_a_time_not_finite():
    psid, t, groups, line = _groups(np.random.default_rng(2))
    g = group_keys(psid, t, GAP_S)
    missing = groups[groups != g[-1]]  # the last point's group unknown: the file changed
    assert chunk_lines(psid, t, GAP_S, missing, line[: missing.size]) == (None, False)
    t2 = t.copy()
    t2[100] = np.nan  # numpy's cast of NaN is the caller's
    assert chunk_lines(psid, t2, GAP_S, groups, line) == (None, True)
    t2[100] = 1e30  # a bin beyond int64: numpy's cast
    assert chunk_lines(psid, t2, GAP_S, groups, line) == (None, True)
    assert chunk_lines(psid.astype(float), t, GAP_S, groups, line) == (None, True)


def _numpy_rows(ids, xyz, factor, cell_m, kept, classes):
    """_kept_rows_numpy's steps: planar_xy, cell_keys, calibration_mask, then the rows in the kept
    cells (split_rows, searchsorted)."""
    keys = cell_keys(xyz[:, :2] * factor, cell_m)
    use = None if classes is None else ~excluded(classes)
    return list(rows_in_kept_cells(ids, keys, use, kept))


@pytest.mark.parametrize("factor", [1.0, 0.3048006096012192])
@pytest.mark.parametrize("by_class", [True, False])
def test_kept_rows_as_the_numpy_steps(factor, by_class):
    rng = np.random.default_rng(3)
    n, cell_m = 60_000, 5.0
    ids = np.repeat(rng.integers(0, 7, 40), n // 40)  # runs of lines, some repeated
    xyz = np.c_[rng.uniform(-200.0, 300.0, n), rng.uniform(5e6, 5e6 + 400.0, n),
                rng.normal(0, 3, n)]
    xyz[:20, :2] = np.arange(-10, 10)[:, None] * cell_m / factor  # on cell edges
    keys = cell_keys(xyz[:, :2] * factor, cell_m)
    kept = {i: np.unique(rng.choice(keys[ids == i], 300)) for i in range(5)}
    kept[2] = np.zeros(0, np.int64)  # a line without kept cells: no rows at all
    classes = rng.integers(0, 20, n).astype(np.uint8) if by_class else None
    mask, lines = kept_mask(ids, xyz, factor, cell_m, kept_table(kept), classes)
    sel = np.flatnonzero(mask)
    got = [(int(i), sel[ids[sel] == i]) for i in lines]
    ref = _numpy_rows(ids, xyz, factor, cell_m, kept, classes)
    assert [i for i, _ in got] == [i for i, _ in ref] == [0, 1, 3, 4]
    for (_, a), (_, b) in zip(got, ref):
        np.testing.assert_array_equal(a, b)
    assert 0 < sel.size < n


def test_kept_mask_leaves_the_unusual_to_numpy():
    ids = np.zeros(3, np.int64)
    xyz = np.array([[0.0, 0.0, 0.0], [np.inf, 1.0, 0.0], [1.0, 1.0, 0.0]])
    table = kept_table({0: np.array([0], np.int64)})
    assert kept_mask(ids, xyz, 1.0, 5.0, table, None) is None  # not finite
    assert kept_mask(ids, xyz[[0, 2]], 1.0, 5.0, table, np.zeros(2, np.int16)) is None


def test_class_masks_as_isin():
    c = np.arange(256, dtype=np.uint8).repeat(3)
    np.testing.assert_array_equal(excluded(c), np.isin(c, EXCLUDED_CLASSES))
    for classes in [(2,), (2, 6, 255), (0, 300), ()]:
        np.testing.assert_array_equal(among(c, classes), np.isin(c, classes))
    wide = np.array([2, 300, 9], np.int16)  # not 8-bit: numpy's isin
    np.testing.assert_array_equal(among(wide, (300,)), [False, True, False])


def test_nan_rows_around_the_taken_ones():
    out = np.zeros((2, 10, 3))
    _nan_rows(np.array([1, 4, 5, 9]), out)
    nan = np.isnan(out[:, :, 0])
    assert (nan == np.isnan(out[:, :, 2])).all()
    np.testing.assert_array_equal(nan[0], [True, False, True, True, False, False, True, True,
                                           True, False])
    out = np.zeros((1, 4, 3))
    _nan_rows(np.array([2, 1]), out)  # not ascending: every row, the kernel writes the taken
    assert np.isnan(out).all()


def test_tile_indices_as_the_numpy_floor():
    from calidar.crs import _tile_indices

    rng = np.random.default_rng(8)
    xyz = np.c_[rng.uniform(-1e3, 1e6, 5000), rng.uniform(-50.0, 5e6, 5000), rng.normal(0, 9, 5000)]
    xyz[:20, :2] = np.arange(-10, 10)[:, None] * 50.0  # on tile edges
    for tile in (50.0, 50.0 / 1e5, 7.3):
        np.testing.assert_array_equal(_tile_indices(xyz, tile),
                                      np.floor(xyz[:, :2] / tile).astype(np.int64))
    for bad in (np.nan, np.inf, 1e30):  # numpy's cast
        xyz[3, 1] = bad
        assert _tile_indices(xyz, 50.0) is None
