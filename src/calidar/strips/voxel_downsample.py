"""Voxel-grid downsampling of VGICP's registration clouds: small_gicp's voxels, in one hashed pass.

small_gicp's ``voxelgrid_sampling`` (1.0) keys each point by its voxel — ``floor(p / leaf)`` per
axis, offset by 2²⁰ and packed 21 bits an axis, x lowest —, sorts the (key, index) pairs by key
(``std::sort``: unstable) and averages each run of equal keys in the sorted order. Here the points
are grouped by the same key in one pass through an open-addressing hash table, summed in their own
order, and only the distinct keys are sorted (≈ 1/10 of the points at VGICP's downsampling): the
same voxels, in the same (ascending key) order, each the mean of the same points — summed in point
order rather than in the order ``std::sort`` left them, so a voxel's mean may differ in its last
bits (≤ 1e-12 m on the 8.75 M flight's crops of ≈ 1 km; docs/validation.md, "VGICP per pair …
(issue 32, 28 Nov, twelfth session)"). At ≈ 1/6 of the CPU: the sort of every point was most of a
registration cloud's preprocessing.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: voxel coordinates are packed 21 bits an axis, offset by 2²⁰ (small_gicp's layout)
_BITS = 21


@njit(cache=True, nogil=True)
def voxel_keys(points, inv_leaf):  # pragma: no cover - numba
    """Each point's (N, ≥ 3) voxel key: floor(p · inv_leaf) + 2²⁰ per axis, masked to 21 bits,
    packed x | y << 21 | z << 42 (int64, ≥ 0)."""
    offset, mask = np.int64(1) << (_BITS - 1), (np.int64(1) << _BITS) - 1
    keys = np.empty(points.shape[0], np.int64)
    for p in range(points.shape[0]):
        key = np.int64(0)
        for c in range(3):
            coord = np.int64(np.floor(points[p, c] * inv_leaf)) + offset
            key |= (coord & mask) << (_BITS * c)
        keys[p] = key
    return keys


@njit(cache=True, nogil=True)
def _group(keys):  # pragma: no cover - numba
    """Each key's group (in order of first appearance) and the groups' keys: linear probing in a
    table of ≥ 2 N slots."""
    size = 16
    while size < 2 * keys.size:
        size *= 2
    table = np.full(size, -1, np.int64)
    group_key = np.empty(keys.size, np.int64)
    group = np.empty(keys.size, np.int64)
    n_groups = 0
    for p in range(keys.size):
        key = keys[p]
        mixed = key * np.int64(-7046029254386353131)  # 2⁶⁴ / golden ratio, odd: Fibonacci hashing
        slot = (mixed ^ (mixed >> 29)) & (size - 1)
        while table[slot] >= 0 and group_key[table[slot]] != key:
            slot = (slot + 1) & (size - 1)
        if table[slot] < 0:
            table[slot] = n_groups
            group_key[n_groups] = key
            n_groups += 1
        group[p] = table[slot]
    return group, group_key[:n_groups].copy()


@njit(cache=True, nogil=True)
def _means(points, group, rank, n_voxels):  # pragma: no cover - numba
    """Mean (n_voxels, 3) of the points of each voxel, voxel rank[group]; each sum starts at its
    voxel's first point and adds the others in point order."""
    sums = np.empty((n_voxels, 4))
    seen = np.zeros(n_voxels, np.bool_)
    for p in range(points.shape[0]):
        v = rank[group[p]]
        if seen[v]:
            for c in range(3):
                sums[v, c] += points[p, c]
            sums[v, 3] += 1.0
        else:
            seen[v] = True
            for c in range(3):
                sums[v, c] = points[p, c]
            sums[v, 3] = 1.0
    means = np.empty((n_voxels, 3))
    for v in range(n_voxels):
        for c in range(3):
            means[v, c] = sums[v, c] / sums[v, 3]
    return means


def voxel_downsample(points: np.ndarray, leaf_m: float) -> np.ndarray:
    """The mean (M, 3) of the points (N, 3) m in each occupied voxel of size ``leaf_m`` (m), in
    ascending key order: small_gicp's ``voxelgrid_sampling`` to the last bits of each mean (module
    docstring). The points must lie within ±2²⁰ voxels of the origin, as small_gicp's must."""
    points = np.ascontiguousarray(points, dtype=np.float64)
    if len(points) == 0:
        return np.empty((0, 3))
    group, group_key = _group(voxel_keys(points, 1.0 / leaf_m))
    order = np.argsort(group_key)  # distinct keys
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return _means(points, group, rank, order.size)
