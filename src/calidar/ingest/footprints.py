"""The strip ingest's first pass (:mod:`calidar.ingest.strips`): each file read chunk by chunk
into footprints on the overlap grid, per group of points (point_source_id, GPS time bin of
``gap_s``: a bin never holds two lines), with the time checks (trajectory coverage, one GPS
week), the geometry checks (:mod:`calidar.ingest.plausibility`) and the overlap-quality counts
(:class:`calidar.ingest.stages.LineCounts`); what the second pass needs of each point kept on
disk when it fits (:mod:`calidar.ingest.held`). The groups become flight lines by
:func:`calidar.strips.lines.split_lines`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from types import SimpleNamespace

import numpy as np

from calidar.ingest import Progress
from calidar.ingest.plausibility import GeometryCheck, sample_rows
from calidar.ingest.settings import BIN_BITS, HELD_BYTES_PER_POINT, IngestSettings
from calidar.ingest.source import (
    StripFile, calibration_mask, group_keys, planar_xy, split_rows,
)
from calidar.ingest.stages import LineCounts
from calidar.ingest.times import FileTimes, points_ecef
from calidar.io.las import iter_las_chunks, las_header
from calidar.strips.lines import add_spans, split_lines, widen_span
from calidar.strips.overlap import cell_counts, cell_keys
from calidar.strips.quality import overlap_cell
from calidar.strips.selection import FIELDS as SELECTION_FIELDS
from calidar.strips.strip import LocalFrame


@dataclass
class Footprints:
    """Pass 1's accumulators per group: cell counts, time range (trajectory's system), the
    overlap-quality counts (:class:`calidar.ingest.stages.LineCounts`)."""

    cells: dict = field(default_factory=dict)
    t_min: dict = field(default_factory=dict)
    t_max: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)  #: group → the name of the (first) file holding it
    points: dict = field(default_factory=dict)  #: group → its points (every class)
    spans: dict = field(default_factory=dict)  #: (point_source_id, file name) → (first, last time)
    #: file → its GeometryCheck (calidar.ingest.plausibility)
    checks: dict = field(default_factory=dict)
    quality: LineCounts = field(default_factory=lambda: LineCounts(overlap_cell(None)))

    def add(self, groups: np.ndarray, keys: np.ndarray, t: np.ndarray, name: str, chunk,
            quality_keys, use: np.ndarray | None = None) -> None:
        """A chunk's points (LasPoints with the selection fields) of ``groups`` in overlap cells
        ``keys`` and quality-grid cells ``quality_keys``, at times ``t``; the footprints count
        the points of ``use`` only (None: all; :func:`calidar.ingest.source.calibration_mask`)."""
        if chunk.point_source_id is not None:
            add_spans(self.spans, chunk.point_source_id, t, name)
        one = groups.size and groups[0] == groups[-1] and np.all(groups == groups[0])
        # one group (as usual): the chunk's own arrays, not gathered copies
        parts = [(int(groups[0]), slice(None))] if one else split_rows(groups)
        for g, rows in parts:
            self.files.setdefault(g, name)
            self.points[g] = self.points.get(g, 0) + (groups.size if one else rows.size)
            counted = (rows if use is None else use) if one else (
                rows if use is None else rows[use[rows]])
            self.cells.setdefault(g, []).append(cell_counts(keys[counted]))
            self.t_min[g] = min(self.t_min.get(g, np.inf), float(t[rows].min()))
            self.t_max[g] = max(self.t_max.get(g, -np.inf), float(t[rows].max()))
            fields = {f: None if getattr(chunk, f) is None else getattr(chunk, f)[rows]
                      for f in SELECTION_FIELDS}
            points = SimpleNamespace(xyz=quality_keys[rows], **fields)
            self.quality.add(g, points, quality_keys[rows])

    def merge(self, other: "Footprints") -> "Footprints":
        """Both files' groups (a group may span files)."""
        self.checks.update(other.checks)
        for k, (t0, t1) in other.spans.items():
            widen_span(self.spans, k, t0, t1)
        for g, cells in other.cells.items():
            self.files.setdefault(g, other.files[g])
            self.points[g] = self.points.get(g, 0) + other.points[g]
            self.cells.setdefault(g, []).extend(cells)
            self.t_min[g] = min(self.t_min.get(g, np.inf), other.t_min[g])
            self.t_max[g] = max(self.t_max.get(g, -np.inf), other.t_max[g])
        self.quality.merge(other.quality)
        return self

    def lines(self, gap_s: float, notes: list | None = None) -> tuple[np.ndarray, np.ndarray, str]:
        """(sorted groups, line id of each, how), by :func:`calidar.strips.lines.split_lines` (what
        the user should know about the lines added to ``notes``)."""
        groups = np.array(sorted(self.cells), np.int64)
        psid = groups >> BIN_BITS
        t0 = np.array([self.t_min[int(g)] for g in groups])
        t1 = np.array([self.t_max[int(g)] for g in groups])
        index = split_lines(np.unique(psid).tolist(), self.spans, t0, t1, gap_s)
        if notes is not None:
            notes += index.notes
        return groups, index.of(psid, t0), index.how


