"""Which flight strips overlap, and which of their points lie in each overlap.

Each strip's horizontal footprint is rasterised on a common grid (cells of ``cell_m``);
two strips overlap where both occupy the same cells.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from calidar.cells import cell_keys_of, grid_indices


@dataclass(frozen=True)
class Overlap:
    """One overlapping pair; indices point into each strip's point array."""

    a: int  #: strip id
    b: int
    n_cells: int  #: common occupied cells
    area_m2: float
    index_a: np.ndarray  #: (Na,) points of a inside the common cells
    index_b: np.ndarray


def cell_keys(xy: np.ndarray, cell_m: float, origin: np.ndarray | None = None) -> np.ndarray:
    """One int64 key per point for the grid cell holding it (cells of ``cell_m`` metres)."""
    if origin is None:  # one numba pass, bit for bit the numpy below (NaN, ±inf: the numpy)
        from calidar.strips.moments_kernel import point_cell_keys

        keys = point_cell_keys(np.asarray(xy, float), float(cell_m))
        if keys is not None:
            return keys
    ij = grid_indices(np.asarray(xy, float), cell_m, origin)
    return cell_keys_of(ij[:, 0], ij[:, 1])


def _members(keys: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Indices of the keys found in the sorted unique ``cells``."""
    pos = np.minimum(np.searchsorted(cells, keys), cells.size - 1)
    return np.flatnonzero(cells[pos] == keys)


def footprint_area_m2(xy: np.ndarray, cell_m: float = 5.0) -> float:
    """Horizontal area (m²) of the ``cell_m`` cells holding at least one of the points (N, ≥2) m."""
    if len(xy) == 0:
        return 0.0
    ij = grid_indices(np.asarray(xy, float), cell_m)
    ij -= ij.min(axis=0)
    flat = ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1]  # one index per cell of the box
    return float(np.count_nonzero(np.bincount(flat)) * cell_m**2)


def cell_counts(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The distinct cell keys (sorted) and how many of ``keys`` fall in each (a dense table in numba
    when the cells' box is small against the keys:
    :func:`calidar.strips.moments_kernel.dense_cell_counts`)."""
    from calidar.strips.moments_kernel import dense_cell_counts

    dense = dense_cell_counts(keys)
    if dense is not None:
        return dense
    ks = np.sort(np.asarray(keys, np.int64))
    start = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1] if ks.size else np.zeros(0, np.int64)
    return ks[start], np.diff(np.r_[start, ks.size]).astype(np.int64)


def merge_counts(*parts: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Sum several (cells, counts) of :func:`cell_counts` into one (chunk by chunk footprints)."""
    cells = np.concatenate([p[0] for p in parts])
    counts = np.concatenate([p[1] for p in parts])
    order = np.argsort(cells, kind="stable")
    cells, counts = cells[order], counts[order]
    if cells.size:
        start = np.r_[0, np.flatnonzero(cells[1:] != cells[:-1]) + 1]
    else:
        start = np.zeros(0, np.int64)
    return cells[start], np.add.reduceat(counts, start) if cells.size else counts


def common_cells(occupied: Mapping[int, np.ndarray],
                 min_cells: int) -> list[tuple[int, int, np.ndarray]]:
    """(a, b, sorted common cells) of every pair of strips (ids ascending) sharing at least
    ``min_cells`` of their occupied cells {id: sorted unique keys}."""
    ids = sorted(occupied)
    out = []
    for k, a in enumerate(ids):
        for b in ids[k + 1:]:
            common = _intersection(occupied[a], occupied[b])
            if common.size >= min_cells:
                out.append((a, b, common))
    return out


def _intersection(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.intersect1d(a, b, assume_unique=True)`` of sorted unique keys by binary search (no
    sort of both together); the same array."""
    increasing = a.size and b.size and np.all(a[1:] > a[:-1]) and np.all(b[1:] > b[:-1])
    if increasing and a.dtype == b.dtype:
        return a[_members(a, b)]
    return np.intersect1d(a, b, assume_unique=True)


def unpaired_notes(ids, pairs, cell_m: float, min_cells: int,
                   names: Mapping[int, str] | None = None) -> list[str]:
    """Plain-words notes about the strips ``ids`` in none of the ``pairs`` (a, b, ...), named by
    ``names`` {id: file name} when given."""
    paired = {p[0] for p in pairs} | {p[1] for p in pairs}
    return [f"strip {strip_name(i, names)} overlaps no other strip (fewer than {min_cells} common "
            f"{cell_m:g} m cells); it is not used"
            for i in sorted(ids) if i not in paired]


def strip_name(i: int, names: Mapping[int, str] | None = None) -> str:
    """"3 (line_003.laz)": a flight line's id and the file holding it, when known."""
    return f"{i} ({names[i]})" if names and i in names else str(i)


def find_overlaps(strips_xy: Mapping[int, np.ndarray], cell_m: float = 5.0, min_cells: int = 4,
                  min_points_per_cell: int = 3, names: Mapping[int, str] | None = None
                  ) -> tuple[list[Overlap], list[str]]:
    """Overlapping pairs among strips given as {id: (N, ≥2) coordinates in metres}.

    A cell counts as occupied by a strip when it holds at least ``min_points_per_cell``
    of its points; pairs sharing fewer than ``min_cells`` cells are left out. Returns the
    pairs (ids ascending) and plain-words notes about strips that overlap no other strip
    (named by ``names`` {id: file name} when given). (Streamed files:
    :class:`calidar.ingest.strips.StripIngest` accumulates the same footprints chunk by chunk with
    :func:`cell_counts` and :func:`merge_counts`.)
    """
    keys = {i: cell_keys(xy, cell_m) for i, xy in strips_xy.items()}
    occupied = {}
    for i, k in keys.items():
        cells, counts = cell_counts(k)
        occupied[i] = cells[counts >= min_points_per_cell]
    pairs = [Overlap(a, b, int(common.size), float(common.size * cell_m**2),
                     _members(keys[a], common), _members(keys[b], common))
             for a, b, common in common_cells(occupied, min_cells)]
    return pairs, unpaired_notes(keys, [(p.a, p.b) for p in pairs], cell_m, min_cells, names)
