"""Grid cells of points and points grouped by the grid cell holding them.

The one implementation of a point's cell and of a cell's key: cell (i, j) =
(floor((x − x0) / cell), floor((y − y0) / cell)) (origin (x0, y0); none: no subtraction),
key (i << 32) + (j & 0xFFFFFFFF) — :func:`grid_indices` and :func:`cell_keys_of` in numpy,
:func:`cell_index` and :func:`cell_key` inlined in numba kernels, the same IEEE operations.
Grouping in O(N): a dense table over the cells' bounding box when it is small against the points
(≤ 4 N + 65 536 cells, as for a chunk of a strip), else a sort. Used for the per-cell moments of
the overlap quality and the per-tile transforms of :mod:`calidar.crs`. Also rows of point and cell
arrays taken by position (:func:`take_rows`)."""

from __future__ import annotations

import numpy as np
from numba import njit


def grid_indices(xy: np.ndarray, cell_m: float, origin=None) -> np.ndarray:
    """Cell indices (N, 2) int64 floor((xy − origin) / cell_m) of points (N, ≥ 2) m on cells of
    ``cell_m`` m (origin (2,) m, none: 0, not subtracted) in xy's own precision (the caller casts);
    NaN and ±inf as numpy casts them."""
    xy = np.asarray(xy)[:, :2]
    return np.floor((xy if origin is None else xy - origin) / cell_m).astype(np.int64)


def cell_keys_of(i, j) -> np.ndarray:
    """One int64 key per cell of integer indices i, j: i in the high 32 bits, j (two's
    complement) in the low 32 — ascending keys order cells by i, then j ≥ 0, then j < 0."""
    return (np.asarray(i).astype(np.int64) << 32) + (np.asarray(j).astype(np.int64) & 0xFFFFFFFF)


def key_indices(keys: np.ndarray) -> np.ndarray:
    """Grid indices (K, 2) (i east, j north) of int64 cell keys: the inverse of
    :func:`cell_keys_of`."""
    i = keys >> 32
    j = keys & 0xFFFFFFFF
    j = np.where(j >= 2**31, j - 2**32, j)
    return np.stack([i, j], axis=1)


@njit(cache=True, nogil=True, inline="always")
def cell_index(x, cell):  # pragma: no cover - numba
    """:func:`grid_indices` of one coordinate (x − origin, if any, by the caller): floor(x / cell)
    as int64."""
    return np.int64(np.floor(x / cell))


@njit(cache=True, nogil=True, inline="always")
def cell_key(i, j):  # pragma: no cover - numba
    """:func:`cell_keys_of` of one cell (int64 i, j)."""
    return (i << 32) + (j & 0xFFFFFFFF)


@njit(cache=True, nogil=True, inline="always")
def key_cell(key):  # pragma: no cover - numba
    """:func:`key_indices` of one int64 key: (i, j)."""
    j = key & 0xFFFFFFFF
    return key >> 32, j - 4294967296 if j >= 2147483648 else j


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
    box = cell_box(ij)
    if not dense_fits(n, box):
        return np.zeros(0, np.int64), np.zeros(0, np.int64), False
    _, inv, first = first_appearance(ij, box)
    return inv, first, True


# The dense table, one implementation for every grouping by cells (here and in
# calidar.strips.moments_kernel): the cells' bounding box (lo0, hi0, lo1, hi1), table slot
# (i − lo0) · width + j − lo1, used when it holds ≤ 4 N + 65 536 cells.

@njit(cache=True, nogil=True)
def cell_box(ij: np.ndarray):  # pragma: no cover - numba
    """(lo0, hi0, lo1, hi1): the bounding box of integer cells ij (N ≥ 1, 2)."""
    lo0, hi0, lo1, hi1 = ij[0, 0], ij[0, 0], ij[0, 1], ij[0, 1]
    for k in range(ij.shape[0]):
        lo0, hi0 = min(lo0, ij[k, 0]), max(hi0, ij[k, 0])
        lo1, hi1 = min(lo1, ij[k, 1]), max(hi1, ij[k, 1])
    return lo0, hi0, lo1, hi1


@njit(cache=True, nogil=True)
def dense_fits(n: int, box) -> bool:  # pragma: no cover - numba
    """Whether a dense table over ``box`` is small against ``n`` points (≤ 4 n + 65 536 cells)."""
    lo0, hi0, lo1, hi1 = box
    return (hi0 - lo0 + 1) * (hi1 - lo1 + 1) <= 4 * n + 65536


@njit(cache=True, nogil=True)
def first_appearance(ij: np.ndarray, box):  # pragma: no cover - numba
    """(table: each slot's group or −1, group of each point (N,), first point of each group (K,))
    of cells ij (N, 2) inside ``box``, groups numbered in order of first appearance."""
    lo0, hi0, lo1, hi1 = box
    width = hi1 - lo1 + 1
    slot = np.full((hi0 - lo0 + 1) * width, -1, np.int64)
    inv, first, groups = np.empty(ij.shape[0], np.int64), np.empty(ij.shape[0], np.int64), 0
    for k in range(ij.shape[0]):
        s = (ij[k, 0] - lo0) * width + ij[k, 1] - lo1
        if slot[s] < 0:
            slot[s] = groups
            first[groups] = k
            groups += 1
        inv[k] = slot[s]
    return slot, inv, first[:groups]


@njit(cache=True, nogil=True)
def key_order(occupied: np.ndarray, box):  # pragma: no cover - numba
    """The occupied slots of a table over ``box`` in the order of their cells' keys
    (:func:`cell_key`): a walk over the table, i ascending, then j ≥ 0 ascending, then j < 0
    ascending — no sort."""
    lo0, hi0, lo1, hi1 = box
    width = hi1 - lo1 + 1
    out, r = np.empty(np.count_nonzero(occupied), np.int64), 0
    # the table columns of j < 0 come first in the table, last in key order
    j_split = min(max(-lo1, 0), width)
    for a in range(hi0 - lo0 + 1):
        for b in range(width):
            col = b + j_split if b + j_split < width else b + j_split - width
            if occupied[a * width + col]:
                out[r] = a * width + col
                r += 1
    return out


def index_rows(mask, n: int):
    """``mask`` over n rows as the positions it selects (a boolean array of n: its true rows),
    else unchanged: what :func:`take_rows` takes."""
    if isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (n,):
        return np.flatnonzero(mask)
    return mask


def take_rows(a: np.ndarray, rows) -> np.ndarray:
    """``a[rows]``, the same array: ``np.take`` along the first axis for an integer index array
    (several times faster than indexing an (N, 3) array with a boolean mask), else indexing."""
    if isinstance(rows, np.ndarray) and rows.dtype.kind in "iu" and rows.ndim == 1 and a.ndim:
        return a.take(rows, axis=0)
    return a[rows]
