"""A LAS/LAZ file checked for what its header claims (issue 27): the scale factors and offsets,
the point count against the LAZ chunk table and against the compressed bytes of the last chunk,
and every chunk's coordinates against the header's bounds while streaming.

A LAZ file whose header counts fewer points than it holds would otherwise be read at the
header's count (laspy stops there) and one counting more would decode past its data; a
corrupted chunk decodes to coordinates kilometres outside the bounds. Each becomes a clear
:class:`calidar.errors.InputError` naming the file, the field and the point range.
"""

from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path

import laspy
import lazrs
import numpy as np

from calidar.errors import InputError

MAX_OFFSET = 1e9  #: |offset| beyond this (CRS units) is a damaged header, not a place
MAX_SCALE = 1.0  #: a scale factor above 1 (m or deg) would store coordinates coarser than a metre
MIN_SCALE = 1e-12
#: compressed bytes the LAZ decoder may still hold unread at the end of a chunk (its look-ahead is
#: a few bytes; ≈ 10 bytes a point): fewer bytes used than the chunk holds minus this means the
#: header counts fewer points than the chunk holds
LAZ_SLACK_BYTES = 96
LAZ_RECORD_ID = 22204
LAYERED_FORMAT = 6  #: LAS point formats from 6 on are compressed in layers (LAZ 1.4)


def check_scales(header: laspy.LasHeader, path: Path) -> None:
    """Error unless every scale factor is finite, positive and ≤ :data:`MAX_SCALE`, and every offset
    finite within ±:data:`MAX_OFFSET` (a zero scale stores every coordinate at the offset)."""
    scales, offsets = np.asarray(header.scales, float), np.asarray(header.offsets, float)
    for axis, scale, offset in zip("xyz", scales, offsets):
        if not (MIN_SCALE <= scale <= MAX_SCALE):
            raise InputError(path, f"{axis} scale factor", "expected a positive scale ≤ "
                             f"{MAX_SCALE:g} (e.g. 0.01 or 0.001), got {scale:g}: a damaged or "
                             "wrongly written header")
        if not abs(offset) <= MAX_OFFSET:
            raise InputError(path, f"{axis} offset", "expected a finite offset within "
                             f"±{MAX_OFFSET:g}, got {offset:g}: a damaged or wrongly written "
                             "header")


def _laz_vlr(header: laspy.LasHeader):
    """The LAZ VLR of ``header`` (None: not a LAZ file)."""
    for v in header.vlrs:
        if getattr(v, "record_id", None) == LAZ_RECORD_ID:
            return v
    return None


def check_laz_count(header: laspy.LasHeader, path: Path) -> None:
    """Error when a LAZ file's chunk table, or the compressed bytes of its last chunk, hold more or
    fewer points than the header counts. Cached per file (path, size, modification time): it
    decodes the last chunk (≤ 50 000 points, some 30 ms) once a process."""
    if not header.are_points_compressed or header.point_count == 0:
        return
    vlr = _laz_vlr(header)
    # laspy drops the LAZ VLR once points are read: its chunk size kept for check_bounds' messages
    if vlr is not None:
        laz = lazrs.LazVlr(vlr.record_data)
        fixed = not laz.uses_variable_size_chunks()
        header.calidar_laz_chunk_size = laz.chunk_size() if fixed else None
    st = os.stat(path)
    layered = header.point_format.id >= LAYERED_FORMAT
    problem = _laz_count_problem(str(Path(path).resolve()), st.st_size, st.st_mtime_ns,
                                 int(header.offset_to_point_data), int(header.point_count),
                                 layered)
    if problem:
        raise InputError(path, "point_count", problem)


@lru_cache(maxsize=256)
def _laz_count_problem(path: str, size: int, mtime_ns: int, offset: int, count: int,
                       layered: bool) -> str | None:
    """What is wrong with the point count of a LAZ file (None: nothing); size and mtime key the
    cache. ``layered``: point formats 6–10, whose chunks state their own point counts."""
    with laspy.open(path) as reader:
        vlr = _laz_vlr(reader.header)
    if vlr is None:
        return None
    laz = lazrs.LazVlr(vlr.record_data)
    try:
        with open(path, "rb") as f:
            f.seek(offset)
            table = lazrs.read_chunk_table(f, laz)
            data_start = f.tell()
    except (lazrs.LazrsError, OSError, ValueError):
        return None  # no chunk table: the points are read sequentially and checked while read
    if not table:
        return None
    if layered:
        return _layered_count_problem(path, data_start, table, laz.item_size(), count)
    problem, last_first = _table_count_problem(laz, table, count)
    if problem:
        return problem
    last_bytes = int(table[-1][1])
    chunk_end = data_start + sum(int(c[1]) for c in table)
    return _last_chunk_problem(path, offset, vlr.record_data, laz, last_first, count - last_first,
                               chunk_end, last_bytes)


def _table_count_problem(laz, table, count: int) -> tuple[str | None, int]:
    """The header's ``count`` against a point-wise LAZ chunk table (what is wrong, None: nothing)
    and the number of the last chunk's first point: variable-size chunks state their counts,
    fixed-size ones hold ``chunk_size`` points each, the last one 1 to ``chunk_size``."""
    counts = np.array([c[0] for c in table], np.int64)
    if laz.uses_variable_size_chunks():
        held = int(counts.sum())
        if held != count:
            return (f"the header says {count} points, the LAZ chunk table {held}: a damaged header "
                    "(or a truncated file); expected the same count"), 0
        return None, held - int(counts[-1])
    size_ = laz.chunk_size()
    lo, hi = (len(table) - 1) * size_ + 1, len(table) * size_
    if not lo <= count <= hi:
        return (f"the header says {count} points, the LAZ chunk table {len(table)} chunks of "
                f"{size_} ({lo}–{hi} points): a damaged header; expected a count in that range"), 0
    return None, (len(table) - 1) * size_


