"""The merged grid-cell and LAS-scaling functions against the expressions they replaced, copied
here verbatim (bit for bit on random and edge inputs: negative coordinates, points exactly on a
cell edge, huge offsets, ±0, NaN and ±inf where the old code passed them on)."""

import warnings

import numpy as np
import pytest
from numba import njit

from calidar.cells import cell_index, cell_key, cell_keys_of, grid_indices, key_cell, key_indices
from calidar.ingest.chunk_pass import second_and_cell, selected_points
from calidar.ingest.held import scaled_integers, stored_integers
from calidar.strips.cell_moments import index_keys
from calidar.strips.moments_kernel import point_cell_keys
from calidar.strips.overlap import cell_keys
from calidar.strips.vgicp_kernels import cell_keys as vgicp_cell_keys


def _coordinates(rng, n=20000):
    cell = 0.37
    xy = np.concatenate([
        rng.uniform(-1e3, 1e3, (n, 2)),
        rng.uniform(-1e7, 1e7, (n, 2)) + np.array([5e5, 5.4e6]),  # UTM-sized
        np.round(rng.uniform(-50, 50, (n, 2))) * cell,  # exactly on (or next to) a cell edge
        np.nextafter(np.round(rng.uniform(-50, 50, (n, 2))) * cell, -np.inf),
        [[0.0, -0.0], [-0.0, 0.0], [cell, -cell], [-1e-300, 1e-300], [-1e9, 1e9]],
    ])
    return xy, cell


def _old_numpy(xy, cell_m, origin=None):  # strips/overlap.py cell_keys before the merge
    o = np.zeros(2) if origin is None else origin
    ij = np.floor((np.asarray(xy, float)[:, :2] - o) / cell_m).astype(np.int64)
    return (ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF)


@njit
def _old_point_keys(p, cell_m, out):  # strips/moments_kernel.py _point_cell_keys before
    for k in range(p.shape[0]):
        x, y = p[k, 0] / cell_m, p[k, 1] / cell_m
        if not (np.isfinite(x) and np.isfinite(y)):
            return False
        i, j = np.int64(np.floor(x)), np.int64(np.floor(y))
        out[k] = (i << 32) + (j & 0xFFFFFFFF)
    return True


@njit
def _new_indices(p, lo, cell):
    out = np.empty((p.shape[0], 4), np.int64)
    for k in range(p.shape[0]):
        out[k, 0], out[k, 1] = cell_index(p[k, 0], cell), cell_index(p[k, 1], cell)
        out[k, 2], out[k, 3] = cell_index(p[k, 0] - lo[0], cell), cell_index(p[k, 1] - lo[1], cell)
    return out


@njit
def _old_indices(p, lo, cell):  # chunk_pass.second_and_cell, vgicp_kernels._cell before
    out = np.empty((p.shape[0], 4), np.int64)
    for k in range(p.shape[0]):
        out[k, 0] = np.int64(np.floor(p[k, 0] / cell))
        out[k, 1] = np.int64(np.floor(p[k, 1] / cell))
        out[k, 2] = np.int64(np.floor((p[k, 0] - lo[0]) / cell))
        out[k, 3] = np.int64(np.floor((p[k, 1] - lo[1]) / cell))
    return out


@njit
def _new_keys(i, j):
    out = np.empty(i.size, np.int64)
    for k in range(i.size):
        out[k] = cell_key(i[k], j[k])
    return out


def test_numpy_cells_and_keys_are_the_old_expressions():
    xy, cell = _coordinates(np.random.default_rng(1))
    origin = np.array([-123.456, 987.125])
    for o in (None, origin):
        assert np.array_equal(cell_keys(xy, cell, o), _old_numpy(xy, cell, o))
        ij = np.floor((xy - (0.0 if o is None else o)) / cell).astype(np.int64)
        assert np.array_equal(grid_indices(xy, cell, o), ij)
    ij = grid_indices(xy, cell)
    old = (ij[:, 0].astype(np.int64) << 32) + (ij[:, 1].astype(np.int64) & 0xFFFFFFFF)
    assert np.array_equal(cell_keys_of(ij[:, 0], ij[:, 1]), old)  # planimetric._cell_key
    assert np.array_equal(index_keys(ij), old)


def test_numpy_cells_keep_the_callers_precision():  # planimetric's centres as given
    c32 = (np.random.default_rng(4).uniform(-1e4, 1e4, (5000, 2))).astype(np.float32)
    assert np.array_equal(grid_indices(c32, 0.3), np.floor(c32 / 0.3).astype(np.int64))
    assert np.array_equal(cell_keys(c32, 0.3), _old_numpy(c32, 0.3))


def test_numpy_cells_of_non_finite_points_as_numpy_casts_them():
    xy = np.array([[np.nan, 1.0], [np.inf, -np.inf], [2.0, np.nan]])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert np.array_equal(cell_keys(xy, 0.5), _old_numpy(xy, 0.5))
        assert np.array_equal(grid_indices(xy, 0.5), np.floor(xy / 0.5).astype(np.int64))


