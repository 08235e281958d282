"""Flight lines: by point_source_id, or by gaps in GPS time when ids are missing
(:func:`split_lines`, the one splitter; the files are read by :mod:`calidar.ingest.lines`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

GAP_S = 10.0  #: a pause in GPS time longer than this starts a new flight line (s)


def line_ids(point_source_id: np.ndarray | None, gps_time: np.ndarray,
             gap_s: float = GAP_S) -> tuple[np.ndarray, str]:
    """One flight-line id per point and how they were found ("point_source_id" or "gps_time_gaps"):
    :func:`split_lines` with every point its own span of time."""
    psid = () if point_source_id is None else distinct(np.asarray(point_source_id)).tolist()
    index = split_lines(psid, {}, gps_time, gps_time, gap_s)
    return index.of(point_source_id, gps_time), index.how


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
        listed = "; ".join(f"{', '.join(f[2] for f in p)} "
                           f"({p[0][0]:.1f}–{max(f[1] for f in p):.1f} s) as line {j}"
                           for p, j in zip(parts, ids))
        notes.append(f"point_source_id {i} is held by {sum(map(len, parts))} files whose GPS times "
                     f"do not interleave: kept apart as {len(parts)} flight lines: {listed}")
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
            ids[rows] = part_ids[np.clip(np.searchsorted(starts, t[rows], side="right") - 1, 0,
                                         starts.size - 1)]
    return ids


@dataclass(frozen=True)
class LineIndex:
    """The flight lines of a survey (:func:`split_lines`), to sort points into them chunk by chunk
    (:meth:`of`) as they would be sorted all at once."""

    how: str  #: "point_source_id" | "gps_time_gaps"
    ids: tuple[int, ...]
    starts: np.ndarray | None  #: gps_time_gaps: first GPS time (s) of each line
    #: point_source_ids shared by files apart in time (:func:`shared_id_splits`)
    splits: dict = field(default_factory=dict)
    notes: tuple[str, ...] = ()  #: what the user should know about how the lines were found
    #: LAS classes present in each file (:func:`calidar.ingest.lines.index_flight_lines`)
    classes: dict = field(default_factory=dict)

    def of(self, point_source_id: np.ndarray | None, gps_time: np.ndarray) -> np.ndarray:
        """The flight-line id of each point (or of each span of points starting at ``gps_time``)."""
        if self.starts is None:
            return split_ids(np.asarray(point_source_id, np.int64), np.asarray(gps_time, float),
                             self.splits)
        return np.searchsorted(self.starts, gps_time, side="right").astype(np.int64)


def split_lines(point_source_ids, spans: dict, first: np.ndarray, last: np.ndarray,
                gap_s: float = GAP_S) -> LineIndex:
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


def add_spans(spans: dict, point_source_id, t: np.ndarray, name: str) -> None:
    """Widen ``spans`` {(point_source_id, file name): (first, last GPS time)} by a chunk."""
    psid = np.asarray(point_source_id, np.int64)
    ok = np.isfinite(t)
    ids = distinct(psid[ok])
    if ids.size == 1:  # one line in the chunk (the usual case): no masks
        ti = t[ok]
        widen_span(spans, (int(ids[0]), name), float(ti.min()), float(ti.max()))
        return
    for i in ids:
        ti = t[ok & (psid == i)]
        widen_span(spans, (int(i), name), float(ti.min()), float(ti.max()))


def widen_span(spans: dict, key, first: float, last: float) -> None:
    """``spans[key]`` (first, last GPS time) widened to take in ``first`` … ``last``."""
    t0, t1 = spans.get(key, (np.inf, -np.inf))
    spans[key] = (min(t0, first), max(t1, last))


def distinct(values: np.ndarray) -> np.ndarray:
    """The distinct values, ascending, of small non-negative integers (LAS ids, classes) by one
    bincount; others by np.unique."""
    v = np.asarray(values)
    if v.size and v.dtype.kind in "ui" and 0 <= v.min() and v.max() < 1 << 16:
        return np.flatnonzero(np.bincount(v.ravel())).astype(v.dtype)
    return np.unique(v)


