"""``calidar quality``'s per-point work in one numba pass per chunk (issue 32), each bit for bit
what it replaces (``tests/unit/pipelines/test_chunk_pass.py``):

- :func:`chunk_pass`: the first pass's whole GPS second and overlap cell of each point
  (:func:`calidar.ingest.cell_counts._seconds_cells`) and, in the same loop, which candidate
  selections keep it (:meth:`calidar.strips.selection.PointSelection.mask` as a table over the
  LAS classes and the last-return test), as one byte of bits;
- :func:`held_rows`: the kept points' stored integers, point_source_id, GPS time and bits
  gathered in one loop (:func:`calidar.ingest.cell_counts.held_arrays`' takes);
- :func:`selected_points`: the second pass's points of one selection from the held arrays,
  coordinates scaled as laspy scales them (X · scale + offset).

Anything these tables do not describe (a field missing, classes not 8-bit, more than 8
selections, other dtypes) returns None: the caller goes the numpy way.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from calidar.cells import cell_index
from calidar.ingest.held import las_coordinate
from calidar.strips.selection import EXCLUDED_CLASSES

_INT = ("i", "u")  #: integer kinds the kernels take


def selection_tables(selections) -> tuple[np.ndarray, np.ndarray] | None:
    """(which of the 256 LAS classes each selection keeps (S, 256) bool, whether it also asks
    return_number == number_of_returns (S,) bool): :meth:`PointSelection.mask` with every field
    present; None for more than 8 selections (a byte of bits) or a class outside 0–255."""
    if len(selections) > 8:
        return None
    keeps, last = np.zeros((len(selections), 256), np.bool_), np.zeros(len(selections), np.bool_)
    for s, sel in enumerate(selections):
        if sel.classes is not None:
            if not all(isinstance(c, int) and 0 <= c < 256 for c in sel.classes):
                return None
            keeps[s, list(sel.classes)] = True
        else:
            keeps[s] = True
            keeps[s, list(EXCLUDED_CLASSES)] = False
            last[s] = True
    return keeps, last


def chunk_pass(t: np.ndarray, xyz: np.ndarray, grid_m: float, fields: dict, selections):
    """(whole GPS second (N,), overlap cell (N, 2), bit s set where ``selections[s]`` keeps the
    point (N,) uint8) of a chunk (``fields``: classification, return_number,
    number_of_returns), or None when the tables do not describe it."""
    tables = selection_tables(selections)
    names = ("classification", "return_number", "number_of_returns")
    if tables is None or any(fields.get(f) is None for f in names):
        return None
    cls, rn, nr = (fields[f] for f in names)
    if cls.dtype != np.uint8 or any(a.dtype.kind not in _INT for a in (rn, nr)):
        return None
    if xyz.dtype != np.float64 or t.dtype != np.float64 or xyz.ndim != 2 or xyz.shape[1] != 3:
        return None
    return _chunk_kernel(t, xyz, float(grid_m), cls, rn, nr, *tables)


@njit(cache=True, nogil=True)
def second_and_cell(t, x, y, grid):  # pragma: no cover - numba
    """A point's whole GPS second (2³² − 1 when not finite; clipped to 0…2³² − 1) and overlap-grid
    cell (i, j) = floor(x / grid), floor(y / grid): the one rule of
    :func:`calidar.ingest.cell_counts._seconds_cells` and :func:`_chunk_kernel`."""
    s = np.floor(t) if np.isfinite(t) else 4294967295.0
    sec = min(max(np.int64(s), 0), 4294967295) if s < 9.2e18 else np.int64(4294967295)
    return sec, cell_index(x, grid), cell_index(y, grid)


@njit(cache=True, nogil=True)
def _chunk_kernel(t, xyz, grid, cls, rn, nr, keeps, last):  # pragma: no cover - numba
    n = t.size
    sec, ij, bits = np.empty(n, np.int64), np.empty((n, 2), np.int64), np.empty(n, np.uint8)
    for k in range(n):
        sec[k], ij[k, 0], ij[k, 1] = second_and_cell(t[k], xyz[k, 0], xyz[k, 1], grid)
        same, b = rn[k] == nr[k], 0
        for m in range(keeps.shape[0]):
            if keeps[m, cls[k]] and (same or not last[m]):
                b |= 1 << m
        bits[k] = b
    return sec, ij, bits


def held_rows(bits: np.ndarray, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray] | None:
    """``arrays`` (X, Y, Z, point_source_id, gps_time, each (N,)) and ``bits`` at the points
    with some bit set, in one loop; None unless they are integers and float64 GPS times."""
    names = ("X", "Y", "Z", "point_source_id")
    if any(arrays[a].dtype.kind not in _INT or arrays[a].ndim != 1 for a in names):
        return None
    if arrays["gps_time"].dtype != np.float64 or bits.dtype != np.uint8:
        return None
    out = _held_kernel(bits, *(arrays[a] for a in names), arrays["gps_time"])
    return dict(zip((*names, "gps_time", "bits"), out))


@njit(cache=True, nogil=True)
def _held_kernel(bits, x, y, z, psid, t):  # pragma: no cover - numba
    n = 0
    for k in range(bits.size):
        n += bits[k] != 0
    ox, oy, oz = np.empty(n, x.dtype), np.empty(n, y.dtype), np.empty(n, z.dtype)
    op, ot, ob = np.empty(n, psid.dtype), np.empty(n, t.dtype), np.empty(n, bits.dtype)
    r = 0
    for k in range(bits.size):
        if bits[k] != 0:
            ox[r], oy[r], oz[r], op[r], ot[r], ob[r] = x[k], y[k], z[k], psid[k], t[k], bits[k]
            r += 1
    return ox, oy, oz, op, ot, ob


def selected_points(c: dict[str, np.ndarray], bit: int, scales, offsets):
    """(xyz (M, 3) float64: X · scale + offset, point_source_id, GPS time) of the held points
    whose ``bit`` is set, or None when the held arrays are not stored integers."""
    names = ("X", "Y", "Z", "point_source_id")
    if any(a not in c or c[a].dtype.kind not in _INT for a in names):
        return None
    scales, offsets = (np.ascontiguousarray(v, np.float64) for v in (scales, offsets))
    return _selected_kernel(c["bits"], np.uint8(1 << bit), c["X"], c["Y"], c["Z"],
                            c["point_source_id"], c["gps_time"], scales, offsets)


@njit(cache=True, nogil=True)
def _selected_kernel(bits, b, x, y, z, psid, t, scales, offsets):  # pragma: no cover - numba
    n = 0
    for k in range(bits.size):
        n += (bits[k] & b) != 0
    xyz, op, ot = np.empty((n, 3)), np.empty(n, psid.dtype), np.empty(n, t.dtype)
    r = 0
    for k in range(bits.size):
        if (bits[k] & b) != 0:  # laspy's scaling
            xyz[r, 0] = las_coordinate(x[k], scales[0], offsets[0])
            xyz[r, 1] = las_coordinate(y[k], scales[1], offsets[1])
            xyz[r, 2] = las_coordinate(z[k], scales[2], offsets[2])
            op[r], ot[r] = psid[k], t[k]
            r += 1
    return xyz, op, ot


def chunk_summary(psid: np.ndarray, cls: np.ndarray, t: np.ndarray):
    """What :func:`calidar.ingest.lines.index_flight_lines` keeps of a chunk, in one numba pass:
    (distinct point_source_ids, distinct classes, (each whole second's first and last finite
    time, seconds ascending) or None when its dense table would be too large (the caller sorts),
    {point_source_id: (first, last finite time)}) — :func:`calidar.strips.lines.distinct`,
    :func:`calidar.ingest.lines._second_spans` and :func:`calidar.strips.lines.add_spans`' values;
    None unless point_source_id is uint16, classification uint8 and the times float64."""
    if psid.dtype != np.uint16 or cls.dtype != np.uint8 or t.dtype != np.float64:
        return None
    ids, classes, lo, hi, first, last, dense = _summary_kernel(psid, cls, t)
    spans = {int(i): (float(a), float(b)) for i, a, b in zip(*np.nonzero(lo <= hi), lo[lo <= hi],
                                                              hi[lo <= hi])}
    return (np.flatnonzero(ids).astype(np.uint16), np.flatnonzero(classes).astype(np.uint8),
            (first, last) if dense else None, spans)


@njit(cache=True, nogil=True)
def _summary_kernel(psid, cls, t):  # pragma: no cover - numba
    ids, classes = np.zeros(65536, np.bool_), np.zeros(256, np.bool_)
    lo, hi = np.full(65536, np.inf), np.full(65536, -np.inf)
    n_finite, s_lo, s_hi = 0, np.inf, -np.inf
    for k in range(t.size):
        ids[psid[k]] = True
        classes[cls[k]] = True
        if np.isfinite(t[k]):
            n_finite += 1
            lo[psid[k]], hi[psid[k]] = min(lo[psid[k]], t[k]), max(hi[psid[k]], t[k])
            s = np.floor(t[k])
            s_lo, s_hi = min(s_lo, s), max(s_hi, s)
    empty = np.zeros(0)
    if n_finite == 0:
        return ids, classes, lo, hi, empty, empty, True
    if not s_hi - s_lo < 4 * n_finite + 65536:  # as _second_spans: a sort instead
        return ids, classes, lo, hi, empty, empty, False
    n = np.int64(s_hi - s_lo) + 1
    first, last, held = np.full(n, np.inf), np.full(n, -np.inf), np.zeros(n, np.bool_)
    for k in range(t.size):  # as calidar.ingest.lines._dense_spans
        if np.isfinite(t[k]):
            j = np.int64(np.floor(t[k]) - s_lo)
            first[j], last[j], held[j] = min(first[j], t[k]), max(last[j], t[k]), True
    return ids, classes, lo, hi, first[held], last[held], True