def test_numba_cells_and_keys_are_the_old_expressions():
    xy, cell = _coordinates(np.random.default_rng(2))
    lo = xy.min(axis=0)
    assert np.array_equal(_new_indices(xy, lo, cell), _old_indices(xy, lo, cell))
    new, old = np.empty(len(xy), np.int64), np.empty(len(xy), np.int64)
    assert point_cell_keys(xy, cell) is not None and _old_point_keys(xy, cell, old)
    assert np.array_equal(point_cell_keys(xy, cell), old)
    ij = grid_indices(xy, cell)
    assert np.array_equal(_new_keys(ij[:, 0], ij[:, 1]), cell_keys_of(ij[:, 0], ij[:, 1]))
    ncol = int((xy[:, 1].max() - lo[1]) // cell) + 1
    old_v = _old_indices(xy, lo, cell)
    assert np.array_equal(vgicp_cell_keys(xy, lo, cell, ncol), old_v[:, 2] * ncol + old_v[:, 3])
    for k in (0, 7, len(xy) - 1):
        s, i, j = second_and_cell(1e9 + 0.5, xy[k, 0], xy[k, 1], cell)
        assert (i, j) == tuple(old_v[k, :2])


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 1e308])
def test_point_cell_keys_still_hand_non_finite_quotients_to_numpy(bad):
    xy = np.array([[1.0, 2.0], [bad, 0.0]])
    new = np.empty(2, np.int64)
    assert point_cell_keys(xy, 0.01) is None
    assert not _old_point_keys(xy, 0.01, new)


def _old_scaled(x, y, z, scales, offsets):  # laspy: the integer as float64, times, plus
    return np.stack([a.astype(np.float64) * scales[k] + offsets[k]
                     for k, a in enumerate((x, y, z))], axis=1)


@pytest.mark.parametrize("dtype", [np.int32, np.uint32, np.int64])
def test_las_scaling_is_laspy_bit_for_bit(dtype):
    rng = np.random.default_rng(3)
    info = np.iinfo(np.int32 if dtype != np.uint32 else np.uint32)
    n = 50000
    x, y, z = (rng.integers(info.min, info.max, n, endpoint=True).astype(dtype) for _ in "xyz")
    x[:4] = [info.min, info.max, 0, 1]
    for scales, offsets in (([0.01, 0.01, 0.001], [5e5, 5.4e6, 100.0]),
                            ([1e-7, 3e-3, 0.25], [-4e12, 1e15, -7.77]),
                            ([0.001, 0.001, 0.001], [0.0, -0.0, 0.0])):
        scales, offsets = np.array(scales), np.array(offsets)
        xyz = scaled_integers(x, y, z, scales, offsets)
        assert np.array_equal(xyz, _old_scaled(x, y, z, scales, offsets))
        bits = rng.integers(0, 4, n).astype(np.uint8)
        c = {"X": x, "Y": y, "Z": z, "point_source_id": np.arange(n).astype(np.uint16),
             "gps_time": rng.uniform(0, 1, n), "bits": bits}
        sel, _, _ = selected_points(c, 1, scales, offsets)
        assert np.array_equal(sel, xyz[(bits & 2) != 0])
        for q in (xyz, xyz[4:] / 7e3, xyz + np.array([scales[0] / 3, 0, 0])):
            old = _old_stored_integers(q, scales, offsets)
            assert _same(stored_integers(q, scales, offsets), old)
    small = np.stack([x, y, z], 1)[:, :] // 1024
    xyz = _old_scaled(*small.T, np.full(3, 0.01), np.array([5e5, 5.4e6, 100.0]))
    assert np.array_equal(stored_integers(xyz, np.full(3, 0.01), [5e5, 5.4e6, 100.0]), small)


def _same(a, b):
    return a is None and b is None or a is not None and b is not None and np.array_equal(a, b)


@njit
def _old_stored_kernel(xyz, scales, offsets, stored):  # ingest/held.py before the merge
    for i in range(xyz.shape[0]):
        for a in range(3):
            r = np.rint((xyz[i, a] - offsets[a]) / scales[a])
            if not abs(r) < 2147483648.0:
                return False
            s = np.int32(r)
            if np.float64(s) * scales[a] + offsets[a] != xyz[i, a]:
                return False
            stored[i, a] = s
    return True


def _old_stored_integers(xyz, scales, offsets):
    stored = np.empty(xyz.shape, np.int32)
    xyz = np.ascontiguousarray(xyz)
    return stored if _old_stored_kernel(xyz, scales, offsets, stored) else None


@njit
def _new_unpacked(keys):
    out = np.empty((keys.size, 2), np.int64)
    for k in range(keys.size):
        out[k, 0], out[k, 1] = key_cell(keys[k])
    return out


def test_keys_unpack_as_the_old_expressions():
    rng = np.random.default_rng(5)
    ij = rng.integers(-2**31, 2**31, (20000, 2))
    ij[:6] = [[0, 0], [-1, -1], [-2**31, 2**31 - 1], [2**31 - 1, -2**31], [5, -7], [-7, 5]]
    keys = cell_keys_of(ij[:, 0], ij[:, 1])
    j = keys & 0xFFFFFFFF
    old = np.stack([keys >> 32, np.where(j >= 2**31, j - 2**32, j)], axis=1)  # cell_moments
    assert np.array_equal(old, ij)
    assert np.array_equal(key_indices(keys), old)
    assert np.array_equal(_new_unpacked(keys), old)  # moments_kernel._unpacked
    thin_j = ((keys & 0xFFFFFFFF) ^ 0x80000000) - 0x80000000  # strips/thin.py spread_rank
    assert np.array_equal(thin_j, old[:, 1])


@pytest.mark.parametrize("block", [1, 3])
def test_spread_rank_as_before(block):
    from calidar.strips import thin

    ij = np.random.default_rng(6).integers(-70000, 70000, (20000, 2))
    cells = cell_keys_of(ij[:, 0], ij[:, 1])
    i = (cells >> 32) // block  # spread_rank before the merge
    j = (((cells & 0xFFFFFFFF) ^ 0x80000000) - 0x80000000) // block
    i, j = i & 0xFFFF, j & 0xFFFF
    rev = thin._reverse16()
    code = (thin._spread16(rev[i]) << np.uint64(1)) | thin._spread16(rev[j])
    assert np.array_equal(thin.spread_rank(cells, block), code.astype(np.float64) / 2.0**32)
