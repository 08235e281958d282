"""Flight lines of LAS/LAZ files, read: all at once (:func:`read_flight_lines`) or from a streamed
pass over point_source_id, classification and GPS time only (:func:`index_flight_lines`), both
split by the one splitter, :func:`calidar.strips.lines.split_lines`; and the checks every strip
reader makes first (a file given twice or copied, files in different CRSs or time systems)."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pyproj
from numba import njit

from calidar.errors import InputError
from calidar.ingest.chunk_pass import chunk_summary
from calidar.ingest.prefetch import prefetched
from calidar.io.las import (LasPoints, PointOptions, concat_points, iter_las_fields, las_header,
                            las_time_system, read_las)
from calidar.io.las_crs import las_crs
from calidar.strips.lines import (GAP_S, LineIndex, add_spans, distinct, split_lines,
                                  widen_span)


def read_flight_lines(paths: Sequence[str | Path], crs=None, gap_s: float = GAP_S,
                      options: PointOptions | None = None) -> tuple[dict[int, LasPoints], str]:
    """Read LAS/LAZ files (``crs``, or ``options``: the shared point options) and split their points
    into flight lines {id: points}.

    All files must share one CRS and one GPS time system (clear errors otherwise).
    """
    if not paths:
        raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
    _check_alike([Path(p) for p in paths], options or PointOptions(crs=crs))
    check_distinct(paths)
    clouds = [read_las(p, crs=crs, options=options) for p in paths]
    merged = concat_points(clouds)
    spans: dict = {}
    for c in clouds:
        if c.point_source_id is not None:
            add_spans(spans, c.point_source_id, c.gps_time, c.path.name)
    psid = () if merged.point_source_id is None else distinct(merged.point_source_id).tolist()
    index = split_lines(psid, spans, merged.gps_time, merged.gps_time, gap_s)
    ids, how = index.of(merged.point_source_id, merged.gps_time), index.how
    source = np.repeat(np.arange(len(clouds)), [len(c) for c in clouds])  # the file of each point
    return {int(i): replace(merged.select(ids == i), path=clouds[source[np.argmax(ids == i)]].path)
            for i in np.unique(ids)}, how


def check_distinct(paths: Sequence[str | Path]) -> None:
    """Refuse a file given twice, a file without points and a file holding the same points as
    another (a copy: the same point count and bounds and the same first MiB of point records):
    each would silently merge into, or vanish from, the flight lines. Reads headers and 1 MiB."""
    seen: dict[tuple, Path] = {}
    for path in map(Path, paths):
        h = las_header(path)
        if h.point_count == 0:
            raise InputError(path, "points",
                             "no points; expected a strip (flight line) with points")
        with open(path, "rb") as f:
            f.seek(h.offset_to_point_data)
            head = hashlib.sha256(f.read(1 << 20)).hexdigest()
        key = (int(h.point_count), tuple(np.round(h.mins, 6)), tuple(np.round(h.maxs, 6)), head)
        other = seen.setdefault(key, path)
        if other is not path:
            same = other.resolve() == path.resolve() or other.samefile(path)
            copy = f"holds the same points as {other.name}: a duplicate"
            raise InputError(path, None, f"{'given twice' if same else copy}; expected each strip "
                             "once")


def index_flight_lines(paths: Sequence[str | Path], options: PointOptions = PointOptions(),
                       gap_s: float = GAP_S, chunk_points: int = 2_000_000,
                       fields: tuple[str, ...] = (), on_chunk=None) -> LineIndex:
    """Flight lines and classes of LAS/LAZ files from a pass over their point_source_id,
    classification and GPS time only (every file: one CRS, one time system, clear errors otherwise).
    Time gaps are found from each second's first and last time, so memory holds seconds, not points.
    ``on_chunk(path, chunk)``, when given, sees every chunk ({name: array}, with ``fields`` too)."""
    if not paths:
        raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
    paths = [Path(p) for p in paths]
    _check_alike(paths, options)
    check_distinct(paths)
    ids, seconds, classes, spans = set(), [], {}, {}
    for path in paths:
        present = np.zeros(256, bool)
        # the next chunk decompressed while this one is worked on (calidar.ingest.prefetch)
        names = ("point_source_id", "classification", "gps_time", *fields)
        for c in prefetched(iter_las_fields(path, names, chunk_points)):
            if on_chunk is not None:
                on_chunk(path, c)
            psid, t = c["point_source_id"], c["gps_time"]
            got = chunk_summary(psid, c["classification"], t)  # one numba pass, the same values
            if got is None:
                ids.update(distinct(psid).tolist())
                present[distinct(c["classification"])] = True
                seconds.append(_second_spans(t))
                add_spans(spans, psid, t, path.name)
                continue
            ids.update(got[0].tolist())
            present[got[1]] = True
            seconds.append(got[2] if got[2] is not None else _second_spans(t))
            for i, (t0, t1) in got[3].items():  # as add_spans
                widen_span(spans, (i, path.name), t0, t1)
        classes[path] = np.flatnonzero(present)
    if seconds:  # each second's first and last time, of every chunk
        lo, hi = _second_spans(np.concatenate([s[0] for s in seconds] + [s[1] for s in seconds]))
    else:
        lo, hi = (), ()
    return replace(split_lines(ids, spans, lo, hi, gap_s), classes=classes)


def _second_spans(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """First and last finite time (s) within each whole second holding any, seconds ascending."""
    t = t[np.isfinite(t)]
    if t.size == 0:
        return t, t
    sec = np.floor(t)
    lo = sec.min()
    if sec.max() - lo < 4 * t.size + 65536:  # a chunk's seconds: one pass over a dense table
        first, last, held = _dense_spans(t, (sec - lo).astype(np.int64), int(sec.max() - lo) + 1)
        return first[held], last[held]
    t = np.sort(t)
    sec = np.floor(t)
    start = np.r_[0, np.flatnonzero(sec[1:] != sec[:-1]) + 1]
    return t[start], t[np.r_[start[1:], t.size] - 1]


@njit(cache=True, nogil=True)
def _dense_spans(t, k, n):  # pragma: no cover - numba
    """Smallest and largest of the times ``t`` in each slot ``k`` (0 ≤ k < n), and which slots hold
    any."""
    first, last, held = np.full(n, np.inf), np.full(n, -np.inf), np.zeros(n, np.bool_)
    for m in range(t.size):
        first[k[m]] = min(first[k[m]], t[m])
        last[k[m]] = max(last[k[m]], t[m])
        held[k[m]] = True
    return first, last, held


def _check_alike(paths: list[Path], options: PointOptions) -> None:
    """Every file in the CRS and GPS time system of the first (from their headers)."""
    check_consistent([(p, las_crs(las_header(p)) if options.crs is None else None,
                       las_time_system(p, options.time_system)) for p in paths])


def check_consistent(files: Sequence[tuple[Path, pyproj.CRS | None, str]]) -> None:
    """Error unless every (path, CRS, GPS time system) has the CRS and time system of the first."""
    path0, crs0, system0 = files[0]
    for path, crs, system in files[1:]:
        other = (crs is None) != (crs0 is None)
        other |= crs is not None and not crs.equals(crs0, ignore_axis_order=True)
        if other:
            raise InputError(path, "crs", f"expected the CRS of {Path(path0).name} "
                             f"({_name(crs0)}), got {_name(crs)}")
        if system != system0:
            raise InputError(path, "gps_time",
                             f"expected {system0} like {Path(path0).name}, got {system}")


def _name(crs: pyproj.CRS | None) -> str:
    return "none" if crs is None else (f"EPSG:{crs.to_epsg()}" if crs.to_epsg() else crs.name)
