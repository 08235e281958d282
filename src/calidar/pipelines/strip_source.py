"""The files behind the strips and how they are read: :class:`IngestOptions`, each
:class:`StripFile`, and :class:`StripSource`, which streams the whole flight lines again for the
outputs (overlap quality, recalibrated strips) — per chunk the points with their line ids and
GPS times in the trajectory's system — as :func:`line_chunks` re-georeferences them.
:mod:`calidar.pipelines.strip_ingest` reads the files into strips with these.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.io.las import PointOptions, iter_las_chunks
from calidar.pipelines.inputs import FileTimes, points_ecef, points_tile_linear
from calidar.pipelines.line_quality import LineCounts
from calidar.strips.lines import GAP_S
from calidar.strips.overlap import cell_keys
from calidar.strips.strip import LocalFrame

#: points kept per strip by default: enough for the tie planes and VGICP on the test surveys
#: (results within σ of every overlapping point), small enough for bounded memory
BUDGET_POINTS = 300_000
MIN_BUDGET_POINTS = 10_000  #: fewer leave too few tie planes per pair to be worth a run
BIN_BITS = 40  #: group key = point_source_id << 40 | GPS time bin
#: kept blocks span this many tie-plane patches (of ≈ PlaneSettings.target_points points) across
BLOCK_PATCHES = 6
MAX_BLOCK_CELLS = 20

#: points read at once: with the overlap-quality stages' copies (a chunk re-georeferenced per stage)
#: this, not the files, sets the streaming memory (8.75 M points: 2 M → 2.1 GiB peak, 0.5 M → 1.3 GiB)
CHUNK_POINTS = 250_000
#: pass 1 keeps what pass 2 and the overlap-quality stages need of each point (stored coordinates,
#: time, point_source_id, the selection's fields: 25 B a point) in files of a temporary folder
#: (:class:`calidar.pipelines.held_points.HeldFiles`) when it runs in this process, so that no
#: point is decompressed twice: files in file order while they fit in this and in half the folder's
#: free space; the others are read again. Memory holds a chunk; 0 turns it off.
HOLD_POINTS_BYTES = 64 * 2**30
HELD_BYTES_PER_POINT = 25


@dataclass(frozen=True)
class IngestOptions:
    """How strips are read: ``budget_points`` kept per strip (None: every overlapping point),
    ``chunk_points`` per read, ``points`` (the shared --crs/--time-system/--geoid-undulation),
    ``gap_s`` (a pause in GPS time that starts a flight line when point_source_id does not
    tell them apart), the overlap grid (``cell_m``, ``min_cells``, ``min_points_per_cell``
    as :func:`calidar.strips.overlap.find_overlaps`) and the side of the square blocks kept
    whole (``block_cells`` overlap cells; None: :data:`BLOCK_PATCHES` tie-plane patches at the
    survey's density, at most :data:`MAX_BLOCK_CELLS`)."""

    budget_points: int | None = BUDGET_POINTS
    block_cells: int | None = None
    chunk_points: int = CHUNK_POINTS
    points: PointOptions = field(default_factory=PointOptions)
    gap_s: float = GAP_S
    cell_m: float = 5.0
    min_cells: int = 4
    min_points_per_cell: int = 3
    hold_bytes: int = HOLD_POINTS_BYTES  #: see :data:`HOLD_POINTS_BYTES`
    #: ground control points (ECEF (N, 3) m, ``calidar boresight --control``): each line also keeps
    #: its cells around them (:func:`calidar.strips.control.cells_near`)
    control_ecef: np.ndarray | None = field(default=None, compare=False, repr=False)


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
    options: IngestOptions
    weeks: dict = field(default_factory=dict)  #: path → GPS week of the time conversion (None: none)
    counts: dict = field(default_factory=dict)  #: line id → points in the files
    quality: LineCounts | None = None  #: the lines' overlap-quality counts as delivered (the first pass's)
    names: dict = field(default_factory=dict)  #: line id → the name of a file holding it
    #: the points pass 1 kept (:class:`calidar.pipelines.held_points.HeldFiles`; None: none), read
    #: instead of the files; not sent to other processes
    held: object = field(default=None, compare=False, repr=False)

    def __getstate__(self):
        return {**self.__dict__, "held": None}

    def chunks(self, fields: Sequence[str] = (), files: Sequence[StripFile] | None = None,
               span: tuple[int, int | None] = (0, None)) -> Iterator[tuple]:
        """(file, LasPoints chunk, line id per point, GPS time in the trajectory's system (s)) of
        every chunk of every file (or of ``files``; of their points [``span``) only): as pass 1
        kept them when it did (and ``fields`` are among those kept), else read again."""
        from calidar.pipelines.held_points import STRIP_FIELDS

        for f in self.files if files is None else files:
            held = None if self.held is None or not set(fields) <= set(STRIP_FIELDS) else self.held.chunks(f.path, span)
            for chunk, t in held if held is not None else self._read(f, fields, span):
                g = group_keys(chunk.point_source_id, t, self.options.gap_s)
                pos = np.minimum(np.searchsorted(self.groups, g), self.groups.size - 1)
                if not np.array_equal(self.groups[pos], g):
                    raise InputError(f.path, None, "the file changed while it was read")
                yield f, chunk, self.group_line[pos], t

    def _read(self, f: StripFile, fields: Sequence[str], span: tuple[int, int | None]) -> Iterator[tuple]:
        """(LasPoints chunk, its GPS times in the trajectory's system) of the file ``f``."""
        times = FileTimes(f.path, self.trajectory, f.time_system)
        for chunk in iter_las_chunks(f.path, self.options.chunk_points,
                                     fields=tuple(dict.fromkeys(("point_source_id", *fields))), options=f.points,
                                     start=span[0], stop=span[1]):
            yield chunk, times.feed(chunk.gps_time)

    def cell_keys(self, chunk) -> np.ndarray:
        """The overlap-grid cell of each point of a chunk (:func:`planar_xy`)."""
        return cell_keys(planar_xy(chunk, self.frame), self.options.cell_m)


def line_chunks(source: StripSource, nominal, models=(None,), fields=None, where=None,
                files: Sequence[StripFile] | None = None, span=(0, None)) -> Iterator[tuple[int, list]]:
    """Per chunk of the files (or of ``files``, their points [``span``)) and flight line, (line
    id, [LasPoints per model]):
    for each of ``models`` the delivered points (None) or those re-georeferenced with a (sensor,
    trajectory) (inverse once with the ``nominal`` sensor and the source's trajectory, forward
    with each, as :func:`calidar.georef.regeoreference`), in the files' CRS (the moves through
    :class:`calidar.crs.TileLinear`, within 0.1 mm of the full transform), ``fields``
    (default: all) as read; ``where(chunk)``: a mask of the points wanted. Whole lines, chunk by
    chunk (bounded memory)."""
    from calidar import georef
    from calidar.io.las import OPTIONAL_FIELDS

    for _, chunk, ids, t in source.chunks(OPTIONAL_FIELDS if fields is None else fields, files, span):
        if where is not None:
            keep = where(chunk)
            chunk, ids, t = chunk.select(keep), ids[keep], t[keep]
        lin = None if all(m is None for m in models) else points_tile_linear(chunk)  # one for every model
        ecef = None if lin is None else lin.near_ecef()  # ~1 mm: only the moves below count
        v_s = None if ecef is None else georef.scanner_vectors(source.trajectory, nominal, t, ecef)
        versions = [chunk if m is None else replace(chunk, xyz=lin.moved(
            georef.reforward(nominal, m[0], m[1], t, v_s) - ecef)) for m in models]
        if ids.size and ids[0] == ids[-1] and np.all(ids == ids[0]):  # one line: no copies
            yield int(ids[0]), versions
            continue
        for i, rows in split_rows(ids):
            yield i, [v.select(rows) for v in versions]


def planar_xy(chunk, frame: LocalFrame) -> np.ndarray:
    """Horizontal coordinates (n, 2) m for the overlap grid: the CRS's own when projected (scaled
    to metres), else east/north in ``frame`` (a geographic CRS)."""
    axis = chunk.crs.axis_info[0] if chunk.crs is not None and chunk.crs.is_projected else None
    if axis is not None and axis.unit_conversion_factor:
        return chunk.xyz[:, :2] * axis.unit_conversion_factor
    return frame.to_local(points_ecef(chunk))[:, :2]


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