def _layered_count_problem(path: str, data_start: int, table, item_size: int,
                           count: int) -> str | None:
    """The header's count against the counts the chunks of a layered LAZ (formats 6–10) state:
    each chunk starts with its first point raw (``item_size`` bytes), then its point count
    (uint32; LASzip's layered chunk layout)."""
    held, start = 0, data_start
    with open(path, "rb") as f:
        for n_bytes in (int(c[1]) for c in table):
            f.seek(start + item_size)
            raw = f.read(4)
            if len(raw) < 4:
                return f"the LAZ chunk at byte {start} is cut short: a truncated file"
            held += int.from_bytes(raw, "little")
            start += n_bytes
    if held != count:
        what = "fewer" if count < held else "more"
        return (f"the header says {count} points, the LAZ chunks hold {held}: a header counting "
                f"{what} points than the file holds; expected the true count (rewrite the file, "
                "e.g. with las2las or pdal translate)")
    return None


def _last_chunk_problem(path, offset, record_data, laz, first, n, chunk_end,
                        chunk_bytes) -> str | None:
    """Decode the last chunk's ``n`` points (by the header): the decoder must have used its bytes
    (to within :data:`LAZ_SLACK_BYTES`), else the chunk holds more points than the header
    counts."""
    with open(path, "rb") as f:
        f.seek(offset)
        try:
            dec = lazrs.LasZipDecompressor(f, record_data)
            dec.seek(first)
            dec.decompress_many(bytearray(n * laz.item_size()))
        except (lazrs.LazrsError, ValueError, OSError) as e:
            return (f"cannot decode the {n} points the header counts in the last LAZ chunk "
                    f"(points {first}–{first + n - 1}: {e}): a truncated or damaged file, or a "
                    "header counting more points than it holds")
        used = f.tell()
    if used > chunk_end + LAZ_SLACK_BYTES:
        return (f"the header says {first + n} points, but the last LAZ chunk ends before its "
                f"{n}th point (decoding ran {used - chunk_end} bytes past it): a header counting "
                "more points than the file holds; expected the true count")
    if used < chunk_end - LAZ_SLACK_BYTES:
        share = (used - (chunk_end - chunk_bytes)) / max(chunk_bytes, 1)
        return (f"the header says {first + n} points, but the last LAZ chunk holds more (its {n} "
                f"points use {share:.0%} of its {chunk_bytes} bytes): a header counting fewer "
                "points than the file holds; expected the true count (rewrite the file, e.g. with "
                "las2las or pdal translate)")
    return None


def bounds_tolerance(header: laspy.LasHeader) -> tuple[np.ndarray, np.ndarray]:
    """Low and high limits of plausible coordinates: the header's bounds widened on each axis by its
    own extent (at least 1 unit) and ten scale steps; (-inf, inf) when the header has no bounds."""
    lo, hi = np.asarray(header.mins, float), np.asarray(header.maxs, float)
    valid = np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi >= lo)
    if not valid or not (lo.any() or hi.any()):
        return np.full(3, -np.inf), np.full(3, np.inf)
    tol = np.maximum(hi - lo, 1.0) + 10 * np.asarray(header.scales, float)
    return lo - tol, hi + tol


def check_bounds(xyz: np.ndarray, limits: tuple[np.ndarray, np.ndarray],
                 header: laspy.LasHeader, path, first: int) -> None:
    """Error when points of a chunk (``first``: the number of its first point) lie outside the
    header's bounds by more than their extent: a corrupted (LAZ) chunk or a damaged header. Costs
    one min and max per axis."""
    lo, hi = limits
    if xyz.shape[0] == 0 or not np.isfinite(lo).all():
        return
    for k, axis in enumerate("xyz"):
        col = xyz[:, k]  # per column: 8× faster than xyz.min(axis=0) on (N, 3)
        if col.min() >= lo[k] and col.max() <= hi[k]:
            continue
        bad = (xyz[:, k] < lo[k]) | (xyz[:, k] > hi[k])
        rows = np.flatnonzero(bad)
        i0, i1 = first + int(rows[0]), first + int(rows[-1])
        where = _laz_chunks(header, i0, i1)
        raise InputError(path, axis, f"{rows.size} points ({i0}–{i1}{where}) have {axis} from "
                         f"{xyz[rows, k].min():.6g} to {xyz[rows, k].max():.6g}, outside the "
                         f"header's bounds {header.mins[k]:.6g}–{header.maxs[k]:.6g}: a corrupted "
                         "chunk or a damaged header; expected coordinates within the bounds")


def _laz_chunks(header: laspy.LasHeader, i0: int, i1: int) -> str:
    """", LAZ chunk k" (or "chunks k–l") of points i0–i1 of a LAZ file with fixed-size chunks,
    else ""."""
    size = getattr(header, "calidar_laz_chunk_size", None)
    if not size:
        return ""
    c0, c1 = i0 // size, i1 // size
    return f", LAZ chunk {c0}" if c0 == c1 else f", LAZ chunks {c0}–{c1}"
