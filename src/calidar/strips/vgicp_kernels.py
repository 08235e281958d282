"""numba kernels of VGICP's pair matching: the xy-grid bookkeeping and the neighbourhoods' moments.

Each kernel computes exactly what the numpy expression it replaces computed (the same IEEE
operations in the same order: ``floor((x − lo) / cell)`` for a cell index, minima and maxima, sums
in the neighbours' order; the balls' averaging rows are
:meth:`calidar.strips.vgicp_knn.GridKnn.ball_rows`), in one pass over the points instead of one
numpy pass (and one temporary array) per operation — so a pair's correspondences are bit for bit the
same (docs/validation.md, "VGICP pairs … (issue 32, 27 Nov, seventh session)"). The lookup tables
hold one byte per cell of the grid; :class:`calidar.strips.vgicp_planes.Grid` falls back to sorting
beyond ``Grid.MAX_TABLE`` cells, and so do the callers of these kernels.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from calidar.cells import cell_index


@njit(cache=True, nogil=True)
def xy_bounds(points):  # pragma: no cover - numba
    """(lower, upper) (2,) of the points' (N, ≥ 2) x and y, as ``xy.min(axis=0)`` and
    ``xy.max(axis=0)`` (N ≥ 1)."""
    lo, hi = points[0, :2].copy(), points[0, :2].copy()
    for i in range(1, points.shape[0]):
        for c in range(2):
            v = points[i, c]
            if v < lo[c]:
                lo[c] = v
            if v > hi[c]:
                hi[c] = v
    return lo, hi


@njit(cache=True, nogil=True, inline="always")
def _cell(x, y, lo0, lo1, cell):  # pragma: no cover - numba
    """:func:`calidar.cells.cell_index` from the grid's corner (lo0, lo1)."""
    return cell_index(x - lo0, cell), cell_index(y - lo1, cell)


@njit(cache=True, nogil=True)
def cell_keys(points, lo, cell, ncol):  # pragma: no cover - numba
    """Grid keys i·ncol + j of the points' (N, ≥ 2) xy cells (``Grid.keys(Grid.ij(xy))``): not
    :func:`calidar.cells.cell_key`, for the cells index a byte table of ``Grid.MAX_TABLE``."""
    keys = np.empty(points.shape[0], np.int64)
    for p in range(points.shape[0]):
        i, j = _cell(points[p, 0], points[p, 1], lo[0], lo[1], cell)
        keys[p] = i * ncol + j
    return keys


@njit(cache=True, nogil=True)
def common_cells(keys_a, keys_b, size):  # pragma: no cover - numba
    """Which of a's and b's cell keys lie in cells occupied by both, and how many such cells."""
    table = np.zeros(size, np.uint8)
    for k in keys_a:
        table[k] = 1
    common = 0
    for k in keys_b:
        if table[k] == 1:
            common += 1
        table[k] |= 2
    in_a = np.empty(keys_a.size, np.bool_)
    for p in range(keys_a.size):
        in_a[p] = table[keys_a[p]] == 3
    in_b = np.empty(keys_b.size, np.bool_)
    for p in range(keys_b.size):
        in_b[p] = table[keys_b[p]] == 3
    return in_a, in_b, common


@njit(cache=True, nogil=True)
def near_cells(keys, at, lo, cell, shape):  # pragma: no cover - numba
    """Ascending indices of the ``keys`` in the cells holding ``at`` (M, ≥ 2) or next to them (the
    3 × 3 block, inside the grid of ``shape``)."""
    table = np.zeros(shape[0] * shape[1], np.uint8)
    for m in range(at.shape[0]):
        i, j = _cell(at[m, 0], at[m, 1], lo[0], lo[1], cell)
        for di in range(-1, 2):
            for dj in range(-1, 2):
                ii, jj = i + di, j + dj
                if 0 <= ii < shape[0] and 0 <= jj < shape[1]:
                    table[ii * shape[1] + jj] = 1
    out = np.empty(keys.size, np.int64)
    n = 0
    for p in range(keys.size):
        if table[keys[p]]:
            out[n] = p
            n += 1
    return out[:n]


