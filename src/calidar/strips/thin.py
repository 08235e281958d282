"""Thinning the overlaps to a point budget by keeping WHOLE grid cells, spread evenly.

A calibration needs the overlaps at their full local density (a tie plane fits ≈ 12
neighbouring points, VGICP the 12 nearest), not every overlapping point: a few hundred
thousand points per strip in small patches spread over the overlap determine the mounting as
well as millions. So the overlap cells (those of :func:`calidar.strips.overlap.common_cells`)
are grouped in square blocks (several tie-plane patches across, so that few patches are cut
at a block's edge) ranked by :func:`spread_rank`, a bit-reversed Morton (Z-order) code of the
block indices: the blocks ranked below 2⁻ᵏ form a regular lattice of stride 2^(k/2) blocks,
and any prefix of the ranking is spread evenly over the grid. Each strip keeps the lowest-ranked of
its overlap cells that fit its budget (threshold τ); a pair keeps its common cells ranked below
min(τ_a, τ_b), so that both strips keep the same cells and no kept point lacks a partner.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from functools import lru_cache

import numpy as np

from calidar.cells import key_indices


@lru_cache(maxsize=1)
def _reverse16() -> np.ndarray:
    """Bit reversal of every 16-bit number."""
    v = np.arange(65536, dtype=np.uint32)
    r = np.zeros_like(v)
    for b in range(16):
        r |= ((v >> b) & 1) << (15 - b)
    return r


def _spread16(v: np.ndarray) -> np.ndarray:
    """Bits of 16-bit ``v`` moved to the even positions of 32 bits (Morton interleave)."""
    v = v.astype(np.uint64) & 0xFFFF
    for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
        v = (v | (v << np.uint64(shift))) & np.uint64(mask)
    return v


def spread_rank(cells: np.ndarray, block: int = 1) -> np.ndarray:
    """Rank in [0, 1) of cells (keys of :func:`calidar.strips.overlap.cell_keys`): the bit-reversed
    Morton code of the low 16 bits of the column and row of their block of ``block`` × ``block``
    cells, so that the blocks ranked lowest are spread evenly (a block's cells share its rank;
    unique within 65 536 blocks in each direction)."""
    ij = key_indices(np.asarray(cells, np.int64)) // block
    i, j = ij[:, 0], ij[:, 1]
    i, j = i & 0xFFFF, j & 0xFFFF
    rev = _reverse16()
    code = (_spread16(rev[i]) << np.uint64(1)) | _spread16(rev[j])
    return code.astype(np.float64) / 2.0**32


def budget_threshold(cells: np.ndarray, counts: np.ndarray, budget: int | None,
                     block: int = 1) -> float:
    """The rank τ below which the lowest-ranked ``cells`` (with their point ``counts``) hold at most
    ``budget`` points (2.0, all of them, when they fit or ``budget`` is None)."""
    if budget is None or int(np.sum(counts)) <= budget:
        return 2.0
    rank = spread_rank(cells, block)
    order = np.argsort(rank, kind="stable")
    over = np.flatnonzero(np.cumsum(counts[order]) > budget)
    return float(rank[order[over[0]]])


def thin_cells(pairs: Sequence[tuple[int, int, np.ndarray]],
               footprints: Mapping[int, tuple[np.ndarray, np.ndarray]], budget: int | None,
               block: int = 1) -> dict[int, np.ndarray]:
    """The cells each strip keeps: {id: sorted keys}, at most ``budget`` points per strip (None: no
    limit), whole blocks of ``block`` × ``block`` cells at a time.

    ``pairs``: (a, b, common cells) as :func:`calidar.strips.overlap.common_cells` gives;
    ``footprints``: per strip (cells, point counts), sorted cells as
    :func:`calidar.strips.overlap.cell_counts` gives.
    """
    overlap: dict[int, list[np.ndarray]] = {}
    for a, b, common in pairs:
        overlap.setdefault(a, []).append(common)
        overlap.setdefault(b, []).append(common)
    tau = {}
    for i, parts in overlap.items():
        cells = np.unique(np.concatenate(parts))
        fc, fn = footprints[i]
        tau[i] = budget_threshold(cells, fn[np.searchsorted(fc, cells)], budget, block)
    kept: dict[int, list[np.ndarray]] = {}
    for a, b, common in pairs:
        keep = common[spread_rank(common, block) < min(tau[a], tau[b])]
        kept.setdefault(a, []).append(keep)
        kept.setdefault(b, []).append(keep)
    return {i: np.unique(np.concatenate(v)) for i, v in kept.items()}
