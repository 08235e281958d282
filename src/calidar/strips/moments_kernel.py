"""Per-cell point moments of a chunk in one numba kernel (:func:`dense_moments`): the cells
(``floor(x / cell_m)``, ``floor(y / cell_m)``), their grouping over a dense table, the keys in
ascending order (a walk over the table, no sort) and the two passes of :func:`moments` (the mean,
then the centred products about it), without the N-sized temporaries of doing it in numpy
(the floored coordinates, the cell of each point, its group renumbered into key order).

The arithmetic is that of :meth:`calidar.strips.cell_moments.CellMoments.of_points` operation
for operation, points summed in their order within each cell, so the moments are bit for bit
the same (``tests/unit/strips/test_moments_kernel.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit


def dense_moments(points: np.ndarray, cell_m: float):
    """(keys ascending, count, mean (x, y from the cell centre, z), scatter (PRODUCTS order)) of
    points (N, 3) float64 C-contiguous on cells of ``cell_m``, or None when their cells' bounding
    box is too large for a dense table (> 4 N + 65 536 cells: the caller sorts instead)."""
    keys, count, mean, scatter, dense = _dense_moments(points, float(cell_m))
    return (keys, count, mean, scatter) if dense else None


@njit(cache=True, nogil=True)
def _dense_moments(p, cell_m):  # pragma: no cover - numba
    n = p.shape[0]
    ij = np.empty((n, 2), np.int64)
    lo0, hi0, lo1, hi1 = 0, 0, 0, 0
    for k in range(n):
        i, j = np.int64(np.floor(p[k, 0] / cell_m)), np.int64(np.floor(p[k, 1] / cell_m))
        ij[k, 0], ij[k, 1] = i, j
        if k == 0:
            lo0, hi0, lo1, hi1 = i, i, j, j
        else:
            lo0, hi0, lo1, hi1 = min(lo0, i), max(hi0, i), min(lo1, j), max(hi1, j)
    width = hi1 - lo1 + 1
    if n == 0 or (hi0 - lo0 + 1) * width > 4 * n + 65536:  # nothing, or not a dense table
        e = np.zeros(0, np.int64)
        return e, e, np.zeros((0, 3)), np.zeros((0, 6)), n == 0
    slot = np.full((hi0 - lo0 + 1) * width, -1, np.int64)
    inv, first, groups = np.empty(n, np.int64), np.empty(n, np.int64), 0
    for k in range(n):  # groups in order of first appearance (as calidar.cells.group_cells)
        s = (ij[k, 0] - lo0) * width + ij[k, 1] - lo1
        if slot[s] < 0:
            slot[s] = groups
            first[groups] = k
            groups += 1
        inv[k] = slot[s]
    # the groups in key order: a walk over the table, i ascending, then j as (j & 0xFFFFFFFF) orders it
    # (j >= 0 ascending, then j < 0 ascending), so no sort
    keys, rank, centres, r = np.empty(groups, np.int64), np.empty(groups, np.int64), np.empty((groups, 2)), 0
    j_split = min(max(-lo1, 0), width)  # table columns of j < 0 come first in the table, last in key order
    for a in range(hi0 - lo0 + 1):
        for b in range(width):
            col = b + j_split if b + j_split < width else b + j_split - width
            g = slot[a * width + col]
            if g >= 0:
                i, j = lo0 + a, lo1 + col
                keys[r], rank[g] = (i << 32) + (j & 0xFFFFFFFF), r
                centres[r, 0], centres[r, 1] = (i + 0.5) * cell_m, (j + 0.5) * cell_m
                r += 1
    for k in range(n):  # each point's group in key order
        inv[k] = rank[inv[k]]
    count, mean, scatter = moments(p, inv, centres)
    return keys, count, mean, scatter, True


@njit(cache=True, nogil=True)
def moments(p: np.ndarray, inv: np.ndarray, centres: np.ndarray):  # pragma: no cover - numba
    """Count, mean (x, y from the cell centre ``centres`` (K, 2) m, z) and centred scatter (m², the
    PRODUCTS order of :mod:`calidar.strips.cell_moments`) of points (N, 3) m in groups ``inv``
    (N,) numbered 0..K−1: two passes (the mean, then the products about it), points summed in
    their order within each group."""
    K = centres.shape[0]
    count, mean, scatter = np.zeros(K, np.int64), np.zeros((K, 3)), np.zeros((K, 6))
    for k in range(p.shape[0]):
        g = inv[k]
        count[g] += 1
        mean[g, 0] += p[k, 0] - centres[g, 0]
        mean[g, 1] += p[k, 1] - centres[g, 1]
        mean[g, 2] += p[k, 2]
    for g in range(K):
        for a in range(3):
            mean[g, a] /= count[g]
    for k in range(p.shape[0]):
        g = inv[k]
        dx, dy, dz = p[k, 0] - centres[g, 0] - mean[g, 0], p[k, 1] - centres[g, 1] - mean[g, 1], p[k, 2] - mean[g, 2]
        scatter[g, 0] += dx * dx
        scatter[g, 1] += dx * dy
        scatter[g, 2] += dx * dz
        scatter[g, 3] += dy * dy
        scatter[g, 4] += dy * dz
        scatter[g, 5] += dz * dz
    return count, mean, scatter


def dense_cell_counts(keys: np.ndarray):
    """(distinct keys ascending, how many of ``keys`` in each) of cell keys (int64, as
    :func:`calidar.strips.overlap.cell_keys`) by a dense table over their cells' bounding box, or
    None when it is too large (> 4 N + 65 536 cells: the caller sorts)."""
    cells, counts, dense = _dense_counts(np.ascontiguousarray(keys, np.int64))
    return (cells, counts) if dense else None


@njit(cache=True, nogil=True)
def _dense_counts(keys):  # pragma: no cover - numba
    n = keys.size
    lo0, hi0, lo1, hi1 = 0, 0, 0, 0
    for k in range(n):
        i, j = keys[k] >> 32, keys[k] & 0xFFFFFFFF
        j = j - 4294967296 if j >= 2147483648 else j
        if k == 0:
            lo0, hi0, lo1, hi1 = i, i, j, j
        else:
            lo0, hi0, lo1, hi1 = min(lo0, i), max(hi0, i), min(lo1, j), max(hi1, j)
    width = hi1 - lo1 + 1
    if n == 0 or (hi0 - lo0 + 1) * width > 4 * n + 65536:
        e = np.zeros(0, np.int64)
        return e, e, n == 0
    table = np.zeros((hi0 - lo0 + 1) * width, np.int64)
    for k in range(n):
        i, j = keys[k] >> 32, keys[k] & 0xFFFFFFFF
        j = j - 4294967296 if j >= 2147483648 else j
        table[(i - lo0) * width + j - lo1] += 1
    held = 0
    for s in range(table.size):
        held += table[s] > 0
    cells, counts, r = np.empty(held, np.int64), np.empty(held, np.int64), 0
    j_split = min(max(-lo1, 0), width)  # key order: i ascending, then j >= 0, then j < 0
    for a in range(hi0 - lo0 + 1):
        for b in range(width):
            col = b + j_split if b + j_split < width else b + j_split - width
            c = table[a * width + col]
            if c > 0:
                cells[r], counts[r] = ((lo0 + a) << 32) + ((lo1 + col) & 0xFFFFFFFF), c
                r += 1
    return cells, counts, True


def dense_row_ids(ij: np.ndarray):
    """(id of each row, number of distinct rows) of integer rows (K, 2), ids in the lexicographic
    order of the rows — ``np.unique(ij, axis=0, return_inverse=True)``'s — by a dense table over
    their bounding box, or None when it is too large (> 4 K + 65 536 cells)."""
    inv, n, dense = _dense_row_ids(np.ascontiguousarray(ij, np.int64))
    return (inv, n) if dense else None


@njit(cache=True, nogil=True)
def _dense_row_ids(ij):  # pragma: no cover - numba
    n = ij.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), 0, True
    lo0, hi0, lo1, hi1 = ij[0, 0], ij[0, 0], ij[0, 1], ij[0, 1]
    for k in range(n):
        lo0, hi0 = min(lo0, ij[k, 0]), max(hi0, ij[k, 0])
        lo1, hi1 = min(lo1, ij[k, 1]), max(hi1, ij[k, 1])
    width = hi1 - lo1 + 1
    if (hi0 - lo0 + 1) * width > 4 * n + 65536:
        return np.zeros(0, np.int64), 0, False
    table = np.full((hi0 - lo0 + 1) * width, -1, np.int64)
    for k in range(n):
        table[(ij[k, 0] - lo0) * width + ij[k, 1] - lo1] = 0
    ids = 0
    for s in range(table.size):  # the table's order is the rows' lexicographic order
        if table[s] == 0:
            table[s] = ids
            ids += 1
    inv = np.empty(n, np.int64)
    for k in range(n):
        inv[k] = table[(ij[k, 0] - lo0) * width + ij[k, 1] - lo1]
    return inv, ids, True
