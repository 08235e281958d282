"""The strip-quality pipeline (``calidar quality`` and the boresight report's before/after):
flight lines of LAS/LAZ files, the points fit for a swath difference, and the swath-overlap
difference of every overlapping pair.

``calidar quality`` streams in two passes. The first reads point_source_id, classification,
GPS time and coordinates (:func:`calidar.ingest.lines.index_flight_lines`: the flight lines
and the classes each file holds, hence its point selection) and counts the points of each
candidate selection on the 5 m overlap grid (:class:`calidar.ingest.cell_counts.CellCounts`): which lines overlap and the
cell of each pair (:func:`calidar.strips.quality.overlap_plan`). The second feeds the selected
points of each chunk to a :class:`calidar.strips.quality.SwathAccumulator` that keeps moments
on those cells only; memory holds cells, not points. The boresight pipeline feeds its
(re-georeferenced) lines to the same plan and accumulator (:mod:`calidar.ingest.stages`).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.ingest.cell_counts import CellCounts, Metric, held_chunks
from calidar.ingest.stages import checked_differences
from calidar.io.las import PointOptions
from calidar.strips.selection import FIELDS as SELECTION_FIELDS
from calidar.strips.selection import choose_selection

CHUNK_POINTS = 500_000  #: points read at once (the chunk, not the file, sets the peak memory with the cells)
FIELDS = ("point_source_id", *SELECTION_FIELDS)  #: point fields a chunk needs: flight line and the selection's


def measure(paths, cell_m=None, classes=None, options: PointOptions = PointOptions(), chunk_points: int = CHUNK_POINTS):
    """Streamed ``calidar quality``: (line index, file CRS, PairQualitys, notes, selection per file,
    each line's smooth-surface precision (:class:`calidar.strips.usgs.LinePrecision`)). Every point
    is decompressed once: the first pass keeps what the second needs (:mod:`calidar.ingest.held`)."""
    from calidar.io.las import las_file_crs, las_header
    from calidar.ingest.held import HeldPoints
    from calidar.ingest.lines import index_flight_lines
    from calidar.strips.quality import QualitySettings, SwathAccumulator, overlap_cell, overlap_plan
    from calidar.strips.selection import PointSelection

    paths = [Path(p) for p in paths]
    crs, header = las_file_crs(paths[0], options.crs), las_header(paths[0])
    metric = Metric.at(crs, header.mins, header.maxs, options.geoid_undulation_m, paths[0])
    first = [PointSelection("classes", classes)] if classes else [PointSelection("ground", (2,)),
                                                                  PointSelection("last returns")]
    with tempfile.TemporaryDirectory(prefix="calidar-moments-") as spill:  # held points, cell moments beyond HOLD_BYTES
        counts = CellCounts({p: first for p in paths}, metric, overlap_cell(cell_m), HeldPoints(Path(spill)))
        raw = ("X", "Y", "Z") if metric.frame is None else ()
        index = index_flight_lines(paths, options, chunk_points=chunk_points, on_chunk=counts,
                                   fields=("x", "y", "z", *raw, *SELECTION_FIELDS[1:]))
        if len(index.ids) < 2:
            raise InputError(", ".join(sorted({str(p) for p in paths})), "point_source_id",
                             f"found one flight line ({index.how}); expected at least two overlapping lines")
        selections = {p: choose_selection(p, index.classes[p], classes) for p in paths}
        settings = QualitySettings(cell_m=cell_m)
        names = counts.names(index)  #: line → a file holding it (for messages)
        plan = overlap_plan(counts.by_line(index, selections), counts.grid_m, settings, names)
        acc = SwathAccumulator(cell_m, plan, Path(spill))
        for p in paths:
            for xyz, psid, t in held_chunks(counts.held, p, first.index(selections[p]), metric):
                ids = index.of(psid, t)
                for i in np.unique(ids):
                    acc.add(int(i), xyz[ids == i], selections[p])
        for i in index.ids:  # lines without a selected point: named in the notes
            acc.add(i, np.zeros((0, 3)))
        results, notes = checked_differences(acc, settings, names)
        precisions = line_precisions(acc, settings)
    from calidar.ingest.plausibility import heights_notes

    notes = [*index.notes, *notes, *heights_notes(crs, options.geoid_undulation_m, relative=True)]
    return index, crs, results, notes, selections, precisions


def line_precisions(acc, settings) -> list:
    """Each line's intraswath precision from the accumulator's moments (:mod:`calidar.strips.usgs`)."""
    from calidar.strips.usgs import line_precision

    return [line_precision(i, acc.line_moments(i), settings.max_rms_m, settings.max_slope_deg, settings.min_points)
            for i in sorted(acc.selections)]


def write_rasters(q, out_dir: str | Path, crs=None, force: bool = False) -> list[Path]:
    """A pair's dz grid as GeoTIFF (``dz_<a>_<b>.tif``, float32 m, NaN nodata) and its picture
    (``dz_<a>_<b>.png``, :func:`calidar.strips.quality.dz_figure`); none when the pair has no grid."""
    import matplotlib

    matplotlib.use("Agg")
    from calidar.io.raster import write_geotiff, write_png
    from calidar.strips.quality import dz_figure

    if q.grid.size == 0:
        return []
    out_dir = Path(out_dir)
    tif = write_geotiff(out_dir / f"dz_{q.a}_{q.b}.tif", q.grid, q.cell_m, q.origin, crs, force)
    return [tif, write_png(out_dir / f"dz_{q.a}_{q.b}.png", dz_figure(q), force)]
