"""Per-cell point moments of a chunk in one numba kernel (:func:`dense_moments`): the cells
(``floor(x / cell_m)``, ``floor(y / cell_m)``), their grouping over a dense table and the keys
in ascending order (a walk over the table, no sort) — both :mod:`calidar.cells`', the one
implementation of the dense table — and the two passes of :func:`moments` (the mean,
then the centred products about it), without the N-sized temporaries of doing it in numpy
(the floored coordinates, the cell of each point, its group renumbered into key order).

The arithmetic is that of :meth:`calidar.strips.cell_moments.CellMoments.of_points` operation
for operation, points summed in their order within each cell, so the moments are bit for bit
the same (``tests/unit/strips/test_moments_kernel.py``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from calidar.cells import (cell_box, cell_index, cell_key, dense_fits, first_appearance, key_cell,
                           key_order)


def dense_moments(points: np.ndarray, cell_m: float):
    """(keys ascending, count, mean (x, y from the cell centre, z), scatter (PRODUCTS order)) of
    points (N, 3) float64 C-contiguous on cells of ``cell_m``, or None when their cells' bounding
    box is too large for a dense table (> 4 N + 65 536 cells: the caller sorts instead)."""
    keys, count, mean, scatter, dense = _dense_moments(points, float(cell_m))
    return (keys, count, mean, scatter) if dense else None


@njit(cache=True, nogil=True)
def _dense_moments(p, cell_m):  # pragma: no cover - numba
    n = p.shape[0]
    e = np.zeros(0, np.int64)
    if n == 0:
        return e, e, np.zeros((0, 3)), np.zeros((0, 6)), True
    ij = np.empty((n, 2), np.int64)
    for k in range(n):
        ij[k, 0] = cell_index(p[k, 0], cell_m)
        ij[k, 1] = cell_index(p[k, 1], cell_m)
    box = cell_box(ij)
    if not dense_fits(n, box):
        return e, e, np.zeros((0, 3)), np.zeros((0, 6)), False
    slot, inv, _ = first_appearance(ij, box)  # groups in order of first appearance (as group_cells)
    order = key_order(slot >= 0, box)  # the groups in key order, no sort
    width = box[3] - box[2] + 1
    keys, rank = np.empty(order.size, np.int64), np.empty(order.size, np.int64)
    centres = np.empty((order.size, 2))
    for r in range(order.size):
        i, j = box[0] + order[r] // width, box[2] + order[r] % width
        keys[r], rank[slot[order[r]]] = cell_key(i, j), r
        centres[r, 0], centres[r, 1] = (i + 0.5) * cell_m, (j + 0.5) * cell_m
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
        dx = p[k, 0] - centres[g, 0] - mean[g, 0]
        dy = p[k, 1] - centres[g, 1] - mean[g, 1]
        dz = p[k, 2] - mean[g, 2]
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
def _key_box(keys):  # pragma: no cover - numba
    """(lo0, hi0, lo1, hi1): the box of the cells of ``keys`` (at least one), from the keys
    themselves (no (N, 2) cells: twice as fast as :func:`calidar.cells.cell_box`)."""
    i, j = key_cell(keys[0])
    lo0, hi0, lo1, hi1 = i, i, j, j
    for k in range(1, keys.size):
        i, j = key_cell(keys[k])
        lo0, hi0, lo1, hi1 = min(lo0, i), max(hi0, i), min(lo1, j), max(hi1, j)
    return lo0, hi0, lo1, hi1


@njit(cache=True, nogil=True)
def _dense_counts(keys):  # pragma: no cover - numba
    n = keys.size
    e = np.zeros(0, np.int64)
    if n == 0:
        return e, e, True
    box = _key_box(keys)
    lo0, hi0, lo1, hi1 = box
    if not dense_fits(n, box):
        return e, e, False
    width = hi1 - lo1 + 1
    table = np.zeros((hi0 - lo0 + 1) * width, np.int64)
    for k in range(n):
        i, j = key_cell(keys[k])
        table[(i - lo0) * width + j - lo1] += 1
    order = key_order(table > 0, box)
    cells, counts = np.empty(order.size, np.int64), np.empty(order.size, np.int64)
    for r in range(order.size):
        i, j = lo0 + order[r] // width, lo1 + order[r] % width
        cells[r], counts[r] = cell_key(i, j), table[order[r]]
    return cells, counts, True


def stable_key_order(keys: np.ndarray) -> np.ndarray:
    """``np.argsort(keys, kind="stable")`` of int64 cell keys (as
    :func:`calidar.strips.overlap.cell_keys`): a counting sort over the dense table of their cells
    (a stable order is unique: the same indices), or the argsort when the table is too large
    (> 4 N + 65 536 cells). 5–10× fewer CPU seconds than the argsort (the tie planes' patches)."""
    keys = np.ascontiguousarray(keys, np.int64)
    order, dense = _dense_order(keys)
    return order if dense else np.argsort(keys, kind="stable")


@njit(cache=True, nogil=True)
def _dense_order(keys):  # pragma: no cover - numba
    n = keys.size
    if n == 0:
        return np.zeros(0, np.int64), True
    box = _key_box(keys)
    lo0, hi0, lo1, hi1 = box
    if not dense_fits(n, box):
        return np.zeros(0, np.int64), False
    width = hi1 - lo1 + 1
    slot = np.empty(n, np.int64)
    table = np.zeros((hi0 - lo0 + 1) * width, np.int64)
    for k in range(n):
        i, j = key_cell(keys[k])
        slot[k] = (i - lo0) * width + j - lo1
        table[slot[k]] += 1
    at = 0  # each occupied slot's first position, slots in key order
    for s in key_order(table > 0, box):
        at, table[s] = at + table[s], at
    order = np.empty(n, np.int64)
    for k in range(n):  # points in their order within each slot: stable
        order[table[slot[k]]] = k
        table[slot[k]] += 1
    return order, True


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
    box = cell_box(ij)
    if not dense_fits(n, box):
        return np.zeros(0, np.int64), 0, False
    lo0, hi0, lo1, hi1 = box
    width = hi1 - lo1 + 1
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


def point_cell_keys(points: np.ndarray, cell_m: float) -> np.ndarray | None:
    """:func:`calidar.strips.overlap.cell_keys` of points (N, ≥ 2) without an origin in one pass:
    ``(floor(x / cell_m) << 32) + (floor(y / cell_m) & 0xFFFFFFFF)`` per point, the same
    operations as the numpy there (no (N, 2) temporaries); None when a coordinate is not finite
    (numpy's cast of NaN is the caller's)."""
    if points.ndim != 2 or points.shape[1] < 2:
        return None
    out = np.empty(points.shape[0], np.int64)
    return out if _point_cell_keys(points, cell_m, out) else None


@njit(cache=True, nogil=True)
def _point_cell_keys(p, cell_m, out):  # pragma: no cover - numba
    for k in range(p.shape[0]):
        if not (np.isfinite(p[k, 0] / cell_m) and np.isfinite(p[k, 1] / cell_m)):
            return False
        out[k] = cell_key(cell_index(p[k, 0], cell_m), cell_index(p[k, 1], cell_m))
    return True
