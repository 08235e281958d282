"""The streaming engine's reading of LAS/LAZ strips for the strip calibration
(:class:`StripIngest`, one :class:`~calidar.ingest.settings.IngestSettings`): bounded memory,
linear time.

Two streamed passes over the files (chunks of :attr:`IngestSettings.chunk_points`, never a
whole file in memory):

1. coarse (:mod:`calidar.ingest.footprints`): footprints on the overlap grid (cells of ``cell_m``
   in the CRS's own metres when it is projected, else in the survey's
   :class:`~calidar.strips.strip.LocalFrame`, set from the files' header bounds) per group of
   points, and the time checks. The groups become flight lines
   (:func:`calidar.strips.lines.split_lines`), their footprints the pairwise overlap cells
   (:func:`calidar.strips.overlap.common_cells`), thinned to ``budget_points`` per strip by
   keeping whole cells spread evenly (:mod:`calidar.strips.thin`);
2. keep: the points of each line inside its kept cells, transformed to ECEF, from which the
   :class:`~calidar.strips.strip.Strip` s are built (one inverse georeferencing).

:class:`~calidar.ingest.source.StripSource` streams the whole lines again for the outputs.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np

from calidar.errors import CalibrationError, InputError
from calidar.ingest import Progress, no_progress
from calidar.ingest.footprints import Footprints, first_pass
from calidar.ingest.plausibility import GeometryCheck, heights_notes
from calidar.ingest.settings import BLOCK_PATCHES, MAX_BLOCK_CELLS, IngestSettings
from calidar.ingest.source import StripFile, StripSource, calibration_mask, split_rows
from calidar.ingest.stages import LineCounts
from calidar.ingest.times import points_ecef
from calidar.io.las import las_file_crs, las_header, las_time_system
from calidar.strips.overlap import common_cells, merge_counts, strip_name, unpaired_notes
from calidar.strips.selection import excluded_words
from calidar.strips.strip import LocalFrame, Strip
from calidar.strips.thin import thin_cells


def _files(paths, trajectory, sensor, settings: IngestSettings) -> list[StripFile]:
    """Each file's CRS (its own, --crs or sensor.toml's) and time system; all must agree, and
    match the trajectory's (adjusted standard points become its week seconds, not back)."""
    from calidar.ingest.lines import check_consistent, check_distinct

    check_distinct(paths)
    files = []
    for p in map(Path, paths):
        crs = las_file_crs(p, settings.points.crs)
        if crs is None and sensor.crs is None:
            raise InputError(p, "crs", "the file has no CRS and sensor.toml gives none; expected "
                             "one of them")
        opts = settings.points if crs is not None else replace(settings.points, crs=sensor.crs)
        files.append(StripFile(p, opts, las_time_system(p, opts.time_system)))
        week_seconds = files[-1].time_system == "gps_week_seconds"
        if week_seconds and trajectory.time_system == "gps_adjusted_standard":
            raise InputError(p, "gps_time", "holds GPS week seconds but the trajectory holds "
                             "adjusted standard GPS time; expected the same time system")
    check_consistent([(f.path, las_file_crs(f.path, f.points.crs), f.time_system) for f in files])
    return files


def bounds(files: list[StripFile]) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest x, y, z (CRS units) of the files' headers (of those holding
    points)."""
    headers = [h for h in (las_header(f.path) for f in files) if h.point_count]
    headers = headers or [las_header(files[0].path)]
    return np.min([h.mins for h in headers], axis=0), np.max([h.maxs for h in headers], axis=0)


def _frame(files: list[StripFile]) -> LocalFrame:
    """The local frame at the centre of the files' header bounds (of those holding points)."""
    from calidar import georef

    lo, hi = bounds(files)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                        for z in (lo[2], hi[2])])
    f = files[0]
    crs = las_file_crs(f.path, f.points.crs)
    return LocalFrame.at(georef.from_crs(corners, crs, f.points.geoid_undulation_m, source=f.path))


def _plan(acc: Footprints, settings: IngestSettings,
          notes: list | None = None) -> tuple[np.ndarray, np.ndarray, str, dict, dict, list, dict]:
    """Lines, their footprints, the overlapping pairs and the cells each line keeps (what the
    user should know about the lines added to ``notes``)."""
    groups, line, how = acc.lines(settings.gap_s, notes)
    footprint, span = {}, {}
    for i in np.unique(line):
        gs = groups[line == i]
        footprint[int(i)] = merge_counts(*(c for g in gs for c in acc.cells[int(g)]))
        span[int(i)] = (min(acc.t_min[int(g)] for g in gs), max(acc.t_max[int(g)] for g in gs))
    occupied = {i: c[n >= settings.min_points_per_cell] for i, (c, n) in footprint.items()}
    pairs = common_cells(occupied, settings.min_cells)
    block = settings.block_cells or block_cells(footprint, settings)
    kept = thin_cells(pairs, footprint, settings.budget_points, block)
    return groups, line, how, footprint, span, pairs, kept


