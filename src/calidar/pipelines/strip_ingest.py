"""Streaming ingest of LAS/LAZ strips for the strip calibration: bounded memory, linear time.

Two streamed passes over the files (chunks of :attr:`IngestOptions.chunk_points`, never a
whole file in memory):

1. coarse: footprints on the overlap grid (cells of ``cell_m`` in the CRS's own metres when it
   is projected, else in the survey's :class:`~calidar.strips.strip.LocalFrame`, set from the
   files' header bounds)
   accumulated per group of points (point_source_id, GPS time bin of ``gap_s``), the time
   checks (trajectory coverage, one GPS week). The groups become flight lines exactly as
   :func:`calidar.strips.lines.line_ids` splits them (by point_source_id, else by gaps
   > ``gap_s`` in GPS time: a bin of ``gap_s`` never holds two lines), their footprints the
   pairwise overlap cells (:func:`calidar.strips.overlap.common_cells`), thinned to
   ``budget_points`` per strip by keeping whole cells spread evenly (:mod:`calidar.strips.thin`);
2. keep: the points of each line inside its kept cells, transformed to ECEF, from which the
   :class:`~calidar.strips.strip.Strip` s are built (one inverse georeferencing).

:class:`~calidar.pipelines.strip_source.StripSource` streams the whole lines again for the
outputs.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from calidar.errors import CalibrationError, InputError
from calidar.io.las import iter_las_chunks, las_file_crs, las_header, las_time_system
from calidar.pipelines import Progress, no_progress
from calidar.pipelines.inputs import FileTimes, points_ecef
from calidar.pipelines.line_quality import LineCounts
from calidar.pipelines.plausibility import GeometryCheck, heights_notes, sample_rows
from calidar.pipelines.strip_source import (
    BIN_BITS, BLOCK_PATCHES, HELD_BYTES_PER_POINT, MAX_BLOCK_CELLS, IngestOptions, StripFile, StripSource, group_keys,
    planar_xy, split_rows,
)
from calidar.strips.overlap import cell_counts, cell_keys, common_cells, merge_counts, strip_name, unpaired_notes
from calidar.strips.quality import overlap_cell
from calidar.strips.lines import add_spans, shared_id_splits, split_ids
from calidar.strips.selection import FIELDS as SELECTION_FIELDS
from calidar.strips.strip import LocalFrame, Strip
from calidar.strips.thin import thin_cells


def _files(paths, trajectory, sensor, options: IngestOptions) -> list[StripFile]:
    """Each file's CRS (its own, --crs or sensor.toml's) and time system; all must agree, and
    match the trajectory's (adjusted standard points become its week seconds, not back)."""
    from calidar.strips.lines import check_consistent, check_distinct

    check_distinct(paths)
    files = []
    for p in map(Path, paths):
        crs = las_file_crs(p, options.points.crs)
        if crs is None and sensor.crs is None:
            raise InputError(p, "crs", "the file has no CRS and sensor.toml gives none; expected one of them")
        opts = options.points if crs is not None else replace(options.points, crs=sensor.crs)
        files.append(StripFile(p, opts, las_time_system(p, opts.time_system)))
        if files[-1].time_system == "gps_week_seconds" and trajectory.time_system == "gps_adjusted_standard":
            raise InputError(p, "gps_time", "holds GPS week seconds but the trajectory holds adjusted standard GPS "
                             "time; expected the same time system")
    check_consistent([(f.path, las_file_crs(f.path, f.points.crs), f.time_system) for f in files])
    return files


def bounds(files: list[StripFile]) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest x, y, z (CRS units) of the files' headers (of those holding points)."""
    headers = [h for h in (las_header(f.path) for f in files) if h.point_count] or [las_header(files[0].path)]
    return np.min([h.mins for h in headers], axis=0), np.max([h.maxs for h in headers], axis=0)


def _frame(files: list[StripFile]) -> LocalFrame:
    """The local frame at the centre of the files' header bounds (of those holding points)."""
    from calidar import georef

    lo, hi = bounds(files)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    f = files[0]
    crs = las_file_crs(f.path, f.points.crs)
    return LocalFrame.at(georef.from_crs(corners, crs, f.points.geoid_undulation_m, source=f.path))


