"""The files behind the strips: each :class:`StripFile` as it is read, and :class:`StripSource`,
which streams the whole flight lines again for the outputs (overlap quality, recalibrated
strips) — per chunk the points with their line ids and GPS times in the trajectory's system — as
:func:`line_chunks` re-georeferences them. :mod:`calidar.ingest.strips` reads the files into
strips with these.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.ingest.settings import BIN_BITS, IngestSettings
from calidar.ingest.stages import LineCounts
from calidar.ingest.times import FileTimes, points_ecef, points_tile_linear
from calidar.io.las import OPTIONAL_FIELDS, PointOptions, iter_las_chunks
from calidar.strips.overlap import cell_keys
from calidar.strips.selection import excluded
from calidar.strips.strip import LocalFrame

@dataclass(frozen=True)
class StripFile:
    """One input file as it is read: its point options (CRS resolved) and time system."""

    path: Path
    points: PointOptions
    time_system: str


@dataclass
class StripSource:
    """The files behind the strips, to stream again: frame, lines and the trajectory they use."""

    files: list[StripFile]
    frame: LocalFrame
    trajectory: object  #: calidar.trajectory.Trajectory
    groups: np.ndarray  #: sorted group keys (point_source_id, time bin)
    group_line: np.ndarray  #: flight-line id of each group
    how: str  #: "point_source_id" | "gps_time_gaps"
    settings: IngestSettings
    #: path → GPS week of the time conversion (None: none)
    weeks: dict = field(default_factory=dict)
    counts: dict = field(default_factory=dict)  #: line id → points in the files
    #: the lines' overlap-quality counts as delivered (the first pass's)
    quality: LineCounts | None = None
    names: dict = field(default_factory=dict)  #: line id → the name of a file holding it
    #: the points pass 1 kept (:class:`calidar.ingest.held.HeldFiles`; None: none), read
    #: instead of the files; not sent to other processes
    held: object = field(default=None, compare=False, repr=False)

    def __getstate__(self):
        return {**self.__dict__, "held": None}

    def chunks(self, fields: Sequence[str] = (), files: Sequence[StripFile] | None = None,
               span: tuple[int, int | None] = (0, None)) -> Iterator[tuple]:
        """(file, LasPoints chunk, line id per point, GPS time in the trajectory's system (s)) of
        every chunk of every file (or of ``files``; of their points [``span``) only): as pass 1
        kept them when it did (and ``fields`` are among those kept), else read again."""
        from calidar.ingest.held import STRIP_FIELDS

        kept = self.held is not None and set(fields) <= set(STRIP_FIELDS)
        for f in self.files if files is None else files:
            held = self.held.chunks(f.path, span) if kept else None
            for chunk, t in held if held is not None else self._read(f, fields, span):
                yield f, chunk, self.line_ids(f, chunk.point_source_id, t), t

    def line_ids(self, f: StripFile, psid, t: np.ndarray) -> np.ndarray:
        """The flight line of each point of a chunk of ``f`` (point_source_id, times in the
        trajectory's system): its group's (:func:`group_keys`); an error when a group was not
        seen in pass 1."""
        from calidar.ingest.line_kernels import chunk_lines

        ids, found = chunk_lines(psid, t, self.settings.gap_s, self.groups, self.group_line)
        if ids is None and found:  # a time not finite: numpy's cast
            g = group_keys(psid, t, self.settings.gap_s)
            pos = np.minimum(np.searchsorted(self.groups, g), self.groups.size - 1)
            found = np.array_equal(self.groups[pos], g)
            ids = self.group_line[pos]
        if not found:
            raise InputError(f.path, None, "the file changed while it was read")
        return ids

    def _read(self, f: StripFile, fields: Sequence[str],
              span: tuple[int, int | None]) -> Iterator[tuple]:
        """(LasPoints chunk, its GPS times in the trajectory's system) of the file ``f``."""
        times = FileTimes(f.path, self.trajectory, f.time_system)
        names = tuple(dict.fromkeys(("point_source_id", *fields)))
        for chunk in iter_las_chunks(f.path, self.settings.chunk_points, fields=names,
                                     options=f.points, start=span[0], stop=span[1]):
            yield chunk, times.feed(chunk.gps_time)

    def cell_keys(self, chunk) -> np.ndarray:
        """The overlap-grid cell of each point of a chunk (:func:`planar_xy`)."""
        return cell_keys(planar_xy(chunk, self.frame), self.settings.cell_m)


def line_chunks(source: StripSource, nominal, models=(None,), fields=None, where=None,
                files: Sequence[StripFile] | None = None, span=(0, None),
                select=None) -> Iterator[tuple[int, list]]:
    """Per chunk of the files (or of ``files``, their points [``span``)) and flight line, (line
    id, [LasPoints per model]):
    for each of ``models`` the delivered points (None) or those re-georeferenced with a (sensor,
    trajectory) (inverse once with the ``nominal`` sensor and the source's trajectory, forward
    with each, as :func:`calidar.georef.regeoreference`), in the files' CRS (the moves through
    :class:`calidar.crs.TileLinear`, within 0.1 mm of the full transform), ``fields``
    (default: all) as read; ``where(chunk)``: a mask of the points wanted. Whole lines, chunk by
    chunk (bounded memory). ``select(chunk, line ids)``: a mask of the points the caller reads
    (the tiles of the moves still laid over every point ``where`` keeps, so each moves as among
    all): only those go on, in their order, every line of the chunk still given (perhaps with
    none of its points)."""
    names = OPTIONAL_FIELDS if fields is None else fields
    for _, chunk, ids, t in source.chunks(names, files, span):
        if where is not None:
            keep = where(chunk)
            if not keep.all():  # (every point kept, as usual: the chunk itself, no copies)
                chunk, ids, t = chunk.select(keep), ids[keep], t[keep]
        take = None if select is None else _positions(select(chunk, ids))
        moved = _moved(source, nominal, models, chunk, t, take)
        every_line = ids  # the chunk's lines, before the selection
        if take is not None:
            chunk, ids = chunk.select(take), ids[take]
        versions = [chunk if m is None else replace(chunk, xyz=xyz)
                    for m, xyz in zip(models, moved or models)]
        one = every_line.size and every_line[0] == every_line[-1]
        if one and np.all(every_line == every_line[0]):  # one line: no copies
            yield int(every_line[0]), versions
            continue
        for i, rows in (split_rows(ids) if take is None else _rows_of(every_line, ids)):
            yield i, [v.select(rows) for v in versions]


def _moved(source: StripSource, nominal, models, chunk, t: np.ndarray,
           take: np.ndarray | None) -> list | None:
    """Per model (None: None) the CRS coordinates of the chunk's points (of those at ``take``
    only, in its order) re-georeferenced: every model in one pass (poses interpolated once;
    :mod:`calidar.ingest.regeoref`), else model by model; None when every model is None."""
    from calidar import georef
    from calidar.ingest.regeoref import moved_versions

    if all(m is None for m in models):
        return None
    lin = points_tile_linear(chunk)  # one TileLinear for every model
    moved = moved_versions(source.trajectory, nominal, models, t, lin, take, True)  # compact
    if moved is not None:
        return moved
    ecef = lin.near_ecef()  # ~1 mm: only the moves below count
    v_s = georef.scanner_vectors(source.trajectory, nominal, t, ecef)

    def move(m):
        xyz = lin.moved(georef.reforward(nominal, m[0], m[1], t, v_s) - ecef)
        return xyz if take is None else xyz[take]

    return [None if m is None else move(m) for m in models]


def _rows_of(every_line: np.ndarray, ids: np.ndarray) -> Iterator[tuple[int, np.ndarray]]:
    """(line, positions in ``ids`` of its points) of each line of ``every_line`` (sorted; a line
    none of whose points is in ``ids``: no positions)."""
    for i in np.unique(every_line).tolist():
        yield i, np.flatnonzero(ids == i)


def _positions(mask: np.ndarray) -> np.ndarray | None:
    """The positions a mask keeps; None when it keeps every one."""
    return None if mask.all() else np.flatnonzero(mask)


def planar_xy(chunk, frame: LocalFrame) -> np.ndarray:
    """Horizontal coordinates (n, 2) m for the overlap grid: the CRS's own when projected (scaled
    to metres), else east/north in ``frame`` (a geographic CRS)."""
    axis = chunk.crs.axis_info[0] if chunk.crs is not None and chunk.crs.is_projected else None
    if axis is not None and axis.unit_conversion_factor:
        return chunk.xyz[:, :2] * axis.unit_conversion_factor
    return frame.to_local(points_ecef(chunk))[:, :2]


def calibration_mask(chunk, settings: IngestSettings) -> np.ndarray | None:
    """Mask of the points of a chunk the strip calibration may use: all but the classes of
    :func:`calidar.strips.selection.excluded` (vegetation, noise, water), unless
    ``settings.all_classes``; None: every point (that option, or no classification read)."""
    if settings.all_classes or chunk.classification is None:
        return None
    return ~excluded(chunk.classification)


def group_keys(psid, t: np.ndarray, gap_s: float) -> np.ndarray:
    """Group key per point: point_source_id and the GPS time bin of ``gap_s``."""
    bins = np.floor(t / gap_s).astype(np.int64) & ((1 << BIN_BITS) - 1)
    return bins if psid is None else (np.asarray(psid, np.int64) << BIN_BITS) | bins


def split_rows(keys: np.ndarray) -> Iterator[tuple[int, np.ndarray]]:
    """(key, positions) of each distinct key of ``keys`` (e.g. the line ids of a chunk)."""
    order = np.argsort(keys, kind="stable")
    ks = keys[order]
    start = np.r_[0, np.flatnonzero(ks[1:] != ks[:-1]) + 1]
    for k, s, e in zip(ks[start], start, np.r_[start[1:], ks.size]):
        yield int(k), order[s:e]