def _with_near(kept: dict, footprint: dict, f: StripFile, frame: LocalFrame, near: np.ndarray,
               cell_m: float) -> dict:
    """``kept`` with, for each line kept, its occupied cells around the points ``near`` (ECEF (N,
    3) m; in the overlap grid's plane: the CRS's own metres when projected, else ``frame``'s
    east/north)."""
    from calidar.crs import to_crs
    from calidar.strips.control import cells_near

    crs = las_file_crs(f.path, f.points.crs)
    axis = crs.axis_info[0] if crs is not None and crs.is_projected else None
    if axis is not None and axis.unit_conversion_factor:
        xy = to_crs(near, crs, None, f.path)[:, :2] * axis.unit_conversion_factor
    else:
        xy = frame.to_local(near)[:, :2]
    around = cells_near(xy, cell_m)
    out = dict(kept)
    for i, cells in kept.items():
        mine = np.intersect1d(footprint[i][0], around)
        out[i] = np.union1d(cells, mine) if mine.size else cells
    return out


def block_cells(footprint: dict, settings: IngestSettings) -> int:
    """Side (overlap cells) of the blocks kept whole: :data:`BLOCK_PATCHES` tie-plane patches of
    ≈ PlaneSettings.target_points points at the median density of the lines."""
    from calidar.strips.planes import PlaneSettings

    # points per m² of each line's occupied cells
    density = np.median([n.sum() / max(n.size * settings.cell_m**2, 1e-9)
                         for _, n in footprint.values()])
    patch_m = np.sqrt(PlaneSettings().target_points / max(density, 1e-9))
    return int(np.clip(np.ceil(BLOCK_PATCHES * patch_m / settings.cell_m), 1, MAX_BLOCK_CELLS))


def _kept_points(source: StripSource, kept: dict, f: StripFile) -> dict[int, tuple]:
    """The points of one file inside its lines' kept cells (of the classes the calibration uses:
    :func:`~calidar.ingest.source.calibration_mask`): line → (ECEF (n, 3) m, times s), as pass 1
    kept them or read again (a task)."""
    from calidar.ingest.line_kernels import kept_table

    ecef, times, table = {}, {}, kept_table(kept)
    for _, chunk, ids, t in source.chunks(("classification",), files=[f]):
        for i, sel in _kept_rows(source, kept, table, chunk, ids):
            ecef.setdefault(i, []).append(points_ecef(chunk.select(sel)))
            times.setdefault(i, []).append(t[sel])
    return {i: (np.concatenate(ecef[i]), np.concatenate(times[i])) for i in ecef}


def _kept_rows(source: StripSource, kept: dict, table: tuple, chunk, ids: np.ndarray):
    """(line, positions in the chunk of its points in its kept cells and of the classes used) of
    each line of the chunk with kept cells, in line order: one numba loop
    (:func:`calidar.ingest.line_kernels.kept_mask`) where the overlap grid is the CRS's own
    metres (``table``: :func:`~calidar.ingest.line_kernels.kept_table` of ``kept``), else the
    numpy steps (the same rows)."""
    from calidar.ingest.line_kernels import kept_mask

    axis = chunk.crs.axis_info[0] if chunk.crs is not None and chunk.crs.is_projected else None
    factor = axis.unit_conversion_factor if axis is not None else None
    classes = None if source.settings.all_classes else chunk.classification
    got = None if not factor else kept_mask(ids, chunk.xyz, factor, source.settings.cell_m,
                                            table, classes)
    if got is None:
        yield from _kept_rows_numpy(source, kept, chunk, ids)
        return
    mask, lines = got
    sel = np.flatnonzero(mask)
    if lines.size == 1:
        yield int(lines[0]), sel
        return
    of = ids[sel]
    for i in lines.tolist():
        yield i, sel[of == i]


def _kept_rows_numpy(source: StripSource, kept: dict, chunk, ids: np.ndarray):
    """:func:`_kept_rows` by numpy steps (any CRS, any classes)."""
    yield from rows_in_kept_cells(ids, source.cell_keys(chunk),
                                  calibration_mask(chunk, source.settings), kept)


def rows_in_kept_cells(ids: np.ndarray, keys: np.ndarray, use: np.ndarray | None, kept: dict):
    """(line, rows) of a chunk's points whose line ``ids`` has its cell ``keys`` among the line's
    ``kept`` cells (sorted keys) and whose ``use`` is true (None: every point)."""
    for i, rows in split_rows(ids):
        cells = kept.get(i)
        if cells is None or cells.size == 0:
            continue
        pos = np.minimum(np.searchsorted(cells, keys[rows]), cells.size - 1)
        inside = cells[pos] == keys[rows]
        yield i, rows[inside if use is None else inside & use[rows]]