@dataclass
class _Footprints:
    """Pass 1's accumulators per group: cell counts, time range (trajectory's system), the
    overlap-quality counts (:class:`calidar.pipelines.line_quality.LineCounts`)."""

    cells: dict = field(default_factory=dict)
    t_min: dict = field(default_factory=dict)
    t_max: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)  #: group → the name of the (first) file holding it
    spans: dict = field(default_factory=dict)  #: (point_source_id, file name) → (first, last time)
    checks: dict = field(default_factory=dict)  #: file → its GeometryCheck (calidar.pipelines.plausibility)
    quality: LineCounts = field(default_factory=lambda: LineCounts(overlap_cell(None)))

    def add(self, groups: np.ndarray, keys: np.ndarray, t: np.ndarray, name: str, chunk, quality_keys) -> None:
        """A chunk's points (LasPoints with the selection fields) of ``groups`` in overlap cells
        ``keys`` and quality-grid cells ``quality_keys``, at times ``t``."""
        if chunk.point_source_id is not None:
            add_spans(self.spans, chunk.point_source_id, t, name)
        for g, rows in split_rows(groups):
            self.files.setdefault(g, name)
            self.cells.setdefault(g, []).append(cell_counts(keys[rows]))
            self.t_min[g] = min(self.t_min.get(g, np.inf), float(t[rows].min()))
            self.t_max[g] = max(self.t_max.get(g, -np.inf), float(t[rows].max()))
            fields = {f: None if getattr(chunk, f) is None else getattr(chunk, f)[rows] for f in SELECTION_FIELDS}
            self.quality.add(g, SimpleNamespace(xyz=quality_keys[rows], **fields), quality_keys[rows])

    def merge(self, other: "_Footprints") -> "_Footprints":
        """Both files' groups (a group may span files)."""
        self.checks.update(other.checks)
        for k, (t0, t1) in other.spans.items():
            s0, s1 = self.spans.get(k, (np.inf, -np.inf))
            self.spans[k] = (min(s0, t0), max(s1, t1))
        for g, cells in other.cells.items():
            self.files.setdefault(g, other.files[g])
            self.cells.setdefault(g, []).extend(cells)
            self.t_min[g] = min(self.t_min.get(g, np.inf), other.t_min[g])
            self.t_max[g] = max(self.t_max.get(g, -np.inf), other.t_max[g])
        self.quality.merge(other.quality)
        return self

    def lines(self, gap_s: float, notes: list | None = None) -> tuple[np.ndarray, np.ndarray, str]:
        """(sorted groups, line id of each, how): lines by point_source_id when it holds two
        distinct values (files sharing one id at times that do not interleave kept apart:
        :func:`calidar.strips.lines.shared_id_splits`, told in ``notes``), else numbered 1, 2, … in
        time order split at gaps > ``gap_s``."""
        groups = np.array(sorted(self.cells), np.int64)
        psid = groups >> BIN_BITS
        if np.unique(psid).size >= 2:
            splits, told = shared_id_splits(self.spans, gap_s)
            if notes is not None:
                notes += told
            return groups, split_ids(psid, np.array([self.t_min[int(g)] for g in groups]), splits), "point_source_id"
        t0 = np.array([self.t_min[g] for g in groups])
        t1 = np.array([self.t_max[g] for g in groups])
        order = np.argsort(t0, kind="stable")
        reach = np.maximum.accumulate(t1[order])
        new = np.r_[True, t0[order][1:] - reach[:-1] > gap_s]
        line = np.empty(groups.size, np.int64)
        line[order] = np.cumsum(new)
        return groups, line, "gps_time_gaps"


def _footprints(frame: LocalFrame, trajectory, options: IngestOptions, f: StripFile,
                hold=None) -> tuple[_Footprints, int | None, bool]:
    """Footprints and time checks of one file, chunk by chunk, its GPS week and whether ``hold``
    (a :class:`calidar.pipelines.held_points.HeldFiles`, or None) keeps the whole file: what pass
    2 and the overlap-quality stages need of its chunks (a task)."""
    acc, times, grid = _Footprints(), FileTimes(f.path, trajectory, f.time_system), overlap_cell(None)
    check, header = GeometryCheck(f.path.name), las_header(f.path)
    acc.checks[f.path] = check
    for chunk in iter_las_chunks(f.path, options.chunk_points, fields=("point_source_id", "scan_angle_deg",
                                                                       *SELECTION_FIELDS), options=f.points):
        t = times.feed(chunk.gps_time)
        ok = np.isfinite(t)
        if hold is not None and not (ok.all() and hold.add(f.path, chunk, t, header.scales, header.offsets)):
            hold = None  # not whole: read again
        chunk = chunk if ok.all() else chunk.select(ok)
        k = sample_rows(len(chunk))
        if np.all(trajectory.covers(t[ok][k])):  # points outside the trajectory: told by times.finish()
            check.add(trajectory, t[ok][k], points_ecef(chunk.select(k)), chunk.scan_angle_deg[k], len(chunk))
        else:
            check.seen += len(chunk)
        chunk = replace(chunk, scan_angle_deg=None)
        xy = planar_xy(chunk, frame)
        keys = cell_keys(xy, options.cell_m)
        acc.add(group_keys(chunk.point_source_id, t[ok], options.gap_s), keys, t[ok], f.path.name, chunk,
                keys if grid == options.cell_m else cell_keys(xy, grid))
    return acc, times.finish(name_trajectory=True), hold is not None  # the trajectory's span is what falls short


