"""Flight lines from LAS/LAZ files: by point_source_id, or by gaps in GPS time when ids are missing."""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pyproj
from numba import njit

from calidar.errors import InputError
from calidar.io.las import (
    LasPoints, PointOptions, concat_points, iter_las_fields, las_header, las_time_system, read_las,
)
from calidar.io.las_crs import las_crs

GAP_S = 10.0  #: a pause in GPS time longer than this starts a new flight line (s)


def line_ids(point_source_id: np.ndarray | None, gps_time: np.ndarray, gap_s: float = GAP_S) -> tuple[np.ndarray, str]:
    """One flight-line id per point and how they were found ("point_source_id" or "gps_time_gaps"):
    :func:`split_lines` with every point its own span of time."""
    psid = () if point_source_id is None else _distinct(np.asarray(point_source_id)).tolist()
    index = split_lines(psid, {}, gps_time, gps_time, gap_s)
    return index.of(point_source_id, gps_time), index.how


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
    psid = () if merged.point_source_id is None else _distinct(merged.point_source_id).tolist()
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
            raise InputError(path, "points", "no points; expected a strip (flight line) with points")
        with open(path, "rb") as f:
            f.seek(h.offset_to_point_data)
            head = hashlib.sha256(f.read(1 << 20)).hexdigest()
        key = (int(h.point_count), tuple(np.round(h.mins, 6)), tuple(np.round(h.maxs, 6)), head)
        other = seen.setdefault(key, path)
        if other is not path:
            same = other.resolve() == path.resolve() or other.samefile(path)
            raise InputError(path, None, "given twice; expected each strip once" if same else
                             f"holds the same points as {other.name}: a duplicate; expected each strip once")


def shared_id_splits(spans: dict[tuple[int, str], tuple[float, float]], gap_s: float = GAP_S
                     ) -> tuple[dict[int, tuple[np.ndarray, np.ndarray]], list[str]]:
    """Flight lines that are distinct files with one point_source_id, kept apart (issue 27).

    ``spans``: (point_source_id, file name) → (first, last GPS time s) of its points. Files of one
    id whose time spans lie more than ``gap_s`` apart (they do not interleave: separate passes,
    not one line cut into tiles) are separate flight lines: {id: (start times of its parts, the
    line id of each part: the id itself, then ids above every id held)} and a note per split id."""
    by_id: dict[int, list] = {}
    for (i, name), (t0, t1) in spans.items():
        by_id.setdefault(int(i), []).append((float(t0), float(t1), name))
    splits, notes, free = {}, [], max(by_id, default=0) + 1
    for i, files in sorted(by_id.items()):
        if len(files) < 2:
            continue
        files.sort()
        parts, reach = [[files[0]]], files[0][1]
        for f in files[1:]:
            if f[0] - reach > gap_s:
                parts.append([])
            parts[-1].append(f)
            reach = max(reach, f[1])
        if len(parts) < 2:
            continue
        ids = np.array([i, *range(free, free + len(parts) - 1)], np.int64)
        free += len(parts) - 1
        splits[i] = (np.array([p[0][0] for p in parts]), ids)
        listed = "; ".join(f"{', '.join(f[2] for f in p)} ({p[0][0]:.1f}–{max(f[1] for f in p):.1f} s) as line {j}"
                           for p, j in zip(parts, ids))
        notes.append(f"point_source_id {i} is held by {sum(map(len, parts))} files whose GPS times do not interleave: "
                     f"kept apart as {len(parts)} flight lines: {listed}")
    return splits, notes


def split_ids(ids: np.ndarray, t: np.ndarray, splits: dict) -> np.ndarray:
    """Line ids (point_source_id) of points at times ``t`` with the shared ids of ``splits``
    (:func:`shared_id_splits`) replaced by their parts' ids."""
    if not splits:
        return ids
    ids = np.array(ids, np.int64)
    for i, (starts, part_ids) in splits.items():
        rows = np.flatnonzero(ids == i)
        if rows.size:
            ids[rows] = part_ids[np.clip(np.searchsorted(starts, t[rows], side="right") - 1, 0, starts.size - 1)]
    return ids


@dataclass(frozen=True)
class LineIndex:
    """The flight lines of a survey (:func:`split_lines`), to sort points into them chunk by chunk
    (:meth:`of`) as they would be sorted all at once."""

    how: str  #: "point_source_id" | "gps_time_gaps"
    ids: tuple[int, ...]
    starts: np.ndarray | None  #: gps_time_gaps: first GPS time (s) of each line
    splits: dict = field(default_factory=dict)  #: point_source_ids shared by files apart in time (:func:`shared_id_splits`)
    notes: tuple[str, ...] = ()  #: what the user should know about how the lines were found
    classes: dict = field(default_factory=dict)  #: LAS classes present in each file (:func:`index_flight_lines`)

    def of(self, point_source_id: np.ndarray | None, gps_time: np.ndarray) -> np.ndarray:
        """The flight-line id of each point (or of each span of points starting at ``gps_time``)."""
        if self.starts is None:
            return split_ids(np.asarray(point_source_id, np.int64), np.asarray(gps_time, float), self.splits)
        return np.searchsorted(self.starts, gps_time, side="right").astype(np.int64)


