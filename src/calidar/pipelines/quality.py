"""The strip-quality pipeline (``calidar quality`` and the boresight report's before/after):
flight lines of LAS/LAZ files, the points fit for a swath difference, and the swath-overlap
difference of every overlapping pair.

``calidar quality`` streams in two passes. The first reads point_source_id, classification,
GPS time and coordinates (:func:`calidar.ingest.lines.index_flight_lines`: the flight lines
and the classes each file holds, hence its point selection) and counts the points of each
candidate selection on the 5 m overlap grid (:class:`calidar.ingest.cell_counts.CellCounts`):
which lines overlap and the cell of each pair (:func:`calidar.strips.quality.overlap_plan`).
The second feeds the selected points of each chunk to a
:class:`calidar.strips.quality.SwathAccumulator` that keeps moments on those cells only; memory
holds cells, not points. The boresight pipeline feeds its (re-georeferenced) lines to the same
plan and accumulator (:mod:`calidar.ingest.stages`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.ingest.cell_counts import CellCounts, Metric, held_chunks
from calidar.ingest.stages import checked_differences
from calidar.io.las import PointOptions
from calidar.pipelines.config_file import FileConfig, Key, point_keys
from calidar.strips.quality import QualitySettings
from calidar.strips.selection import FIELDS as SELECTION_FIELDS
from calidar.strips.selection import choose_selection

#: m, grid cells accepted by --cell (finer than lidar spacing, coarser than overlaps)
CELL_RANGE_M = (0.01, 1000.0)
#: points read at once (the chunk, not the file, sets the peak memory with the cells)
CHUNK_POINTS = 500_000
#: point fields a chunk needs: flight line and the selection's
FIELDS = ("point_source_id", *SELECTION_FIELDS)


@dataclass(frozen=True)
class QualityConfig(FileConfig):
    """Everything a ``calidar quality`` run takes besides its files, built and checked once at the
    edge (the CLI, the accuracy pipeline) and passed down unchanged: the swath difference's
    settings (``settings``, its grid cell among them), the LAS ``classes`` compared (None: ground,
    class 2, where a file has it, else last and single returns on smooth cells), how the points
    are read (``points``: --crs, --time-system, --geoid-undulation) and ``chunk_points`` read at
    once.

    >>> QualityConfig(QualitySettings(cell_m=1.0), classes=(6, 2)).classes
    (2, 6)
    """

    #: its TOML file (``config.toml`` beside quality.json, ``--config``): the options' settings
    KEYS = (Key("cell_m", "settings.cell_m", "--cell"), Key("classes", "classes", "--classes"),
            *point_keys())
    COMMAND = "quality"

    settings: QualitySettings = QualitySettings()
    classes: tuple[int, ...] | None = None
    points: PointOptions = PointOptions()
    chunk_points: int = CHUNK_POINTS

    def __post_init__(self):
        typed = isinstance(self.settings, QualitySettings) and isinstance(self.points, PointOptions)
        if not typed:
            got = f"{self.settings!r}, {self.points!r}"
            raise TypeError(f"expected QualitySettings and PointOptions, got {got}")
        if self.classes is not None:
            if not self.classes or not all(_las_class(c) for c in self.classes):
                expected = f"expected LAS classes (integers 0–255), got {self.classes!r}"
                raise InputError(None, "--classes", expected)
            object.__setattr__(self, "classes", tuple(sorted(set(self.classes))))
        if not (isinstance(self.chunk_points, int) and self.chunk_points > 0):
            raise ValueError(f"chunk_points must be an integer > 0, got {self.chunk_points!r}")

    def check(self) -> None:
        """The grid cell in its range (the other values are checked when made)."""
        from calidar.validate import number

        if self.settings.cell_m is not None:
            number(self.settings.cell_m, "--cell", *CELL_RANGE_M, "m")


def _las_class(c) -> bool:
    """Whether ``c`` is a LAS classification (an integer 0–255)."""
    return isinstance(c, int) and 0 <= c <= 255


def measure(paths, config: QualityConfig = QualityConfig()):
    """Streamed ``calidar quality``: (line index, file CRS, PairQualitys, notes, selection per file,
    each line's smooth-surface precision (:class:`calidar.strips.usgs.LinePrecision`)). Every point
    is decompressed once: the first pass keeps what the second needs
    (:mod:`calidar.ingest.held`)."""
    from calidar.io.las import las_file_crs, las_header
    from calidar.ingest.held import HeldPoints, spill_folder
    from calidar.ingest.lines import index_flight_lines
    from calidar.strips.quality import SwathAccumulator, overlap_cell, overlap_plan
    from calidar.strips.distribute import IN_PROCESS_THREADS
    from calidar.strips.selection import PointSelection

    settings, classes, options = config.settings, config.classes, config.points
    cell_m = settings.cell_m
    paths = [Path(p) for p in paths]
    crs, header = las_file_crs(paths[0], options.crs), las_header(paths[0])
    metric = Metric.at(crs, header.mins, header.maxs, options.geoid_undulation_m, paths[0])
    first = [PointSelection("classes", classes)] if classes else [PointSelection("ground", (2,)),
                                                                  PointSelection("last returns")]
    # spill: held points, cell moments beyond HOLD_BYTES (removed beside the outputs' writing)
    with spill_folder("calidar-moments-") as spill:
        held = HeldPoints(spill)
        counts = CellCounts({p: first for p in paths}, metric, overlap_cell(cell_m), held)
        raw = ("X", "Y", "Z") if metric.frame is None else ()
        fields = ("x", "y", "z", *raw, *SELECTION_FIELDS[1:])
        index = index_flight_lines(paths, options, chunk_points=config.chunk_points,
                                   on_chunk=counts, fields=fields)
        if len(index.ids) < 2:
            files = ", ".join(sorted({str(p) for p in paths}))
            found = f"found one flight line ({index.how})"
            raise InputError(files, "point_source_id",
                             f"{found}; expected at least two overlapping lines")
        selections = {p: choose_selection(p, index.classes[p], classes) for p in paths}
        names = counts.names(index)  #: line → a file holding it (for messages)
        plan = overlap_plan(counts.by_line(index, selections), counts.grid_m, settings, names)
        acc = SwathAccumulator(cell_m, plan, spill)
        for p in paths:
            for xyz, psid, t in held_chunks(counts.held, p, first.index(selections[p]), metric):
                ids = index.of(psid, t)
                lines = np.unique(ids)
                if lines.size == 1:  # the chunk's points of one line (as usual): no copy
                    acc.add(int(lines[0]), xyz, selections[p])
                    continue
                for i in lines:
                    acc.add(int(i), xyz.take(np.flatnonzero(ids == i), axis=0), selections[p])
        for i in index.ids:  # lines without a selected point: named in the notes
            acc.add(i, np.zeros((0, 3)))
        # the pairs in threads
        results, notes = checked_differences(acc, settings, names, IN_PROCESS_THREADS)
        precisions = line_precisions(acc, settings)
    from calidar.ingest.plausibility import heights_notes

    notes = [*index.notes, *notes, *heights_notes(crs, options.geoid_undulation_m, relative=True)]
    return index, crs, results, notes, selections, precisions


def line_precisions(acc, settings) -> list:
    """Each line's intraswath precision from the accumulator's moments
    (:mod:`calidar.strips.usgs`)."""
    from calidar.strips.usgs import line_precision

    limits = (settings.max_rms_m, settings.max_slope_deg, settings.min_points)
    return [line_precision(i, acc.line_moments(i), *limits) for i in sorted(acc.selections)]


def write_rasters(q, out_dir: str | Path, crs=None, force: bool = False) -> list[Path]:
    """A pair's dz grid as GeoTIFF (``dz_<a>_<b>.tif``, float32 m, NaN nodata) and its picture
    (``dz_<a>_<b>.png``: :func:`dz_picture`); none when the pair has no grid."""
    from calidar.io.raster import write_geotiff
    from calidar.outputs import atomic_path

    if q.grid.size == 0:
        return []
    out_dir = Path(out_dir)
    tif = write_geotiff(out_dir / f"dz_{q.a}_{q.b}.tif", q.grid, q.cell_m, q.origin, crs, force)
    png = out_dir / f"dz_{q.a}_{q.b}.png"
    with atomic_path(png, force) as tmp:
        tmp.write_bytes(dz_picture(q))
    return [tif, png]


def dz_picture(q) -> bytes:
    """A pair's dz map as PNG bytes (:func:`calidar.report.map_picture.map_png`, no matplotlib
    figure): diverging colours on ± the 98th percentile of |dz|, its colour bar and title."""
    from calidar.report.map_picture import map_png

    median, rmsdz = f"{q.median_dz_m or 0:+.3f} m", f"{q.rmsdz_m or 0:.3f} m"
    return map_png(q.grid, q.origin, q.cell_m,
                   f"strips {q.a} − {q.b}: median {median}, RMSDz {rmsdz}",
                   f"dz = z({q.a}) − z({q.b}) [m]")


def write_pairs_rasters(results, out_dir: str | Path, crs=None, force: bool = False) -> list[Path]:
    """:func:`write_rasters` of every pair."""
    return [f for q in results for f in write_rasters(q, out_dir, crs, force)]