def _pass1(files: list[StripFile], frame: LocalFrame, trajectory, options: IngestOptions, progress: Progress,
           run: Callable | None = None, in_process: bool = True) -> tuple[_Footprints, dict, object]:
    """Footprints and time checks of every file (one task each, run by ``run``: a
    :meth:`calidar.strips.distribute.Workers.run`; None: one at a time here); the GPS week of each
    file; the points kept for pass 2 and the overlap quality (``in_process``: the tasks run here;
    see :data:`calidar.pipelines.strip_source.HOLD_POINTS_BYTES`): a HeldFiles, or None."""
    import shutil
    import tempfile

    from calidar.pipelines.held_points import HeldFiles
    from calidar.strips.distribute import Workers

    run = run or Workers().run
    acc, weeks, done = _Footprints(), {}, 0
    counts = [las_header(f.path).point_count for f in files]
    room = min(options.hold_bytes, shutil.disk_usage(tempfile.gettempdir()).free // 2) if in_process else 0
    hold = _held_files(counts, room)
    held = HeldFiles() if any(hold) else None
    parts = run(_footprints, [(f, held if h else None) for f, h in zip(files, hold)], shared=(frame, trajectory, options),
                kind="read footprints")
    for f, n, (part, week, whole) in zip(files, counts, parts):
        acc.merge(part)
        weeks[f.path] = week
        if whole:
            held.complete.add(f.path)
        done += n
        progress("reading strips", done, 2 * sum(counts))  # points, both passes
    return acc, weeks, held


def _held_files(counts: list[int], room: int) -> list[bool]:
    """Which files pass 1 holds for pass 2: in file order, those whose points still fit in ``room`` bytes."""
    hold = []
    for n in counts:
        need = HELD_BYTES_PER_POINT * n
        hold.append(need <= room)
        room -= need if need <= room else 0
    return hold


def _plan(acc: _Footprints, options: IngestOptions, notes: list | None = None) -> tuple[np.ndarray, np.ndarray, str, dict, dict,
                                                                        list, dict]:
    """Lines, their footprints, the overlapping pairs and the cells each line keeps (what the
    user should know about the lines added to ``notes``)."""
    groups, line, how = acc.lines(options.gap_s, notes)
    footprint, span = {}, {}
    for i in np.unique(line):
        gs = groups[line == i]
        footprint[int(i)] = merge_counts(*(c for g in gs for c in acc.cells[int(g)]))
        span[int(i)] = (min(acc.t_min[int(g)] for g in gs), max(acc.t_max[int(g)] for g in gs))
    occupied = {i: c[n >= options.min_points_per_cell] for i, (c, n) in footprint.items()}
    pairs = common_cells(occupied, options.min_cells)
    kept = thin_cells(pairs, footprint, options.budget_points, options.block_cells or block_cells(footprint, options))
    return groups, line, how, footprint, span, pairs, kept


def _with_control(kept: dict, footprint: dict, f: StripFile, frame: LocalFrame, options: IngestOptions) -> dict:
    """``kept`` with, for each line kept, its occupied cells around the control points (in the
    overlap grid's plane: the CRS's own metres when projected, else ``frame``'s east/north)."""
    from calidar.crs import to_crs
    from calidar.strips.control import cells_near

    crs = las_file_crs(f.path, f.points.crs)
    axis = crs.axis_info[0] if crs is not None and crs.is_projected else None
    if axis is not None and axis.unit_conversion_factor:
        xy = to_crs(options.control_ecef, crs, None, f.path)[:, :2] * axis.unit_conversion_factor
    else:
        xy = frame.to_local(options.control_ecef)[:, :2]
    near = cells_near(xy, options.cell_m)
    out = dict(kept)
    for i, cells in kept.items():
        mine = np.intersect1d(footprint[i][0], near)
        out[i] = np.union1d(cells, mine) if mine.size else cells
    return out


def block_cells(footprint: dict, options: IngestOptions) -> int:
    """Side (overlap cells) of the blocks kept whole: :data:`BLOCK_PATCHES` tie-plane patches of
    ≈ PlaneSettings.target_points points at the median density of the lines."""
    from calidar.strips.planes import PlaneSettings

    density = np.median([n.sum() / max(n.size * options.cell_m**2, 1e-9) for _, n in footprint.values()])
    patch_m = np.sqrt(PlaneSettings().target_points / max(density, 1e-9))
    return int(np.clip(np.ceil(BLOCK_PATCHES * patch_m / options.cell_m), 1, MAX_BLOCK_CELLS))


def _kept_points(source: StripSource, kept: dict, f: StripFile) -> dict[int, tuple]:
    """The points of one file inside its lines' kept cells: line → (ECEF (n, 3) m, times s), as
    pass 1 kept them or read again (a task)."""
    ecef, times = {}, {}
    for _, chunk, ids, t in source.chunks(files=[f]):
        keys = source.cell_keys(chunk)
        for i, rows in split_rows(ids):
            cells = kept.get(i)
            if cells is None or cells.size == 0:
                continue
            pos = np.minimum(np.searchsorted(cells, keys[rows]), cells.size - 1)
            sel = rows[cells[pos] == keys[rows]]
            ecef.setdefault(i, []).append(points_ecef(chunk.select(sel)))
            times.setdefault(i, []).append(t[sel])
    return {i: (np.concatenate(ecef[i]), np.concatenate(times[i])) for i in ecef}


def ingest_strips(paths, trajectory, sensor, options: IngestOptions = IngestOptions(), progress: Progress = no_progress,
                  work=None) -> tuple[list[Strip], object, StripSource, list[str]]:
    """The strips of the LAS/LAZ files (only their kept overlap points), the CRS, the
    :class:`StripSource` to stream the whole lines again, and notes for the user. Each file is
    read as one task per pass, run by ``work`` (a :class:`calidar.strips.distribute.Workers`;
    None: one at a time here)."""
    from calidar.strips.distribute import Workers, run_tasks

    if not paths:
        raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
    run = (work or Workers()).run
    files = _files(paths, trajectory, sensor, options)
    frame = _frame(files)
    acc, weeks, held = _pass1(files, frame, trajectory, options, progress, run, work is None or work.client is None)
    line_notes: list[str] = []
    groups, line, how, footprint, span, pairs, kept = _plan(acc, options, line_notes)
    if options.control_ecef is not None:
        kept = _with_control(kept, footprint, files[0], frame, options)
    names = {int(i): acc.files[int(groups[line == i][0])] for i in footprint}
    if not pairs:
        listed = ", ".join(strip_name(i, names) for i in sorted(footprint))
        raise CalibrationError(f"no two of the {len(footprint)} flight lines ({listed}) overlap (no {options.min_cells} "
                               f"common {options.cell_m:g} m cells); strip calibration needs overlapping flight lines")
    line_of = dict(zip(groups.tolist(), line.tolist()))
    source = StripSource(files, frame, trajectory, groups, line, how, options, weeks,
                         {i: int(n.sum()) for i, (_, n) in footprint.items()},
                         LineCounts(acc.quality.grid_m).merge(acc.quality, line_of.__getitem__), names, held)
    ecef, times, where = {}, {}, {}
    total = 2 * sum(las_header(f.path).point_count for f in files)
    done = total // 2
    for f, part in zip(files, run(_kept_points, [(f,) for f in files], shared=(source, kept), kind="read kept points")):
        for i, (e, t) in part.items():
            ecef.setdefault(i, []).append(e)
            times.setdefault(i, []).append(t)
            where.setdefault(i, {})[str(f.path)] = None
        done += las_header(f.path).point_count
        progress("reading strips", done, total)
    build = [(i, np.concatenate(ecef.pop(i)), np.concatenate(times.pop(i)), trajectory, sensor, frame,
              ", ".join(where[i]), span[i]) for i in sorted(ecef)]
    for i, e, t, *_ in build:  # wrong CRS or zone, wrong trajectory: one clear error before the adjustment
        GeometryCheck(f"flight line {strip_name(i, names)}", label="its overlap points").add(trajectory, t, e, None)
    strips = list(run_tasks(Strip.from_ecef, build, threads=work.local_threads if work else 1))
    crs = las_file_crs(files[0].path, files[0].points.crs)
    notes = line_notes + unpaired_notes(footprint, pairs, options.cell_m, options.min_cells, names)
    checks = [acc.checks[f.path] for f in files if f.path in acc.checks]
    return strips, crs, source, notes + heights_notes(crs, files[0].points.geoid_undulation_m, checks)
