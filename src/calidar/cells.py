"""Points grouped by the grid cell holding them, in O(N): a dense table over the cells' bounding
box when it is small against the points (≤ 4 N + 65 536 cells, as for a chunk of a strip), else a
sort. Used for the per-cell moments of the overlap quality and the per-tile transforms of
:mod:`calidar.crs`."""

from __future__ import annotations

import numpy as np
from numba import njit


def group_cells(ij: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(group of each point (N,), first point of each group (K,)) for integer cell indices ij
    (N, 2); groups in order of first appearance (dense table) or of the cells (sort)."""
    ij = np.ascontiguousarray(ij, np.int64)
    inv, first, dense = _dense_groups(ij)
    if dense:
        return inv, first
    _, first, inv = np.unique(ij, axis=0, return_index=True, return_inverse=True)
    return inv.ravel(), first


@njit(cache=True, nogil=True)
def _dense_groups(ij: np.ndarray):  # pragma: no cover - numba
    """:func:`group_cells` by a dense table, and whether the cells fit one (else nothing
    grouped)."""
    n = ij.shape[0]
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), True
    lo0, hi0, lo1, hi1 = ij[0, 0], ij[0, 0], ij[0, 1], ij[0, 1]
    for k in range(n):
        lo0, hi0 = min(lo0, ij[k, 0]), max(hi0, ij[k, 0])
        lo1, hi1 = min(lo1, ij[k, 1]), max(hi1, ij[k, 1])
    width = hi1 - lo1 + 1
    if (hi0 - lo0 + 1) * width > 4 * n + 65536:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), False
    slot = np.full((hi0 - lo0 + 1) * width, -1, np.int64)
    inv, first, groups = np.empty(n, np.int64), np.empty(n, np.int64), 0
    for k in range(n):
        s = (ij[k, 0] - lo0) * width + ij[k, 1] - lo1
        if slot[s] < 0:
            slot[s] = groups
            first[groups] = k
            groups += 1
        inv[k] = slot[s]
    return inv, first[:groups], True