def split_lines(point_source_ids, spans: dict, first: np.ndarray, last: np.ndarray, gap_s: float = GAP_S) -> LineIndex:
    """The one flight-line splitter (every reader of strips calls it: points at once, a streamed
    pass's seconds, the strip ingest's groups).

    By point_source_id when ``point_source_ids`` (the distinct ids held) has at least two values,
    files sharing an id at times that do not interleave kept apart (:func:`shared_id_splits` on
    ``spans`` {(id, file name): (first, last GPS time)}); otherwise lines numbered 1, 2, … in time
    order from spans of points [``first``, ``last``] (GPS s; a point, a second, a group of points,
    none holding a gap > ``gap_s`` within): a line starts where a span begins more than ``gap_s``
    after every earlier one ended."""
    ids = {int(i) for i in point_source_ids}
    if len(ids) >= 2:
        splits, notes = shared_id_splits(spans, gap_s)
        ids |= {int(j) for _, part_ids in splits.values() for j in part_ids}
        return LineIndex("point_source_id", tuple(sorted(ids)), None, splits, tuple(notes))
    first, last = np.asarray(first, float), np.asarray(last, float)
    if first.size == 0:
        return LineIndex("gps_time_gaps", (1,), np.zeros(1))
    order = np.argsort(first, kind="stable")
    reach = np.maximum.accumulate(last[order])  # the latest end so far
    new = np.r_[True, first[order][1:] - reach[:-1] > gap_s]
    starts = first[order][new]
    return LineIndex("gps_time_gaps", tuple(range(1, starts.size + 1)), starts)


def index_flight_lines(paths: Sequence[str | Path], options: PointOptions = PointOptions(), gap_s: float = GAP_S,
                       chunk_points: int = 2_000_000, fields: tuple[str, ...] = (), on_chunk=None) -> LineIndex:
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
        for c in iter_las_fields(path, ("point_source_id", "classification", "gps_time", *fields), chunk_points):
            if on_chunk is not None:
                on_chunk(path, c)
            ids.update(_distinct(c["point_source_id"]).tolist())
            present[_distinct(c["classification"])] = True
            seconds.append(_second_spans(c["gps_time"]))
            add_spans(spans, c["point_source_id"], c["gps_time"], path.name)
        classes[path] = np.flatnonzero(present)
    lo, hi = _second_spans(np.concatenate([s[0] for s in seconds] + [s[1] for s in seconds])) if seconds else ((), ())
    return replace(split_lines(ids, spans, lo, hi, gap_s), classes=classes)


def add_spans(spans: dict, point_source_id, t: np.ndarray, name: str) -> None:
    """Widen ``spans`` {(point_source_id, file name): (first, last GPS time)} by a chunk's points."""
    psid = np.asarray(point_source_id, np.int64)
    ok = np.isfinite(t)
    ids = _distinct(psid[ok])
    if ids.size == 1:  # one line in the chunk (the usual case): no masks
        ti = t[ok]
        t0, t1 = spans.get((int(ids[0]), name), (np.inf, -np.inf))
        spans[(int(ids[0]), name)] = (min(t0, float(ti.min())), max(t1, float(ti.max())))
        return
    for i in ids:
        ti = t[ok & (psid == i)]
        t0, t1 = spans.get((int(i), name), (np.inf, -np.inf))
        spans[(int(i), name)] = (min(t0, float(ti.min())), max(t1, float(ti.max())))


def _distinct(values: np.ndarray) -> np.ndarray:
    """The distinct values, ascending, of small non-negative integers (LAS ids, classes) by one
    bincount; others by np.unique."""
    v = np.asarray(values)
    if v.size and v.dtype.kind in "ui" and 0 <= v.min() and v.max() < 1 << 16:
        return np.flatnonzero(np.bincount(v.ravel())).astype(v.dtype)
    return np.unique(v)


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
    """Smallest and largest of the times ``t`` in each slot ``k`` (0 ≤ k < n), and which slots hold any."""
    first, last, held = np.full(n, np.inf), np.full(n, -np.inf), np.zeros(n, np.bool_)
    for m in range(t.size):
        first[k[m]] = min(first[k[m]], t[m])
        last[k[m]] = max(last[k[m]], t[m])
        held[k[m]] = True
    return first, last, held


def _check_alike(paths: list[Path], options: PointOptions) -> None:
    """Every file in the CRS and GPS time system of the first (from their headers)."""
    check_consistent([(p, las_crs(las_header(p)) if options.crs is None else None, las_time_system(p, options.time_system))
                      for p in paths])


def check_consistent(files: Sequence[tuple[Path, pyproj.CRS | None, str]]) -> None:
    """Error unless every (path, CRS, GPS time system) has the CRS and time system of the first."""
    path0, crs0, system0 = files[0]
    for path, crs, system in files[1:]:
        if (crs is None) != (crs0 is None) or (crs is not None and not crs.equals(crs0, ignore_axis_order=True)):
            raise InputError(path, "crs", f"expected the CRS of {Path(path0).name} ({_name(crs0)}), got {_name(crs)}")
        if system != system0:
            raise InputError(path, "gps_time", f"expected {system0} like {Path(path0).name}, got {system}")


def _name(crs: pyproj.CRS | None) -> str:
    return "none" if crs is None else (f"EPSG:{crs.to_epsg()}" if crs.to_epsg() else crs.name)