class Ingested(NamedTuple):
    """What :meth:`StripIngest.read` gives."""

    strips: list[Strip]  #: one per overlapping flight line: its kept overlap points
    crs: object  #: the files' CRS (pyproj.CRS, or None)
    source: StripSource  #: the files behind the strips, to stream the whole lines again
    notes: list[str]  #: what the user should know (lines split, pairs not overlapping, heights)


@dataclass(frozen=True)
class StripIngest:
    """The streaming engine for strip calibration: reads LAS/LAZ strips as its ``settings`` say.

    >>> StripIngest().settings.budget_points
    300000
    """

    settings: IngestSettings = field(default_factory=IngestSettings)

    def read(self, paths, trajectory, sensor, near: np.ndarray | None = None,
             progress: Progress = no_progress, work=None) -> Ingested:
        """The strips of the LAS/LAZ files ``paths`` flown with ``trajectory`` and georeferenced
        with ``sensor`` (only their kept overlap points; each line also keeps its cells around the
        points ``near``, ECEF (N, 3) m: ground control, checkpoints). Each file is read as one task
        per pass, run by ``work`` (a :class:`calidar.strips.distribute.Workers`; None: one at a
        time here)."""
        from calidar.strips.distribute import Workers

        s = self.settings
        if not paths:
            raise InputError(None, "STRIPS", "expected at least one LAS/LAZ file")
        run = (work or Workers()).run
        files = _files(paths, trajectory, sensor, s)
        frame = _frame(files)
        in_process = work is None or work.client is None
        acc, weeks, held = first_pass(files, frame, trajectory, s, progress, run, in_process)
        line_notes: list[str] = []
        groups, line, how, footprint, span, pairs, kept = _plan(acc, s, line_notes)
        if near is not None:
            kept = _with_near(kept, footprint, files[0], frame, near, s.cell_m)
        names = {int(i): acc.files[int(groups[line == i][0])] for i in footprint}
        if not pairs:
            listed = ", ".join(strip_name(i, names) for i in sorted(footprint))
            raise CalibrationError(f"no two of the {len(footprint)} flight lines ({listed}) "
                                   f"overlap (no {s.min_cells} common {s.cell_m:g} m cells); strip "
                                   "calibration needs overlapping flight lines"
                                   + ("" if s.all_classes else
                                      f" (of classified files, {excluded_words(False)} are "
                                      "left out: --all-classes counts them)"))
        line_of = dict(zip(groups.tolist(), line.tolist()))
        counts = {i: sum(acc.points[int(g)] for g in groups[line == i]) for i in footprint}
        quality = LineCounts(acc.quality.grid_m).merge(acc.quality, line_of.__getitem__)
        source = StripSource(files, frame, trajectory, groups, line, how, s, weeks, counts,
                             quality, names, held)
        strips = _strips(source, kept, sensor, span, progress, work)
        crs = las_file_crs(files[0].path, files[0].points.crs)
        notes = line_notes + unpaired_notes(footprint, pairs, s.cell_m, s.min_cells, names)
        checks = [acc.checks[f.path] for f in files if f.path in acc.checks]
        notes += heights_notes(crs, files[0].points.geoid_undulation_m, checks)
        return Ingested(strips, crs, source, notes)


def _strips(source: StripSource, kept: dict, sensor, span: dict, progress: Progress,
            work) -> list[Strip]:
    """Pass 2: the points of each line in its ``kept`` cells (one task per file), checked and
    built into Strips."""
    from calidar.strips.distribute import Workers, run_tasks

    files, trajectory, names = source.files, source.trajectory, source.names
    ecef, times, where = {}, {}, {}
    total = 2 * sum(las_header(f.path).point_count for f in files)
    done = total // 2
    parts = (work or Workers()).run(_kept_points, [(f,) for f in files], shared=(source, kept),
                                    kind="read kept points")
    for f, part in zip(files, parts):
        for i, (e, t) in part.items():
            ecef.setdefault(i, []).append(e)
            times.setdefault(i, []).append(t)
            where.setdefault(i, {})[str(f.path)] = None
        done += las_header(f.path).point_count
        progress("reading strips", done, total)
    build = [(i, np.concatenate(ecef.pop(i)), np.concatenate(times.pop(i)), trajectory, sensor,
              source.frame, ", ".join(where[i]), span[i]) for i in sorted(ecef)]
    # wrong CRS or zone, wrong trajectory: one clear error before the adjustment
    for i, e, t, *_ in build:
        check = GeometryCheck(f"flight line {strip_name(i, names)}", label="its overlap points")
        check.add(trajectory, t, e, None)
    return list(run_tasks(Strip.from_ecef, build, threads=work.local_threads if work else 1))
