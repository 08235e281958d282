"""The strip-quality pipeline (``calidar quality`` and the boresight report's before/after):
flight lines of LAS/LAZ files, the points fit for a swath difference, and the swath-overlap
difference of every overlapping pair.

``calidar quality`` streams: a first pass reads point_source_id, classification and GPS time
(:func:`calidar.strips.lines.index_flight_lines`: the flight lines and the classes each file
holds, hence its point selection), a second pass feeds the selected points of each chunk to a
:class:`calidar.strips.quality.SwathAccumulator`; memory holds cells, not points. The boresight
pipeline feeds its (re-georeferenced) lines to the same accumulator (:func:`lines_quality`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from calidar.errors import InputError
from calidar.io.las import PointOptions

CHUNK_POINTS = 1_000_000
#: point fields a chunk needs: flight line and the selection's
FIELDS = ("point_source_id", "classification", "return_number", "number_of_returns")


@dataclass(frozen=True)
class Metric:
    """Coordinates for the swath difference: metric with z up: the CRS's own when projected, else
    local ENU at ``frame`` (one frame for all lines)."""

    frame: object | None = None  #: calidar.strips.strip.LocalFrame for a geographic CRS

    @classmethod
    def at(cls, crs, xyz_min, xyz_max, geoid_undulation_m=None, source=None) -> "Metric":
        """For points in ``crs`` within the bounds (x/lon, y/lat, z)."""
        if crs is None or not crs.is_geographic:
            return cls()
        from calidar.georef import from_crs
        from calidar.strips.strip import LocalFrame

        centre = 0.5 * (np.asarray(xyz_min, float) + np.asarray(xyz_max, float))
        return cls(LocalFrame.at(from_crs(centre[None, :], crs, geoid_undulation_m, source=source)))

    def of(self, points) -> np.ndarray:
        """Metric coordinates (N, 3) of LasPoints."""
        if self.frame is None:
            return points.xyz
        from calidar.georef import from_crs

        return self.frame.to_local(from_crs(points.xyz, points.crs, points.geoid_undulation_m, source=points.path))


def measure(paths, cell_m=None, classes=None, options: PointOptions = PointOptions(), chunk_points: int = CHUNK_POINTS):
    """Streamed ``calidar quality``: (line index, file CRS, PairQualitys, notes, selection per file)."""
    from calidar.io.las import iter_las_chunks, las_file_crs, las_header
    from calidar.strips.lines import index_flight_lines
    from calidar.strips.quality import SwathAccumulator
    from calidar.strips.selection import choose_selection

    paths = [Path(p) for p in paths]
    index = index_flight_lines(paths, options, chunk_points=chunk_points)
    if len(index.ids) < 2:
        raise InputError(paths[0], "point_source_id",
                         f"found one flight line ({index.how}); expected at least two overlapping lines")
    selections = {p: choose_selection(p, index.classes[p], classes) for p in paths}
    crs, header = las_file_crs(paths[0], options.crs), las_header(paths[0])
    metric = Metric.at(crs, header.mins, header.maxs, options.geoid_undulation_m, paths[0])
    acc = SwathAccumulator(cell_m)
    for p in paths:
        for chunk in iter_las_chunks(p, chunk_points, fields=FIELDS, options=options):
            chunk = chunk.select(selections[p].mask(chunk))
            ids, xyz = index.of(chunk.point_source_id, chunk.gps_time), metric.of(chunk)
            for i in np.unique(ids):
                acc.add(int(i), xyz[ids == i], selections[p])
    for i in index.ids:  # lines without a selected point: named in the notes
        acc.add(i, np.zeros((0, 3)))
    results, notes = _differences(acc, cell_m)
    return index, crs, results, notes, selections


def lines_quality(lines, cell_m=None, classes=None):
    """The PairQuality of every overlapping pair of flight lines given as (id, LasPoints) in memory
    (the selection chosen per line from the classes it holds), and the notes: what the boresight
    pipeline measures, with the code ``calidar quality`` runs."""
    from calidar.strips.quality import SwathAccumulator
    from calidar.strips.selection import choose_selection

    acc, metric = SwathAccumulator(cell_m), None
    for i, p in lines:
        if metric is None:
            metric = Metric.at(p.crs, p.xyz.min(axis=0), p.xyz.max(axis=0), p.geoid_undulation_m, p.path)
        present = None if p.classification is None else np.unique(p.classification)
        selection = choose_selection(p.path, present, classes)
        keep = selection.mask(p)
        acc.add(int(i), metric.of(p)[keep], selection)
    return _differences(acc, cell_m)


def _differences(acc, cell_m):
    """The accumulator's pairs and notes; an error when no line overlaps another."""
    from calidar.strips.quality import QualitySettings

    results, notes = acc.differences(QualitySettings(cell_m=cell_m))
    if not results:
        ids = sorted(acc.moments)
        raise InputError(None, "STRIPS", f"none of the {len(ids)} flight lines ({', '.join(map(str, ids))}) "
                         "overlap another; nothing to compare")
    return results, notes
