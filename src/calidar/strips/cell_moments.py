"""Per-cell point moments on a horizontal grid, accumulated chunk by chunk.

For every cell of ``cell_m`` metres (keys of :func:`calidar.strips.overlap.cell_keys`, i.e.
``floor(x / cell_m)``, ``floor(y / cell_m)``) the count n, the mean and the centred scatter
S = Σ (p − mean)(p − mean)ᵀ of the points in it. Chunks combine exactly (Chan et al. 1979):

    n = Σ nᵢ,  mean = Σ nᵢ meanᵢ / n,  S = Σ Sᵢ + Σ nᵢ (meanᵢ − mean)(meanᵢ − mean)ᵀ

so moments accumulated over chunks equal those of all points at once (to rounding), and the
least-squares plane of a cell (normal = eigenvector of the smallest eigenvalue of S / n) is the
same. Memory grows with the cells, not the points. Means are kept as x, y offsets from the
cell centre (and z as is) so that large projected coordinates lose no precision; a grid of
1 m coarsens exactly into any whole number of metres (:meth:`CellMoments.coarsened`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from calidar.cells import (cell_keys_of, grid_indices, group_cells, index_rows, key_indices,
                           take_rows)
from calidar.strips.moments_kernel import dense_moments, moments

#: the 6 distinct products of a symmetric 3 × 3 scatter, in this order
PRODUCTS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def index_keys(ij: np.ndarray) -> np.ndarray:
    """Keys of integer grid indices (K, 2): the inverse of :func:`key_indices`."""
    ij = np.asarray(ij, np.int64)
    return cell_keys_of(ij[:, 0], ij[:, 1])


@dataclass(frozen=True)
class CellMoments:
    """Moments of the points of each occupied cell, keys sorted ascending."""

    cell_m: float
    keys: np.ndarray  #: (K,) int64
    count: np.ndarray  #: (K,) int64
    mean: np.ndarray  #: (K, 3) m: x, y from the cell centre, z
    scatter: np.ndarray  #: (K, 6) m², centred sums of products in the order of PRODUCTS

    @classmethod
    def empty(cls, cell_m: float) -> "CellMoments":
        return cls(float(cell_m), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 3)),
                   np.zeros((0, 6)))

    @classmethod
    def of_points(cls, points: np.ndarray, cell_m: float) -> "CellMoments":
        """Moments of points (N, 3) m, z up (:func:`calidar.cells.group_cells`, then two passes to
        sum; one numba kernel when the cells fit a dense table:
        :mod:`calidar.strips.moments_kernel`)."""

        p = np.ascontiguousarray(points, float)
        fused = dense_moments(p, cell_m)
        if fused is not None:
            return cls(float(cell_m), *fused)
        return cls.sorted_points(p, cell_m)

    @classmethod
    def sorted_points(cls, p: np.ndarray, cell_m: float) -> "CellMoments":
        """:meth:`of_points` in numpy (group_cells, sorts); any cells."""
        p = np.ascontiguousarray(p, float)
        ij = grid_indices(p, cell_m)
        inv, first = group_cells(ij)
        keys = index_keys(ij[first])
        order = np.argsort(keys)
        inv = np.argsort(order)[inv]  # groups in key order
        keys = keys[order]
        count, mean, scatter = moments(p, inv, cell_centres(keys, cell_m))
        return cls(float(cell_m), keys, count, mean, scatter)

    @classmethod
    def combined(cls, parts: "list[CellMoments]", cell_m: float | None = None) -> "CellMoments":
        """The moments of the points of all ``parts`` (same grid; none: empty on ``cell_m``)."""
        if not parts:
            return cls.empty(cell_m)
        if len(parts) == 1:
            return parts[0]
        if len({p.cell_m for p in parts}) > 1:
            raise ValueError("cannot merge moments on cells of "
                             f"{sorted({p.cell_m for p in parts})} m")
        return _combine(parts[0].cell_m, *(np.concatenate([getattr(p, f) for p in parts])
                                           for f in ("keys", "count", "mean", "scatter")))

    @property
    def nbytes(self) -> int:
        return self.keys.nbytes + self.count.nbytes + self.mean.nbytes + self.scatter.nbytes

    def save(self, path) -> None:
        """To an .npy file of ``path`` (one record array, read back by :meth:`load`)."""
        table = np.column_stack([self.keys.view(np.float64), self.count.view(np.float64),
                                 self.mean, self.scatter])
        np.save(path, table, allow_pickle=False)

    @classmethod
    def load(cls, path, cell_m: float) -> "CellMoments":
        a = np.load(path, allow_pickle=False)
        return cls(float(cell_m), np.ascontiguousarray(a[:, 0]).view(np.int64),
                   np.ascontiguousarray(a[:, 1]).view(np.int64), a[:, 2:5].copy(),
                   a[:, 5:11].copy())

    def __len__(self) -> int:
        return self.keys.size

    def merged(self, other: "CellMoments") -> "CellMoments":
        """The moments of the points of both (same grid)."""
        return CellMoments.combined([self, other])

    def coarsened(self, factor: int) -> "CellMoments":
        """The same points' moments on cells ``factor`` times larger (aligned with this grid)."""
        if factor == 1:
            return self
        ij = key_indices(self.keys)
        coarse = np.floor_divide(ij, factor)
        cell = self.cell_m * factor
        shift = (ij + 0.5) * self.cell_m - (coarse + 0.5) * cell  # fine centre − coarse centre, m
        mean = self.mean.copy()
        mean[:, :2] += shift
        return _combine(cell, index_keys(coarse), self.count, mean, self.scatter)

    def centroid(self) -> np.ndarray:
        """Means (K, 3) in the points' coordinates, m."""
        return self.mean + np.column_stack([cell_centres(self.keys, self.cell_m),
                                            np.zeros(len(self))])

    def covariance(self) -> np.ndarray:
        """Covariances (K, 3, 3) m² of the points of each cell (divided by n)."""
        cov = np.empty((len(self), 3, 3))
        for k, (a, b) in enumerate(PRODUCTS):
            cov[:, a, b] = cov[:, b, a] = self.scatter[:, k] / self.count
        return cov

    def select(self, index) -> "CellMoments":
        rows = index_rows(index, len(self))
        return CellMoments(self.cell_m, *(take_rows(a, rows) for a in (self.keys, self.count,
                                                                        self.mean, self.scatter)))


def cell_centres(keys: np.ndarray, cell_m: float) -> np.ndarray:
    """Horizontal centres (K, 2) m of the cells with these keys."""
    return (key_indices(keys) + 0.5) * cell_m


def _combine(cell_m: float, keys, count, mean, scatter) -> CellMoments:
    """Moments of groups with equal keys combined (Chan's parallel formula)."""
    uk, inv = np.unique(keys, return_inverse=True)
    if uk.size == keys.size:  # nothing to combine
        order = np.argsort(keys)
        return CellMoments(cell_m, keys[order], count[order], mean[order], scatter[order])
    n = np.bincount(inv, count, uk.size)
    sums = np.stack([np.bincount(inv, count * mean[:, k], uk.size) for k in range(3)], axis=1)
    m = sums / n[:, None]
    d = mean - m[inv]
    s = np.stack([np.bincount(inv, scatter[:, k] + count * d[:, a] * d[:, b], uk.size)
                  for k, (a, b) in enumerate(PRODUCTS)], axis=1)
    return CellMoments(cell_m, uk, n.astype(np.int64), m, s)
