"""``calidar quality``'s first pass, chunk by chunk (:class:`CellCounts`): the points of every
candidate selection counted on the overlap grid by (point_source_id, GPS second), and what the
second pass needs of each candidate point kept on disk (:func:`held_arrays`, read back by
:func:`held_chunks`); the metric coordinates of the swath difference (:class:`Metric`).
:func:`calidar.pipelines.quality.measure` runs it.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from calidar.cells import cell_keys_of
from calidar.ingest.chunk_pass import chunk_pass, held_rows, second_and_cell, selected_points
from calidar.strips.overlap import merge_counts
from calidar.strips.selection import FIELDS as SELECTION_FIELDS


@dataclass(frozen=True)
class Metric:
    """Coordinates for the swath difference: metric with z up: the CRS's own when projected, else
    local ENU at ``frame`` (one frame for all lines)."""

    crs: object = None
    frame: object | None = None  #: calidar.strips.strip.LocalFrame for a geographic CRS
    geoid_undulation_m: float | None = None
    source: object = None

    @classmethod
    def at(cls, crs, xyz_min, xyz_max, geoid_undulation_m=None, source=None) -> "Metric":
        """For points in ``crs`` within the bounds (x/lon, y/lat, z)."""
        if crs is None or not crs.is_geographic:
            return cls(crs)
        from calidar.georef import from_crs
        from calidar.strips.strip import LocalFrame

        centre = 0.5 * (np.asarray(xyz_min, float) + np.asarray(xyz_max, float))
        frame = LocalFrame.at(from_crs(centre[None, :], crs, geoid_undulation_m, source=source))
        return cls(crs, frame, geoid_undulation_m, source)

    def of(self, xyz: np.ndarray) -> np.ndarray:
        """Metric coordinates (N, 3) of points (N, 3) in the CRS."""
        if self.frame is None:
            return xyz
        from calidar.georef import from_crs

        ecef = from_crs(xyz, self.crs, self.geoid_undulation_m, source=self.source)
        return self.frame.to_local(ecef)


class CellCounts:
    """The first pass of ``calidar quality``, chunk by chunk: for each file, its points of every
    candidate selection counted on the overlap grid, by (point_source_id, GPS second), so that
    they go to flight lines (and the file's selection is chosen) once the pass is over; with
    ``held``, what the second pass needs of each candidate point (:func:`held_arrays`)."""

    def __init__(self, candidates: dict, metric: Metric, grid_m: float, held=None):
        #: candidates: path → selections
        self.candidates, self.metric, self.grid_m = candidates, metric, grid_m
        #: (path, selection) → [(tokens, keys, counts)], each sorted
        self.parts: dict[tuple, list] = {}
        self.time: dict[int, float] = {}  #: token → a GPS time of its points (s)
        self.held = held  #: calidar.ingest.held.HeldPoints, or None

    def __call__(self, path, c: dict) -> None:
        from types import SimpleNamespace

        t = c["gps_time"]
        psid = np.asarray(c["point_source_id"], np.int64)
        xyz = self.metric.of(c["xyz"] if "xyz" in c else np.c_[c["x"], c["y"], c["z"]])
        selections = self.candidates[path]
        fused = chunk_pass(t, xyz, float(self.grid_m), c, selections)
        if fused is not None:  # one numba pass: seconds, cells, every selection's bit
            sec, ij, bits = fused
            masks = [(bits & np.uint8(1 << k)) != 0 for k in range(len(selections))]
        else:
            sec, ij = _seconds_cells(t, xyz, float(self.grid_m))  # as cell_keys on the grid
            fields = SimpleNamespace(xyz=ij, **{f: c[f] for f in SELECTION_FIELDS})
            masks, bits = [selection.mask(fields) for selection in selections], None
        for selection, keep in zip(selections, masks):
            (tok, keys, n), first = _kept_counts(psid, sec, ij, keep)
            for k in first:
                self.time.setdefault(int((psid[k] << 32) | sec[k]), float(t[k]))
            parts = self.parts.setdefault((path, selection), [])
            parts.append((tok, keys, n))
            if len(parts) >= MERGE_PARTS:
                parts[:] = [_token_counts(*(np.concatenate(a) for a in zip(*parts)))]
        if self.held is not None:
            metric_xyz = xyz if self.metric.frame is not None else None
            self.held.add(path, **held_arrays(c, metric_xyz, masks, bits))

    def _lines(self, index, key) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(flight line, cell key, count) of the counts of (path, selection) ``key``."""
        tok, keys, n = _token_counts(*(np.concatenate(a) for a in zip(*self.parts[key])))
        utok, inv = np.unique(tok, return_inverse=True)
        if utok.size:  # a token: point_source_id << 32 | GPS second
            lines = index.of(utok >> 32, np.array([self.time[int(u)] for u in utok]))
        else:
            lines = utok
        return lines[inv], keys, n

    def names(self, index) -> dict[int, str]:
        """The name of a file holding each flight line (for messages)."""
        out = {}
        for key in self.parts:
            out.update(dict.fromkeys(np.unique(self._lines(index, key)[0]).tolist(), key[0].name))
        return out

    def by_line(self, index, selections: dict) -> dict[int, tuple[np.ndarray, np.ndarray]]:
        """(keys, counts) per flight line of the points each file's chosen selection keeps."""
        out = {}
        for (path, selection) in self.parts:
            if selections[path] == selection:
                lines, keys, n = self._lines(index, (path, selection))
                for line in np.unique(lines).tolist():
                    rows = lines == line
                    kn = merge_counts((keys[rows], n[rows]))
                    out[line] = merge_counts(out[line], kn) if line in out else kn
        return out


MERGE_PARTS = 16  #: a file's chunk counts combined once this many wait


def _token_counts(tokens: np.ndarray, keys: np.ndarray, n: np.ndarray | None = None):
    """(tokens, keys, counts) of each distinct (token, key): the points' (``n`` None) or summed
    over rows already counted. One bincount over the (line id, second, cell i, cell j) box when it
    is small against the rows (a chunk's), else a sort."""
    from calidar.strips.cell_moments import index_keys, key_indices

    if tokens.size == 0:
        return tokens, keys, np.zeros(0, np.int64)
    ij = key_indices(keys)
    cols = (tokens >> 32, tokens & 0xFFFFFFFF, ij[:, 0], ij[:, 1])
    lo = [int(c.min()) for c in cols]
    span = [int(c.max()) - low + 1 for c, low in zip(cols, lo)]
    if np.prod(np.array(span, float)) <= 4 * tokens.size + 65536:
        flat = np.ravel_multi_index(tuple(c - low for c, low in zip(cols, lo)), span)
        count = np.bincount(flat, n, int(np.prod(span)))
        at = np.flatnonzero(count)
        psid, sec, i, j = (c + low for c, low in zip(np.unravel_index(at, span), lo))
        return (psid << 32) | sec, index_keys(np.stack([i, j], axis=1)), count[at].astype(np.int64)
    order = np.lexsort((keys, tokens))
    tokens, keys = tokens[order], keys[order]
    n = np.ones(tokens.size, np.int64) if n is None else n[order]
    start = np.flatnonzero(np.r_[True, (tokens[1:] != tokens[:-1]) | (keys[1:] != keys[:-1])])
    return tokens[start], keys[start], np.add.reduceat(n, start)


def _kept_counts(psid, sec, ij, keep) -> tuple[tuple, np.ndarray]:
    """(tokens, keys, counts) of the kept points' distinct (point_source_id << 32 | second, overlap
    cell), and the row of the first kept point of each token: one numba pass over a dense
    (id, second, i, j) box when it is small against the points (a chunk's), else sorts."""
    from calidar.strips.cell_moments import index_keys

    if not keep.any():
        none = np.zeros(0, np.int64)
        return (none, none.copy(), none.copy()), none.copy()
    lo, span, counts, first, dense = _box_counts(psid, sec, ij, keep)
    if not dense:
        rows = np.flatnonzero(keep)
        tok = (psid[rows] << 32) | sec[rows]
        keys = cell_keys_of(ij[rows, 0], ij[rows, 1])
        return _token_counts(tok, keys), rows[_first_rows(tok)]
    at = np.flatnonzero(counts)
    p, s, i, j = (c + low for c, low in zip(np.unravel_index(at, tuple(span)), lo))
    tokens = (p << 32) | s
    return (tokens, index_keys(np.stack([i, j], axis=1)), counts[at]), first[first < keep.size]


@njit(cache=True, nogil=True)
def _seconds_cells(t, xyz, grid):  # pragma: no cover - numba
    """Per point the whole GPS second (2³² − 1 when not finite; clipped to 0…2³² − 1) and the
    overlap-grid cell (i, j) = floor(x / grid), floor(y / grid)."""
    n = t.size
    sec, ij = np.empty(n, np.int64), np.empty((n, 2), np.int64)
    for k in range(n):
        sec[k], ij[k, 0], ij[k, 1] = second_and_cell(t[k], xyz[k, 0], xyz[k, 1], grid)
    return sec, ij


@njit(cache=True, nogil=True)
def _box_counts(psid, sec, ij, keep):  # pragma: no cover - numba
    """Counts over the dense (id, second, i, j) box of the kept points, flattened, and the first
    kept row of each (id, second); ``dense`` False (nothing counted) when the box is too large."""
    lo, hi = np.full(4, 9223372036854775807), np.full(4, -9223372036854775807)
    n_kept = 0
    for k in range(keep.size):
        if keep[k]:
            n_kept += 1
            for d, v in enumerate((psid[k], sec[k], ij[k, 0], ij[k, 1])):
                lo[d], hi[d] = min(lo[d], v), max(hi[d], v)
    span = hi - lo + 1
    size = 1.0
    for d in range(4):
        size *= span[d]
    if size > 4 * n_kept + 65536:
        return lo, span, np.zeros(0, np.int64), np.zeros(0, np.int64), False
    counts, first = np.zeros(np.int64(size), np.int64), np.full(span[0] * span[1], keep.size)
    for k in range(keep.size):
        if keep[k]:
            t = (psid[k] - lo[0]) * span[1] + sec[k] - lo[1]
            counts[((t * span[2]) + ij[k, 0] - lo[2]) * span[3] + ij[k, 1] - lo[3]] += 1
            first[t] = min(first[t], k)
    return lo, span, counts, first, True


def _first_rows(tokens: np.ndarray) -> np.ndarray:
    """The row of the first occurrence of each distinct token (a dense table over the tokens'
    (line id, second) box when small, else a sort)."""
    if tokens.size == 0:
        return np.zeros(0, np.int64)
    psid, sec = tokens >> 32, tokens & 0xFFFFFFFF
    span = (int(psid.max() - psid.min()) + 1, int(sec.max() - sec.min()) + 1)
    if span[0] * span[1] > 4 * tokens.size + 65536:
        return np.unique(tokens, return_index=True)[1]
    flat = np.ravel_multi_index((psid - psid.min(), sec - sec.min()), span)
    first = np.full(span[0] * span[1], tokens.size)
    np.minimum.at(first, flat, np.arange(tokens.size))
    return first[first < tokens.size]


def held_arrays(c: dict, metric_xyz: np.ndarray | None, masks: list,
                bits: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """What the second pass needs of a chunk's points that some selection keeps: coordinates (the
    stored integers X, Y, Z; ``metric_xyz`` instead when given), point_source_id, GPS time and
    bit k set when ``masks[k]`` keeps the point (``bits``: those bits, when already made; then
    gathered in one numba loop, :func:`calidar.ingest.chunk_pass.held_rows`)."""
    if bits is not None and metric_xyz is None and all(a in c for a in "XYZ"):
        names = ("X", "Y", "Z", "point_source_id", "gps_time")
        held = held_rows(bits, {a: c[a] for a in names})
        if held is not None:
            return held
    if bits is None:
        bits = np.zeros(len(c["gps_time"]), np.uint8)
        for k, m in enumerate(masks):
            bits |= m.astype(np.uint8) << k
    rows = np.flatnonzero(bits)
    xyz = ({a: c[a][rows] for a in "XYZ"} if metric_xyz is None
           else {"xyz": metric_xyz.take(rows, axis=0)})
    return {**xyz, "point_source_id": c["point_source_id"][rows],
            "gps_time": c["gps_time"][rows], "bits": bits[rows]}


def held_chunks(held, path: Path, bit: int,
                metric: Metric) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(metric xyz, point_source_id, GPS time) of the points of ``path`` that selection ``bit``
    keeps, chunk by chunk as the first pass read them (the coordinates exactly as laspy scales
    them)."""
    from calidar.io.las import las_header

    header = las_header(path)
    for c in held.chunks(path):
        fast = None if "xyz" in c else selected_points(c, bit, header.scales, header.offsets)
        if fast is not None:  # one numba loop (calidar.ingest.chunk_pass)
            yield fast
            continue
        rows = np.flatnonzero((c["bits"] >> bit) & 1)
        if "xyz" in c:
            xyz = c["xyz"].take(rows, axis=0)
        else:
            xyz = np.empty((rows.size, 3))
            for k, a in enumerate("XYZ"):
                xyz[:, k] = c[a][rows] * header.scales[k] + header.offsets[k]
        yield xyz, c["point_source_id"][rows], c["gps_time"][rows]