@njit(cache=True, nogil=True)
def first_in_cells(keys, size):  # pragma: no cover - numba
    """Ascending index of the first of ``keys`` in each occupied cell (``Grid.first``)."""
    first = np.full(size, keys.size, np.int64)
    n = 0
    for p in range(keys.size):
        if first[keys[p]] == keys.size:
            first[keys[p]] = p
            n += 1
    out = np.empty(n, np.int64)
    n = 0
    for p in range(keys.size):
        if first[keys[p]] == p:
            out[n] = p
            n += 1
    return out


@njit(cache=True, nogil=True)
def neighbourhood_centroids(points, idx):  # pragma: no cover - numba
    """Centroid (M, 3) of each row's points ``idx`` (M, k), as ``nb.mean(axis=1)`` sums them: over
    the k points in order."""
    m_rows, k = idx.shape
    centroid = np.empty((m_rows, 3))
    for m in range(m_rows):
        for c in range(3):
            s = points[idx[m, 0], c]
            for j in range(1, k):
                s += points[idx[m, j], c]
            centroid[m, c] = s / k
    return centroid


@njit(cache=True, nogil=True)
def neighbourhood_moments(points, idx):  # pragma: no cover - numba
    """Centroid (M, 3) (:func:`neighbourhood_centroids`) and scatter matrix Σ(p − centroid)(p −
    centroid)ᵀ (M, 3, 3) of each row's points ``idx`` (M, k), as ``np.einsum("mki,mkj->mij", nb −
    centroid, nb − centroid)`` sums it: over the k points in order."""
    m_rows, k = idx.shape
    centroid = neighbourhood_centroids(points, idx)
    scatter = np.empty((m_rows, 3, 3))
    d = np.empty((k, 3))
    for m in range(m_rows):
        for j in range(k):
            for c in range(3):
                d[j, c] = points[idx[m, j], c] - centroid[m, c]
        for a in range(3):
            for b in range(3):
                s = 0.0
                for j in range(k):
                    s += d[j, a] * d[j, b]
                scatter[m, a, b] = s
    return centroid, scatter


@njit(cache=True, nogil=True)
def xy_scatter(points):  # pragma: no cover - numba
    """(sxx, sxy, syy) of the points' (N ≥ 1, ≥ 2) xy about their mean, over N: the covariance
    matrix :func:`calidar.strips.vgicp.overlap_width` takes, in two passes (sums in point order, not
    numpy's: equal to its last bits only)."""
    n = points.shape[0]
    mx, my = 0.0, 0.0
    for p in range(n):
        mx += points[p, 0]
        my += points[p, 1]
    mx, my = mx / n, my / n
    sxx, sxy, syy = 0.0, 0.0, 0.0
    for p in range(n):
        dx, dy = points[p, 0] - mx, points[p, 1] - my
        sxx += dx * dx
        sxy += dx * dy
        syy += dy * dy
    return sxx / n, sxy / n, syy / n


@njit(cache=True, nogil=True)
def rows_mean(points, idx):  # pragma: no cover - numba
    """Mean (3,) of the rows ``idx`` (M ≥ 1,) of the points (N, 3), as ``np.take(points, idx,
    axis=0).mean(axis=0)`` sums them: from 0, adding the rows in order (numpy's reduction over a
    C-ordered array's outer axis is not pairwise), then / M."""
    total = np.zeros(3)
    for r in range(idx.size):
        for c in range(3):
            total[c] += points[idx[r], c]
    return total / idx.size


@njit(cache=True, nogil=True)
def gather_centred(points, idx, origin):  # pragma: no cover - numba
    """The rows ``idx`` of the points (N, 3) less ``origin`` (3,): ``np.take(points, idx, axis=0) -
    origin`` in one pass."""
    out = np.empty((idx.size, 3))
    for r in range(idx.size):
        for c in range(3):
            out[r, c] = points[idx[r], c] - origin[c]
    return out
