"""Exact k nearest neighbours on an xy grid: the full-density searches of VGICP's correspondences.

VGICP's rows look up b's k nearest points about ~2 000 candidates and a's balls about as many
centroids, among the ~10⁵ points of each side's overlap. A small_gicp ``KdTree`` built for those
few queries spends most of its time building (docs/validation.md, issue 32, seventh session);
here the points are bucketed once by xy cell (a counting sort, O(N)) and each query visits the
rings of cells about its own until the nearest unseen cell lies farther than its k-th neighbour,
so the search is exact, as small_gicp's (ε = 0); within a ring, a cell lying wholly beyond the
k-th neighbour found so far is passed over (none of its points could enter), and the points are
held in cell order (a cell's points in consecutive memory). The squared distances are computed as
small_gicp 1.0's ``(p − q).squaredNorm()`` on 4-vectors sums them, (dx² + dz²) + dy², and the
neighbours come in ascending distance (equal distances: first visited first, as a KdTree's
leaf order does — a different order only between points exactly as far), so the rows are bit
for bit the KdTree's (tests/unit/strips/test_vgicp_knn.py, and the pairs of the 8.75 M survey).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from calidar.strips.vgicp_kernels import cell_keys, xy_bounds

#: points per cell on average (≈ k: few cells to visit, few points per cell to test)
POINTS_PER_CELL = 8.0


class GridKnn:
    """The points (N, 3) m bucketed by xy cell, with small_gicp ``KdTree``'s
    ``batch_knn_search``."""

    def __init__(self, points: np.ndarray):
        self.points = np.ascontiguousarray(points, dtype=np.float64)
        lo, hi = xy_bounds(self.points)
        extent = np.maximum(hi - lo, 1e-9)
        cell = float(np.sqrt(extent[0] * extent[1] * POINTS_PER_CELL / len(self.points)))
        cell = max(cell, float(extent.max()) / 4096.0, 1e-9)  # at most 4096 cells a side
        self.lo, self.cell = lo, cell
        self.shape = (np.floor(extent / cell).astype(np.int64) + 1)
        keys = cell_keys(self.points, lo, cell, self.shape[1])
        self.order, self.start, self.in_cells = _bucket(keys, int(self.shape[0] * self.shape[1]),
                                                        self.points)

    def batch_knn_search(self, queries: np.ndarray, k: int, num_threads: int = 1):
        """(indices (M, k) int64, squared distances (M, k)) of each query's k nearest points,
        ascending (k ≤ N; ``num_threads`` is accepted for the KdTree's signature)."""
        if not 1 <= k <= len(self.points):
            raise ValueError(f"k must be 1 … {len(self.points)} (the points), got {k}")
        queries = np.ascontiguousarray(queries, dtype=np.float64)
        return _knn(self.in_cells, self.order, self.start, self.lo, self.cell, self.shape,
                    queries, k)

    def ball_rows(self, queries: np.ndarray, k_max: int, radius2: np.ndarray):
        """Each query's averaging row over its points within √``radius2`` (M,) m — at most the
        k_max nearest, and at least the nearest —, each weighing 1 / count, in ascending distance:
        CSR (weights, columns, indptr) and the counts. The rows of a k_max search filtered by the
        ball, found by a search that takes no point beyond it (the ball's points lead the k_max
        nearest, in the same order; tests/unit/strips/test_vgicp_knn.py)."""
        if not 1 <= k_max <= len(self.points):
            raise ValueError(f"k_max must be 1 … {len(self.points)} (the points), got {k_max}")
        queries = np.ascontiguousarray(queries, dtype=np.float64)
        return _balls(self.in_cells, self.order, self.start, self.lo, self.cell, self.shape,
                      queries, k_max, np.ascontiguousarray(radius2, dtype=np.float64))


@njit(cache=True, nogil=True)
def _bucket(keys, size, points):  # pragma: no cover - numba
    """Counting sort of the points (N, 3) by cell key: (point order, each cell's start in it, size
    + 1 entries, the points in that order)."""
    start = np.zeros(size + 1, np.int64)
    for key in keys:
        start[key + 1] += 1
    for c in range(size):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(keys.size, np.int64)
    for p in range(keys.size):
        order[fill[keys[p]]] = p
        fill[keys[p]] += 1
    in_cells = np.empty((keys.size, 3))
    for s in range(keys.size):
        for c in range(3):
            in_cells[s, c] = points[order[s], c]
    return order, start, in_cells


@njit(cache=True, nogil=True, inline="always")
def _visit(in_cells, order, start, c, q, best_i, best_d, n, k, limit2):  # pragma: no cover - numba
    """Offer cell c's points (``in_cells``: the points in cell order) no farther than √``limit2`` to
    the query's sorted k best (n of them so far); the new n."""
    for s in range(start[c], start[c + 1]):
        dx, dy, dz = in_cells[s, 0] - q[0], in_cells[s, 1] - q[1], in_cells[s, 2] - q[2]
        d = (dx * dx + dz * dz) + dy * dy  # small_gicp's squaredNorm of (dx, dy, dz, 0)
        if (n == k and d >= best_d[k - 1]) or d > limit2:
            continue
        j = n if n < k else k - 1
        while j > 0 and best_d[j - 1] > d:
            best_d[j], best_i[j] = best_d[j - 1], best_i[j - 1]
            j -= 1
        best_d[j], best_i[j] = d, order[s]
        n = min(n + 1, k)
    return n


@njit(cache=True, nogil=True, inline="always")
def _beyond(best_d, n, k, limit2, fx, fy, i, j, cell):  # pragma: no cover - numba
    """Whether cell (i, j) lies wholly beyond what the query may still take — its k-th best
    (squared distance, m²) once k are found, else ``limit2`` (m²; inf: anything) —, the query at
    (fx, fy) in cells: its nearest xy point, less a margin far above the rounding (as the rings'
    bound), is farther."""
    worst = best_d[k - 1] if n == k else limit2
    gx = i - fx if fx < i else (fx - (i + 1) if fx > i + 1 else 0.0)
    gy = j - fy if fy < j else (fy - (j + 1) if fy > j + 1 else 0.0)
    gap = np.sqrt(gx * gx + gy * gy) * cell - 1e-7 * cell
    return gap > 0 and gap * gap > worst


@njit(cache=True, nogil=True)
def _search(in_cells, order, start, lo, cell, shape, q, k, limit2, best_i, best_d
            ):  # pragma: no cover - numba
    """The query q's k nearest points no farther than √``limit2`` (m; inf: the k nearest) into
    ``best_i``, ``best_d`` (squared, m²), ascending; how many were found."""
    ni, nj = shape[0], shape[1]
    fx, fy = (q[0] - lo[0]) / cell, (q[1] - lo[1]) / cell
    ci, cj = np.int64(np.floor(fx)), np.int64(np.floor(fy))
    # distance (m) from the query to the edge of its own cell: ring r's cells lie ≥ (r − 1) cells
    # + this away
    edge = min(fx - ci, ci + 1 - fx, fy - cj, cj + 1 - fy) * cell
    r_max = max(ci + 1, ni - ci, cj + 1, nj - cj)  # beyond it no cell of the grid
    r_min = max(0, -ci, ci - (ni - 1), -cj, cj - (nj - 1))  # nearer rings: none either
    n = 0
    for r in range(r_min, r_max + 1):
        if r > 0 and (n == k or limit2 < np.inf):  # (less a margin far above the rounding)
            bound = (r - 1) * cell + edge - 1e-7 * cell
            if bound > 0 and bound * bound > (best_d[k - 1] if n == k else limit2):
                break
        for i in range(max(ci - r, 0), min(ci + r, ni - 1) + 1):
            if i == ci - r or i == ci + r:  # a whole row of the ring
                j_lo, j_hi, step = max(cj - r, 0), min(cj + r, nj - 1), 1
            else:  # its two ends
                j_lo, j_hi, step = cj - r, cj + r, 2 * r
            for j in range(j_lo, j_hi + 1, step):
                if 0 <= j < nj and not _beyond(best_d, n, k, limit2, fx, fy, i, j, cell):
                    n = _visit(in_cells, order, start, i * nj + j, q, best_i, best_d, n, k,
                               limit2)
    return n


@njit(cache=True, nogil=True)
def _knn(in_cells, order, start, lo, cell, shape, queries, k):  # pragma: no cover - numba
    m_rows = queries.shape[0]
    idx = np.empty((m_rows, k), np.int64)
    d2 = np.empty((m_rows, k), np.float64)
    for m in range(m_rows):
        _search(in_cells, order, start, lo, cell, shape, queries[m], k, np.inf, idx[m], d2[m])
    return idx, d2


@njit(cache=True, nogil=True)
def _balls(in_cells, order, start, lo, cell, shape, queries, k_max, radius2
           ):  # pragma: no cover - numba
    """CSR (weights, columns, indptr) and counts of each query's ball rows (see
    :meth:`GridKnn.ball_rows`)."""
    m_rows = queries.shape[0]
    idx = np.empty((m_rows, k_max), np.int64)
    d2 = np.empty(k_max, np.float64)
    count = np.zeros(m_rows, np.int64)
    indptr = np.zeros(m_rows + 1, np.int64)
    for m in range(m_rows):
        n = _search(in_cells, order, start, lo, cell, shape, queries[m], k_max, radius2[m],
                    idx[m], d2)
        if n == 0:  # none in the ball: the nearest
            n = _search(in_cells, order, start, lo, cell, shape, queries[m], 1, np.inf, idx[m],
                        d2)
        count[m] = n
        indptr[m + 1] = indptr[m] + n
    weights = np.empty(indptr[m_rows], np.float64)
    columns = np.empty(indptr[m_rows], np.int64)
    for m in range(m_rows):
        w = 1.0 / count[m]
        for j in range(count[m]):
            weights[indptr[m] + j] = w
            columns[indptr[m] + j] = idx[m, j]
    return weights, columns, indptr, count