def file_footprints(frame: LocalFrame, trajectory, settings: IngestSettings, f: StripFile,
                hold=None) -> tuple[Footprints, int | None, bool]:
    """Footprints and time checks of one file, chunk by chunk, its GPS week and whether ``hold``
    (a :class:`calidar.ingest.held.HeldFiles`, or None) keeps the whole file: what pass
    2 and the overlap-quality stages need of its chunks (a task)."""
    acc, grid = Footprints(), overlap_cell(None)
    times = FileTimes(f.path, trajectory, f.time_system)
    check, header = GeometryCheck(f.path.name), las_header(f.path)
    scaling = (header.scales, header.offsets)
    acc.checks[f.path] = check
    fields = ("point_source_id", "scan_angle_deg", *SELECTION_FIELDS)
    for chunk in iter_las_chunks(f.path, settings.chunk_points, fields=fields, options=f.points):
        t = times.feed(chunk.gps_time)
        ok = np.isfinite(t)
        if hold is not None and not (ok.all() and hold.add(f.path, chunk, t, *scaling)):
            hold = None  # not whole: read again
        chunk = chunk if ok.all() else chunk.select(ok)
        k = sample_rows(len(chunk))
        # points outside the trajectory: told by times.finish()
        if np.all(trajectory.covers(t[ok][k])):
            check.add(trajectory, t[ok][k], points_ecef(chunk.select(k)), chunk.scan_angle_deg[k],
                      len(chunk))
        else:
            check.seen += len(chunk)
        chunk = replace(chunk, scan_angle_deg=None)
        xy = planar_xy(chunk, frame)
        keys = cell_keys(xy, settings.cell_m)
        quality_keys = keys if grid == settings.cell_m else cell_keys(xy, grid)
        groups = group_keys(chunk.point_source_id, t[ok], settings.gap_s)
        use = calibration_mask(chunk, settings)
        acc.add(groups, keys, t[ok], f.path.name, chunk, quality_keys, use)
    # the trajectory's span is what falls short
    return acc, times.finish(name_trajectory=True), hold is not None


def first_pass(files: list[StripFile], frame: LocalFrame, trajectory, settings: IngestSettings,
               progress: Progress, run: Callable | None = None,
               in_process: bool = True) -> tuple[Footprints, dict, object]:
    """Footprints and time checks of every file (one task each, run by ``run``: a
    :meth:`calidar.strips.distribute.Workers.run`; None: one at a time here); the GPS week of each
    file; the points kept for pass 2 and the overlap quality (``in_process``: the tasks run here;
    see :data:`calidar.ingest.source.HOLD_POINTS_BYTES`): a HeldFiles, or None."""
    import shutil
    import tempfile

    from calidar.ingest.held import HeldFiles
    from calidar.strips.distribute import Workers

    run = run or Workers().run
    acc, weeks, done = Footprints(), {}, 0
    counts = [las_header(f.path).point_count for f in files]
    free = shutil.disk_usage(tempfile.gettempdir()).free // 2 if in_process else 0
    room = min(settings.hold_bytes, free) if in_process else 0
    hold = files_to_hold(counts, room)
    held = HeldFiles() if any(hold) else None
    tasks = [(f, held if h else None) for f, h in zip(files, hold)]
    parts = run(file_footprints, tasks, shared=(frame, trajectory, settings),
                kind="read footprints")
    for f, n, (part, week, whole) in zip(files, counts, parts):
        acc.merge(part)
        weeks[f.path] = week
        if whole:
            held.complete.add(f.path)
        done += n
        progress("reading strips", done, 2 * sum(counts))  # points, both passes
    return acc, weeks, held


def files_to_hold(counts: list[int], room: int) -> list[bool]:
    """Which files pass 1 holds for pass 2: in file order, those whose points still fit in
    ``room`` bytes."""
    hold = []
    for n in counts:
        need = HELD_BYTES_PER_POINT * n
        hold.append(need <= room)
        room -= need if need <= room else 0
    return hold
