"""The strip ingest's per-point bookkeeping after its first pass in one numba loop per chunk
(issue 32), each bit for bit what it replaces (``tests/unit/pipelines/test_line_kernels.py``):

- :func:`chunk_lines`: each point's flight line, :meth:`calidar.ingest.source.StripSource.chunks`'
  lookup — the group key of :func:`calidar.ingest.source.group_keys` (point_source_id, GPS time
  bin) found among the sorted groups (``np.searchsorted``) — without the key array, the search
  skipped while the key repeats (the points come in time order);
- :func:`kept_mask`: pass 2's test (:func:`calidar.ingest.strips._kept_points`) of each point,
  inside its line's kept overlap cells (the key of :func:`calidar.strips.overlap.cell_keys` of
  the CRS's metres, :func:`calidar.ingest.source.planar_xy` in a projected CRS) and of a class
  the calibration uses (:func:`calidar.ingest.source.calibration_mask`).

Anything else (a time or coordinate not finite, classes not 8-bit) returns None: the caller goes
the numpy way.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from calidar.cells import cell_index, cell_key
from calidar.ingest.settings import BIN_BITS
from calidar.strips.selection import EXCLUDED_CLASSES


def chunk_lines(psid, t: np.ndarray, gap_s: float, groups: np.ndarray,
                group_line: np.ndarray) -> tuple[np.ndarray | None, bool]:
    """(the line id of each point, True), (None, False) when a point's group is not among
    ``groups`` (the file changed), or (None, True) when a time is not finite (the numpy way)."""
    t = np.ascontiguousarray(t, np.float64)
    has_psid = psid is not None and np.asarray(psid).dtype.kind in "iu"
    if psid is not None and not has_psid:
        return None, True
    ids = np.empty(t.size, np.int64)
    p = np.asarray(psid) if has_psid else np.zeros(0, np.int64)
    status = _lines_kernel(p, has_psid, t, float(gap_s), np.ascontiguousarray(groups, np.int64),
                           np.ascontiguousarray(group_line, np.int64), ids)
    return (ids, True) if status == 0 else (None, status == 2)


@njit(cache=True, nogil=True)
def _lines_kernel(psid, has_psid, t, gap_s, groups, group_line, ids):  # pragma: no cover - numba
    """0: ``ids`` filled; 1: a group not found; 2: a time not finite (or its bin beyond int64)."""
    mask = (np.int64(1) << BIN_BITS) - 1
    last, line = np.int64(0), np.int64(-1)
    for k in range(t.size):
        b = t[k] / gap_s
        if not abs(b) < 9.2e18:  # NaN, ±inf, beyond int64: numpy's cast
            return 2
        g = np.int64(np.floor(b)) & mask
        if has_psid:
            g = (np.int64(psid[k]) << BIN_BITS) | g
        if line < 0 or g != last:
            lo, hi = 0, groups.size
            while lo < hi:  # np.searchsorted(groups, g), side "left"
                mid = (lo + hi) >> 1
                if groups[mid] < g:
                    lo = mid + 1
                else:
                    hi = mid
            if lo >= groups.size or groups[lo] != g:
                return 1
            last, line = g, group_line[lo]
        ids[k] = line
    return 0


def kept_table(kept: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(sorted lines holding kept cells, offsets (L + 1) into, their sorted cell keys one line
    after another) of ``kept`` (line → sorted cell keys): :func:`kept_mask`'s table."""
    lines = np.array(sorted(int(i) for i, c in kept.items() if c is not None and c.size), np.int64)
    parts = [np.asarray(kept[int(i)], np.int64) for i in lines]
    offsets = np.r_[0, np.cumsum([c.size for c in parts])].astype(np.int64)
    return lines, offsets, np.concatenate(parts) if parts else np.zeros(0, np.int64)


def kept_mask(ids: np.ndarray, xyz: np.ndarray, factor: float, cell_m: float, table: tuple,
              classification) -> tuple[np.ndarray, np.ndarray] | None:
    """(mask of the points in their line's kept cells (``table``: :func:`kept_table`) and of a
    class the calibration uses (``classification`` None: any), the sorted lines of the table that
    some point of the chunk belongs to), or None (the numpy way): planar coordinates
    ``xyz[:, :2] · factor`` m on cells of ``cell_m`` m."""
    if classification is not None and np.asarray(classification).dtype != np.uint8:
        return None
    lines, offsets, cells = table
    usable = np.ones(256, np.bool_)
    usable[list(EXCLUDED_CLASSES)] = False
    by_class = classification is not None
    classes = np.asarray(classification) if by_class else np.zeros(0, np.uint8)
    mask, seen = np.empty(len(ids), np.bool_), np.zeros(lines.size, np.bool_)
    ok = _kept_kernel(np.ascontiguousarray(ids, np.int64), np.ascontiguousarray(xyz, np.float64),
                      float(factor), float(cell_m), lines, offsets, cells, by_class, classes,
                      usable, mask, seen)
    return (mask, lines[seen]) if ok else None


@njit(cache=True, nogil=True)
def _kept_kernel(ids, xyz, factor, cell_m, lines, offsets, cells, by_class, classes, usable,
                 mask, seen):  # pragma: no cover - numba
    slot, last_line = -1, np.int64(0)
    last_key, last_in, have_key = np.int64(0), False, False
    for k in range(ids.size):
        if k == 0 or ids[k] != last_line:
            last_line, have_key = ids[k], False
            lo, hi = 0, lines.size
            while lo < hi:
                mid = (lo + hi) >> 1
                if lines[mid] < last_line:
                    lo = mid + 1
                else:
                    hi = mid
            slot = lo if lo < lines.size and lines[lo] == last_line else -2
            if slot >= 0:
                seen[slot] = True
        x, y = xyz[k, 0] * factor, xyz[k, 1] * factor
        if not (abs(x / cell_m) < 9.2e18 and abs(y / cell_m) < 9.2e18):  # as numpy's cast
            return False
        if slot < 0:
            mask[k] = False
            continue
        key = cell_key(cell_index(x, cell_m), cell_index(y, cell_m))
        if not have_key or key != last_key:
            a, b = offsets[slot], offsets[slot + 1]
            lo, hi = a, b
            while lo < hi:  # np.searchsorted(cells, key) within the line's cells
                mid = (lo + hi) >> 1
                if cells[mid] < key:
                    lo = mid + 1
                else:
                    hi = mid
            last_key, last_in, have_key = key, lo < b and cells[lo] == key, True
        mask[k] = last_in and (not by_class or usable[classes[k]])
    return True
