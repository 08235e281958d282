"""Which flight strips overlap, and which of their points lie in each overlap.

Each strip's horizontal footprint is rasterised on a common grid (cells of ``cell_m``);
two strips overlap where both occupy the same cells.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np


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
    o = np.zeros(2) if origin is None else origin
    ij = np.floor((np.asarray(xy, float)[:, :2] - o) / cell_m).astype(np.int64)
    return (ij[:, 0] << 32) + (ij[:, 1] & 0xFFFFFFFF)


def _members(keys: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """Indices of the keys found in the sorted unique ``cells``."""
    pos = np.minimum(np.searchsorted(cells, keys), cells.size - 1)
    return np.flatnonzero(cells[pos] == keys)


def footprint_area_m2(xy: np.ndarray, cell_m: float = 5.0) -> float:
    """Horizontal area (m²) of the ``cell_m`` cells holding at least one of the points (N, ≥2) m."""
    if len(xy) == 0:
        return 0.0
    ij = np.floor(np.asarray(xy, float)[:, :2] / cell_m).astype(np.int64)
    ij -= ij.min(axis=0)
    return float(np.count_nonzero(np.bincount(ij[:, 0] * (int(ij[:, 1].max()) + 1) + ij[:, 1])) * cell_m**2)


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
    (named by ``names`` {id: file name} when given).
    """
    ids = sorted(strips_xy)
    keys = {i: cell_keys(strips_xy[i], cell_m) for i in ids}
    occupied = {}
    for i in ids:
        ks = np.sort(keys[i])
        start = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1] if ks.size else np.zeros(0, np.int64)
        occupied[i] = ks[start][np.diff(np.r_[start, ks.size]) >= min_points_per_cell]
    pairs = []
    for k, a in enumerate(ids):
        for b in ids[k + 1:]:
            common = np.intersect1d(occupied[a], occupied[b], assume_unique=True)
            if common.size < min_cells:
                continue
            pairs.append(Overlap(a, b, int(common.size), float(common.size * cell_m**2),
                                 _members(keys[a], common), _members(keys[b], common)))
    paired = {p.a for p in pairs} | {p.b for p in pairs}
    notes = [f"strip {strip_name(i, names)} overlaps no other strip (fewer than {min_cells} common {cell_m:g} m "
             "cells); it is not used" for i in ids if i not in paired]
    return pairs, notes
